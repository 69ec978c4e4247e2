//! Inflation of a spherical balloon by arc-length continuation in the pressure: an eighth of a
//! shell (`mesh::sphere::sphere_octant`, inner radius 10 mm, wall 0.5 mm, two hex8 layers,
//! mean-dilatation, κ = 10⁴ μ) under a follower pressure on its inner face, symmetry on the
//! three planes.
//!
//! Reference: the incompressible thick-walled sphere. With λ = r/R, σ_θθ − σ_rr = 2W₁(λ² − λ⁻⁴)
//! − εe², and the radial balance gives the inner pressure
//! p = ∫ 4W₁(λ)(λ³ + 1)/λ⁵ dλ over [λ_o, λ_i] − (ε/2)k²(r_i⁻⁴ − r_o⁻⁴), with k = V/(1/r_i − 1/r_o)
//! (the field e = k/r² between electrodes on the two faces) and R_o³(λ_o³ − 1) = R_i³(λ_i³ − 1).
//! Its thin limit is the membrane formula pR/(μH) = 2(λ⁻¹ − λ⁻⁷) − 2εV²λ/(μH²) (docs/theory.md).
//!
//! - neo-Hooke: every point within the discretisation error of p(λ_i), the error falling under
//!   refinement (n = 4 → 8 cells per cube-face edge). The pressure maximum is located
//!   (the points past it unstable under pressure control), and lies within 0.5 % of the
//!   closed-form maximum.
//! - Gent (J_m = 30): through the maximum and the minimum to the rising branch.
//! - With 5 kV on the electrodes, the peak pressure falls as the closed form says.
//! - Under volume control (the pressure an unknown that makes the cavity reach a volume) the
//!   same curve is followed by a plain load ramp, every state stable, through the maximum.
//! - The `balloon` example (the `sphere` generator, a Gent wall at 5 kV, a pressure acting in its
//!   continuation stage only) reports both limit points at the closed form's values, and
//!   `balloon-volume` (its volume prescribed, the pressure recorded by a `pressure` probe)
//!   follows the same curve with a static ramp to the prescribed volume.

mod common;

use deasim::material::registry::{build, MaterialParams};
use deasim::material::EPSILON_0;
use deasim::mesh::sphere::sphere_octant;
use deasim::problem::dofs::{Dirichlet, Field, FIELDS};
use deasim::problem::model::{Formulation, Model};
use deasim::problem::pressure::{surface, Pressure};
use deasim::problem::statics::StaticProblem;
use deasim::solve::continuation::{continuation, ContinuationSettings, Next, PathEvent};
use deasim::solve::linear::SolverSettings;
use deasim::solve::newton::NewtonSettings;

const R: f64 = 10e-3;
const H: f64 = 0.5e-3;
const MU: f64 = 1e5;
const EPS_R: f64 = 4.7;

/// ∂W/∂I₁ of the material (neo-Hooke without `jm`).
fn w1(jm: Option<f64>, i1: f64) -> f64 {
    match jm {
        None => 0.5 * MU,
        Some(jm) => 0.5 * MU * jm / (jm - i1 + 3.0),
    }
}

/// The thick incompressible sphere's inner pressure at inner stretch `li` with `volts` across it.
fn pressure(jm: Option<f64>, li: f64, volts: f64) -> f64 {
    let ro = R + H;
    let lo = (1.0 + R.powi(3) * (li.powi(3) - 1.0) / ro.powi(3)).cbrt();
    let f = |l: f64| 4.0 * w1(jm, 2.0 * l * l + l.powi(-4)) * (l.powi(3) + 1.0) / l.powi(5);
    let m = 2000;
    let h = (li - lo) / m as f64;
    let mut s = f(lo) + f(li);
    for k in 1..m {
        s += f(lo + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    let (r_i, r_o) = (R * li, ro * lo);
    let k = volts / (1.0 / r_i - 1.0 / r_o);
    s * h / 3.0 - 0.5 * EPS_R * EPSILON_0 * k * k * (r_i.powi(-4) - r_o.powi(-4))
}

/// Extremum of `pressure` in [a, b] (golden section): (λ_i, p).
fn extremum(jm: Option<f64>, volts: f64, a: f64, b: f64, maximum: bool) -> (f64, f64) {
    let sign = if maximum { 1.0 } else { -1.0 };
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (a, b);
    while b - a > 1e-10 {
        let (x1, x2) = (b - g * (b - a), a + g * (b - a));
        if sign * pressure(jm, x1, volts) > sign * pressure(jm, x2, volts) {
            b = x2;
        } else {
            a = x1;
        }
    }
    let x = 0.5 * (a + b);
    (x, pressure(jm, x, volts))
}

/// One converged point: inner stretch, pressure (Pa), stable under pressure control.
type Point = (f64, f64, bool);

/// The octant with `n` cells per cube-face edge (two layers, mean-dilatation, κ = 10⁴ μ; neo-Hooke
/// or Gent `jm`), symmetry on x0, y0, z0, the inner face grounded and the outer one at `volts`
/// (every potential 0 without a voltage).
fn shell(n: usize, jm: Option<f64>, volts: f64) -> Model {
    let mesh = sphere_octant(R, R + H, n, 2);
    let params = MaterialParams {
        mu: vec![MU],
        kappa: Some(1e4 * MU),
        jm,
        permittivity: Some(EPS_R),
        ..Default::default()
    };
    let model_name = if jm.is_some() {
        "gent"
    } else {
        "neo-hooke-split"
    };
    let (material, _) = build(model_name, &params).unwrap();
    let mut model = Model::new(mesh, material).unwrap();
    model.formulation = Formulation::MeanDilatation;
    model.fix("x0", Field::Ux, 0.0).unwrap();
    model.fix("y0", Field::Uy, 0.0).unwrap();
    model.fix("z0", Field::Uz, 0.0).unwrap();
    model.fix("inner", Field::Phi, 0.0).unwrap();
    model.fix("outer", Field::Phi, volts).unwrap();
    // the potential of the wall's middle nodes is free; with no voltage all of it is 0
    if volts == 0.0 {
        model.dirichlet.push(Dirichlet {
            nodes: (0..model.mesh.n_nodes()).collect(),
            field: Field::Phi,
            value: 0.0,
        });
    }
    model
}

/// The mean inner stretch r/R of a state.
fn inner_stretch(model: &Model, state: &[f64]) -> f64 {
    let inner = &model.mesh.node_sets["inner"];
    inner
        .iter()
        .map(|&a| {
            let x = model.mesh.nodes[a];
            let r2: f64 = (0..3).map(|i| (x[i] + state[a * FIELDS + i]).powi(2)).sum();
            r2.sqrt() / R
        })
        .sum::<f64>()
        / inner.len() as f64
}

/// The path of the octant with `n` cells per cube-face edge, from 0 to the inner stretch
/// `until`: its points and its limit points (λ_i, p, maximum).
fn inflate(
    n: usize,
    jm: Option<f64>,
    volts: f64,
    until: f64,
) -> (Vec<Point>, Vec<(f64, f64, bool)>) {
    let mut model = shell(n, jm, volts);
    // the voltage first, without the pressure
    let mut start = None;
    if volts != 0.0 {
        let out = deasim::job::statics::solve_static(
            &model,
            None,
            &Default::default(),
            &NewtonSettings::default(),
            |_, _| {},
        );
        out.result.unwrap();
        start = Some(out.state);
    }
    let faces = surface(&model.mesh, &model.mesh.face_sets["inner"]);
    // the thin sphere's peak is near 1.24 μH/R: the load factor runs to about 0.6
    let p_ref = 2.0 * MU * H / R;
    model.pressures.push(Pressure::new(faces, p_ref));
    let mut problem = StaticProblem::new(&model, start);
    let mut solver = SolverSettings::default().build();
    let settings = ContinuationSettings {
        increment: 0.05,
        max_points: 400,
        ..Default::default()
    };
    let stretch = |state: &[f64]| inner_stretch(&model, state);
    let mut points = Vec::new();
    let mut limits = Vec::new();
    continuation(
        &mut problem,
        solver.as_mut(),
        &NewtonSettings::default(),
        &settings,
        0.0,
        |p, event| match event {
            PathEvent::Point(pt) => {
                let l = stretch(&p.state);
                points.push((l, pt.load * p_ref, pt.stable));
                if l >= until {
                    Next::Stop
                } else {
                    Next::Continue
                }
            }
            PathEvent::Limit(lp) => {
                limits.push((stretch(&p.state), lp.load * p_ref, lp.maximum));
                Next::Continue
            }
        },
    )
    .unwrap();
    (points, limits)
}

/// Largest |p − p(λ_i)| over the points, relative to the closed-form peak.
fn worst(points: &[Point], jm: Option<f64>, volts: f64, peak: f64) -> f64 {
    points
        .iter()
        .map(|&(l, p, _)| (p - pressure(jm, l, volts)).abs() / peak)
        .fold(0.0, f64::max)
}

#[test]
fn neo_hooke_balloon_through_its_pressure_maximum_converges_under_refinement() {
    let (l_peak, p_peak) = extremum(None, 0.0, 1.0, 2.0, true);
    // the thin-membrane figure, for orientation: 1.23946 at λ = 7^(1/6)
    eprintln!(
        "closed form (thick): peak {:.5} μH/R at λ_i = {l_peak:.5}; thin: 1.23946 at 1.38309",
        p_peak * R / (MU * H)
    );
    let mut errors = Vec::new();
    let mut peaks = Vec::new();
    for n in [4, 8] {
        let (points, limits) = inflate(n, None, 0.0, 2.0);
        let e = worst(&points, None, 0.0, p_peak);
        assert_eq!(limits.len(), 1, "{limits:?}");
        let (l, p, maximum) = limits[0];
        assert!(maximum);
        eprintln!(
            "n = {n}: {} points, largest error {e:.2e} of the peak; located peak {p:.4} Pa \
             ({:+.2e}) at λ_i = {l:.4} (closed form {p_peak:.4} at {l_peak:.4})",
            points.len(),
            (p - p_peak) / p_peak
        );
        // stable before the maximum, unstable after it (margin where the stretch is close)
        for &(lp, _, stable) in &points {
            if lp < l_peak - 0.02 {
                assert!(stable, "λ {lp}");
            } else if lp > l_peak + 0.02 {
                assert!(!stable, "λ {lp}");
            }
        }
        assert!(points.last().unwrap().0 >= 2.0);
        errors.push(e);
        peaks.push((p - p_peak).abs() / p_peak);
    }
    assert!(errors[1] < 5e-3, "{errors:?}");
    assert!(
        errors[1] < 0.5 * errors[0],
        "the error falls with refinement: {errors:?}"
    );
    assert!(peaks[1] < 5e-3 && peaks[1] < peaks[0], "{peaks:?}");
}

#[test]
fn gent_balloon_passes_its_maximum_and_minimum_to_the_rising_branch() {
    let jm = Some(30.0);
    let (l_max, p_max) = extremum(jm, 0.0, 1.0, 2.0, true);
    let (l_min, p_min) = extremum(jm, 0.0, 2.0, 4.0, false);
    let until = l_min + 0.8;
    let (points, limits) = inflate(8, jm, 0.0, until);
    let e = worst(&points, jm, 0.0, p_max);
    eprintln!(
        "Gent J_m = 30: {} points, largest error {e:.2e}; limits {limits:?}; closed form max \
         {p_max:.4} at {l_max:.4}, min {p_min:.4} at {l_min:.4}",
        points.len()
    );
    assert!(e < 5e-3, "{e}");
    assert_eq!(limits.len(), 2, "{limits:?}");
    assert!(limits[0].2 && !limits[1].2);
    assert!((limits[0].1 - p_max).abs() < 5e-3 * p_max);
    assert!((limits[1].1 - p_min).abs() < 5e-3 * p_max);
    // the rising branch: stable again past the minimum
    let last = points.last().unwrap();
    assert!(last.0 >= until && last.1 > p_min && last.2, "{last:?}");
}

#[test]
fn a_voltage_lowers_the_peak_pressure_as_the_closed_form_says() {
    let volts = 5000.0;
    let (_, p0) = extremum(None, 0.0, 1.0, 2.0, true);
    let (_, pv) = extremum(None, volts, 1.0, 2.0, true);
    let (points, limits) = inflate(8, None, volts, 1.8);
    let e = worst(&points, None, volts, pv);
    eprintln!(
        "{volts} V: closed-form peak {pv:.4} Pa (0 V: {p0:.4}); located {:?}; largest error \
         {e:.2e}",
        limits
    );
    assert!(
        pv < 0.95 * p0,
        "the voltage must matter in this test: {pv} vs {p0}"
    );
    assert!(e < 5e-3, "{e}");
    assert_eq!(limits.len(), 1);
    assert!((limits[0].1 - pv).abs() < 5e-3 * pv, "{limits:?} vs {pv}");
}

#[test]
fn the_balloon_example_finds_both_limit_points_of_the_closed_form() {
    let dir = common::tempdir("balloon-example");
    let out = common::deasim(&["run", "balloon", "--out", "b"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let jm = Some(30.0);
    let (l_max, p_max) = extremum(jm, 5000.0, 1.0, 2.0, true);
    let (l_min, p_min) = extremum(jm, 5000.0, 2.0, 4.0, false);
    let text = std::fs::read_to_string(dir.join("b/summary.json")).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    let limits = summary["limit_points"].as_array().unwrap();
    assert_eq!(limits.len(), 2, "{limits:?}");
    // measured with 6 cells per patch edge: 5730.25 Pa at λ 1.44001, 4680.18 Pa at 2.51268
    for (lp, kind, l, p) in [
        (&limits[0], "maximum", l_max, p_max),
        (&limits[1], "minimum", l_min, p_min),
    ] {
        let value = lp["value"].as_f64().unwrap();
        let stretch = lp["probes"]["stretch"].as_f64().unwrap();
        eprintln!("{kind}: {value:.2} Pa at λ {stretch:.5}; closed form {p:.2} Pa at {l:.5}");
        assert_eq!(lp["kind"], kind);
        assert_eq!(lp["unit"], "Pa");
        assert!((value - p).abs() < 3e-3 * p_max, "{kind}: {value} vs {p}");
        assert!((stretch - l).abs() < 5e-3 * l, "{kind}: λ {stretch} vs {l}");
        // the whole balloon's cavity, to the faceting of the inner face
        let volume = lp["probes"]["volume"].as_f64().unwrap();
        let sphere = 4.0 / 3.0 * std::f64::consts::PI * (stretch * R).powi(3);
        assert!(
            (volume / sphere - 1.0).abs() < 0.015,
            "{volume} vs {sphere}"
        );
    }
    // between the two, the path is unstable under pressure control; beyond, stable again
    let path = std::fs::read_to_string(dir.join("b/path.csv")).unwrap();
    let mut lines = path.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (stable, stretch) = (col("stable"), col("probe:stretch"));
    let rows: Vec<(bool, f64)> = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            (v[stable] == "true", v[stretch].parse().unwrap())
        })
        .collect();
    for &(st, l) in &rows {
        if l < l_max - 0.02 || l > l_min + 0.02 {
            assert!(st, "λ {l} should be stable");
        } else if l > l_max + 0.02 && l < l_min - 0.02 {
            assert!(!st, "λ {l} should be unstable");
        }
    }
    assert!(rows.last().unwrap().1 >= 3.2);
}

#[test]
fn volume_control_ramps_through_the_pressure_maximum_with_every_state_stable() {
    let mut model = shell(4, None, 0.0);
    let faces = surface(&model.mesh, &model.mesh.face_sets["inner"]);
    let v0 = deasim::problem::pressure::enclosed_volume(
        &faces,
        &vec![0.0; model.mesh.n_nodes() * FIELDS],
    );
    // the pressure is an unknown (fraction of 1 Pa): the cavity grows to 2³ times its volume
    let mut pressure = Pressure::new(faces, 1.0);
    pressure.volume = Some(8.0 * v0);
    model.pressures.push(pressure);
    let stretch = |state: &[f64]| inner_stretch(&model, state);
    let mut problem = StaticProblem::new(&model, None);
    let mut solver = SolverSettings::default().build();
    let control = deasim::solve::stepping::StepControl {
        steps: 20,
        ..Default::default()
    };
    let mut points: Vec<Point> = Vec::new();
    // negative pivots of the tangent at fixed pressure, per step
    let mut negatives = Vec::new();
    let report = deasim::solve::stepping::ramp(
        &mut problem,
        solver.as_mut(),
        &NewtonSettings::default(),
        &control,
        |p, step| {
            let level = p.volume_control.as_ref().unwrap().level;
            points.push((stretch(&p.state), level, step.newton.stable));
            negatives.push(step.newton.inertia.map(|i| i.negative));
        },
    )
    .unwrap();
    let (l_peak, p_peak) = extremum(None, 0.0, 1.0, 2.0, true);
    let e = worst(&points, None, 0.0, p_peak);
    let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
    eprintln!(
        "volume control: {} steps, {} Newton iterations; largest error {e:.2e} of the peak; \
         highest pressure {top:.2} Pa vs closed-form peak {p_peak:.2} Pa at λ {l_peak:.4}",
        points.len(),
        report.newton_iterations
    );
    // within the n = 4 discretisation error of the pressure-controlled path
    assert!(e < 1e-2, "{e}");
    assert!(
        points.iter().all(|p| p.2),
        "every state stable under volume control"
    );
    let last = points.last().unwrap();
    assert!((last.0 - 2.0).abs() < 0.02, "λ_i {}", last.0);
    // through the maximum: the pressure rose to the peak and fell past it
    assert!((top - p_peak).abs() < 1e-2 * p_peak, "{top} vs {p_peak}");
    assert!(last.1 < 0.95 * top);
    let volume =
        deasim::problem::pressure::enclosed_volume(&model.pressures[0].faces, &problem.state);
    assert!(
        (volume / (8.0 * v0) - 1.0).abs() < 1e-9,
        "{volume} vs {}",
        8.0 * v0
    );
}

#[test]
fn the_volume_controlled_balloon_example_follows_the_closed_form_through_both_extrema() {
    let dir = common::tempdir("balloon-volume");
    let out = common::deasim(&["run", "balloon-volume", "--out", "v"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("v/history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (stage, stretch, pressure_col, volume) = (
        col("stage"),
        col("probe:stretch"),
        col("probe:pressure"),
        col("probe:volume"),
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let inflate: Vec<(f64, f64, f64)> = rows
        .iter()
        .filter(|r| r[stage] == "inflate")
        .map(|r| {
            let v = |i: usize| r[i].parse::<f64>().unwrap();
            (v(stretch), v(pressure_col), v(volume))
        })
        .collect();
    assert_eq!(inflate.len(), 40, "a plain ramp: no cut-backs");
    let jm = Some(30.0);
    let (_, p_max) = extremum(jm, 5000.0, 1.0, 2.0, true);
    let (_, p_min) = extremum(jm, 5000.0, 2.0, 4.0, false);
    let mut worst = 0.0f64;
    for &(l, p, _) in &inflate {
        worst = worst.max((p - pressure(jm, l, 5000.0)).abs() / p_max);
    }
    eprintln!("balloon-volume: largest pressure error {worst:.2e} of the peak over 40 steps");
    assert!(worst < 3e-3, "{worst}");
    // the path rose past the maximum, fell to the minimum and rose again
    let falling = inflate.windows(2).filter(|w| w[1].1 < w[0].1).count();
    assert!(falling > 5 && inflate.last().unwrap().1 > p_min);
    let top = inflate.iter().map(|x| x.1).fold(0.0, f64::max);
    assert!(top > 0.99 * p_max, "{top} vs {p_max}");
    // the prescribed volume, whole balloon, at the end
    let last = inflate.last().unwrap();
    assert!((last.2 / 1.3724e-4 - 1.0).abs() < 1e-9, "{}", last.2);
}
