//! Axisymmetric models run through the whole machinery (model, statics, scenario build, run):
//! the homogeneous film as a disc against the closed form with every meridian kind and its
//! pull-in, the pre-stretched free disc, the thick-walled cylinder (Lamé) and the thick sphere
//! under internal pressure converging at the element's order, and the axisymmetric diaphragm
//! against the 3-D one.

mod common;

use deasim::element::CellFields;
use deasim::io::build::{build, Plan};
use deasim::io::scenario::parse;
use deasim::job::observer::Observer;
use deasim::job::run::{run, StepRecord};
use deasim::job::state::RunSummary;
use deasim::job::statics::solve_static;
use deasim::material::ElectroNeoHooke;
use deasim::mesh::meridian::rectangle_mesh;
use deasim::mesh::MeridianKind;
use deasim::problem::dofs::Field;
use deasim::problem::examples::{film_closed_form, FILM_EPS_R, FILM_LAMBDA, FILM_MU, FILM_SIZE};
use deasim::problem::model::{Formulation, Model};
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use std::sync::Arc;

/// The film as a disc of radius 10 mm and thickness 1 mm, `nr × nz` cells: bottom held axially
/// and grounded, top at `voltage`, rim free.
fn film_disc(kind: MeridianKind, nr: usize, nz: usize, voltage: f64) -> Model {
    let mesh = rectangle_mesh(0.0, FILM_SIZE[0], FILM_SIZE[2], nr, nz, kind).unwrap();
    let material = Arc::new(ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R));
    let mut model = Model::new(mesh, material).unwrap();
    model.fix("bottom", Field::Uy, 0.0).unwrap();
    model.fix("bottom", Field::Phi, 0.0).unwrap();
    model.fix("top", Field::Phi, voltage).unwrap();
    model
}

/// Every meridian kind reproduces the homogeneous film at every load step: u_r = (λ − 1)R,
/// u_z = (t − 1)Z, Φ = V Z/H (the state lies in every kind's interpolation).
#[test]
fn the_film_disc_follows_the_closed_form_with_every_kind() {
    let voltage = 30e3;
    let reference = film_closed_form();
    for kind in MeridianKind::ALL {
        let model = film_disc(kind, 3, 2, voltage);
        let mut worst: f64 = 0.0;
        let mut steps = 0;
        let outcome = solve_static(
            &model,
            None,
            &StepControl {
                steps: 15,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |p, step| {
                let v = voltage * step.load;
                let s = reference.state(v / FILM_SIZE[2]).expect("below pull-in");
                for (n, x) in p.model.mesh.nodes.iter().enumerate() {
                    let u = &p.state[n * 4..n * 4 + 4];
                    if x[0] > 0.0 {
                        worst = worst.max((u[0] - (s.lambda - 1.0) * x[0]).abs() / x[0]);
                    }
                    worst = worst.max((u[1] - (s.t - 1.0) * x[1]).abs() / FILM_SIZE[2]);
                    assert_eq!(u[2], 0.0);
                    assert!((u[3] - v * x[1] / FILM_SIZE[2]).abs() <= 1e-9 * voltage);
                }
                steps += 1;
            },
        );
        outcome.result.expect("30 kV is below pull-in");
        println!("{kind:?}: {steps} steps, max |Δλ| = {worst:.3e}");
        assert!(steps >= 15);
        assert!(worst < 1e-10, "{kind:?}: max |Δλ| = {worst:e}");
    }
}

/// Ramped to 40 kV the film disc stops at pull-in, its last converged voltage within 0.5 %
/// below the closed-form critical voltage.
#[test]
fn the_film_disc_stops_at_pull_in() {
    let (ec, _) = film_closed_form().pull_in();
    let v_crit = ec * FILM_SIZE[2];
    for kind in [MeridianKind::Quad4, MeridianKind::Tri6] {
        let model = film_disc(kind, 2, 1, 40e3);
        let outcome = solve_static(
            &model,
            None,
            &StepControl {
                steps: 20,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |_, _| {},
        );
        let failure = outcome.result.expect_err("40 kV is beyond pull-in");
        assert!(failure.limit_point, "{failure:?}");
        let v_last = failure.last_converged * 40e3;
        println!("{kind:?}: last converged {v_last:.2} V, closed form {v_crit:.2} V");
        assert!(v_last <= v_crit && v_last >= 0.995 * v_crit, "{v_last}");
    }
}

/// Keeps every record.
#[derive(Default)]
struct Records(Vec<StepRecord>);

impl Observer for Records {
    fn step(&mut self, _: &Plan, r: &StepRecord, _: &[f64], _: &[CellFields]) {
        self.0.push(r.clone());
    }
    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}

/// Runs a scenario text with overrides; the records, the plan and the last state.
fn run_text(text: &str, sets: &[&str]) -> (Vec<StepRecord>, Plan) {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let scenario = parse(text, "test.toml", &sets).unwrap_or_else(|e| panic!("{e}"));
    let plan = build(&scenario, "test.toml", None).unwrap_or_else(|e| panic!("{e}"));
    let mut rec = Records::default();
    let summary = run(&plan, &mut rec);
    assert!(summary.converged, "{:?}", summary.error);
    (rec.0, plan)
}

fn probe(plan: &Plan, r: &StepRecord, name: &str) -> f64 {
    let i = plan.probes.iter().position(|p| p.0 == name).unwrap();
    r.probes[i]
}

/// A free disc pre-stretched on its rim reaches the homogeneous equibiaxial state: thickness
/// stretch t with zero axial stress, μ(t − 1/t) + Λ ln(λ²t)/t = 0, to 1e-8.
#[test]
fn a_prestretched_free_disc_is_homogeneous() {
    let text = r#"
name = "disc"
[mesh]
geometry = "axisymmetric"
generator = "rectangle"
radius = 10e-3
thickness = 1e-3
radial = 5
layers = 2
element = "quad8"
[materials.elastomer]
model = "neo-hooke"
mu = 1e5
lambda = 1e7
permittivity = 4.7
[[constraints]]
set = "bottom"
fix = ["z"]
[prestretch]
stretch = 1.8
set = "outer"
[electrodes.bottom]
set = "bottom"
voltage = 0.0
[electrodes.top]
set = "top"
voltage = 0.0
[[stages]]
name = "rest"
kind = "static"
steps = 1
[probes.thickness]
kind = "mean"
quantity = "uz"
set = "top"
scale = 1000.0
offset = 1.0
[probes.radius]
kind = "point"
quantity = "ur"
at = [5e-3, 0.0, 0.5e-3]
"#;
    let (records, plan) = run_text(text, &[]);
    let lambda: f64 = 1.8;
    // t from the zero axial stress, by Newton
    let mut t: f64 = 1.0 / (lambda * lambda);
    for _ in 0..50 {
        let f = FILM_MU * (t - 1.0 / t) + FILM_LAMBDA * (lambda * lambda * t).ln() / t;
        let df = FILM_MU * (1.0 + 1.0 / (t * t))
            + FILM_LAMBDA * (1.0 - (lambda * lambda * t).ln()) / (t * t);
        t -= f / df;
    }
    let last = records.last().unwrap();
    let tz = probe(&plan, last, "thickness");
    let ur = probe(&plan, last, "radius");
    println!("t = {tz:.12} (closed form {t:.12}), u_r(5 mm) = {ur:.6e}");
    assert!((tz - t).abs() < 1e-8, "{tz} vs {t}");
    assert!((ur - (lambda - 1.0) * 5e-3).abs() < 1e-8 * 5e-3);
}

/// Largest nodal error of the radial displacement against `exact(R)` (m), relative to its
/// largest value, after a static solve of `model` with its pressure ramped in one step.
fn radial_error(model: &Model, exact: impl Fn(f64, f64) -> f64) -> f64 {
    let mut state = Vec::new();
    let outcome = solve_static(
        model,
        None,
        &StepControl {
            steps: 1,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |p, _| state = p.state.to_vec(),
    );
    outcome.result.expect("converges");
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (n, x) in model.mesh.nodes.iter().enumerate() {
        let ue = exact(x[0], x[1]);
        scale = scale.max(ue.abs());
        // the radial displacement along the position vector (r for the cylinder)
        worst = worst.max((state[n * 4] - ue).abs());
    }
    worst / scale
}

/// Linear-elastic constants of the compressible neo-Hooke solid at small strain.
fn young_poisson(mu: f64, lambda: f64) -> (f64, f64) {
    (
        mu * (3.0 * lambda + 2.0 * mu) / (lambda + mu),
        lambda / (2.0 * (lambda + mu)),
    )
}

/// The quadratic quadrilaterals converge at rate 4 at the nodes (superconvergent: > 3.5
/// asserted), quad4 at rate 2 (> 1.9); the triangles, whose rules integrate the hoop terms less
/// exactly, approach their rates from below (tri3: 1.2, 1.5, 1.64; tri6: 2.3, 2.6 on the
/// cylinder): their rates must grow and the last exceed 1.6 (tri3) and 2.5 (tri6).
fn check_rates(kind: MeridianKind, r: &[f64]) {
    match kind {
        MeridianKind::Tri3 | MeridianKind::Tri6 => {
            let last = if kind == MeridianKind::Tri3 { 1.6 } else { 2.5 };
            assert!(r.windows(2).all(|w| w[1] > w[0]), "{kind:?}: rates {r:?}");
            assert!(r[r.len() - 1] > last, "{kind:?}: rates {r:?}");
        }
        MeridianKind::Quad4 => assert!(r.iter().all(|&q| q > 1.9), "quad4: rates {r:?}"),
        _ => assert!(r.iter().all(|&q| q > 3.5), "{kind:?}: rates {r:?}"),
    }
}

/// Rates log2(e_h / e_{h/2}) of a sequence of errors on meshes halved each time.
fn rates(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// The thick-walled cylinder under internal pressure in plane strain (top and bottom held
/// axially), small pressure: Lamé's u_r = (1 + ν) p a² [(1 − 2ν) r + b²/r] / (E (b² − a²)).
/// The nodal error falls at the element's rate ([`check_rates`]).
#[test]
fn the_thick_cylinder_converges_to_lame() {
    let (a, b) = (5e-3, 10e-3);
    let (mu, lambda) = (1e5, 2e5);
    let p = 1e-3; // Pa: p/μ = 1e-8, far below the nonlinear terms' reach
    let (e, nu) = young_poisson(mu, lambda);
    let exact = |r: f64, _z: f64| {
        (1.0 + nu) * p * a * a * ((1.0 - 2.0 * nu) * r + b * b / r) / (e * (b * b - a * a))
    };
    for kind in MeridianKind::ALL {
        let levels: &[usize] = if kind.is_quadratic() {
            &[2, 4, 8]
        } else {
            &[4, 8, 16, 32]
        };
        let errors: Vec<f64> = levels
            .iter()
            .map(|&n| {
                // square cells, halved each time
                let mesh = rectangle_mesh(a, b, 0.5 * (b - a), n, n / 2, kind).unwrap();
                let inner = mesh.face_sets["inner"].clone();
                let material = Arc::new(ElectroNeoHooke::new(mu, lambda, 1.0));
                let mut model = Model::new(mesh, material).unwrap();
                model.fix("top", Field::Uy, 0.0).unwrap();
                model.fix("bottom", Field::Uy, 0.0).unwrap();
                model.fix("top", Field::Phi, 0.0).unwrap();
                model.fix("bottom", Field::Phi, 0.0).unwrap();
                let faces = deasim::problem::pressure::surface(&model.mesh, &inner);
                model
                    .pressures
                    .push(deasim::problem::pressure::Pressure::new(faces, p));
                radial_error(&model, exact)
            })
            .collect();
        let r = rates(&errors);
        println!("cylinder {kind:?}: errors {errors:?}, rates {r:?}");
        check_rates(kind, &r);
    }
}

/// The thick sphere under internal pressure (the upper half, its equator held axially):
/// u_r = p a³ [(1 − 2ν) r + (1 + ν) b³/(2r²)] / (E (b³ − a³)) along the position vector; the
/// radial component of the nodal displacement converges at the element's rate ([`check_rates`]),
/// and the mean-dilatation quad4 is as close.
#[test]
fn the_thick_sphere_converges_to_lame() {
    let (a, b): (f64, f64) = (5e-3, 10e-3);
    let (mu, lambda) = (1e5, 2e5);
    let p = 1e-3;
    let (e, nu) = young_poisson(mu, lambda);
    let ur = |r: f64| {
        p * a.powi(3) * ((1.0 - 2.0 * nu) * r + (1.0 + nu) * b.powi(3) / (2.0 * r * r))
            / (e * (b.powi(3) - a.powi(3)))
    };
    let solve = |kind: MeridianKind, n: usize, formulation: Formulation| -> f64 {
        let mesh = deasim::mesh::meridian::sphere_meridian(a, b, 2 * n, n, kind).unwrap();
        let inner = mesh.face_sets["inner"].clone();
        let material = Arc::new(ElectroNeoHooke::new(mu, lambda, 1.0));
        let mut model = Model::new(mesh, material).unwrap();
        model.formulation = formulation;
        model.fix("equator", Field::Uy, 0.0).unwrap();
        model.fix("inner", Field::Phi, 0.0).unwrap();
        model.fix("outer", Field::Phi, 0.0).unwrap();
        let faces = deasim::problem::pressure::surface(&model.mesh, &inner);
        model
            .pressures
            .push(deasim::problem::pressure::Pressure::new(faces, p));
        let mut state = Vec::new();
        solve_static(
            &model,
            None,
            &StepControl {
                steps: 1,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |pr, _| state = pr.state.to_vec(),
        )
        .result
        .expect("converges");
        let mut worst: f64 = 0.0;
        for (node, x) in model.mesh.nodes.iter().enumerate() {
            let rho = (x[0] * x[0] + x[1] * x[1]).sqrt();
            let radial = (state[node * 4] * x[0] + state[node * 4 + 1] * x[1]) / rho;
            worst = worst.max((radial - ur(rho)).abs());
        }
        worst / ur(a)
    };
    for kind in MeridianKind::ALL {
        let levels: &[usize] = if kind.is_quadratic() {
            &[2, 4, 8]
        } else {
            &[4, 8, 16, 32]
        };
        let errors: Vec<f64> = levels
            .iter()
            .map(|&n| solve(kind, n, Formulation::Standard))
            .collect();
        let r = rates(&errors);
        println!("sphere {kind:?}: errors {errors:?}, rates {r:?}");
        check_rates(kind, &r);
    }
    let md = solve(MeridianKind::Quad4, 4, Formulation::MeanDilatation);
    println!("sphere quad4 mean-dilatation, n = 4: error {md:.3e}");
    assert!(md < 0.02, "{md}");
}

/// Objectivity about the axis: the deformation gradient of a meridian cell's point, rotated about
/// the axis (e_Z, the second basis vector), leaves the energy and the referential electric
/// displacement unchanged and rotates the first Piola stress (1e-12).
#[test]
fn rotations_about_the_axis_leave_the_response_unchanged() {
    use deasim::fem::axisymmetric::{meridian_geometry, meridian_kinematics};
    use deasim::material::{Mat3, Material, PointHistory};
    let kind = MeridianKind::Quad4;
    let x = [
        [1e-3, 0.0],
        [2e-3, 0.1e-3],
        [2.1e-3, 1e-3],
        [0.9e-3, 0.9e-3],
    ];
    let g = meridian_geometry(kind, &x).unwrap();
    let u = [
        [1e-4, -2e-5, 0.0],
        [2e-4, 1e-5, 0.0],
        [1.5e-4, -3e-5, 0.0],
        [0.5e-4, 2e-5, 0.0],
    ];
    let phi = [0.0, 50.0, 900.0, 1000.0];
    let (f, e0) = meridian_kinematics(&g.grad[0][..4], &g.hoop(0)[..4], &u, &phi);
    let mat = ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R);
    let s = mat.stress_at(&f, &e0, PointHistory::NONE).unwrap();
    for angle in [0.3f64, 1.2, 2.9] {
        let (c, sn) = (angle.cos(), angle.sin());
        // about e_Z in the basis (e_R, e_Z, e_Θ): mixes the first and third components
        let q = Mat3::new(c, 0.0, -sn, 0.0, 1.0, 0.0, sn, 0.0, c);
        let r = mat.stress_at(&(q * f), &e0, PointHistory::NONE).unwrap();
        assert!((r.energy - s.energy).abs() <= 1e-12 * s.energy.abs());
        assert!((r.d0 - s.d0).norm() <= 1e-12 * s.d0.norm());
        assert!((r.p - q * s.p).norm() <= 1e-12 * s.p.norm());
    }
}
