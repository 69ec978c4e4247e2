//! Circuit-driven electrodes (`circuit = { source, resistance }`): a very stiff film (μ = 10⁹ Pa,
//! so its capacitance C = εA/H stays constant) charged through R = 1 GΩ, RC = 4.16 ms, on one
//! cell.
//!
//! - A 100 V step source: the electrode's voltage follows V_s(1 − e^{−t/RC}) to 1e-6 of V_s at
//!   every step, with the midpoint and the Newmark integrator. The source energy
//!   C V_s²(1 − e^{−t/RC}) and the resistor loss ½C V_s²(1 − e^{−2t/RC}) hold to 1e-6, and their
//!   difference is the electric energy stored (the balance); `energy_error` stays at round-off.
//! - A unipolar square source: the steady peak-to-peak voltage is V_s tanh(1/(4fRC)), which rolls
//!   off past the corner 1/(2πRC) (0.1, 1 and 10 times it, to 2e-3).
//! - A static stage holds the electrode at its source's voltage (no current: the DC limit).
//! - Refusals: a circuit with a voltage, a resistance ≤ 0, the explicit integrator, energy
//!   probes of an electrode without a circuit.

mod common;

use common::{deasim, tempdir};

const R: f64 = 1e9;
const VS: f64 = 100.0;

fn rc() -> f64 {
    let c = 4.7 * 8.854_187_812_8e-12 * 1e-4 / 1e-3;
    R * c
}

/// The `film-vibration` example made stiff, on one cell, its top electrode driven by `source`
/// through R, with `stage` lines replacing the example's duration, step and integrator.
fn scenario(dir: &std::path::Path, source: &str, stage: &str) {
    let text =
        String::from_utf8_lossy(&deasim(&["example", "film-vibration"], dir).stdout).into_owned();
    let mut out = Vec::new();
    for l in text.lines() {
        let line = if l.starts_with("mu = ") {
            "mu = 1e9".to_string()
        } else if l.starts_with("lambda = ") {
            "lambda = 4e9".to_string()
        } else if l.starts_with("voltage = { waveform = \"step\"") {
            format!("circuit = {{ source = {source}, resistance = {R} }}")
        } else if l.starts_with("divisions = ") {
            "divisions = [1, 1, 1]".to_string()
        } else if l.starts_with("duration = ") || l.starts_with("dt = ") {
            continue;
        } else if l.starts_with("integrator = ") {
            stage.to_string()
        } else if l.starts_with("fields_every = ") {
            "fields_every = 0".to_string()
        } else if l.starts_with("plots = ") {
            "plots = false".to_string()
        } else {
            l.to_string()
        };
        out.push(line);
    }
    out.push(
        "[probes.source]\nkind = \"source_energy\"\nelectrode = \"top\"\n\n\
         [probes.loss]\nkind = \"resistor_loss\"\nelectrode = \"top\""
            .into(),
    );
    std::fs::write(dir.join("rc.toml"), out.join("\n")).unwrap();
}

/// Runs `rc.toml`; the history's columns by name.
fn run(dir: &std::path::Path) -> std::collections::HashMap<String, Vec<f64>> {
    let o = deasim(&["run", "rc.toml", "--out", "o", "--overwrite"], dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: std::collections::HashMap<String, Vec<f64>> =
        header.iter().map(|h| (h.clone(), Vec::new())).collect();
    for l in lines {
        for (h, v) in header.iter().zip(l.split(',')) {
            cols.get_mut(h).unwrap().push(v.parse().unwrap_or(f64::NAN));
        }
    }
    // and the per-electrode columns of electrodes.csv (one row per record, too)
    let text = std::fs::read_to_string(dir.join("o/electrodes.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    for h in header.iter().skip(3) {
        cols.insert(h.clone(), Vec::new());
    }
    for l in lines {
        for (h, v) in header.iter().zip(l.split(',')).skip(3) {
            cols.get_mut(h).unwrap().push(v.parse().unwrap_or(f64::NAN));
        }
    }
    cols
}

#[test]
fn a_step_source_charges_the_film_exponentially_with_both_integrators() {
    let dir = tempdir("circuit-step");
    let tau = rc();
    let c = tau / R;
    for integrator in ["midpoint", "newmark"] {
        scenario(
            &dir,
            &format!("{VS}"),
            &format!(
                "integrator = \"{integrator}\"\nduration = {}\ndt = {}",
                5.0 * tau,
                tau / 500.0
            ),
        );
        let h = run(&dir);
        let (t, v) = (&h["time"], &h["voltage"]);
        let worst = t
            .iter()
            .zip(v)
            .map(|(t, v)| (v - VS * (1.0 - (-t / tau).exp())).abs() / VS)
            .fold(0.0, f64::max);
        let n = t.len() - 1;
        let (ws, wl) = (h["probe:source"][n], h["probe:loss"][n]);
        let ws_exact = c * VS * VS * (1.0 - (-t[n] / tau).exp());
        let wl_exact = 0.5 * c * VS * VS * (1.0 - (-2.0 * t[n] / tau).exp());
        let electric = h["electric"][n];
        eprintln!(
            "{integrator}: {} steps, largest |V − V_s(1 − e^(−t/RC))| = {worst:.2e} V_s; source \
             {ws:.6e} J ({ws_exact:.6e}), loss {wl:.6e} J ({wl_exact:.6e}), stored electric \
             {electric:.6e} J, energy_error {:.1e} J",
            n, h["energy_error"][n]
        );
        assert!(t[n] > 4.99 * tau);
        assert!(worst < 1e-6, "{integrator}: {worst}");
        assert!(
            (ws - ws_exact).abs() < 1e-6 * ws_exact,
            "{ws} vs {ws_exact}"
        );
        assert!(
            (wl - wl_exact).abs() < 1e-6 * wl_exact,
            "{wl} vs {wl_exact}"
        );
        // the source's energy is the resistor's loss plus the energy stored in the capacitor
        assert!(
            (ws - wl - electric).abs() < 1e-6 * ws,
            "{ws} − {wl} vs {electric}"
        );
        assert!(h["energy_error"][n].abs() < 1e-9 * ws);
        // electrodes.csv: the same voltage, Q = CV on the stiff film, the current its backward
        // difference, the circuit's energies those of the probes; the grounded electrode holds
        // the opposite charge
        assert_eq!(h["voltage:top"], h["voltage"]);
        assert_eq!(h["source_energy:top"], h["probe:source"]);
        assert_eq!(h["resistor_loss:top"], h["probe:loss"]);
        for k in 1..=n {
            let (q, v) = (h["charge:top"][k], h["voltage:top"][k]);
            assert!((q - c * v).abs() < 1e-6 * c * VS, "{k}: {q} vs {}", c * v);
            assert!((h["charge:bottom"][k] + q).abs() < 1e-9 * c * VS);
            assert_eq!(h["voltage:bottom"][k], 0.0);
            let dq = q - h["charge:top"][k - 1];
            let i = h["current:top"][k];
            assert!(
                (i - dq / h["dt"][k]).abs() < 1e-9 * (c * VS / tau),
                "{k}: {i}"
            );
            assert!((h["power:top"][k] - v * i).abs() < 1e-12 * (VS * c * VS / tau));
        }
    }
}

#[test]
fn a_square_source_rolls_off_past_the_corner_frequency() {
    let dir = tempdir("circuit-square");
    let tau = rc();
    let corner = 1.0 / (2.0 * std::f64::consts::PI * tau);
    for ratio in [0.1, 1.0, 10.0] {
        let f = ratio * corner;
        let period = 1.0 / f;
        let periods = (10.0 * tau / period).ceil().max(2.0) + 1.0;
        scenario(
            &dir,
            &format!("{{ waveform = \"square\", amplitude = {VS}, frequency = {f} }}"),
            &format!(
                "integrator = \"midpoint\"\nduration = {}\ndt = {}",
                periods * period,
                period / 200.0
            ),
        );
        let h = run(&dir);
        let (t, v) = (&h["time"], &h["voltage"]);
        let t_end = t[t.len() - 1];
        let last: Vec<f64> = t
            .iter()
            .zip(v)
            .filter(|(t, _)| **t >= t_end - period * (1.0 + 1e-9))
            .map(|(_, v)| *v)
            .collect();
        let pp = last.iter().cloned().fold(f64::MIN, f64::max)
            - last.iter().cloned().fold(f64::MAX, f64::min);
        let expected = VS * (1.0 / (4.0 * f * tau)).tanh();
        eprintln!(
            "f = {ratio} × corner: peak-to-peak {pp:.4} V, V_s tanh(1/(4fRC)) = {expected:.4} V"
        );
        assert!(
            (pp - expected).abs() < 2e-3 * VS,
            "{ratio}: {pp} vs {expected}"
        );
    }
}

#[test]
fn a_static_stage_holds_the_electrode_at_its_source_voltage() {
    let dir = tempdir("circuit-static");
    scenario(
        &dir,
        "250.0",
        "integrator = \"midpoint\"\nduration = 1e-3\ndt = 1e-4",
    );
    let text = std::fs::read_to_string(dir.join("rc.toml")).unwrap();
    let text = text.replace(
        "[[stages]]",
        "[[stages]]\nname = \"hold\"\nkind = \"static\"\nsteps = 2\n\n[[stages]]",
    );
    std::fs::write(dir.join("rc.toml"), text).unwrap();
    let h = run(&dir);
    // after the static stage the electrode is charged: no current flows in the dynamic one
    let v = &h["voltage"];
    assert!(
        v.iter().skip(2).all(|v| (v - 250.0).abs() < 1e-9 * 250.0),
        "{v:?}"
    );
    assert!(
        h["probe:loss"].iter().all(|l| l.abs() < 1e-20),
        "{:?}",
        h["probe:loss"]
    );
}

#[test]
fn bad_circuits_are_refused() {
    let dir = tempdir("circuit-bad");
    let cases = [
        (
            "{ source = 1.0, resistance = 1e9 }\nvoltage = 3.0",
            "integrator = \"midpoint\"\nduration = 1e-3\ndt = 1e-4",
            "one of the three",
        ),
        (
            "{ source = 1.0, resistance = -1 }",
            "integrator = \"midpoint\"\nduration = 1e-3\ndt = 1e-4",
            "electrodes.top.circuit.resistance",
        ),
        (
            "{ source = 1.0, resistance = 1e9 }",
            "integrator = \"trapezoidal\"\nduration = 1e-3\ndt = 1e-4",
            "need the `midpoint` or `newmark` integrator",
        ),
    ];
    for (circuit, stage, expect) in cases {
        scenario(&dir, "0.0", stage);
        let text = std::fs::read_to_string(dir.join("rc.toml"))
            .unwrap()
            .replace(
                &format!("circuit = {{ source = 0.0, resistance = {R} }}"),
                &format!("circuit = {circuit}"),
            );
        std::fs::write(dir.join("rc.toml"), text).unwrap();
        let o = deasim(&["check", "rc.toml", "--no-trial"], &dir);
        let msg =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{circuit}: {msg}");
        assert!(msg.contains(expect), "{circuit}: {msg}");
    }
    // energy probes need a circuit
    scenario(
        &dir,
        "1.0",
        "integrator = \"midpoint\"\nduration = 1e-3\ndt = 1e-4",
    );
    let text = std::fs::read_to_string(dir.join("rc.toml"))
        .unwrap()
        .replace(
            "kind = \"source_energy\"\nelectrode = \"top\"",
            "kind = \"source_energy\"\nelectrode = \"bottom\"",
        );
    std::fs::write(dir.join("rc.toml"), text).unwrap();
    let o = deasim(&["check", "rc.toml", "--no-trial"], &dir);
    let msg = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("`bottom` is not driven through a circuit"),
        "{msg}"
    );
}
