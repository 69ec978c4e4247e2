//! Charge-controlled electrodes: the film of the `film` example, its top electrode carrying a
//! prescribed charge instead of a voltage, follows the homogeneous closed form past the voltage
//! maximum (the pull-in point of voltage control) to λ ≈ 2.6: at every accepted step the in-plane
//! stretch and the electrode's voltage lie on the closed-form curve at the computed thickness
//! stretch, to 1e-6 (one cell: the inhomogeneous modes that make states past the maximum unstable
//! with an equipotential electrode — coexistent thin and thick regions — need more cells). The
//! charge probe reads the prescribed charge. Floating electrodes (zero charge) in a stack take the
//! capacitive divider's potentials to 1e-10. A charge with a voltage, and charge control without a
//! voltage-controlled reference electrode or outside static stages, are refused.

mod common;

use common::{deasim, tempdir};
use deasim::analytic::Film;
use deasim::material::EPSILON_0;
use deasim::problem::examples::{FILM_EPS_R, FILM_LAMBDA, FILM_MU};

const Q: f64 = 3.6e-6;

fn film_with_charge(dir: &std::path::Path, line: &str) -> std::path::PathBuf {
    let text = String::from_utf8_lossy(&deasim(&["example", "film"], dir).stdout).into_owned();
    let lines: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with("voltage = { waveform = \"ramp\"") {
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(lines.iter().any(|l| l == line), "the example changed");
    let path = dir.join("q.toml");
    std::fs::write(&path, lines.join("\n")).unwrap();
    path
}

#[test]
fn charge_controlled_film_follows_the_closed_form_past_the_voltage_maximum() {
    let dir = tempdir("charge-film");
    film_with_charge(&dir, &format!("charge = {Q}"));
    let out = deasim(
        &[
            "run",
            "q.toml",
            "--out",
            "o",
            "--set",
            "stages.0.steps=40",
            "--set",
            "mesh.divisions=[1,1,1]",
        ],
        &dir,
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (c_t, c_v, c_l, c_h, c_q) = (
        col("time"),
        col("voltage"),
        col("probe:inplane_stretch"),
        col("probe:thickness_stretch"),
        col("probe:charge"),
    );
    let film = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    let (peak_field, peak) = film.pull_in();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let mut beyond = 0;
    let mut highest: f64 = 0.0;
    for r in &rows[1..] {
        let (state, e0) = film.on_curve(r[c_h]);
        assert!(
            (r[c_l] - state.lambda).abs() < 1e-6 * state.lambda,
            "λ {} vs {} at t = {}",
            r[c_l],
            state.lambda,
            r[c_h]
        );
        let v = e0 * 1e-3;
        assert!(
            (r[c_v] - v).abs() < 1e-6 * v,
            "V {} vs {v} at t = {}",
            r[c_v],
            r[c_h]
        );
        // the charge probe reads the prescribed charge at the step's load factor
        assert!(
            (r[c_q] - r[c_t] * Q).abs() < 1e-9 * Q,
            "{} vs {}",
            r[c_q],
            r[c_t] * Q
        );
        highest = highest.max(r[c_v]);
        if r[c_h] < peak.t {
            beyond += 1;
        }
    }
    let last = rows.last().unwrap();
    assert!(last[c_l] > 2.5, "λ reaches {}", last[c_l]);
    assert!(beyond > 20, "{beyond} steps past the maximum");
    // the voltage rose to the pull-in voltage and fell after it
    assert!(
        (highest / (peak_field * 1e-3) - 1.0).abs() < 1e-3,
        "{highest}"
    );
    assert!(last[c_v] < 0.6 * highest);
}

/// The last row of a history file, column by name.
fn last_row(path: &std::path::Path) -> impl Fn(&str) -> f64 {
    let text = std::fs::read_to_string(path).unwrap();
    let header: Vec<String> = text
        .lines()
        .next()
        .unwrap()
        .split(',')
        .map(String::from)
        .collect();
    let last: Vec<f64> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap_or(f64::NAN))
        .collect();
    move |n| last[header.iter().position(|h| h == n).unwrap()]
}

/// On 4 × 4 × 2 cells the charged film turns unstable to an inhomogeneous mode soon after its
/// voltage maximum (the voltage already falling). The run's error names that instability and what the stage controls: the charge of the
/// electrode at the last converged and the attempted load factor and the potential the electrode
/// took, which are the last history row's charge probe and voltage (not the grounded electrode's
/// 0 V, which an earlier message printed as "the" voltage).
#[test]
fn a_charged_film_that_turns_unstable_reports_its_charge_and_voltage() {
    let dir = tempdir("charge-unstable");
    let out = deasim(
        &[
            "run",
            "film-charge",
            "--out",
            "o",
            "--set",
            "mesh.divisions=[4,4,2]",
            "--set",
            "output.plots=false",
            "--set",
            "output.fields_every=0",
        ],
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("electromechanical instability under charge control in stage `charge`"),
        "{stderr}"
    );
    assert!(!stderr.contains("last converged voltage"), "{stderr}");
    let number = |marker: &str| -> f64 {
        let rest = stderr
            .split(marker)
            .nth(1)
            .unwrap_or_else(|| panic!("no `{marker}` in {stderr}"));
        let end = rest
            .find(|c: char| !(c.is_ascii_digit() || "+-.e".contains(c)))
            .unwrap_or(rest.len());
        rest[..end]
            .parse()
            .unwrap_or_else(|e| panic!("{e}: `{marker}` in {stderr}"))
    };
    let (q_ok, v_ok, q_failed) = (
        number("last converged charge of `top` "),
        number(" C at "),
        number(" V, failed at "),
    );
    let (s_ok, s_failed) = (
        number("no stable equilibrium beyond load factor "),
        number("(tried "),
    );
    let last = last_row(&dir.join("o/history.csv"));
    let (charge, voltage) = (last("probe:charge"), last("voltage"));
    assert!((q_ok - charge).abs() < 1e-6 * charge, "{q_ok} vs {charge}");
    assert!((v_ok - voltage).abs() < 0.01, "{v_ok} vs {voltage}");
    assert!(v_ok > 1e4, "{v_ok}");
    // the charge ramps from 0 with the load factor (3.6 µC at the stage's end); the load factors
    // are printed to six decimals (3.4e-6 of 0.146)
    assert!((q_ok - 3.6e-6 * s_ok).abs() < 1e-5 * q_ok, "{q_ok} {s_ok}");
    assert!(
        (q_failed - 3.6e-6 * s_failed).abs() < 1e-5 * q_failed && q_failed > q_ok,
        "{q_failed} {s_failed}"
    );
}

#[test]
fn charge_control_is_refused_where_it_cannot_act() {
    let dir = tempdir("charge-refused");
    let check = |extra: &[&str]| {
        let mut args = vec!["check", "q.toml", "--no-trial"];
        args.extend_from_slice(extra);
        let out = deasim(&args, &dir);
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    film_with_charge(&dir, "charge = 1e-7\nvoltage = 100.0");
    let (code, said) = check(&[]);
    assert_eq!(code, Some(2));
    assert!(
        said.contains("key `electrodes.top.charge`") && said.contains("not both"),
        "{said}"
    );
    film_with_charge(&dir, "charge = 1e-7");
    let (code, said) = check(&["--set", "electrodes.bottom.charge=0.0"]);
    assert_eq!(code, Some(2));
    assert!(said.contains("need a voltage-controlled one"), "{said}");
    // quasi-static and dynamic stages hold the charge; the explicit integrator and the
    // small-signal stages (which hold every electrode at its voltage) are refused
    let (code, said) = check(&["--set", "stages.0.kind=\"quasi-static\""]);
    assert_eq!(code, Some(0), "{said}");
    film_with_charge(&dir, "charge = 1e-7");
    let text = std::fs::read_to_string(dir.join("q.toml")).unwrap();
    // a stage put before the film's static one, with a density for the inertia
    let with = |stage: &str| {
        text.replace("[[stages]]", &format!("{stage}\n[[stages]]"))
            .replace("permittivity = 4.7", "permittivity = 4.7\ndensity = 1000.0")
    };
    let dynamic = |integrator: &str| {
        with(&format!(
            "[[stages]]\nname = \"shake\"\nkind = \"dynamic\"\nduration = 1e-4\ndt = 1e-5\n\
             integrator = \"{integrator}\""
        ))
    };
    std::fs::write(dir.join("q.toml"), dynamic("midpoint")).unwrap();
    let (code, said) = check(&[]);
    assert_eq!(code, Some(0), "{said}");
    std::fs::write(dir.join("q.toml"), dynamic("trapezoidal")).unwrap();
    let (code, said) = check(&[]);
    assert_eq!(code, Some(2), "{said}");
    assert!(
        said.contains("key `stages.0.integrator`") && said.contains("is charge-controlled"),
        "{said}"
    );
    std::fs::write(
        dir.join("q.toml"),
        with("[[stages]]\nname = \"m\"\nkind = \"modes\"\ncount = 2"),
    )
    .unwrap();
    let (code, said) = check(&[]);
    assert_eq!(code, Some(2), "{said}");
    assert!(
        said.contains("key `stages.0.kind`") && said.contains("small-signal stages"),
        "{said}"
    );
}

/// The film of `film-vibration` with its top electrode under charge control (8·10⁻⁸ C put on at
/// t = 0) and Kelvin–Voigt damping: the charge stays put at every step (midpoint and Newmark), the
/// film rings down onto the static charge-controlled state (the same charge in a static stage).
#[test]
fn a_charged_film_rings_down_onto_the_static_charge_controlled_state() {
    let dir = tempdir("charge-dynamic");
    let q = 8e-8;
    let text =
        String::from_utf8_lossy(&deasim(&["example", "film-vibration"], &dir).stdout).into_owned();
    let step_line = "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    assert!(text.contains(step_line), "the example changed");
    let text = text
        .lines()
        .map(|l| {
            if l.starts_with(step_line) {
                format!("charge = {q}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(dir.join("d.toml"), &text).unwrap();
    let last = |out: &str| last_row(&dir.join(out).join("history.csv"));
    let quiet = [
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=0",
    ];
    // the static reference
    let stat: String = text
        .lines()
        .filter(|l| !l.starts_with("dt = ") && !l.starts_with("integrator = "))
        .filter(|l| !l.starts_with("duration = "))
        .map(|l| {
            if l.starts_with("kind = \"dynamic\"") {
                "kind = \"static\"\nsteps = 4".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(dir.join("s.toml"), stat).unwrap();
    let mut args = vec!["run", "s.toml", "--out", "s"];
    args.extend_from_slice(&quiet);
    let out = deasim(&args, &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reference = last("s");
    for integrator in ["midpoint", "newmark"] {
        let set = format!("stages.0.integrator={integrator}");
        let mut args = vec![
            "run",
            "d.toml",
            "--out",
            integrator,
            "--set",
            "materials.elastomer.viscosity=100",
            "--set",
            &set,
        ];
        args.extend_from_slice(&quiet);
        let out = deasim(&args, &dir);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // the charge at every recorded step after the first
        let t = std::fs::read_to_string(dir.join(integrator).join("history.csv")).unwrap();
        let header: Vec<&str> = t.lines().next().unwrap().split(',').collect();
        let c = header.iter().position(|h| *h == "probe:charge").unwrap();
        for l in t.lines().skip(2) {
            let charge: f64 = l.split(',').nth(c).unwrap().parse().unwrap();
            assert!((charge / q - 1.0).abs() < 1e-9, "{integrator}: {charge}");
        }
        let end = last(integrator);
        for key in [
            "voltage",
            "probe:thickness_stretch",
            "probe:inplane_stretch",
        ] {
            let (a, b) = (end(key), reference(key));
            assert!((a / b - 1.0).abs() < 1e-9, "{integrator} {key}: {a} vs {b}");
        }
        assert!(
            end("kinetic") < 1e-12 * end("stored"),
            "{integrator}: rung down"
        );
    }
}

/// The capacitive divider of two floating electrodes holds at every instant of a dynamic stage
/// with a sine drive: the projection keeps their charge at zero.
#[test]
fn floating_electrodes_follow_the_divider_in_a_dynamic_stage() {
    let dir = tempdir("floating-dynamic");
    let text = std::fs::read_to_string(divider(&dir, 1000.0))
        .unwrap()
        .replace("permittivity = 3.0", "permittivity = 3.0\ndensity = 1000.0")
        .replace(
            "voltage = 1000",
            "voltage = { waveform = \"sine\", amplitude = 1000.0, frequency = 1000.0 }",
        )
        .replace(
            "kind = \"static\"\nsteps = 1",
            "kind = \"dynamic\"\nduration = 1e-3\ndt = 5e-5",
        )
        + "\n[probes.drive]\nkind = \"mean\"\nquantity = \"phi\"\nset = \"electrode_3\"\n";
    std::fs::write(dir.join("d.toml"), text).unwrap();
    let out = deasim(&["run", "d.toml", "--out", "o"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let t = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let header: Vec<&str> = t.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (d, f, s) = (col("probe:drive"), col("probe:first"), col("probe:second"));
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for l in t.lines().skip(1) {
        let v: Vec<f64> = l
            .split(',')
            .map(|x| x.parse().unwrap_or(f64::NAN))
            .collect();
        lo = lo.min(v[d]);
        hi = hi.max(v[d]);
        assert!((v[f] - v[d] / 3.0).abs() < 1e-9 * 1000.0, "{l}");
        assert!((v[s] - 2.0 * v[d] / 3.0).abs() < 1e-9 * 1000.0, "{l}");
    }
    assert!(hi - lo > 900.0, "the drive swings ({lo} … {hi})");
}

/// Two floating electrodes (zero charge) between a grounded and a driven one in a stack of three
/// equal films with full-area electrodes take the capacitive divider's potentials V/3 and 2V/3
/// (the material is so stiff that the films do not deform measurably).
/// The divider scenario (a grounded, two floating and one driven electrode on a stiff stack),
/// written to `d.toml` in `dir`.
fn divider(dir: &std::path::Path, v: f64) -> std::path::PathBuf {
    let text = format!(
        r#"name = "divider"
[mesh]
generator = "stack"
side = 2e-3
films = 3
film_thickness = 50e-6
border = 0.0
layers_per_film = 2
active_cells = 2
quarter = true
element = "hex8"
[materials.stiff]
model = "neo-hooke"
mu = 1e12
lambda = 1e12
permittivity = 3.0
[[constraints]]
set = "symmetry_x"
fix = ["x"]
[[constraints]]
set = "symmetry_y"
fix = ["y"]
[[constraints]]
set = "bottom"
fix = ["z"]
[electrodes.ground]
set = "electrode_0"
voltage = 0.0
[electrodes.first]
set = "electrode_1"
charge = 0.0
[electrodes.second]
set = "electrode_2"
charge = 0.0
[electrodes.drive]
set = "electrode_3"
voltage = {v}
[[stages]]
name = "on"
kind = "static"
steps = 1
[probes.first]
kind = "mean"
quantity = "phi"
set = "electrode_1"
[probes.second]
kind = "mean"
quantity = "phi"
set = "electrode_2"
[output]
fields_every = 0
plots = false
"#
    );
    let path = dir.join("d.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn floating_electrodes_take_the_capacitive_divider_potentials() {
    let dir = tempdir("floating");
    let v = 1000.0;
    divider(&dir, v);
    let out = deasim(&["run", "d.toml", "--out", "o"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let col = last_row(&dir.join("o/history.csv"));
    assert!(
        (col("probe:first") - v / 3.0).abs() < 1e-10 * v,
        "{}",
        col("probe:first")
    );
    assert!(
        (col("probe:second") - 2.0 * v / 3.0).abs() < 1e-10 * v,
        "{}",
        col("probe:second")
    );
}

/// A Gent film (J_m = 100, κ = 10⁶ μ, equibiaxial, no dead load) under charge control passes the
/// local voltage maximum and the re-stiffening minimum of the incompressible closed form
/// (λ = 1.26380, Φ̂ = 0.68936; λ = 5.07426, Φ̂ = 0.27460) on the closed-form curve: every accepted
/// step lies within 1e-4 of Φ̂(λ) (the compressible film's distance to the incompressible curve
/// grows as 12 μ/κ at λ ≈ 6), and each step was accepted only if stable.
#[test]
fn charge_controlled_gent_film_passes_both_extrema_of_the_closed_form() {
    let dir = tempdir("charge-gent");
    let (mu, jm, eps) = (1e5, 100.0, 4.7 * EPSILON_0);
    let text = format!(
        r#"name = "gent-charge"
[mesh]
generator = "box"
size = [10e-3, 10e-3, 1e-3]
divisions = [1, 1, 1]
element = "hex8"
[materials.gent]
model = "gent"
mu = {mu}
jm = {jm}
kappa = {kappa}
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
charge = 8e-5
[[stages]]
name = "charge"
kind = "static"
steps = 200
[probes.inplane_stretch]
kind = "point"
quantity = "ux"
at = [10e-3, 10e-3, 1e-3]
scale = 100.0
offset = 1.0
[output]
fields_every = 0
plots = false
"#,
        kappa = 1e6 * mu
    );
    std::fs::write(dir.join("g.toml"), text).unwrap();
    let out = deasim(&["run", "g.toml", "--out", "o"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (c_v, c_l) = (col("voltage"), col("probe:inplane_stretch"));
    let scale = 1e-3 * (mu / eps).sqrt();
    let curve: Vec<(f64, f64)> = lines
        .skip(1)
        .map(|l| {
            let r: Vec<f64> = l
                .split(',')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect();
            (r[c_l], r[c_v] / scale)
        })
        .collect();
    for &(l, phi) in &curve {
        let cf = deasim::analytic::incompressible_gent_voltage(l, jm, 0.0).unwrap();
        assert!((phi - cf).abs() < 1e-4 * cf, "λ = {l}: Φ̂ {phi} vs {cf}");
    }
    // a local maximum near λ = 1.26380 and a local minimum near λ = 5.07426 along the path
    let local = |want_max: bool| -> Vec<f64> {
        curve
            .windows(3)
            .filter(|w| {
                if want_max {
                    w[1].1 > w[0].1 && w[1].1 > w[2].1
                } else {
                    w[1].1 < w[0].1 && w[1].1 < w[2].1
                }
            })
            .map(|w| w[1].0)
            .collect()
    };
    let (maxima, minima) = (local(true), local(false));
    assert_eq!(maxima.len(), 1, "{maxima:?}");
    assert_eq!(minima.len(), 1, "{minima:?}");
    assert!((maxima[0] - 1.26380).abs() < 0.05, "{maxima:?}");
    assert!((minima[0] - 5.07426).abs() < 0.1, "{minima:?}");
    assert!(curve.last().unwrap().0 > 5.9);
}
