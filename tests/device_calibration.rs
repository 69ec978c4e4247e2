//! `deasim calibrate` on a scenario: its `[[parameters]]` fitted to probe terms with the finite
//! element run in the loop and adjoint Jacobians.

use deasim::api::{RunOptions, Simulation};

mod common;

/// The diaphragm with its dynamic stage cut to `duration` s and `extra` appended.
fn diaphragm(duration: f64, extra: &str) -> String {
    let base = deasim::io::examples::example("diaphragm").unwrap();
    let base = base.replace(
        "duration = 1.0                # s",
        &format!("duration = {duration}                # s"),
    );
    assert!(base.contains(&format!("duration = {duration} ")));
    format!("{base}\n{extra}")
}

/// The study's 2 mm static sag determines C₁₀ of the Yeoh model: the calibrated preset's
/// 17.85 kPa within 0.5 %, from the literature's 201.9 kPa.
#[test]
fn the_yeoh_c10_of_the_diaphragm_fitted_to_a_2_mm_sag() {
    let text = diaphragm(
        0.002,
        r#"
[[parameters]]
path = "materials.vhb.c10"
lower = 1e3
upper = 1e6
scale = "log"

[[objective]]
kind = "probe-final"
probe = "center_deflection"
stage = "load"
target = 2e-3
weight = 1e6
"#,
    );
    let cal = Simulation::from_toml(&text, None)
        .calibrate_device()
        .unwrap();
    assert!(cal.converged, "{}", cal.reason);
    let c10 = cal.parameters[0].fitted;
    assert!((c10 / 17.85e3 - 1.0).abs() < 5e-3, "{c10}");
    assert_eq!(cal.parameters[0].initial, 201.9e3);
    assert!(cal.rms < 1e-12, "{}", cal.rms);
    // one residual for one parameter: no intervals, said so
    assert!(cal.parameters[0].std_error.is_nan());
    assert!(cal
        .warnings
        .iter()
        .any(|w| w.contains("no residual variance")));
    // fitted.toml runs and sags by 2 mm
    let r = Simulation::from_toml(&cal.fitted, None)
        .run(RunOptions::default())
        .unwrap();
    let stage = &r.history.stage;
    let d = r.history.column("probe:center_deflection").unwrap();
    let last_load = stage.iter().rposition(|s| s == "load").unwrap();
    assert!((d[last_load] - 2e-3).abs() < 1e-9, "{}", d[last_load]);
}

/// C₁₀ and the pad's mass recovered from the pad's deflection history alone (20 ms of the
/// square wave, generated with known values): each residual's Jacobian row by its own adjoint.
#[test]
fn two_parameters_are_recovered_from_a_deflection_history() {
    let dir = tempfile::tempdir().unwrap();
    let truth = diaphragm(0.02, "");
    let r = Simulation::from_toml(&truth, None)
        .with_overrides(&[
            "materials.vhb.preset=\"vhb4910-yeoh-calibrated\"".into(),
            "solver.newton_rtol=1e-13".into(),
        ])
        .run(RunOptions::default())
        .unwrap();
    let (t, d) = (
        r.history.column("time").unwrap(),
        r.history.column("probe:center_deflection").unwrap(),
    );
    let mut csv = String::from("time,value\n");
    for (t, d) in t.iter().zip(d).filter(|(t, _)| **t >= 1.0 - 1e-12) {
        csv += &format!("{t:e},{d:e}\n");
    }
    std::fs::write(dir.path().join("pad.csv"), csv).unwrap();
    let text = diaphragm(
        0.02,
        r#"
[[parameters]]
path = "materials.vhb.c10"
lower = 1e3
upper = 1e6
scale = "log"

[[parameters]]
path = "loads.rigid.0.mass"
lower = 0.01
upper = 0.2

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "pad.csv"
weight = 1e6
"#,
    );
    let cal = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "materials.vhb.preset=\"vhb4910-yeoh-calibrated\"".into(),
            "materials.vhb.c10=20e3".into(),
            "loads.rigid.0.mass=0.05".into(),
            "solver.newton_rtol=1e-13".into(),
        ])
        .calibrate_device()
        .unwrap();
    assert!(cal.converged, "{}", cal.reason);
    let (c10, mass) = (cal.parameters[0].fitted, cal.parameters[1].fitted);
    assert!((c10 / 17.85e3 - 1.0).abs() < 1e-6, "{c10}");
    assert!((mass / 0.04622 - 1.0).abs() < 1e-6, "{mass}");
    assert_eq!(cal.parameters[1].initial, 0.05);
    assert_eq!(cal.rms_by_term.len(), 1);
    // the curve of the plots: the fitted run's deflection on the data at every step it reads
    let c = &cal.curves[0];
    assert_eq!(
        (c.term.as_str(), c.probe.as_str()),
        ("objective.0", "center_deflection")
    );
    assert_eq!(c.time.len(), 20);
    assert!(c.time.windows(2).all(|w| w[1] > w[0]), "{:?}", c.time);
    for (f, m) in c.fitted.iter().zip(&c.measured) {
        assert!((f - m).abs() < 1e-9 * m.abs().max(1e-6), "{f} against {m}");
    }
}

/// `deasim calibrate` on a scenario writes calibration.json, fitted.toml and the plots of the
/// fit: the measured (here the target) against the fitted, the residuals, the correlations.
#[test]
fn the_command_writes_the_fit_and_its_plots() {
    let dir = tempfile::tempdir().unwrap();
    let text = diaphragm(
        0.002,
        r#"
[[parameters]]
path = "materials.vhb.c10"
lower = 1e3
upper = 1e6
scale = "log"

[[objective]]
kind = "probe-final"
probe = "center_deflection"
stage = "load"
target = 2e-3
weight = 1e6
"#,
    );
    std::fs::write(dir.path().join("sag.toml"), text).unwrap();
    let o = common::deasim(
        &[
            "calibrate",
            "sag.toml",
            "--out",
            "out",
            "--set",
            "materials.vhb.c10=1e5",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the fit started where `--set` put it
    let doc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/calibration.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        doc["parameters"]["materials.vhb.c10"]["initial"], 1e5,
        "{doc}"
    );
    // three starts (the set value, then two over the log box 1 kPa … 1 MPa): the same sag fit
    let o = common::deasim(
        &["calibrate", "sag.toml", "--out", "three", "--starts", "3"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("three/calibration.json")).unwrap(),
    )
    .unwrap();
    let c10 = doc["parameters"]["materials.vhb.c10"]["fitted"]
        .as_f64()
        .unwrap();
    assert!((c10 / 17.85e3 - 1.0).abs() < 5e-3, "{c10}");
    assert!(doc["start"].as_u64().is_some_and(|s| s < 3), "{doc}");
    for f in [
        "calibration.json",
        "fitted.toml",
        "fit_objective_0.png",
        "residuals.png",
        "correlation.png",
    ] {
        let p = dir.path().join("out").join(f);
        assert!(
            p.metadata().is_ok_and(|m| m.len() > 100),
            "{} missing or empty",
            p.display()
        );
    }
}

/// Bad input names its key: no parameters, a term that is no probe term, an unknown scale, a
/// start outside its bounds.
#[test]
fn bad_device_input_names_its_key() {
    let term = "[[objective]]\nkind = \"probe-final\"\nprobe = \"center_deflection\"\n\
                stage = \"load\"\ntarget = 2e-3\n";
    let c10 = "[[parameters]]\npath = \"materials.vhb.c10\"\n";
    let cases = [
        (term.to_string(), "parameters"),
        (
            format!("{c10}[[objective]]\nkind = \"rest\"\nstage = \"actuate\"\n"),
            "objective.0.kind",
        ),
        (
            format!("{c10}scale = \"cubic\"\n{term}"),
            "parameters.0.scale",
        ),
        (format!("{c10}lower = 1e6\n{term}"), "parameters.0"),
        (
            format!("[[parameters]]\npath = \"mesh.radius\"\n{term}"),
            "parameters.0.path",
        ),
        // a probe J cannot differentiate, and a charge relative to its stage's start
        (
            format!("{c10}{}", term.replace("center_deflection", "capacitance")),
            "objective.0.probe",
        ),
        (
            format!(
                "{c10}{}relative = true\n",
                term.replace("center_deflection", "charge")
            ),
            "objective.0.relative",
        ),
    ];
    for (extra, key) in cases {
        let text = diaphragm(0.002, &extra);
        match Simulation::from_toml(&text, None).calibrate_device() {
            Err(deasim::api::Error::Input(e)) => {
                assert!(
                    e.key.as_deref().is_some_and(|k| k.starts_with(key)),
                    "{key}: {e:?}"
                )
            }
            other => panic!("{key}: {:?}", other.map(|c| c.parameters)),
        }
    }
}

/// The viscoelastic diaphragm (VHB 4910, three Maxwell branches), shortened: stretched in 0.5 s
/// and held 2 s, the mass hung over 1 s of real time in 10 steps, then 30 ms of the square wave.
fn visco_diaphragm(extra: &str) -> String {
    let base = deasim::io::examples::example("diaphragm-visco").unwrap();
    format!("{base}\n{extra}")
}

const VISCO_SETS: [&str; 9] = [
    "mesh.radial=6",
    "prestretch.steps=8",
    "prestretch.duration=0.5",
    "prestretch.hold=2.0",
    "prestretch.hold_steps=4",
    "stages.1.duration=0.03",
    "output.plots=false",
    "output.fields_every=0",
    "solver.newton_rtol=1e-13",
];

/// The first branch's modulus and relaxation time recovered from the pad's deflection alone
/// (while the mass is hung and under the first 30 ms of the square wave), generated with the
/// preset's values and started 30 % off: through the adjoint of the branches' internal
/// variables over the timed pre-stretch, the static stage in real time and the dynamic stage.
/// Without noise both to 10⁻⁶; with Gaussian noise of 2 µm on every reading (a fixed seed)
/// the true values lie within the reported 95 % intervals.
#[test]
fn branch_constants_are_recovered_from_a_viscoelastic_deflection_history() {
    branch_constants_recovered(0.0);
    branch_constants_recovered(2e-6);
}

/// A standard normal number from the state `s` (a 64-bit linear congruential generator and the
/// Box–Muller transform).
fn gaussian(s: &mut u64) -> f64 {
    let mut uniform = || {
        *s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let (u, v) = (uniform(), uniform());
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

fn branch_constants_recovered(noise: f64) {
    let dir = tempfile::tempdir().unwrap();
    let sets: Vec<String> = VISCO_SETS.iter().map(|s| s.to_string()).collect();
    let r = Simulation::from_toml(&visco_diaphragm(""), None)
        .with_overrides(&sets)
        .run(RunOptions::default())
        .unwrap();
    let (t, d, stage) = (
        r.history.column("time").unwrap(),
        r.history.column("probe:center_deflection").unwrap(),
        &r.history.stage,
    );
    // the hanging of the mass starts after the pre-stretch (0.5 + 2 s)
    let mut csv = String::from("time,value\n2.5,0\n");
    let mut seed = 17u64;
    for ((t, d), s) in t.iter().zip(d).zip(stage) {
        if *t > 2.5 + 1e-9 && (s == "load" || s == "actuate") {
            let d = d + noise * gaussian(&mut seed);
            csv += &format!("{t:e},{d:e}\n");
        }
    }
    std::fs::write(dir.path().join("pad.csv"), csv).unwrap();
    let (_, preset) = deasim::material::registry::preset("vhb4910-wang2016").unwrap();
    let (g0, tau0) = preset.branches[0];
    let text = visco_diaphragm(
        r#"
[[parameters]]
path = "materials.vhb.branches.0.mu"
lower = 1e3
upper = 1e6
scale = "log"

[[parameters]]
path = "materials.vhb.branches.0.tau"
lower = 0.01
upper = 100.0
scale = "log"

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "load"
data = "pad.csv"
weight = 1e6

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "pad.csv"
weight = 1e6
"#,
    );
    let mut start = sets.clone();
    start.push(format!("materials.vhb.branches.0.mu={:e}", 1.3 * g0));
    start.push(format!("materials.vhb.branches.0.tau={:e}", 0.7 * tau0));
    let cal = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&start)
        .calibrate_device()
        .unwrap();
    println!(
        "{} iterations, {}: g = {:e}, tau = {:e}, rms {:e}",
        cal.iterations, cal.reason, cal.parameters[0].fitted, cal.parameters[1].fitted, cal.rms
    );
    assert!(cal.converged, "{}", cal.reason);
    let (g, tau) = (cal.parameters[0].fitted, cal.parameters[1].fitted);
    assert_eq!(cal.rms_by_term.len(), 2);
    if noise == 0.0 {
        assert!((g / g0 - 1.0).abs() < 1e-6, "{g} against {g0}");
        assert!((tau / tau0 - 1.0).abs() < 1e-6, "{tau} against {tau0}");
        return;
    }
    for (p, truth) in cal.parameters.iter().zip([g0, tau0]) {
        println!(
            "{}: {:e} ± {:e}, 95 % [{:e}, {:e}], true {truth:e}",
            p.path, p.fitted, p.std_error, p.ci95[0], p.ci95[1]
        );
        assert!(
            p.ci95[0] <= truth && truth <= p.ci95[1],
            "{}: {truth:e} outside [{:e}, {:e}]",
            p.path,
            p.ci95[0],
            p.ci95[1]
        );
        assert!(p.ci95[1] > p.ci95[0]);
    }
    // the noise's RMS, about (each term's own data)
    assert!(
        cal.rms > 0.5 * noise && cal.rms < 2.0 * noise,
        "{}",
        cal.rms
    );
}

/// The diaphragm driven through a series resistance (the source's square wave reaches the
/// electrode with the time constant RC ≈ 1.3 ms): R recovered from the first 3 ms of the pad's
/// deflection alone, and of the electrode's charge alone (the natural record of such a drive),
/// started at 3 MΩ for the 10 MΩ that generated the data. The fit's Jacobian comes from the
/// adjoint of the circuit (the charge each step carries through R) and, for the charge, of
/// Gauss's law at each step.
#[test]
fn a_series_resistance_is_recovered_from_a_circuit_driven_diaphragm() {
    let dir = tempfile::tempdir().unwrap();
    let circuit = |extra: &str| {
        let text = diaphragm(0.003, extra);
        let square = "{ waveform = \"square\", amplitude = 3000.0, frequency = 2.0 }";
        common::circuit_instead_of(&text, square, square, 1e7)
    };
    let sets = [
        "stages.1.dt=1e-4".to_string(),
        "solver.newton_rtol=1e-13".to_string(),
    ];
    let r = Simulation::from_toml(&circuit(""), None)
        .with_overrides(&sets)
        .run(RunOptions::default())
        .unwrap();
    let t = r.history.column("time").unwrap();
    for (probe, weight) in [("center_deflection", 1e9), ("charge", 1e7)] {
        let values = r.history.column(&format!("probe:{probe}")).unwrap();
        let mut csv = String::from("time,value\n");
        for (t, v) in t.iter().zip(values).filter(|(t, _)| **t >= 1.0 - 1e-12) {
            csv += &format!("{t:.17e},{v:.17e}\n");
        }
        std::fs::write(dir.path().join("data.csv"), csv).unwrap();
        let text = circuit(&format!(
            r#"
[[parameters]]
path = "electrodes.top.circuit.resistance"
lower = 1e5
upper = 1e9
scale = "log"

[[objective]]
kind = "probe-misfit"
probe = "{probe}"
stage = "actuate"
data = "data.csv"
weight = {weight:e}
"#
        ));
        let mut fit_sets = sets.to_vec();
        fit_sets.push("electrodes.top.circuit.resistance=3e6".into());
        let cal = Simulation::from_toml(&text, Some(dir.path()))
            .with_overrides(&fit_sets)
            .calibrate_device()
            .unwrap();
        assert!(cal.converged, "{probe}: {}", cal.reason);
        let p = &cal.parameters[0];
        assert_eq!(p.initial, 3e6);
        assert!(
            (p.fitted / 1e7 - 1.0).abs() < 1e-6,
            "{probe}: R = {}",
            p.fitted
        );
        // the misfit at round-off of the record: the objective reads the probe as the run
        // records it
        let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            cal.rms < 1e-9 * scale,
            "{probe}: rms {} of {scale}",
            cal.rms
        );
    }
}
