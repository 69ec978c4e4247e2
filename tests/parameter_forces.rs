//! The parameter vector–Jacobian product of the cell kernels: ∂f/∂θ of the internal forces, from
//! each kernel's own residual with the material's parameter derivative, against central finite
//! differences of the internal forces of the material rebuilt with θ ± h eₖ.

use deasim::api::{FieldsKept, RunOptions, Simulation};
use deasim::job::plan::Plan;
use deasim::problem::points::PointStates;
use deasim::problem::statics::{nodal_reactions_with, parameter_forces, parameter_vjp};
use deasim::problem::step::StepOperator;

/// The plan of `sim` and the nodal values of its last accepted step.
fn charged(sim: Simulation) -> (Plan, Vec<f64>) {
    let plan = sim.plan().unwrap();
    let results = sim
        .run(RunOptions {
            fields: FieldsKept::Last,
            ..RunOptions::default()
        })
        .expect("the run converges");
    (plan, results.fields[0].nodal.clone())
}

/// Checks every parameter of material `material` at `state` (committed `points`, step `dt`);
/// returns the number of parameters checked.
fn check(plan: &Plan, state: &[f64], points: &PointStates, dt: f64, material: usize) -> usize {
    let model = &plan.model;
    let base = model.materials[material].clone();
    let theta = base.parameters().expect("a registry material").values;
    let analytic = parameter_forces(model, state, points, dt, material, None).unwrap();
    assert_eq!(analytic.len(), theta.len());
    let w: Vec<f64> = (0..state.len())
        .map(|i| ((i * 7919) % 13) as f64 - 6.0)
        .collect();
    let vjp = parameter_vjp(model, state, points, dt, material, None, &w).unwrap();
    // only some entries: the same values there, 0 at the others
    let some: Vec<usize> = (0..theta.len()).step_by(2).collect();
    let part = parameter_vjp(model, state, points, dt, material, Some(&some), &w).unwrap();
    for (k, (a, b)) in part.iter().zip(&vjp).enumerate() {
        assert_eq!(*a, if some.contains(&k) { *b } else { 0.0 }, "entry {k}");
    }
    for (k, exact) in analytic.iter().enumerate() {
        let forces = |sign: f64, h: f64| {
            let mut t = theta.clone();
            t[k] += sign * h;
            let mut m = model.clone();
            m.materials[material] = base.with_parameters(&t).unwrap();
            nodal_reactions_with(&m, state, points, dt).unwrap()
        };
        let h = 1e-5 * theta[k].abs().max(1e-12);
        let (plus, minus) = (forces(1.0, h), forces(-1.0, h));
        let fd: Vec<f64> = plus
            .iter()
            .zip(&minus)
            .map(|(p, q)| (p - q) / (2.0 * h))
            .collect();
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let diff: Vec<f64> = fd.iter().zip(exact).map(|(a, b)| a - b).collect();
        let scale = norm(exact).max(norm(&fd));
        let name = &base.parameters().unwrap().names[k];
        assert!(scale > 0.0, "{name}: no force depends on it");
        // the central difference's round-off: the forces' own round-off over the step 2h (a
        // parameter that barely matters at this state, such as a Yeoh D₃ at J ≈ 1, has a
        // derivative far below the forces it perturbs)
        let round_off = 1e3 * f64::EPSILON * norm(&plus) / (2.0 * h);
        assert!(
            norm(&diff) <= 1e-6 * scale + round_off,
            "{name}: |fd − exact| = {:e} of {scale:e} (round-off {round_off:e})",
            norm(&diff)
        );
        let dot: f64 = exact.iter().zip(&w).map(|(a, b)| a * b).sum();
        assert!(
            (vjp[k] - dot).abs() <= 1e-12 * dot.abs().max(1e-300),
            "{name}"
        );
    }
    theta.len()
}

fn film() -> Simulation {
    Simulation::from_example("film")
        .unwrap()
        .set("stages.0.steps", "4")
        .set("electrodes.top.voltage.amplitude", "25e3")
        .set("materials.elastomer.c1", "1e-12")
        .set("materials.elastomer.c2", "-2e-12")
}

#[test]
fn parameter_forces_of_the_standard_kernel() {
    let (plan, state) = charged(film());
    let n = check(&plan, &state, &PointStates::default(), 0.0, 0);
    assert_eq!(n, 5, "mu, lambda, permittivity, c1, c2");
}

#[test]
fn parameter_forces_of_the_mean_dilatation_kernel() {
    let (plan, state) = charged(film().set("mesh.formulation", "\"mean-dilatation\"").set(
        "materials.elastomer",
        "{ model = \"gent\", mu = 1e5, jm = 20.0, kappa = 1e8, permittivity = 4.7, c1 = 1e-12 }",
    ));
    let n = check(&plan, &state, &PointStates::default(), 0.0, 0);
    assert_eq!(n, 6, "mu, jm, kappa, permittivity, c1, c2");
}

#[test]
fn parameter_forces_of_the_axisymmetric_kernel_with_its_pad() {
    let (plan, state) = charged(Simulation::from_example("diaphragm").unwrap());
    let mut checked = 0;
    for m in 0..plan.model.materials.len() {
        checked += check(&plan, &state, &PointStates::default(), 0.0, m);
    }
    assert!(checked >= 4, "{checked}");
}

#[test]
fn parameter_forces_of_maxwell_branches_through_a_step() {
    let visco = film()
        .set("materials.elastomer", "{ model = \"yeoh\", c10 = 3e4, c20 = -200.0, c30 = 5.0, d1 = 2e-8, permittivity = 4.7, branches = [{ mu = 5e4, tau = 0.3 }, { mu = 2e4, tau = 2.0 }] }");
    let (plan, state) = charged(visco);
    // internal variables committed at half the final state, then a step of 0.1 s to it
    let mut points = PointStates::new(&plan.model);
    let half: Vec<f64> = state.iter().map(|x| 0.5 * x).collect();
    points.commit(&plan.model, &half, 0.1).unwrap();
    let n = check(&plan, &state, &points, 0.1, 0);
    assert_eq!(
        n,
        3 + 1 + 3 + 4,
        "c10, c20, c30, d1, the dielectric three, two branches"
    );
}

/// wᵀ∂R/∂θ of a static problem's scaled residual over its free unknowns against central
/// differences of that residual (the unknowns' scaling held).
#[test]
fn parameter_products_of_a_static_problem() {
    use deasim::problem::statics::StaticProblem;
    use deasim::solve::newton::NonlinearSystem;
    let (plan, state) = charged(film());
    let model = &plan.model;
    let mut problem = StaticProblem::new(model, Some(state.clone()));
    let n = problem.dofs.n_free;
    let w: Vec<f64> = (0..n).map(|i| ((i * 31) % 17) as f64 - 8.0).collect();
    let vjp = problem.parameter_vjp(&w, 0, None).unwrap();
    let base = model.materials[0].clone();
    let theta = base.parameters().unwrap().values;
    for k in 0..theta.len() {
        let h = 1e-5 * theta[k].abs();
        let residual = |sign: f64| {
            let mut t = theta.clone();
            t[k] += sign * h;
            let mut m = model.clone();
            m.materials[0] = base.with_parameters(&t).unwrap();
            let mut p = StaticProblem::new(&m, Some(state.clone()));
            p.dofs.scale = problem.dofs.scale;
            let mut r = vec![0.0; n];
            p.evaluate(&mut r, None).unwrap();
            r
        };
        let (rp, rm) = (residual(1.0), residual(-1.0));
        let fd: f64 = (0..n).map(|i| w[i] * (rp[i] - rm[i]) / (2.0 * h)).sum();
        let round_off = 1e3 * f64::EPSILON * rp.iter().map(|x| x.abs()).sum::<f64>() / h;
        assert!(
            (fd - vjp[k]).abs() <= 1e-6 * fd.abs() + round_off,
            "parameter {k}: {fd:e} against {:e}",
            vjp[k]
        );
    }
}
