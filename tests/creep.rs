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
/// closed-form state at the recorded voltage (to 1e-9). `periods.csv` holds the period's
/// minimum, maximum and trapezoidal mean of the probe.
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
    let (mut volts, mut thickness) = (Vec::new(), Vec::new());
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
        thickness.push(t);
    }
    assert_eq!(volts.len(), 21, "{volts:?}");
    let peak = volts.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 0.99 * 25e3, "{volts:?}");
    assert!(volts.last().unwrap().abs() < 1e-6 * 25e3, "{volts:?}");
    // periods.csv: the one full period of the 1 Hz drive, its statistics from the recorded steps
    let p = std::fs::read_to_string(dir.join("out/periods.csv")).unwrap();
    let mut lines = p.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 1, "{p}");
    let get = |n: &str| -> f64 {
        rows[0][head.iter().position(|h| *h == n).unwrap()]
            .parse()
            .unwrap()
    };
    assert_eq!(rows[0][0], "cycle");
    assert_eq!((get("t_start"), get("t_end")), (0.0, 1.0));
    let thinnest = film.state(peak / 1e-3).unwrap().t;
    let (lo, hi) = (get("thickness_stretch:min"), get("thickness_stretch:max"));
    assert!(
        (lo - thinnest).abs() < 1e-9 && (hi - 1.0).abs() < 1e-9,
        "{lo} {hi}"
    );
    assert!((get("thickness_stretch:peak_to_peak") - (hi - lo)).abs() < 1e-15);
    // trapezoidal mean over the 20 equal steps
    let n = thickness.len();
    let trapezoid =
        (thickness.iter().sum::<f64>() - 0.5 * (thickness[0] + thickness[n - 1])) / (n - 1) as f64;
    let mean = get("thickness_stretch:mean");
    assert!((mean - trapezoid).abs() < 1e-12, "{mean} vs {trapezoid}");
}

/// A film under a slow voltage ramp (to 10 kV in 1 s, held 2 s): in a quasi-static stage and in
/// a dynamic (midpoint) stage with the film's mass. The film's lowest mode is ≈ 2 kHz, so
/// inertia is negligible at this rate and both must follow the same creep history; the
/// difference is the step's evaluation point (midpoint vs end point, first order in Δt) and the
/// tiny ringing the ramp's corners excite. The branches must evolve in the dynamic stage: it
/// creeps during the hold like the quasi-static one (by ≈ 8·10⁻³ in the thickness stretch). The
/// integrator's energy balance with the branches' stored and dissipated energy closes to the
/// update's first order: its error falls by about half with Δt (measured 7.1e-3 and 3.5e-3 of the
/// dissipated energy at Δt = 0.01 and 0.005 s; the two stages agree to 3e-6).
#[test]
fn dynamic_stage_evolves_the_branches() {
    let dir = tempdir("creep-dynamic");
    let stage = |kind: &str, dt: f64| {
        format!(
            r#"name = "dyn"
[mesh]
generator = "box"
size = [1e-3, 1e-3, 1e-3]
divisions = [1, 1, 1]
element = "hex8"
[materials.vhb]
preset = "vhb4910-wang2016"
density = 960.0
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
voltage = {{ waveform = "ramp", amplitude = 10e3, rise_time = 1.0 }}
[[stages]]
name = "drive"
kind = "{kind}"
duration = 3.0
dt = {dt}
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
    };
    let run = |name: &str, kind: &str, dt: f64| {
        std::fs::write(dir.join(format!("{name}.toml")), stage(kind, dt)).unwrap();
        let o = deasim(&["run", &format!("{name}.toml"), "--out", name], &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let h = std::fs::read_to_string(dir.join(name).join("history.csv")).unwrap();
        let mut lines = h.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
        let cols = [
            col("time"),
            col("probe:thickness_stretch"),
            col("energy_error"),
            col("dissipated"),
        ];
        lines
            .map(|l| {
                let v: Vec<f64> = l
                    .split(',')
                    .map(|x| x.parse().unwrap_or(f64::NAN))
                    .collect();
                cols.map(|c| v[c])
            })
            .collect::<Vec<[f64; 4]>>()
    };
    let qs = run("qs", "quasi-static", 0.01);
    let dy = run("dy", "dynamic", 0.01);
    let dy2 = run("dy2", "dynamic", 0.005);
    let at = |h: &[[f64; 4]], t: f64| h.iter().find(|r| (r[0] - t).abs() < 1e-9).unwrap()[1];
    for t in [0.5, 1.0, 2.0, 3.0] {
        let (a, b) = (at(&qs, t), at(&dy, t));
        eprintln!("t = {t}: quasi-static {a:.7}, dynamic {b:.7}");
        assert!((a - b).abs() < 1e-5, "t = {t}: {a} vs {b}");
    }
    let creep = at(&dy, 1.0) - at(&dy, 3.0);
    assert!(
        creep > 5e-3,
        "the dynamic film must creep while held: {creep}"
    );
    let worst = |h: &[[f64; 4]]| h.iter().map(|r| r[2].abs()).fold(0.0, f64::max);
    let dissipated = dy.last().unwrap()[3];
    let (e1, e2) = (worst(&dy) / dissipated, worst(&dy2) / dissipated);
    eprintln!("energy error / dissipated: {e1:.3e} (dt = 0.01 s), {e2:.3e} (dt = 0.005 s)");
    assert!(dissipated > 0.0);
    assert!(e1 < 0.05 && e2 < 0.6 * e1, "{e1} {e2}");
}

/// A timed pre-stretch: the diaphragm's rim stretched to λ = 2 in 1 s and held 5 s with the
/// `vhb4910-wang2016` material. The phase's steps are recorded at their times; during the hold
/// the membrane relaxes at fixed stretch (stored energy falls, the branches dissipate, nothing
/// moves the rim), and the first stage starts at t = 6 s. For an elastic material the timed
/// phase ends in the same state as the instantaneous one (1e-9 of the stretch).
#[test]
fn timed_prestretch_relaxes_during_its_hold() {
    let dir = tempdir("prestretch-hold");
    std::fs::write(
        dir.join("d.toml"),
        deasim(&["example", "diaphragm"], &dir).stdout,
    )
    .unwrap();
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "run",
            "d.toml",
            "--out",
            out,
            "--set",
            "mesh.radial=4",
            "--set",
            "mesh.layers=1",
            "--set",
            "stages.1.duration=0.002",
            "--set",
            "output.plots=false",
            "--set",
            "output.fields_every=0",
        ];
        args.extend_from_slice(extra);
        let o = deasim(&args, &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let h = std::fs::read_to_string(dir.join(out).join("history.csv")).unwrap();
        let mut lines = h.lines();
        let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<Vec<String>> = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        (head, rows)
    };
    let timed = [
        "--set",
        "prestretch.duration=1.0",
        "--set",
        "prestretch.hold=5.0",
        "--set",
        "prestretch.hold_steps=5",
    ];
    let mut visco = timed.to_vec();
    visco.extend(["--set", "materials.vhb.preset=\"vhb4910-wang2016\""]);
    let (head, rows) = run("visco", &visco);
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let num = |r: &Vec<String>, c: usize| -> f64 { r[c].parse().unwrap() };
    let (ct, cs, cd) = (col("time"), col("stored"), col("dissipated"));
    // rows: the initial state, 4 stretch steps (t = 0.25 … 1), 5 hold steps (t = 2 … 6), then
    // the load stage
    let times: Vec<f64> = rows.iter().map(|r| num(r, ct)).collect();
    let expect = [0.0, 0.25, 0.5, 0.75, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    for (t, e) in times.iter().zip(expect) {
        assert!((t - e).abs() < 1e-12, "{times:?}");
    }
    assert!(times[10] > 6.0, "{times:?}");
    let hold = &rows[4..10];
    for w in hold.windows(2) {
        assert!(num(&w[1], cs) < num(&w[0], cs), "stored energy must relax");
        assert!(
            num(&w[1], cd) > num(&w[0], cd),
            "the branches must dissipate"
        );
    }
    // an elastic material: timed and instantaneous pre-stretch reach the same state
    let (_, a) = run("elastic-timed", &timed);
    let (_, b) = run("elastic", &[]);
    // the last record of the phase: at t = 6 s (timed; its ramp may be cut back), at step 1
    let end = |rows: &Vec<Vec<String>>, t: f64| {
        num(
            rows.iter()
                .rfind(|r| (num(r, ct) - t).abs() < 1e-12)
                .unwrap(),
            cs,
        )
    };
    let (x, y) = (end(&a, 6.0), num(&b[1], cs));
    assert!((x - y).abs() < 1e-9 * y, "{x} vs {y}");
}
