//! The material-point state path, with a one-branch Maxwell material (neo-Hooke spring plus a
//! neo-Hookean Maxwell branch on the isochoric deformation, backward-Euler update of the
//! Linder–Tkachuk–Miehe law): a hex8 cell in uniaxial strain, F = diag(λ, 1, 1), stretched to
//! λ = 1.5 in 0.1 s and held for 2 s.
//!
//! Reference: the discrete closed form of the same update, A_{n+1} = (A_n + k C̄⁻¹)/(1 + k), k =
//! Δt/τ, evaluated along the load factors the ramp accepted; tolerance 1e-9 relative (the Newton
//! tolerance). A forced cut-back (one load step, at most 2 Newton iterations) must leave no trace
//! of the rejected attempts; a ramp resumed from a mid-stage state with its point states ends bit
//! for bit where the uninterrupted one does; the dissipated energy closes the energy balance
//! (work = stored + dissipated) to the update's first-order accuracy. A cell in uniaxial stress
//! ramped in one step with at most two Newton iterations is cut back, and its accepted states
//! follow the closed form (bisection for the lateral stretch) along the accepted load factors.

use deasim::job::statics::{solve_static_from, StageTime};
use deasim::material::maxwell::MaxwellBranch;
use deasim::material::ElectroNeoHooke;
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::Field;
use deasim::problem::model::Model;
use deasim::problem::points::PointStates;
use deasim::solve::linear::SolverSettings;
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use std::sync::Arc;

const L: f64 = 1e-3;
const MU: f64 = 1e5;
const LAMBDA: f64 = 1e6;
const G: f64 = 3e5;
const TAU: f64 = 0.5;

fn model(stretch: f64) -> Model {
    let mesh = box_mesh([L, L, L], [1, 1, 1], ElementKind::Hex8);
    let mat = MaxwellBranch {
        equilibrium: ElectroNeoHooke::new(MU, LAMBDA, 4.7),
        g: G,
        tau: TAU,
    };
    let mut m = Model::new(mesh, Arc::new(mat)).unwrap();
    m.fix("x0", Field::Ux, 0.0).unwrap();
    m.fix("x1", Field::Ux, (stretch - 1.0) * L).unwrap();
    for s in ["y0", "y1"] {
        m.fix(s, Field::Uy, 0.0).unwrap();
    }
    for s in ["z0", "z1"] {
        m.fix(s, Field::Uz, 0.0).unwrap();
        m.fix(s, Field::Phi, 0.0).unwrap();
    }
    m
}

/// Nominal stress P₁₁ (Pa) of the step from the committed diagonal A (its three entries).
fn p11(lam: f64, a: [f64; 3], k: f64) -> f64 {
    let eq = MU * (lam - 1.0 / lam) + LAMBDA * lam.ln() / lam;
    let c = G / (2.0 * (1.0 + k));
    let alpha = lam.powf(-2.0 / 3.0);
    let ia = lam * lam * a[0] + a[1] + a[2];
    eq + c * alpha * (2.0 * lam * a[0] - 2.0 / 3.0 * ia / lam)
}

/// A after a step to stretch λ.
fn update(lam: f64, a: [f64; 3], k: f64) -> [f64; 3] {
    let alpha = lam.powf(-2.0 / 3.0);
    let ci = [1.0 / (alpha * lam * lam), 1.0 / alpha, 1.0 / alpha];
    [0, 1, 2].map(|i| (a[i] + k * ci[i]) / (1.0 + k))
}

/// One stage: (load factor, stretch, P₁₁ from the reaction) of every accepted step, the final
/// state and points, the dissipated energy and the cut-backs.
struct Stage {
    steps: Vec<(f64, f64, f64)>,
    state: Vec<f64>,
    points: PointStates,
    dissipated: f64,
    cutbacks: usize,
}

fn run_stage(
    m: &Model,
    start: Vec<f64>,
    points: PointStates,
    duration: f64,
    steps: usize,
    newton: &NewtonSettings,
    resume: Option<(Vec<f64>, deasim::solve::stepping::RampPosition)>,
) -> Stage {
    let x1 = m.mesh.node_sets["x1"].clone();
    let mut out = Vec::new();
    let mut dissipated = 0.0;
    let o = solve_static_from(
        m,
        &SolverSettings::default(),
        start,
        StageTime {
            duration,
            points,
            drive: deasim::problem::drive::Drive::ramped(m),
        },
        resume,
        &StepControl {
            steps,
            ..Default::default()
        },
        newton,
        None,
        |p, acc| {
            let r = p.nodal_reactions().unwrap();
            let force: f64 = x1.iter().map(|&n| r[n * 4]).sum();
            let lam = 1.0 + p.state[x1[0] * 4] / L;
            out.push((acc.load, lam, force / (L * L)));
            dissipated = p.dissipated;
        },
    );
    let report = o.result.expect("the ramp converges");
    Stage {
        steps: out,
        state: o.state,
        points: o.points,
        dissipated,
        cutbacks: report.cutbacks,
    }
}

/// Checks the stage's stresses against the closed form; returns the final A.
fn check(stage: &Stage, duration: f64, mut a: [f64; 3]) -> [f64; 3] {
    let mut s_prev = 0.0;
    for &(s, lam, p) in &stage.steps {
        let k = (s - s_prev) * duration / TAU;
        let expect = p11(lam, a, k);
        assert!(
            (p - expect).abs() <= 1e-9 * expect.abs(),
            "s = {s}: P11 {p} vs {expect}"
        );
        a = update(lam, a, k);
        s_prev = s;
    }
    a
}

#[test]
fn maxwell_relaxation_follows_the_discrete_closed_form() {
    let newton = NewtonSettings {
        rtol: 1e-12,
        ..Default::default()
    };
    let m = model(1.5);
    let n = m.mesh.n_nodes() * 4;
    let ramp = run_stage(
        &m,
        vec![0.0; n],
        PointStates::new(&m),
        0.1,
        10,
        &newton,
        None,
    );
    let a = check(&ramp, 0.1, [1.0; 3]);
    let hold = run_stage(
        &m,
        ramp.state.clone(),
        ramp.points.clone(),
        2.0,
        20,
        &newton,
        None,
    );
    let a_end = check(&hold, 2.0, a);
    // relaxed toward the spring alone: P₁₁ falls from its peak to near the equilibrium branch
    let peak = ramp.steps.last().unwrap().2;
    let last = hold.steps.last().unwrap().2;
    let eq = p11(1.5, [0.0; 3], 0.0) - 0.0;
    let eq_only = MU * (1.5 - 1.0 / 1.5) + LAMBDA * 1.5f64.ln() / 1.5;
    assert!(peak > last && last > eq_only, "{peak} {last} {eq}");
    eprintln!(
        "P11: {peak:.6e} Pa at 0.1 s, {last:.6e} Pa at 2.1 s (spring alone {eq_only:.6e}); A_xx {:.6}",
        a_end[0]
    );

    // energy balance: the work of the prescribed stretch (trapezoidal rule on P₁₁ dλ over the
    // volume) equals the stored energy (spring + branch at the committed A) plus the dissipation
    let v = L * L * L;
    let mut work = 0.0;
    let (mut lam0, mut p0) = (1.0, 0.0);
    for &(_, lam, p) in ramp.steps.iter().chain(&hold.steps) {
        work += 0.5 * (p0 + p) * (lam - lam0) * v;
        (lam0, p0) = (lam, p);
    }
    let alpha = 1.5f64.powf(-2.0 / 3.0);
    let spring =
        MU / 2.0 * (1.5 * 1.5 - 1.0) - MU * 1.5f64.ln() + LAMBDA / 2.0 * 1.5f64.ln().powi(2);
    let branch = G / 2.0 * (alpha * (1.5 * 1.5 * a_end[0] + a_end[1] + a_end[2]) - 3.0);
    let stored = (spring + branch) * v;
    let dissipated = ramp.dissipated + hold.dissipated;
    let error = (work - stored - dissipated) / dissipated;
    eprintln!("work {work:.6e} J, stored {stored:.6e} J, dissipated {dissipated:.6e} J, balance {error:.3e}");
    assert!(dissipated > 0.0);
    assert!(error.abs() < 0.05, "energy balance off by {error}");
}

/// Lateral stretch λ₂ = λ₃ of uniaxial stress at axial stretch λ from the committed diagonal A
/// (P₂₂ = 0, solved by bisection), and the axial nominal stress P₁₁ there.
fn uniaxial_stress(lam: f64, a: [f64; 3], k: f64) -> (f64, f64) {
    let p = |l: [f64; 3], i: usize| {
        let j = l[0] * l[1] * l[2];
        let c = G / (2.0 * (1.0 + k));
        let alpha = j.powf(-2.0 / 3.0);
        let ia: f64 = (0..3).map(|m| l[m] * l[m] * a[m]).sum();
        MU * (l[i] - 1.0 / l[i])
            + LAMBDA * j.ln() / l[i]
            + c * alpha * (2.0 * l[i] * a[i] - 2.0 / 3.0 * ia / l[i])
    };
    let (mut lo, mut hi) = (0.5, 1.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if p([lam, mid, mid], 1) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let l2 = 0.5 * (lo + hi);
    (l2, p([lam, l2, l2], 0))
}

/// One load step to λ = 1.5 of a cell in uniaxial stress (lateral faces free) with at most 2
/// Newton iterations: the ramp cuts back, and every accepted state still follows the closed form
/// along the accepted load factors — a rejected attempt never commits its point states.
#[test]
fn cut_back_steps_leave_no_trace_in_the_points() {
    let mesh = box_mesh([L, L, L], [1, 1, 1], ElementKind::Hex8);
    let mat = MaxwellBranch {
        equilibrium: ElectroNeoHooke::new(MU, LAMBDA, 4.7),
        g: G,
        tau: TAU,
    };
    let mut m = Model::new(mesh, Arc::new(mat)).unwrap();
    m.fix("x0", Field::Ux, 0.0).unwrap();
    m.fix("x1", Field::Ux, 0.5 * L).unwrap();
    m.fix("y0", Field::Uy, 0.0).unwrap();
    m.fix("z0", Field::Uz, 0.0).unwrap();
    m.fix("z0", Field::Phi, 0.0).unwrap();
    m.fix("z1", Field::Phi, 0.0).unwrap();
    let newton = NewtonSettings {
        rtol: 1e-12,
        max_iterations: 2,
        ..Default::default()
    };
    let n = m.mesh.n_nodes() * 4;
    let y1 = m.mesh.node_sets["y1"].clone();
    let mut states = Vec::new();
    let stage = run_stage(
        &m,
        vec![0.0; n],
        PointStates::new(&m),
        0.1,
        1,
        &newton,
        None,
    );
    assert!(stage.cutbacks > 0, "no cut-back was forced");
    assert!(stage.steps.len() > 1);
    let mut a = [1.0; 3];
    let mut s_prev = 0.0;
    for &(s, lam, p11) in &stage.steps {
        let k = (s - s_prev) * 0.1 / TAU;
        let (l2, expect) = uniaxial_stress(lam, a, k);
        assert!(
            (p11 - expect).abs() <= 1e-7 * expect.abs(),
            "s = {s}: P11 {p11} vs {expect}"
        );
        states.push(l2);
        let alpha = (lam * l2 * l2).powf(-2.0 / 3.0);
        let l = [lam, l2, l2];
        a = [0, 1, 2].map(|i| (a[i] + k / (alpha * l[i] * l[i])) / (1.0 + k));
        s_prev = s;
    }
    let l2_fe = 1.0 + stage.state[y1[0] * 4 + 1] / L;
    let l2_ref = *states.last().unwrap();
    assert!((l2_fe - l2_ref).abs() < 1e-9, "{l2_fe} vs {l2_ref}");
    eprintln!(
        "{} accepted steps after {} cut-backs; lateral stretch {l2_fe:.9}",
        stage.steps.len(),
        stage.cutbacks
    );
}

/// A ramp resumed from its state, ramp position and point states after step 4 ends bit for bit
/// where the uninterrupted ramp ends.
#[test]
fn resumed_ramp_with_point_states_is_bitwise() {
    let newton = NewtonSettings::default();
    let m = model(1.4);
    let n = m.mesh.n_nodes() * 4;
    let full = run_stage(
        &m,
        vec![0.0; n],
        PointStates::new(&m),
        1.0,
        8,
        &newton,
        None,
    );
    // the state after step 4
    let mut saved = None;
    let mut count = 0;
    solve_static_from(
        &m,
        &SolverSettings::default(),
        vec![0.0; n],
        StageTime {
            duration: 1.0,
            points: PointStates::new(&m),
            drive: deasim::problem::drive::Drive::ramped(&m),
        },
        None,
        &StepControl {
            steps: 8,
            ..Default::default()
        },
        &newton,
        None,
        |p, acc| {
            count += 1;
            if count == 4 {
                saved = Some((p.state.clone(), acc.position, p.points.clone()));
            }
        },
    );
    let (state, position, points) = saved.unwrap();
    let resumed = run_stage(
        &m,
        vec![0.0; n],
        points,
        1.0,
        8,
        &newton,
        Some((state, position)),
    );
    assert_eq!(resumed.state, full.state);
    assert_eq!(resumed.points, full.points);
    assert_eq!(resumed.steps[..], full.steps[4..]);
}

/// Through the whole run: the `film` example with its material replaced by the Maxwell material
/// (a run-level path no scenario key reaches yet). The field files carry the internal variables,
/// checkpoints carry them, and a run resumed from a checkpoint ends with the same records, bit for
/// bit, as the uninterrupted run.
#[test]
fn run_exports_checkpoints_and_resumes_point_states() {
    use deasim::io::build::build;
    use deasim::io::checkpoint::{latest, CheckpointWriter, ScenarioSource};
    use deasim::io::output::OutputWriter;
    use deasim::io::scenario::parse;
    use deasim::job::observer::Observer;
    use deasim::job::run::run_with;
    let text = deasim::io::examples::example("film").unwrap();
    let s = parse(text, "film.toml", &["stages.0.steps=6".to_string()]).unwrap();
    let mut plan = build(&s, "film.toml", None).unwrap();
    let eps_r = 4.7;
    plan.model.materials[0] = Arc::new(MaxwellBranch {
        equilibrium: ElectroNeoHooke::new(MU, 1e7, eps_r),
        g: G,
        tau: TAU,
    });
    let scratch = tempfile::Builder::new()
        .prefix("deasim-test-mstate-")
        .tempdir()
        .unwrap();
    let base = scratch.path().to_path_buf();
    let run = |dir: &std::path::Path, every: usize, start| {
        let mut writer = OutputWriter::new(dir).unwrap();
        let mut ck = CheckpointWriter {
            dir: dir.to_path_buf(),
            every,
            source: ScenarioSource {
                text: text.to_string(),
                file: "film.toml".into(),
                base_dir: None,
                overrides: vec![],
            },
            fingerprint: plan.fingerprint(),
            ranks: 1,
            part: None,
        };
        let mut obs: Vec<&mut dyn Observer> = vec![&mut writer, &mut ck];
        let summary = run_with(&plan, &mut obs, start);
        assert!(summary.converged, "{:?}", summary.error);
    };
    let full = base.join("full");
    run(&full, 4, None);
    let vtu = std::fs::read_dir(full.join("fields"))
        .unwrap()
        .flatten()
        .map(|e| std::fs::read_to_string(e.path()).unwrap())
        .find(|t| t.contains("Name=\"A_xx\""));
    assert!(vtu.is_some(), "no field file carries A_xx");
    let (ck, _, _) = latest(&full).unwrap();
    let n_points = plan.model.mesh.n_cells() * plan.model.reference.n_qp * 9;
    assert_eq!(ck.state.points.len(), n_points);
    assert!(ck
        .state
        .points
        .iter()
        .any(|&a| (a - 1.0).abs() > 1e-6 && a != 0.0));
    // resume from the checkpoint after step 4 into a copy holding the outputs up to it
    let resumed = base.join("resumed");
    std::fs::create_dir_all(&resumed).unwrap();
    run(&resumed, 1_000_000, Some(ck.state.clone()));
    let rows = |d: &std::path::Path| std::fs::read_to_string(d.join("history.csv")).unwrap();
    let (a, b) = (rows(&full), rows(&resumed));
    let tail = |t: &str| {
        t.lines()
            .skip(1 + ck.state.records.len())
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(tail(&a), tail(&b));
    assert!(!tail(&a).is_empty());
}
