//! Optimal control (`deasim control`): the optimum of the FE model against that of its
//! linearisation, the bounds and rate limits of the optimised drive, the objective of
//! `controlled.toml`, and bad input.

use deasim::api::{ControlOptions, ControlQuantity, RunOptions, Simulation};
use nalgebra::{DMatrix, DVector};
use std::process::Command;

/// The diaphragm biased at 2 kV (static), then 0.1 s of dynamics in which a control with a knot
/// every 10 ms moves the pad by `move_m` (relative misfit, raised-cosine target in 30 ms), with a
/// rate effort that keeps the problem well conditioned.
fn biased_diaphragm(move_m: f64) -> String {
    let base = deasim::io::examples::example("diaphragm").unwrap();
    let base = base
        .replace(
            "voltage = { waveform = \"square\", amplitude = 3000.0, frequency = 2.0 }",
            "voltage = 2000.0",
        )
        .replace(
            "preset = \"vhb4910-yeoh\"",
            "preset = \"vhb4910-yeoh-calibrated\"",
        );
    let stages = base.find("[[stages]]").unwrap();
    let probes = base.find("[probes.center_deflection]").unwrap();
    format!(
        "{}{}{}",
        &base[..stages],
        r#"[[stages]]
name = "load"
kind = "static"
steps = 4
electrodes_on = false

[[stages]]
name = "bias"
kind = "static"
steps = 4

[[stages]]
name = "move"
kind = "dynamic"
duration = 0.1
dt = 2e-3

"#,
        &base[probes..]
    ) + &format!(
        r#"
[[controls]]
electrode = "top"
stage = "move"
interval = 0.01
lower = 0.0
upper = 5000.0

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "move"
relative = true
target = {{ waveform = "ramp", amplitude = {move_m:e}, rise_time = 0.03, rise = "cosine" }}
weight = 1e18

[[objective]]
kind = "drive-effort"
electrode = "top"
stage = "move"
of = "rate"
weight = 0.1
"#
    )
}

/// The pad's deflection at the steps of the `move` stage, less its value at the stage's start,
/// for the knots `values`.
fn moves(text: &str, values: &[f64]) -> Vec<f64> {
    let v: Vec<String> = values.iter().map(|x| format!("{x:e}")).collect();
    let r = Simulation::from_toml(text, None)
        .with_overrides(&[
            format!("controls.0.values=[{}]", v.join(", ")),
            "solver.newton_rtol=1e-13".into(),
        ])
        .run(RunOptions::default())
        .unwrap();
    let stage = &r.history.stage;
    let d = r.history.column("probe:center_deflection").unwrap();
    let first = stage.iter().position(|s| s == "move").unwrap();
    d[first..].iter().map(|x| x - d[first - 1]).collect()
}

#[test]
fn a_small_move_about_a_bias_has_the_optimum_of_the_linearised_model() {
    let move_m = 3e-9;
    let text = biased_diaphragm(move_m);
    let n = 11;
    let v0 = vec![2000.0; n];
    // the linearised model: central differences of the steps' moves in each knot (h = 1 V:
    // exact to O(h²) = 1e-7 relative of the quadratic Maxwell force's curvature)
    let y0 = moves(&text, &v0);
    let m = y0.len();
    let mut g = DMatrix::zeros(m, n);
    for j in 0..n {
        let (mut up, mut down) = (v0.clone(), v0.clone());
        up[j] += 1.0;
        down[j] -= 1.0;
        let (a, b) = (moves(&text, &up), moves(&text, &down));
        for k in 0..m {
            g[(k, j)] = (a[k] - b[k]) / 2.0;
        }
    }
    // its optimum: (w GᵀG + wₑ R) δ = w Gᵀ (target − y₀), R the rate effort's matrix of the
    // knots (Σ (δᵢ − δᵢ₋₁)²/h, h = 10 ms; ½ wₑ δᵀRδ)
    let (w, we, h) = (1e18, 0.1, 0.01);
    let dt = 2e-3;
    let target = DVector::from_fn(m, |k, _| {
        let t = (k + 1) as f64 * dt;
        move_m * 0.5 * (1.0 - (std::f64::consts::PI * (t / 0.03).min(1.0)).cos())
    });
    let mut r = DMatrix::zeros(n, n);
    for i in 1..n {
        for (a, b, s) in [
            (i, i, 1.0),
            (i - 1, i - 1, 1.0),
            (i, i - 1, -1.0),
            (i - 1, i, -1.0),
        ] {
            r[(a, b)] += 2.0 * s / h;
        }
    }
    let b = &target - DVector::from_vec(y0.clone());
    let lhs = g.transpose() * &g * w + &r * (0.5 * we);
    let delta = lhs.lu().solve(&(g.transpose() * &b * w)).unwrap();
    let residual = &g * &delta - &b;
    let j_lin =
        0.5 * w * residual.norm_squared() + 0.5 * we * (delta.transpose() * &r * &delta)[0] * 0.5;
    // the FE optimum
    let sim =
        Simulation::from_toml(&text, None).with_overrides(&["solver.newton_rtol=1e-13".into()]);
    let o = sim
        .control(
            &ControlOptions {
                gradient_tolerance: 1e-10,
                objective_tolerance: 0.0,
                max_iterations: 300,
                ..Default::default()
            },
            |_| {},
        )
        .unwrap();
    let fe: Vec<f64> = o.drives[0].values.iter().map(|v| v - 2000.0).collect();
    let scale = delta.amax();
    let worst = fe
        .iter()
        .zip(delta.iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f64, f64::max);
    assert!(
        worst <= 1e-3 * scale,
        "drive: FE {fe:?} vs linearised {:?} ({worst:e} V of {scale:e} V); {} after {} iterations",
        delta.as_slice(),
        o.reason,
        o.history.len() - 1
    );
    assert!(
        (o.objective - j_lin).abs() <= 1e-3 * j_lin,
        "objective: FE {:e} vs linearised {j_lin:e}",
        o.objective
    );
}

fn deasim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(args)
        .output()
        .unwrap()
}

/// (time, value) columns of a CSV file.
fn columns(path: &std::path::Path, names: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .unwrap_or_else(|| panic!("{n}"))
        })
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|c| c.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    idx.iter()
        .map(|&i| rows.iter().map(|r| r[i]).collect())
        .collect()
}

/// Peak-to-peak of the pad's deflection after the 30 ms move of the `actuate` stage (m).
fn ringing(history: &std::path::Path) -> f64 {
    let c = columns(history, &["time", "probe:center_deflection"]);
    let start = c[0].iter().position(|t| *t >= 1.0).unwrap();
    let after: Vec<f64> = (start..c[0].len())
        .filter(|&i| c[0][i] >= 1.03 - 1e-9)
        .map(|i| c[1][i])
        .collect();
    after.iter().cloned().fold(f64::MIN, f64::max) - after.iter().cloned().fold(f64::MAX, f64::min)
}

fn objective_of(path: &std::path::Path, key: &str) -> f64 {
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    doc[key].as_f64().unwrap()
}

#[test]
fn the_optimised_move_does_not_ring_and_its_scenario_repeats_its_objective() {
    let dir = tempfile::tempdir().unwrap();
    let (step, opt, again) = (
        dir.path().join("step"),
        dir.path().join("opt"),
        dir.path().join("again"),
    );
    let quiet = [
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=0",
    ];
    let run = |args: &[&str]| {
        let mut all: Vec<&str> = args.to_vec();
        all.extend_from_slice(&quiet);
        let o = deasim(&all);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o
    };
    run(&["run", "diaphragm-control", "--out", step.to_str().unwrap()]);
    run(&[
        "control",
        "diaphragm-control",
        "--out",
        opt.to_str().unwrap(),
    ]);
    let (r_step, r_opt) = (
        ringing(&step.join("history.csv")),
        ringing(&opt.join("history.csv")),
    );
    assert!(
        r_opt < 0.01 * r_step,
        "ringing after the move: optimised {r_opt:e} m, step {r_step:e} m"
    );
    // the pad is where it should be: 20 µm below its start
    let c = columns(
        &opt.join("history.csv"),
        &["time", "probe:center_deflection"],
    );
    let start = c[0].iter().position(|t| *t >= 1.0).unwrap();
    let moved = c[1][c[1].len() - 1] - c[1][start];
    assert!((moved - 20e-6).abs() < 0.1e-6, "moved {moved:e} m");
    // controlled.toml repeats the optimised run and its objective
    let controlled = opt.join("controlled.toml");
    let o = run(&[
        "run",
        controlled.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("objective J = "), "{stdout}");
    let (reported, repeated) = (
        objective_of(&opt.join("control.json"), "final_objective"),
        objective_of(&again.join("summary.json"), "objective"),
    );
    assert!(
        (reported - repeated).abs() <= 1e-10 * reported.abs(),
        "{reported:e} vs {repeated:e}"
    );
    // the drive of control.csv is the table of controlled.toml
    let drive = columns(&opt.join("control.csv"), &["time", "voltage:top"]);
    assert_eq!(drive[0].len(), 301);
    assert!(drive[1].iter().all(|v| (0.0..=5000.0).contains(v)));
}

#[test]
fn every_bound_and_rate_limit_holds_at_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let (upper, rate) = (3400.0, 1.5e5);
    let o = deasim(&[
        "control",
        "diaphragm-control",
        "--out",
        out.to_str().unwrap(),
        "--max-iterations",
        "12",
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=0",
        "--set",
        &format!("controls.0.upper={upper}"),
        "--set",
        &format!("controls.0.max_rate={rate}"),
        "--set",
        "controls.0.lower=3000",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let drive = columns(&out.join("control.csv"), &["time", "voltage:top"]);
    let (t, v) = (&drive[0], &drive[1]);
    // the bounds bind: the unconstrained drive reaches 5 kV at the start
    assert!(v.contains(&upper), "{v:?}");
    for (i, x) in v.iter().enumerate() {
        assert!((3000.0..=upper).contains(x), "knot {i}: {x} V");
        if i > 0 {
            let r = (x - v[i - 1]).abs() / (t[i] - t[i - 1]);
            assert!(r <= rate * (1.0 + 1e-9), "knots {} to {i}: {r} V/s", i - 1);
        }
    }
    // and so do the voltages the run applied at its steps
    let h = columns(&out.join("history.csv"), &["time", "voltage"]);
    let mut worst_rate = 0.0f64;
    for i in 1..h[0].len() {
        if h[0][i] > 1.0 + 1e-9 {
            assert!(
                (3000.0 - 1e-9..=upper + 1e-9).contains(&h[1][i]),
                "step {i}: {} V",
                h[1][i]
            );
            // (the stage's first step jumps from the electrodes off of `load` to the first knot)
            if h[0][i - 1] > 1.0 + 1e-9 {
                worst_rate =
                    worst_rate.max((h[1][i] - h[1][i - 1]).abs() / (h[0][i] - h[0][i - 1]));
            }
        }
    }
    assert!(worst_rate <= rate * (1.0 + 1e-9), "{worst_rate} V/s");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("control.json")).unwrap()).unwrap();
    assert_eq!(doc["objective"].as_array().unwrap().len(), 13);
    let j: Vec<f64> = doc["objective"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(j.windows(2).all(|w| w[1] < w[0]), "{j:?}");
}

#[test]
fn bad_control_input_exits_2_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let cases: &[(&[&str], &str)] = &[
        (&["--set", "controls.0.upper=3000"], "controls.0.upper"),
        (&["--set", "controls.0.lower=3500"], "controls.0.lower"),
        (
            &["--set", "objective.0.probe=\"nowhere\""],
            "objective.0.probe",
        ),
        (&["--set", "controls.0.stage=\"load\""], "controls.0.stage"),
        (&["--gradient-tolerance=-1"], "tolerance"),
    ];
    for (extra, expect) in cases {
        let mut args = vec![
            "control",
            "diaphragm-control",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = deasim(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(expect), "{extra:?}: {err}");
    }
    // a scenario without controls
    let o = deasim(&["control", "diaphragm", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("[[controls]]"));
}

/// A field-penalty term keeps the optimised drive's field near its limit: the biased diaphragm
/// asked to move its pad by 8 µm in 30 ms reaches a largest true field E₀ without the term; with
/// `limit` = 0.9 E₀ (weight 10³) the optimum trades the misfit against the excess, and its
/// largest field comes within a fifth of the excess of the limit.
#[test]
fn a_field_penalty_keeps_the_drive_near_its_limit() {
    let text = biased_diaphragm(8e-6);
    let options = ControlOptions {
        max_iterations: 60,
        ..Default::default()
    };
    let largest = |o: &deasim::api::OptimalControl| -> f64 {
        let h = &o.results.history;
        let field = h.column("max_electric_field").unwrap();
        h.stage
            .iter()
            .zip(field)
            .filter(|(s, _)| *s == "move")
            .map(|(_, &e)| e)
            .fold(0.0, f64::max)
    };
    let free = Simulation::from_toml(&text, None)
        .control(&options, |_| {})
        .unwrap();
    let e0 = largest(&free);
    let limit = 0.9 * e0;
    let penalised = format!(
        "{text}\n[[objective]]\nkind = \"field-penalty\"\nstage = \"move\"\nlimit = {limit:e}\nweight = 1e3\n"
    );
    let held = Simulation::from_toml(&penalised, None)
        .control(&options, |_| {})
        .unwrap();
    let e1 = largest(&held);
    println!(
        "largest field {e0:.4e} V/m without the penalty ({} its, J {:.3e}); {e1:.4e} V/m with \
         limit {limit:.4e} ({} its, J {:.3e})",
        free.history.len() - 1,
        free.objective,
        held.history.len() - 1,
        held.objective
    );
    assert!(
        e1 < limit + 0.2 * (e0 - limit),
        "{e1:e} against {e0:e}, limit {limit:e}"
    );
}

/// The film of `film-vibration` (a quarter, 10 × 10 × 1 mm, on 2 × 2 × 1 cells, Kelvin–Voigt
/// η = 50 Pa·s) with its top electrode driven by `top` (a TOML line) through a control with
/// knots every 0.5 ms between 0 and `upper`, optimised so that the film reaches a thickness
/// stretch of 0.95 at 4 ms and is at rest there. Asserts that the optimum meets both within
/// its bounds, and that its `controlled.toml`, run as it is, repeats its objective; returns it.
fn film_moved_and_held(top: &str, upper: f64) -> deasim::api::OptimalControl {
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let step = "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    assert!(base.contains(step));
    let base = base.replace(step, top);
    let text = format!(
        r#"{base}

[[controls]]
electrode = "top"
interval = 5e-4
lower = 0.0
upper = {upper:e}

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.95
weight = 1e4

[[objective]]
kind = "rest"
weight = 1e3
"#
    );
    let overrides: Vec<String> = vec![
        "mesh.divisions=[2, 2, 1]".into(),
        "stages.0.duration=4e-3".into(),
        "stages.0.dt=1e-4".into(),
        "materials.elastomer.viscosity=50.0".into(),
        "output.fields_every=0".into(),
        "output.plots=false".into(),
    ];
    let o = Simulation::from_toml(&text, None)
        .with_overrides(&overrides)
        .control(
            &ControlOptions {
                max_iterations: 200,
                ..Default::default()
            },
            |_| {},
        )
        .unwrap();
    let first = o.history[0].objective;
    let h = &o.results.history;
    let stretch = *h.column("probe:thickness_stretch").unwrap().last().unwrap();
    println!(
        "J {first:.4e} → {:.4e} in {} iterations ({}); thickness stretch {stretch:.6}; drive \
         {:?}",
        o.objective,
        o.history.len() - 1,
        o.reason,
        o.drives[0].values
    );
    assert!(o.objective < 1e-6 * first, "{} vs {first}", o.objective);
    assert!((stretch - 0.95).abs() < 1e-5, "{stretch}");
    assert!(o.drives[0].values.iter().all(|v| (0.0..=upper).contains(v)));
    // the scenario with the optimised drive, run as it is, repeats J
    let again = Simulation::from_toml(&o.controlled, None);
    let mut tape = again.objective_tape().unwrap().unwrap();
    again
        .run(RunOptions {
            observers: vec![tape.observer()],
            ..Default::default()
        })
        .unwrap();
    let repeated = tape.value().unwrap();
    assert!(
        (repeated - o.objective).abs() <= 1e-10 * o.objective,
        "{repeated} vs {}",
        o.objective
    );
    o
}

/// The optimal drive of a circuit's source: the film charged through R = 10⁸ Ω (RC ≈ 1.7 ms),
/// the source's table (0–30 kV) starting at 5 kV.
#[test]
fn an_optimal_drive_through_a_circuit() {
    let o = film_moved_and_held("circuit = { source = 5e3, resistance = 1e8 }", 30e3);
    assert_eq!(o.drives[0].quantity, ControlQuantity::Voltage);
}

/// The optimal drive of an electrode's charge (the controls of Huang & Leyendecker, Soft
/// Robotics 2023): the film under charge control from a constant 20 nC, bounded by 0 and
/// 200 nC.
#[test]
fn an_optimal_charge_drive() {
    let o = film_moved_and_held("charge = 2e-8", 2e-7);
    assert_eq!(o.drives[0].quantity, ControlQuantity::Charge);
}
