//! Creep of a VHB 4910 film under a held voltage (the `vhb4910-wang2016` preset: Arruda–Boyce
//! equilibrium branch and three Maxwell branches), through the command line. Static stages run
//! in real time for materials with internal variables: a stage ramps its targets over its
//! `duration` (s) and the branches relax meanwhile; a stage that keeps the targets is a hold.
//!
//! References: the relaxed response is the equilibrium material alone (the same scenario without
//! branches), reached after a hold much longer than the longest relaxation time (tolerance 1e-4,
//! the remaining relaxation e^(−hold/τ₃) plus the solver tolerance); a voltage between the
//! relaxed and the instantaneous pull-in limits (about 13 kV and 30 kV for this 1 mm film, from
//! the Zhao–Suo limit with the relaxed and the instantaneous shear modulus) is held first and
//! creeps into pull-in after a delay: the run ends with exit 1, pull-in, in the hold stage.

mod common;
use common::{deasim, tempdir};

fn scenario(voltage: f64, hold: f64, branches: bool) -> String {
    let material = if branches {
        "preset = \"vhb4910-wang2016\""
    } else {
        "preset = \"vhb4910-ab-wang\""
    };
    format!(
        r#"name = "creep"
[mesh]
generator = "box"
size = [1e-3, 1e-3, 1e-3]
divisions = [1, 1, 1]
element = "hex8"
[materials.vhb]
{material}
[[constraints]]
set = "x0"
fix = ["x"]
[[constraints]]
set = "y0"
fix = ["y"]
[[constraints]]
set = "z0"
fix = ["z"]
[electrodes.bottom]
set = "z0"
voltage = 0.0
[electrodes.top]
set = "z1"
voltage = {voltage}
[[stages]]
name = "ramp"
kind = "static"
steps = 10
duration = 1.0
[[stages]]
name = "hold"
kind = "static"
steps = 100
duration = {hold}
[probes.thickness_stretch]
kind = "mean"
quantity = "uz"
set = "z1"
scale = 1000.0
offset = 1.0
[output]
fields_every = 0
plots = false
"#
    )
}

/// The `thickness_stretch` column of a run's history.
fn thickness(dir: &std::path::Path) -> Vec<(String, f64)> {
    let h = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let mut lines = h.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let c = head
        .iter()
        .position(|n| *n == "probe:thickness_stretch")
        .unwrap();
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            (v[1].to_string(), v[c].parse().unwrap())
        })
        .collect()
}

#[test]
fn held_voltage_creeps_to_the_relaxed_state() {
    let dir = tempdir("creep-relaxed");
    std::fs::write(dir.join("visco.toml"), scenario(10e3, 2000.0, true)).unwrap();
    std::fs::write(dir.join("elastic.toml"), scenario(10e3, 2000.0, false)).unwrap();
    for (f, out) in [("visco.toml", "visco"), ("elastic.toml", "elastic")] {
        let o = deasim(&["run", f, "--out", out], &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let v = thickness(&dir.join("visco"));
    let e = thickness(&dir.join("elastic"));
    let hold: Vec<f64> = v.iter().filter(|r| r.0 == "hold").map(|r| r.1).collect();
    // the film thins while the voltage is held (creep), monotonically
    assert!(hold.windows(2).all(|w| w[1] <= w[0] + 1e-12), "{hold:?}");
    let ramp_end = v.iter().rfind(|r| r.0 == "ramp").unwrap().1;
    assert!(
        hold.last().unwrap() < &(ramp_end - 1e-3),
        "{ramp_end} {hold:?}"
    );
    let relaxed = e.last().unwrap().1;
    let last = *hold.last().unwrap();
    eprintln!("thickness stretch: {ramp_end:.6} after the ramp, {last:.6} after 2000 s, relaxed {relaxed:.6}");
    assert!((last - relaxed).abs() < 1e-4, "{last} vs {relaxed}");
}

#[test]
fn voltage_between_the_limits_creeps_into_pull_in() {
    let dir = tempdir("creep-pullin");
    std::fs::write(dir.join("s.toml"), scenario(20e3, 200.0, true)).unwrap();
    let o = deasim(&["run", "s.toml", "--out", "out"], &dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("pull-in") && err.contains("`hold`"), "{err}");
    let v = thickness(&dir.join("out"));
    let hold: Vec<f64> = v.iter().filter(|r| r.0 == "hold").map(|r| r.1).collect();
    assert!(hold.len() > 2, "the ramp itself must pass: {v:?}");
    eprintln!(
        "{} hold steps before pull-in; last {:.4}",
        hold.len(),
        hold.last().unwrap()
    );
    // the same voltage on the relaxed (equilibrium) material alone fails in the ramp already
    std::fs::write(dir.join("e.toml"), scenario(20e3, 200.0, false)).unwrap();
    let o = deasim(&["run", "e.toml", "--out", "eq"], &dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("pull-in") && err.contains("`ramp`"), "{err}");
}

/// A quasi-static stage: the electrodes follow their waveform in real time (a unipolar sine,
/// up and down again), no inertia; for an elastic film every recorded step is the homogeneous
/// closed-form state at the recorded voltage (to 1e-9).
#[test]
fn quasi_static_stage_follows_the_waveform() {
    let dir = tempdir("quasi-static");
    let text = r#"name = "qs"
[mesh]
generator = "box"
size = [1e-3, 1e-3, 1e-3]
divisions = [1, 1, 1]
element = "hex8"
[materials.film]
model = "neo-hooke"
mu = 1e5
lambda = 1e7
permittivity = 4.7
[[constraints]]
set = "x0"
fix = ["x"]
[[constraints]]
set = "y0"
fix = ["y"]
[[constraints]]
set = "z0"
fix = ["z"]
[electrodes.bottom]
set = "z0"
voltage = 0.0
[electrodes.top]
set = "z1"
voltage = { waveform = "sine", amplitude = 25e3, frequency = 1.0 }
[[stages]]
name = "cycle"
kind = "quasi-static"
duration = 1.0
dt = 0.05
[probes.thickness_stretch]
kind = "mean"
quantity = "uz"
set = "z1"
scale = 1000.0
offset = 1.0
[output]
fields_every = 0
plots = false
"#;
    std::fs::write(dir.join("qs.toml"), text).unwrap();
    let o = deasim(&["run", "qs.toml", "--out", "out"], &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let h = std::fs::read_to_string(dir.join("out/history.csv")).unwrap();
    let mut lines = h.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let (cv, ct, cs) = (col("voltage"), col("probe:thickness_stretch"), col("stage"));
    let film = deasim::analytic::Film {
        mu: 1e5,
        lambda: 1e7,
        eps: 4.7 * deasim::material::EPSILON_0,
        c2: 0.0,
    };
    let mut volts = Vec::new();
    for l in lines {
        let v: Vec<&str> = l.split(',').collect();
        if v[cs] != "cycle" {
            continue;
        }
        let volt: f64 = v[cv].parse().unwrap();
        let t: f64 = v[ct].parse().unwrap();
        let expect = film.state(volt / 1e-3).unwrap().t;
        assert!((t - expect).abs() < 1e-9, "V = {volt}: {t} vs {expect}");
        volts.push(volt);
    }
    assert_eq!(volts.len(), 21, "{volts:?}");
    let peak = volts.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 0.99 * 25e3, "{volts:?}");
    assert!(volts.last().unwrap().abs() < 1e-6 * 25e3, "{volts:?}");
}
