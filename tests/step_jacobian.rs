//! The exact Jacobian of a dynamic step (midpoint and Newmark) against central differences of the
//! step residual, on the examples' models: a 3-D film with Kelvin–Voigt viscosity, the
//! axisymmetric diaphragm with its rigid pad and dashpot, viscoelastic (Maxwell) models, a
//! charge-controlled film and a film driven through a resistance; and the parameter
//! vector–Jacobian product of a step against differences of its residual in the parameters.

mod common;

use deasim::algebra::csr::CsrMatrix;
use deasim::io::build::{build, Plan};
use deasim::io::examples::example;
use deasim::io::scenario::parse;
use deasim::job::plan::StageKind;
use deasim::problem::dofs::{Dirichlet, Field, FIELDS};
use deasim::problem::model::Model;
use deasim::problem::points::PointStates;
use deasim::problem::step::StepOperator;
use deasim::solve::newton::NonlinearSystem;
use deasim::time::integrator::{Scheme, TimeLevel, TimeStep};
use deasim::time::mass::{MassKind, NodalMass};

/// The film example's drive, and the smaller step its circuit variants take as their source.
const STEP_20KV: &str = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
const STEP_1KV: &str = "{ waveform = \"step\", amplitude = 1e3, at = 0.0 }";

fn plan_of(text: &str, sets: &[&str]) -> Plan {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let scenario = parse(text, "test.toml", &sets).unwrap_or_else(|e| panic!("{e}"));
    build(&scenario, "test.toml", None).unwrap_or_else(|e| panic!("{e}"))
}

/// Values in (−1, 1) from a seed.
fn generator(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// The model of the plan's dynamic stage (its supports and prescribed potentials held), its
/// time step and its nodal masses (rigid pads' masses included).
fn dynamic_model(plan: &Plan) -> (Model, f64, MassKind) {
    let stage = plan
        .stages
        .iter()
        .find(|s| matches!(s.kind, StageKind::Dynamic { .. }))
        .expect("a dynamic stage");
    let StageKind::Dynamic { dt, mass, .. } = stage.kind else {
        unreachable!()
    };
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    for e in plan.electrodes.iter().filter(|e| e.prescribed(true)) {
        model.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value: 0.0,
        });
    }
    (model, dt, mass)
}

/// The nodal masses of `model` in the plan's dynamic stage.
fn nodal_mass(plan: &Plan, model: &Model, mass: MassKind) -> NodalMass {
    let mut nodal = NodalMass::new(model, &plan.densities, mass);
    for r in &plan.rigid {
        if r.mass > 0.0 {
            nodal.add_point_mass(r.nodes[0], r.mass);
        }
    }
    nodal
}

/// A step of `model` from a general previous level (random q, v, a of a fiftieth of a
/// millimetre's size, the same for the same model and scaling) to a general q_{n+1}; `next`
/// continues the random sequence; `scale`: the unknowns' scaling to hold instead of the model's.
fn general_step<'m>(
    plan: &Plan,
    model: &'m Model,
    nodal: &'m NodalMass,
    (dt, scheme): (f64, Scheme),
    scale: Option<[f64; FIELDS]>,
    next: &mut dyn FnMut() -> f64,
) -> TimeStep<'m> {
    let n = model.mesh.n_nodes() * FIELDS;
    let zero = TimeLevel {
        t: 0.0,
        q: vec![0.0; n],
        v: vec![0.0; n],
        a: vec![0.0; n],
    };
    let mut step = TimeStep::new(model, nodal, plan.viscosities.clone(), scheme, zero);
    if let Some(scale) = scale {
        step.dofs.scale = scale;
    }
    step.points = PointStates::new(model);
    let nf = step.dofs.n_free;
    let length = 1e-3;
    let level = |step: &TimeStep, size: f64, next: &mut dyn FnMut() -> f64| {
        let x: Vec<f64> = (0..nf).map(|_| next()).collect();
        let x = scaled(step, x, size);
        let mut full = vec![0.0; n];
        step.dofs.add_scaled(&mut full, &x, 1.0);
        full
    };
    let q0 = level(&step, 0.02 * length, next);
    let v0 = level(&step, 0.02 * length / dt, next);
    let a0 = level(&step, 0.02 * length / (dt * dt), next);
    step.prev = TimeLevel {
        t: 0.0,
        q: q0,
        v: v0,
        a: a0,
    };
    step.begin(dt, &[]);
    let sources = vec![[100.0, 150.0, 200.0]; model.circuits.len()];
    step.begin_circuits(&sources).unwrap();
    let dq = level(&step, 0.01 * length, next);
    for (q, d) in step.q.iter_mut().zip(&dq) {
        *q += d;
    }
    step
}

/// The relative difference between J·x of the step's matrix and central differences of its
/// residual along x, for a few random x, at a general state of the plan's dynamic stage: the
/// largest over the directions. `exact`: the step's matrix is its exact Jacobian.
fn jacobian_error(plan: &Plan, scheme: Scheme, exact: bool) -> f64 {
    let (model, dt, mass) = dynamic_model(plan);
    let nodal = nodal_mass(plan, &model, mass);
    let mut next = generator(7);
    let mut step = general_step(plan, &model, &nodal, (dt, scheme), None, &mut next);
    step.exact_jacobian = exact;
    let nf = step.dofs.n_free;
    let length = 1e-3;
    let mut r = vec![0.0; nf];
    let mut k: CsrMatrix = step.new_matrix();
    step.evaluate(&mut r, Some(&mut k)).unwrap();
    // the matrix alone is the same bits, and leaves the dissipation of the evaluated point
    let power = step.dissipation_power().unwrap();
    let mut alone: CsrMatrix = step.new_matrix();
    step.jacobian(&mut alone).unwrap();
    assert_eq!(alone.values, k.values);
    assert_eq!(step.dissipation_power().unwrap(), power);
    let mut worst = 0.0f64;
    for _ in 0..3 {
        let x: Vec<f64> = (0..nf).map(|_| next()).collect();
        let x = scaled(&step, x, 1e-3 * length);
        let mut jx = vec![0.0; nf];
        k.mul_vec(&x, &mut jx);
        let start = step.snapshot();
        let h = 1e-2;
        let (mut rp, mut rm) = (vec![0.0; nf], vec![0.0; nf]);
        step.increment(&x, h);
        step.evaluate(&mut rp, None).unwrap();
        step.restore(&start);
        step.increment(&x, -h);
        step.evaluate(&mut rm, None).unwrap();
        step.restore(&start);
        let diff: f64 = (0..nf)
            .map(|i| ((rp[i] - rm[i]) / (2.0 * h) - jx[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let norm: f64 = jx.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(norm > 0.0);
        worst = worst.max(diff / norm);
    }
    worst
}

/// `x` (free unknowns) scaled so that its largest displacement is `size` (m).
fn scaled(step: &TimeStep, x: Vec<f64>, size: f64) -> Vec<f64> {
    let n = step.q.len();
    let mut full = vec![0.0; n];
    step.dofs.add_scaled(&mut full, &x, 1.0);
    let umax = (0..n)
        .filter(|d| d % FIELDS != FIELDS - 1)
        .fold(0.0f64, |m, d| m.max(full[d].abs()));
    x.into_iter().map(|v| v * size / umax).collect()
}

const SCHEMES: [Scheme; 2] = [
    Scheme::Midpoint,
    Scheme::Newmark {
        beta: 0.25,
        gamma: 0.5,
    },
];

/// Checks both schemes: the exact Jacobian within 1e-6; when `viscous`, the symmetric iteration
/// matrix (without ∂f_vis/∂q) is not.
fn check(plan: &Plan, viscous: bool, what: &str) {
    for scheme in SCHEMES {
        let e = jacobian_error(plan, scheme, true);
        assert!(
            e <= 1e-6,
            "{what}, {}: exact Jacobian off by {e:e}",
            scheme.name()
        );
        if viscous {
            let s = jacobian_error(plan, scheme, false);
            assert!(
                s > 1e-6,
                "{what}, {}: the symmetric matrix is off by only {s:e}",
                scheme.name()
            );
        }
    }
}

fn film(sets: &[&str]) -> Plan {
    plan_of(example("film-vibration").unwrap(), sets)
}

#[test]
fn exact_jacobian_of_a_viscous_film() {
    let plan = film(&["materials.elastomer.viscosity=100"]);
    check(&plan, true, "3-D film");
    let plan = film(&[
        "materials.elastomer.viscosity=100",
        "mesh.element=tet10",
        "mesh.divisions=[2,2,1]",
    ]);
    check(&plan, true, "3-D tet10 film");
}

#[test]
fn exact_jacobian_of_the_axisymmetric_diaphragm_with_its_pad() {
    let plan = plan_of(example("diaphragm").unwrap(), &[]);
    assert!(!plan.rigid.is_empty() && !plan.model.point_dampers.is_empty());
    check(&plan, true, "diaphragm");
}

#[test]
fn exact_jacobian_of_viscoelastic_models() {
    let plan = plan_of(example("diaphragm-visco").unwrap(), &[]);
    check(&plan, true, "diaphragm-visco");
    let text = example("film-vibration")
        .unwrap()
        .replace("model = \"neo-hooke\"", "preset = \"vhb4910-wang2016\"\n#");
    let text = text
        .replace("mu = 1e5", "")
        .replace("lambda = 1e7", "")
        .replace("permittivity = 4.7", "");
    let plan = plan_of(&text, &["materials.elastomer.viscosity=0"]);
    assert!(plan.model.materials[0].state_size() > 0);
    check(&plan, false, "Maxwell film");
}

#[test]
fn exact_jacobian_of_charge_and_circuit_controlled_films() {
    let text = example("film-vibration").unwrap();
    let top = "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    assert!(text.contains(top));
    let charge = text.replace(top, "charge = 3.6e-9");
    let plan = plan_of(&charge, &["materials.elastomer.viscosity=100"]);
    assert!(!plan.model.point_charges.is_empty() || !plan.model.ties.is_empty());
    check(&plan, true, "charge-controlled film");
    let circuit = common::circuit_instead_of(text, STEP_20KV, STEP_1KV, 1e6);
    let plan = plan_of(&circuit, &["materials.elastomer.viscosity=100"]);
    check(&plan, true, "circuit-driven film");
}

/// Runs `text` with overrides through the library; returns the summary and the records' probes.
fn run_probes(text: &str, sets: &[&str]) -> (deasim::job::state::RunSummary, Vec<Vec<f64>>) {
    use deasim::element::CellFields;
    use deasim::job::observer::Observer;
    use deasim::job::run::{run, StepRecord};
    use deasim::job::state::RunSummary;
    #[derive(Default)]
    struct Probes(Vec<Vec<f64>>);
    impl Observer for Probes {
        fn step(&mut self, _: &Plan, r: &StepRecord, _: &[f64], _: &[CellFields]) {
            self.0.push(r.probes.clone());
        }
        fn finished(&mut self, _: &Plan, _: &RunSummary) {}
    }
    let plan = plan_of(text, sets);
    let mut rec = Probes::default();
    let summary = run(&plan, &mut rec);
    assert!(summary.converged, "{:?}", summary.error);
    (summary, rec.0)
}

/// `[solver] jacobian = "exact"` runs the dynamic steps' Newton on the exact Jacobian: fewer
/// iterations than the symmetric matrix, and the same history to the Newton tolerance.
#[test]
fn newton_on_the_exact_jacobian_takes_fewer_iterations_to_the_same_history() {
    let text = example("diaphragm").unwrap();
    let short = ["stages.1.duration=0.05"];
    let (sym, a) = run_probes(text, &[short[0], "solver.jacobian=\"symmetric\""]);
    let (exact, b) = run_probes(text, &[short[0], "solver.jacobian=\"exact\""]);
    let it = |s: &deasim::job::state::RunSummary| s.stages[1].newton_iterations;
    assert!(it(&exact) < it(&sym), "{} vs {}", it(&exact), it(&sym));
    assert_eq!(a.len(), b.len());
    // each probe against its largest value over the run
    for p in 0..a[0].len() {
        let scale = a.iter().map(|r| r[p]).filter(|v| v.is_finite());
        let scale = scale.fold(0.0f64, |m, v| m.max(v.abs()));
        for (ra, rb) in a.iter().zip(&b) {
            let (x, y) = (ra[p], rb[p]);
            assert!(
                (x - y).abs() <= 1e-6 * scale || (x.is_nan() && y.is_nan()),
                "probe {p}: {x} vs {y}"
            );
        }
    }
}

/// A jacobian that is neither `exact` nor `symmetric` is refused, naming the key.
#[test]
fn an_unknown_jacobian_is_refused() {
    let sets: Vec<String> = vec!["solver.jacobian=\"full\"".into()];
    let scenario = parse(example("diaphragm").unwrap(), "test.toml", &sets).unwrap();
    let e = build(&scenario, "test.toml", None).unwrap_err().to_string();
    assert!(e.contains("solver.jacobian"), "{e}");
    assert!(e.contains("expected one of: exact, symmetric"), "{e}");
}

/// wᵀ∂R/∂θ of a step (the step's parameter vector–Jacobian product) against central differences
/// of the residual of the same step with the material rebuilt at θ ± h eₖ: the largest relative
/// difference over the parameters of every material.
fn parameter_error(plan: &Plan, scheme: Scheme) -> f64 {
    let (model, dt, mass) = dynamic_model(plan);
    let nodal = nodal_mass(plan, &model, mass);
    // the unknowns' scaling (from the moduli) held: a numerical choice, not part of the equations
    let scale = {
        let mut next = generator(11);
        general_step(plan, &model, &nodal, (dt, scheme), None, &mut next)
            .dofs
            .scale
    };
    let residual = |m: &Model| {
        let mut next = generator(11);
        let mut step = general_step(plan, m, &nodal, (dt, scheme), Some(scale), &mut next);
        let mut r = vec![0.0; step.dofs.n_free];
        step.evaluate(&mut r, None).unwrap();
        r
    };
    let mut next = generator(11);
    let mut step = general_step(plan, &model, &nodal, (dt, scheme), None, &mut next);
    let w: Vec<f64> = (0..step.dofs.n_free).map(|_| next()).collect();
    let mut worst = 0.0f64;
    for (mi, base) in model.materials.iter().enumerate() {
        let theta = base.parameters().unwrap().values;
        let vjp = step.parameter_vjp(&w, mi, None).unwrap();
        for k in 0..theta.len() {
            let h = 1e-5 * theta[k].abs().max(1e-12);
            let at = |sign: f64| {
                let mut t = theta.clone();
                t[k] += sign * h;
                let mut m = model.clone();
                m.materials[mi] = base.with_parameters(&t).unwrap();
                residual(&m)
            };
            let (rp, rm) = (at(1.0), at(-1.0));
            let fd: f64 = (0..w.len())
                .map(|i| w[i] * (rp[i] - rm[i]) / (2.0 * h))
                .sum();
            let round_off = 1e3 * f64::EPSILON * rp.iter().map(|x| x.abs()).sum::<f64>() / h;
            let err = ((fd - vjp[k]).abs() - round_off).max(0.0) / fd.abs().max(vjp[k].abs());
            worst = worst.max(err);
        }
    }
    worst
}

#[test]
fn parameter_products_of_the_step_match_finite_differences() {
    let film = film(&["materials.elastomer.c1=1e-12"]);
    let visco = plan_of(example("diaphragm-visco").unwrap(), &[]);
    for (plan, what) in [(&film, "film"), (&visco, "diaphragm-visco")] {
        for scheme in SCHEMES {
            let e = parameter_error(plan, scheme);
            assert!(e <= 1e-6, "{what}, {scheme:?}: {e:e}");
        }
    }
}

/// An input of a step: where it lies in the step.
type Input<S> = for<'a> fn(&'a mut S) -> &'a mut Vec<f64>;

/// Central differences of wᵀR along `delta` of the input `input` of the step, against the
/// product of `delta` with the step's transposed derivative `product`: the relative difference
/// (round-off of the differences allowed for).
fn directional_error<S: NonlinearSystem>(
    step: &mut S,
    w: &[f64],
    input: Input<S>,
    product: &[f64],
    delta: &[f64],
) -> f64 {
    let analytic: f64 = product.iter().zip(delta).map(|(p, d)| p * d).sum();
    let start = input(step).clone();
    let mut at = |sign: f64| {
        let x = input(step);
        for (x, (s, d)) in x.iter_mut().zip(start.iter().zip(delta)) {
            *x = s + sign * d;
        }
        let mut r = vec![0.0; step.n()];
        step.evaluate(&mut r, None).unwrap();
        let wr: f64 = w.iter().zip(&r).map(|(a, b)| a * b).sum();
        let size: f64 = w.iter().zip(&r).map(|(a, b)| (a * b).abs()).sum();
        (wr, size)
    };
    let ((rp, size), (rm, _)) = (at(1.0), at(-1.0));
    input(step).clone_from(&start);
    let fd = (rp - rm) / 2.0;
    let round_off = 1e3 * f64::EPSILON * size;
    ((fd - analytic).abs() - round_off).max(0.0) / fd.abs().max(analytic.abs()).max(1e-300)
}

/// A direction over a vector `x` of nodal values: each field's entries random of a ten
/// thousandth of the field's largest value in `x` (of `fallback`'s when `x` has none).
fn nodal_direction(x: &[f64], fallback: &[f64], next: &mut dyn FnMut() -> f64) -> Vec<f64> {
    let largest = |v: &[f64], f: usize| {
        v.iter()
            .skip(f)
            .step_by(FIELDS)
            .fold(0.0f64, |m, x| m.max(x.abs()))
    };
    let sizes: Vec<f64> = (0..FIELDS)
        .map(|f| {
            let s = largest(x, f);
            1e-4 * if s > 0.0 { s } else { largest(fallback, f) }
        })
        .collect();
    (0..x.len()).map(|d| sizes[d % FIELDS] * next()).collect()
}

/// The step's products in each input (the new state over every dof, the previous level's q, v
/// and a, the internal variables and the circuits' states) against central differences of wᵀR,
/// at a general state with perturbed internal variables: the largest relative difference per
/// input.
fn level_errors(plan: &Plan, scheme: Scheme) -> Vec<(&'static str, f64)> {
    let (model, dt, mass) = dynamic_model(plan);
    let nodal = nodal_mass(plan, &model, mass);
    let mut next = generator(23);
    let mut step = general_step(plan, &model, &nodal, (dt, scheme), None, &mut next);
    // internal variables away from the virgin state: those of a long step to the previous
    // level's configuration (so that they are what the material makes, e.g. symmetric)
    let configuration = step.prev.q.iter().map(|x| 5.0 * x).collect::<Vec<f64>>();
    let virgin = step.points.data.clone();
    step.points
        .commit(&model, &configuration, 1e3 * dt)
        .unwrap_or_else(|e| panic!("{e}"));
    let size = step.points.data.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let moved = step.points.data.iter().zip(&virgin);
    let moved = moved.fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        virgin.is_empty() || moved > 1e-3 * size,
        "{moved} of {size}"
    );
    let w: Vec<f64> = (0..step.dofs.n_free).map(|_| next()).collect();
    let vjp = step.level_vjp(&w).unwrap();
    let q = step.prev.q.clone();
    let mut errors = Vec::new();
    let inputs: [(&str, Input<TimeStep>, &[f64]); 4] = [
        ("q_new", |s| &mut s.q, &vjp.q_new),
        ("q", |s| &mut s.prev.q, &vjp.q),
        ("v", |s| &mut s.prev.v, &vjp.v),
        ("a", |s| &mut s.prev.a, &vjp.a),
    ];
    for (name, input, product) in inputs {
        let mut worst = 0.0f64;
        for _ in 0..3 {
            let delta = nodal_direction(input(&mut step), &q, &mut next);
            worst = worst.max(directional_error(&mut step, &w, input, product, &delta));
        }
        errors.push((name, worst));
    }
    if !step.points.data.is_empty() {
        let mut worst = 0.0f64;
        for _ in 0..3 {
            let delta: Vec<f64> = (0..step.points.data.len())
                .map(|_| 1e-4 * size * next())
                .collect();
            let input: Input<TimeStep> = |s| &mut s.points.data;
            worst = worst.max(directional_error(&mut step, &w, input, &vjp.points, &delta));
        }
        errors.push(("internal variables", worst));
    }
    // each circuit's charge, start voltage and source values
    for (i, product) in vjp.circuits.iter().enumerate() {
        let flat = |c: &deasim::problem::circuit::CircuitStep| {
            [c.charge, c.voltage, c.source[0], c.source[1], c.source[2]]
        };
        let (start, product) = (step.circuits[i], flat(product));
        let mut worst = 0.0f64;
        for (k, &p) in product.iter().enumerate() {
            let h = 1e-4 * flat(&start)[k].abs().max(1e-12);
            let mut at = |sign: f64| {
                let mut v = flat(&start);
                v[k] += sign * h;
                step.circuits[i] = deasim::problem::circuit::CircuitStep {
                    charge: v[0],
                    voltage: v[1],
                    source: [v[2], v[3], v[4]],
                };
                let mut r = vec![0.0; step.dofs.n_free];
                step.evaluate(&mut r, None).unwrap();
                w.iter().zip(&r).map(|(a, b)| a * b).sum::<f64>()
            };
            let fd = (at(1.0) - at(-1.0)) / (2.0 * h);
            step.circuits[i] = start;
            if fd != 0.0 || p != 0.0 {
                worst = worst.max((fd - p).abs() / fd.abs().max(p.abs()));
            }
        }
        errors.push(("circuit", worst));
    }
    errors
}

/// Checks every input of both schemes within 1e-6.
fn check_levels(plan: &Plan, what: &str) {
    for scheme in SCHEMES {
        for (input, e) in level_errors(plan, scheme) {
            assert!(e <= 1e-6, "{what}, {}: {input} off by {e:e}", scheme.name());
        }
    }
}

#[test]
fn level_products_of_a_viscous_film_match_finite_differences() {
    check_levels(&film(&["materials.elastomer.viscosity=100"]), "3-D film");
}

#[test]
fn level_products_of_the_diaphragm_with_its_pad_match_finite_differences() {
    check_levels(&plan_of(example("diaphragm").unwrap(), &[]), "diaphragm");
}

#[test]
fn level_products_of_viscoelastic_models_match_finite_differences() {
    let plan = plan_of(example("diaphragm-visco").unwrap(), &[]);
    assert!(plan.model.materials[0].state_size() > 0);
    check_levels(&plan, "diaphragm-visco");
    let plan = plan_of(
        example("diaphragm-visco").unwrap(),
        &["mesh.formulation=\"standard\""],
    );
    check_levels(&plan, "diaphragm-visco, standard formulation");
    let text = example("film-vibration")
        .unwrap()
        .replace("model = \"neo-hooke\"", "preset = \"vhb4910-wang2016\"\n#")
        .replace("mu = 1e5", "")
        .replace("lambda = 1e7", "")
        .replace("permittivity = 4.7", "");
    let plan = plan_of(&text, &["materials.elastomer.viscosity=0"]);
    check_levels(&plan, "3-D Maxwell film");
}

#[test]
fn level_products_of_charge_and_circuit_controlled_films_match_finite_differences() {
    let text = example("film-vibration").unwrap();
    let top = "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let charge = text.replace(top, "charge = 3.6e-9");
    check_levels(
        &plan_of(&charge, &["materials.elastomer.viscosity=100"]),
        "charge-controlled film",
    );
    let circuit = common::circuit_instead_of(text, STEP_20KV, STEP_1KV, 1e6);
    check_levels(
        &plan_of(&circuit, &["materials.elastomer.viscosity=100"]),
        "circuit-driven film",
    );
}

/// A load step's products (the new state over every dof, follower pressures included, and the
/// committed internal variables of a quasi-static step) against central differences of wᵀR, at
/// a general state of `plan`'s model with its pressures on: the largest relative difference
/// per input.
fn static_level_errors(plan: &Plan) -> Vec<(&'static str, f64)> {
    use deasim::algebra::system::LoadedSystem;
    use deasim::problem::statics::StaticProblem;
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    let mut next = generator(31);
    let mut problem = StaticProblem::new(&model, None);
    let mut drive = deasim::problem::drive::Drive::ramped(&model);
    for r in &mut drive.pressures {
        r.from = 0.5;
    }
    problem.set_drive(drive);
    problem.duration = 1.0;
    problem.set_load(0.7);
    let x: Vec<f64> = (0..problem.dofs.n_free).map(|_| next()).collect();
    let mut full = vec![0.0; problem.state.len()];
    problem.dofs.add_scaled(&mut full, &x, 1.0);
    let umax = (0..full.len())
        .filter(|d| d % FIELDS != FIELDS - 1)
        .fold(0.0f64, |m, d| m.max(full[d].abs()));
    let length = model.cell_size();
    let x: Vec<f64> = x.iter().map(|v| v * 0.02 * length / umax).collect();
    problem.increment(&x, 1.0);
    let configuration: Vec<f64> = problem.state.iter().map(|v| 2.0 * v).collect();
    let virgin = problem.points.data.clone();
    problem.points.commit(&model, &configuration, 10.0).unwrap();
    assert!(virgin.is_empty() || problem.points.data != virgin);
    let w: Vec<f64> = (0..problem.dofs.n_free).map(|_| next()).collect();
    let vjp = problem.level_vjp(&w).unwrap();
    let (state, size) = (problem.state.clone(), 1e-4);
    let mut errors = Vec::new();
    let mut worst = 0.0f64;
    for _ in 0..3 {
        let delta = nodal_direction(&state, &state, &mut next);
        let input: Input<StaticProblem> = |s| &mut s.state;
        worst = worst.max(directional_error(
            &mut problem,
            &w,
            input,
            &vjp.q_new,
            &delta,
        ));
    }
    errors.push(("q_new", worst));
    if !virgin.is_empty() {
        let mut worst = 0.0f64;
        for _ in 0..3 {
            let delta: Vec<f64> = (0..virgin.len()).map(|_| size * next()).collect();
            let input: Input<StaticProblem> = |s| &mut s.points.data;
            worst = worst.max(directional_error(
                &mut problem,
                &w,
                input,
                &vjp.points,
                &delta,
            ));
        }
        errors.push(("internal variables", worst));
    }
    errors
}

#[test]
fn level_products_of_load_steps_match_finite_differences() {
    let balloon = plan_of(example("balloon").unwrap(), &[]);
    assert!(!balloon.model.pressures.is_empty());
    let visco = plan_of(example("diaphragm-visco").unwrap(), &[]);
    let balloon_3d = plan_of(example("balloon-volume").unwrap(), &[]);
    for (plan, what) in [
        (&balloon, "balloon under pressure"),
        (&balloon_3d, "3-D balloon"),
        (&visco, "quasi-static diaphragm-visco"),
    ] {
        for (input, e) in static_level_errors(plan) {
            assert!(e <= 1e-6, "{what}: {input} off by {e:e}");
        }
    }
}

/// wᵀR of the step of `general_step` (seed 41) for a model and nodal masses, with `w` of that
/// seed, and the step's scaled unknowns held at `scale`.
fn seeded_wr(
    plan: &Plan,
    model: &Model,
    nodal: &NodalMass,
    (dt, scheme): (f64, Scheme),
    scale: Option<[f64; FIELDS]>,
) -> (f64, Vec<f64>, [f64; FIELDS]) {
    let mut next = generator(41);
    let mut step = general_step(plan, model, nodal, (dt, scheme), scale, &mut next);
    let w: Vec<f64> = (0..step.dofs.n_free).map(|_| next()).collect();
    let mut r = vec![0.0; step.dofs.n_free];
    step.evaluate(&mut r, None).unwrap();
    let wr = w.iter().zip(&r).map(|(a, b)| a * b).sum();
    (wr, w, step.dofs.scale)
}

/// The step's products in a rigid pad's mass and in a circuit's resistance against central
/// differences of wᵀR in them.
#[test]
fn mass_and_resistance_products_match_finite_differences() {
    for scheme in SCHEMES {
        // the diaphragm's pad mass
        let plan = plan_of(example("diaphragm").unwrap(), &[]);
        let (model, dt, mass) = dynamic_model(&plan);
        let node = plan.rigid[0].nodes[0];
        let nodal = nodal_mass(&plan, &model, mass);
        let (_, w, scale) = seeded_wr(&plan, &model, &nodal, (dt, scheme), None);
        let mut next = generator(41);
        let step = general_step(&plan, &model, &nodal, (dt, scheme), None, &mut next);
        let analytic = step.point_mass_vjp(&w, node);
        let h = 1e-4 * plan.rigid[0].mass;
        let at = |dm: f64| {
            let mut m = nodal_mass(&plan, &model, mass);
            m.add_point_mass(node, dm);
            seeded_wr(&plan, &model, &m, (dt, scheme), Some(scale)).0
        };
        let fd = (at(h) - at(-h)) / (2.0 * h);
        assert!(analytic != 0.0);
        assert!(
            (fd - analytic).abs() <= 1e-6 * analytic.abs(),
            "{scheme:?}: pad mass {fd} vs {analytic}"
        );
        // a film driven through a resistance
        let text = common::circuit_instead_of(
            example("film-vibration").unwrap(),
            STEP_20KV,
            STEP_1KV,
            1e6,
        );
        let plan = plan_of(&text, &["materials.elastomer.viscosity=100"]);
        let (model, dt, mass) = dynamic_model(&plan);
        let nodal = nodal_mass(&plan, &model, mass);
        let (_, w, scale) = seeded_wr(&plan, &model, &nodal, (dt, scheme), None);
        let mut next = generator(41);
        let mut step = general_step(&plan, &model, &nodal, (dt, scheme), None, &mut next);
        let analytic = step.resistance_vjp(&w, 0);
        let r0 = model.circuits[0].resistance;
        let at = |dr: f64| {
            let mut m = model.clone();
            m.circuits[0].resistance = r0 + dr;
            seeded_wr(&plan, &m, &nodal, (dt, scheme), Some(scale)).0
        };
        let h = 1e-4 * r0;
        let fd = (at(h) - at(-h)) / (2.0 * h);
        assert!(analytic != 0.0);
        assert!(
            (fd - analytic).abs() <= 1e-6 * analytic.abs(),
            "{scheme:?}: resistance {fd} vs {analytic}"
        );
    }
}

/// The explicit trapezoidal step's velocity equation: its products in the new positions, the
/// previous positions and velocities and the given forces against central differences.
#[test]
fn level_products_of_the_trapezoidal_step_match_finite_differences() {
    use deasim::time::trapezoidal::TrapezoidalStep;
    for plan in [
        film(&["materials.elastomer.viscosity=100"]),
        plan_of(
            example("diaphragm").unwrap(),
            &["materials.vhb.viscosity=50"],
        ),
    ] {
        let (model, dt, mass) = dynamic_model(&plan);
        let nodal = nodal_mass(&plan, &model, mass);
        let mut next = generator(53);
        let reference = general_step(&plan, &model, &nodal, (dt, SCHEMES[0]), None, &mut next);
        let mut step = TrapezoidalStep::new(&model, &nodal, plan.viscosities.clone());
        step.dt = dt;
        step.q_n.clone_from(&reference.prev.q);
        step.v_n.clone_from(&reference.prev.v);
        step.q.clone_from(&reference.q);
        step.f_n = (0..step.q.len()).map(|_| next()).collect();
        let w: Vec<f64> = (0..step.n()).map(|_| next()).collect();
        let vjp = step.level_vjp(&w).unwrap();
        let inputs: [(&str, Input<TrapezoidalStep>, &[f64]); 4] = [
            ("q_new", |s| &mut s.q, &vjp.q_new),
            ("q", |s| &mut s.q_n, &vjp.q),
            ("v", |s| &mut s.v_n, &vjp.v),
            ("forces", |s| &mut s.f_n, &vjp.forces),
        ];
        let q = step.q_n.clone();
        for (name, input, product) in inputs {
            for _ in 0..3 {
                let delta = nodal_direction(input(&mut step), &q, &mut next);
                let e = directional_error(&mut step, &w, input, product, &delta);
                assert!(e <= 1e-6, "{name} off by {e:e}");
            }
        }
    }
}

/// From 128 cells the transposed products run their cells on the pool (a pass of their own, or
/// the kept cell tangents'): the same numbers, bit for bit, as on one thread, and the same
/// agreement with central differences.
#[test]
fn level_products_on_the_pool_equal_those_on_one_thread() {
    let plan = film(&[
        "mesh.divisions=[8,8,2]",
        "materials.elastomer.viscosity=100",
    ]);
    assert!(plan.model.mesh.n_cells() >= 128);
    let (model, dt, mass) = dynamic_model(&plan);
    let nodal = nodal_mass(&plan, &model, mass);
    let products = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut next = generator(5);
            let scheme = SCHEMES[0];
            let mut step = general_step(&plan, &model, &nodal, (dt, scheme), None, &mut next);
            let w: Vec<f64> = (0..step.dofs.n_free).map(|_| next()).collect();
            let own = step.level_vjp(&w).unwrap();
            // and from the cell tangents an evaluation with the exact Jacobian kept
            step.exact_jacobian = true;
            step.keep_cell_tangents = true;
            let mut r = vec![0.0; step.n()];
            let mut k = step.new_matrix();
            step.evaluate(&mut r, Some(&mut k)).unwrap();
            (own, step.level_vjp(&w).unwrap())
        })
    };
    let (one, two) = (products(1), products(2));
    assert!(one.0.q.iter().any(|&x| x != 0.0));
    assert!(one.1.q.iter().any(|&x| x != 0.0));
    assert_eq!(one, two);
    assert!(relative_gap(&one.0.q, &one.1.q) <= 1e-13);
    check_levels(&plan, "3-D film of 128 cells");
}

/// The largest difference between two products, relative to the larger's largest entry.
fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let size = a.iter().chain(b).fold(0.0f64, |m, x| m.max(x.abs()));
    let gap = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    if size > 0.0 {
        gap / size
    } else {
        gap
    }
}

/// An adjoint's products from the cell tangents its evaluation kept equal those of a pass of
/// their own, with the Maxwell branches' internal variables (whose own products then take a
/// pass of point products, no tangent); internal variables changed after the evaluation are
/// not served from the kept tangents. Steps of both schemes, and the electrostatic projection
/// and a quasi-static load step.
#[test]
fn kept_tangents_give_the_products_of_a_pass_of_their_own() {
    use deasim::algebra::system::LoadedSystem;
    use deasim::problem::statics::StaticProblem;
    let plan = plan_of(example("diaphragm-visco").unwrap(), &[]);
    let (model, dt, mass) = dynamic_model(&plan);
    let nodal = nodal_mass(&plan, &model, mass);
    let products = |v: &deasim::problem::step::LevelVjp| {
        [
            v.q_new.clone(),
            v.q.clone(),
            v.v.clone(),
            v.a.clone(),
            v.points.clone(),
        ]
    };
    for scheme in SCHEMES {
        let mut next = generator(7);
        let mut step = general_step(&plan, &model, &nodal, (dt, scheme), None, &mut next);
        let configuration: Vec<f64> = step.prev.q.iter().map(|x| 5.0 * x).collect();
        step.points
            .commit(&model, &configuration, 1e3 * dt)
            .unwrap();
        assert!(!step.points.data.is_empty());
        let w: Vec<f64> = (0..step.dofs.n_free).map(|_| next()).collect();
        let own = products(&step.level_vjp(&w).unwrap());
        step.exact_jacobian = true;
        step.keep_cell_tangents = true;
        let mut r = vec![0.0; step.n()];
        let mut k = step.new_matrix();
        step.evaluate(&mut r, Some(&mut k)).unwrap();
        let kept = products(&step.level_vjp(&w).unwrap());
        for i in [0, 1, 2, 4] {
            let nonzero = kept[i].iter().any(|&x| x != 0.0);
            assert!(nonzero, "{}: product {i} is zero", scheme.name());
        }
        for (i, (a, b)) in kept.iter().zip(&own).enumerate() {
            let gap = relative_gap(a, b);
            assert!(
                gap <= 1e-13,
                "{}: product {i} off by {gap:e}",
                scheme.name()
            );
        }
        // other internal variables after the evaluation: a pass of its own, bit for bit
        step.points.data.iter_mut().for_each(|x| *x *= 1.5);
        let moved = products(&step.level_vjp(&w).unwrap());
        step.keep_cell_tangents = false;
        let mut fresh = general_step(&plan, &model, &nodal, (dt, scheme), None, &mut generator(7));
        fresh.points = step.points.clone();
        assert_eq!(moved, products(&fresh.level_vjp(&w).unwrap()));
        // (the kept tangents would have served other stiffness products)
        assert!(relative_gap(&moved[0], &own[0]) > 1e-9);
    }
    // the load steps: the projection (every displacement held) and a quasi-static step
    let mut held = model.clone();
    held.dirichlet = [Field::Ux, Field::Uy, Field::Uz]
        .into_iter()
        .map(|field| Dirichlet {
            nodes: (0..model.mesh.n_nodes()).collect(),
            field,
            value: 0.0,
        })
        .chain(
            plan.supports
                .iter()
                .filter(|d| d.field == Field::Phi)
                .cloned(),
        )
        .collect();
    let mut quasi_static = model.clone();
    quasi_static.dirichlet = plan.supports.clone();
    for (m, what) in [(&held, "projection"), (&quasi_static, "load step")] {
        let mut next = generator(11);
        let mut problem = StaticProblem::new(m, None);
        problem.duration = 1.0;
        problem.set_load(0.7);
        let x: Vec<f64> = (0..problem.dofs.n_free).map(|_| 1e-5 * next()).collect();
        problem.increment(&x, 1.0);
        let configuration: Vec<f64> = (0..problem.state.len()).map(|_| 1e-4 * next()).collect();
        problem.points.commit(m, &configuration, 10.0).unwrap();
        let w: Vec<f64> = (0..problem.dofs.n_free).map(|_| next()).collect();
        let own = products(&problem.level_vjp(&w).unwrap());
        problem.keep_cell_tangents = true;
        let mut r = vec![0.0; problem.n()];
        let mut k = problem.new_matrix();
        problem.evaluate(&mut r, Some(&mut k)).unwrap();
        let kept = products(&problem.level_vjp(&w).unwrap());
        assert!(kept[0].iter().any(|&x| x != 0.0), "{what}");
        for (i, (a, b)) in kept.iter().zip(&own).enumerate() {
            let gap = relative_gap(a, b);
            assert!(gap <= 1e-13, "{what}: product {i} off by {gap:e}");
        }
    }
}
