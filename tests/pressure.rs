//! Follower pressure loads in a run: an eighth of a neo-Hooke cube (symmetry planes x0, y0, z0)
//! under a pressure on its three outer faces is compressed homogeneously, σ = −p I, with
//! λ from μ(λ² − 1) + Λ ln λ³ = −p λ³ (to Newton's tolerance, for hex8, tet4 and tet10); the
//! `volume` probe of the top face reads −⅓ λ³ a³ (x·n vanishes on the symmetry planes through the
//! origin, the two side faces hold the other two thirds). Stages that cannot carry a pressure
//! refuse it with exit 2.

mod common;

use common::{deasim, tempdir};

const MU: f64 = 1e5;
const LAMBDA: f64 = 1e7;
const A: f64 = 1e-3;
const P: f64 = 1e6;

fn scenario(element: &str, extra: &str) -> String {
    format!(
        r#"name = "cube"
[mesh]
generator = "box"
size = [{A}, {A}, {A}]
divisions = [2, 2, 2]
element = "{element}"
[materials.rubber]
model = "neo-hooke"
mu = {MU}
lambda = {LAMBDA}
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
[[loads.pressure]]
set = "x1"
value = {P}
[[loads.pressure]]
set = "y1"
value = {P}
[[loads.pressure]]
set = "z1"
value = {P}
{extra}
[probes.stretch]
kind = "mean"
quantity = "uz"
set = "z1"
scale = {s}
offset = 1.0
unit = "-"
[probes.volume_z1]
kind = "volume"
set = "z1"
[output]
fields_every = 0
plots = false
"#,
        s = 1.0 / A
    )
}

/// λ of the homogeneous state under the pressure, by bisection on the Cauchy stress.
fn closed_form() -> f64 {
    let sigma = |l: f64| (MU * (l * l - 1.0) + LAMBDA * 3.0 * l.ln()) / l.powi(3);
    let (mut lo, mut hi) = (0.5, 1.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if sigma(mid) < -P {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn last_row(dir: &std::path::Path) -> std::collections::HashMap<String, f64> {
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let last: Vec<&str> = lines.last().unwrap().split(',').collect();
    header
        .iter()
        .zip(last)
        .map(|(h, v)| (h.to_string(), v.parse().unwrap_or(f64::NAN)))
        .collect()
}

#[test]
fn hydrostatic_pressure_on_a_cube_matches_the_closed_form() {
    let dir = tempdir("pressure-cube");
    let l = closed_form();
    assert!(l < 0.98, "the pressure compresses visibly ({l})");
    for element in ["hex8", "tet4", "tet10"] {
        let stage = "[[stages]]\nname = \"squeeze\"\nkind = \"static\"\nsteps = 16\n";
        std::fs::write(dir.join("c.toml"), scenario(element, stage)).unwrap();
        let out = deasim(&["run", "c.toml", "--out", element], &dir);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let row = last_row(&dir.join(element));
        let stretch = row["probe:stretch"];
        assert!(
            (stretch - l).abs() < 1e-9,
            "{element}: λ = {stretch} vs {l}"
        );
        // the pressure's work ∫ p dV is in the balance (trapezoidal in (p, V): second order;
        // 1.2e-7 J with 4 steps, 7.6e-9 J with 16)
        let (error, stored) = (row["energy_error"], row["stored"]);
        eprintln!("{element}: energy_error {error:e} J of stored {stored:e} J");
        assert!(
            error.abs() < 1e-3 * stored,
            "{element}: {error} vs {stored}"
        );
        let v = row["probe:volume_z1"];
        let expected = -(l * A).powi(3) / 3.0;
        assert!(
            (v - expected).abs() < 1e-8 * expected.abs(),
            "{element}: {v} vs {expected}"
        );
    }
}

#[test]
fn stages_without_the_follower_stiffness_refuse_a_pressure() {
    let dir = tempdir("pressure-refused");
    let stage = "[[stages]]\nname = \"shake\"\nkind = \"dynamic\"\nduration = 1e-3\ndt = 1e-4\n";
    let text = scenario("hex8", stage)
        .replace("permittivity = 4.7", "permittivity = 4.7\ndensity = 1000.0");
    std::fs::write(dir.join("c.toml"), text).unwrap();
    let out = deasim(&["check", "c.toml"], &dir);
    assert_eq!(out.status.code(), Some(2));
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("key `stages.0.kind`") && said.contains("pressure loads act in static"),
        "{said}"
    );
}

/// Rows of history.csv as maps from column to value (the stage column by name).
fn rows(dir: &std::path::Path) -> Vec<(String, std::collections::HashMap<String, f64>)> {
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let stage = header.iter().position(|h| *h == "stage").unwrap();
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let map = header
                .iter()
                .zip(&v)
                .map(|(h, x)| (h.to_string(), x.parse().unwrap_or(f64::NAN)))
                .collect();
            (v[stage].to_string(), map)
        })
        .collect()
}

#[test]
fn a_pressure_acts_in_its_stages_and_is_ramped_off_after_them() {
    let dir = tempdir("pressure-stages");
    let l = closed_form();
    let stages = "[[stages]]\nname = \"squeeze\"\nkind = \"static\"\nsteps = 16\n\
                  [[stages]]\nname = \"hold\"\nkind = \"static\"\nsteps = 2\n\
                  [[stages]]\nname = \"release\"\nkind = \"static\"\nsteps = 16\n";
    let text = scenario("hex8", stages).replace(
        &format!("value = {P}\n"),
        &format!("value = {P}\nstages = [\"squeeze\", \"hold\"]\n"),
    );
    std::fs::write(dir.join("c.toml"), &text).unwrap();
    let out = deasim(&["run", "c.toml", "--out", "o"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = rows(&dir.join("o"));
    let last_of = |name: &str| &rows.iter().rfind(|(s, _)| s == name).unwrap().1;
    for name in ["squeeze", "hold"] {
        let stretch = last_of(name)["probe:stretch"];
        assert!((stretch - l).abs() < 1e-9, "{name}: λ = {stretch} vs {l}");
    }
    // released: back to the reference state, and the work done on the way down is returned
    let end = last_of("release");
    assert!(
        (end["probe:stretch"] - 1.0).abs() < 1e-9,
        "released: λ = {}",
        end["probe:stretch"]
    );
    let peak = last_of("hold")["stored"];
    assert!(
        end["stored"].abs() < 1e-12 * peak.max(1.0),
        "{}",
        end["stored"]
    );
    assert!(
        end["energy_error"].abs() < 1e-3 * peak,
        "{} of {peak}",
        end["energy_error"]
    );
    // the stage halfway down holds half the pressure: the ramp is linear in the load factor
    let mid = &rows
        .iter()
        .filter(|(s, _)| s == "release")
        .nth(7)
        .unwrap()
        .1;
    assert!(mid["probe:stretch"] > l && mid["probe:stretch"] < 1.0);

    // a stage name the pressure does not know is refused, naming the key
    let bad = text.replace("\"hold\"]", "\"hodl\"]");
    std::fs::write(dir.join("bad.toml"), bad).unwrap();
    let out = deasim(&["check", "bad.toml"], &dir);
    assert_eq!(out.status.code(), Some(2));
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("loads.pressure.0.stages") && said.contains("hodl"),
        "{said}"
    );

    // a dynamic stage after the pressure's stages is accepted (the pressure is off there)
    let shake = "[[stages]]\nname = \"shake\"\nkind = \"dynamic\"\nduration = 1e-4\ndt = 1e-5\n";
    let text = text.replace("permittivity = 4.7", "permittivity = 4.7\ndensity = 1000.0") + shake;
    std::fs::write(dir.join("d.toml"), text).unwrap();
    let out = deasim(&["check", "d.toml"], &dir);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

#[test]
fn volume_control_inputs_are_checked() {
    let dir = tempdir("pressure-volume-inputs");
    let stage = "[[stages]]\nname = \"squeeze\"\nkind = \"static\"\nsteps = 4\n";
    let base = scenario("hex8", stage);
    let cases = [
        (
            base.replacen(
                &format!("value = {P}\n"),
                &format!("value = {P}\nvolume = 1e-9\n"),
                1,
            ),
            "loads.pressure.0.volume",
            "not both",
        ),
        (
            base.replacen(&format!("value = {P}\n"), "", 1),
            "loads.pressure.0",
            "`value` (the pressure, Pa) or `volume`",
        ),
        (
            base.replacen(&format!("value = {P}\n"), "volume = -1e-9\n", 1),
            "loads.pressure.0.volume",
            "positive",
        ),
        (
            base.replacen(&format!("value = {P}\n"), "volume = 1e-9\n", 2),
            "loads.pressure.1.volume",
            "only one pressure",
        ),
        (
            base.replace("kind = \"volume\"", "kind = \"pressure\"")
                .replace("set = \"z1\"\n[output]", "set = \"top\"\n[output]"),
            "probes.volume_z1.set",
            "no `[[loads.pressure]]` acts on `top`",
        ),
    ];
    for (i, (text, key, words)) in cases.iter().enumerate() {
        std::fs::write(dir.join(format!("c{i}.toml")), text).unwrap();
        let out = deasim(&["check", &format!("c{i}.toml")], &dir);
        let said = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(2), "case {i}: {said}");
        assert!(
            said.contains(&format!("key `{key}`")) && said.contains(words),
            "case {i}: {said}"
        );
    }
    // a continuation stage in which a volume-controlled pressure acts is refused
    let arc = "[[stages]]\nname = \"arc\"\nkind = \"continuation\"\nparameter = \"pressure\"\n\
               steps = 4\ntarget = { points = 3 }\n";
    let text = scenario("hex8", arc).replacen(&format!("value = {P}\n"), "volume = 1e-9\n", 1);
    std::fs::write(dir.join("arc.toml"), text).unwrap();
    let out = deasim(&["check", "arc.toml"], &dir);
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(
        said.contains("key `stages.0.kind`") && said.contains("volume-controlled pressure"),
        "{said}"
    );
}
