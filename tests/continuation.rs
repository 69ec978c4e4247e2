//! Arc-length continuation stages (`kind = "continuation"`) on the film of the `film` example
//! (one cell: the homogeneous state).
//!
//! - In voltage, the path runs through the voltage maximum (pull-in) to λ = 2.5. Every point lies
//!   on the compressible closed-form curve to 1e-6. The limit point is located at the
//!   closed-form pull-in voltage (1e-5) and stretch (1e-3). The points before it are stable and
//!   those past it unstable under voltage control (one more negative pivot).
//! - In charge, the same curve has no limit point of the charge, and every point is stable.
//!   A load-factor target is landed on exactly.
//! - Bad stage definitions are refused with exit 2, naming the key.

mod common;

use common::{deasim, tempdir};
use deasim::analytic::Film;
use deasim::material::EPSILON_0;
use deasim::problem::examples::{FILM_EPS_R, FILM_LAMBDA, FILM_MU};

fn film() -> Film {
    Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    }
}

/// The `film` example on one cell with the top electrode's line replaced by `electrode` and the
/// stage by `stage`.
fn scenario(dir: &std::path::Path, electrode: &str, stage: &str) {
    let text = String::from_utf8_lossy(&deasim(&["example", "film"], dir).stdout).into_owned();
    let mut out = Vec::new();
    let mut in_stage = false;
    let mut replaced = (false, false);
    for l in text.lines() {
        if l.starts_with("voltage = { waveform = \"ramp\"") {
            out.push(electrode.to_string());
            replaced.0 = true;
            continue;
        }
        if l == "[[stages]]" {
            in_stage = true;
            out.push(stage.to_string());
            replaced.1 = true;
            continue;
        }
        if in_stage {
            if l.starts_with('[') {
                in_stage = false;
            } else {
                continue;
            }
        }
        out.push(l.to_string());
    }
    assert!(replaced.0 && replaced.1, "the example changed");
    std::fs::write(dir.join("s.toml"), out.join("\n")).unwrap();
}

/// Runs `s.toml` on one cell; (exit code, stderr).
fn run(dir: &std::path::Path) -> (Option<i32>, String) {
    let o = deasim(
        &[
            "run",
            "s.toml",
            "--out",
            "o",
            "--overwrite",
            "--set",
            "mesh.divisions=[1,1,1]",
        ],
        dir,
    );
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The rows of `path.csv` with its header.
fn path_rows(dir: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("o/path.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

fn col(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

#[test]
fn voltage_path_goes_through_pull_in_and_reports_the_points_past_it_unstable() {
    let dir = tempdir("arc-voltage");
    scenario(
        &dir,
        "voltage = 40000.0",
        "[[stages]]\nname = \"path\"\nkind = \"continuation\"\nparameter = \"voltage\"\n\
         steps = 40\ntarget = { probe = \"inplane_stretch\", value = 2.5 }\n",
    );
    let (code, err) = run(&dir);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("limit point: maximum of voltage_top"), "{err}");
    let (h, rows) = path_rows(&dir);
    let (c_v, c_l, c_t, c_stable, c_neg, c_exp) = (
        col(&h, "parameter"),
        col(&h, "probe:inplane_stretch"),
        col(&h, "probe:thickness_stretch"),
        col(&h, "stable"),
        col(&h, "negative_pivots"),
        col(&h, "stable_negative_pivots"),
    );
    let f = film();
    let (peak_field, peak) = f.pull_in();
    let v_peak = peak_field * 1e-3;
    let (mut before, mut after) = (0, 0);
    for r in &rows {
        let num = |c: usize| r[c].parse::<f64>().unwrap();
        let (state, e0) = f.on_curve(num(c_t));
        assert!(
            (num(c_l) - state.lambda).abs() < 1e-6 * state.lambda,
            "λ {} vs {}",
            num(c_l),
            state.lambda
        );
        let v = e0 * 1e-3;
        assert!(
            (num(c_v) - v).abs() < 1e-6 * v_peak,
            "V {} vs {v}",
            num(c_v)
        );
        let stable = r[c_stable] == "true";
        let negative: usize = r[c_neg].parse().unwrap();
        let expected: usize = r[c_exp].parse().unwrap();
        // a margin around the maximum where the parabola of the limit point decides
        if num(c_t) > peak.t + 1e-3 {
            assert!(stable && negative == expected, "{r:?}");
            before += 1;
        } else if num(c_t) < peak.t - 1e-3 {
            assert!(!stable && negative == expected + 1, "{r:?}");
            after += 1;
        }
    }
    assert!(before > 10 && after > 10, "{before} before, {after} after");
    let last: f64 = rows.last().unwrap()[c_l].parse().unwrap();
    assert!((2.5..2.7).contains(&last), "the path ends at λ = {last}");
    // the located limit point
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "finished");
    let limits = summary["limit_points"].as_array().unwrap();
    assert_eq!(limits.len(), 1, "{limits:?}");
    let l = &limits[0];
    assert_eq!(l["kind"], "maximum");
    assert_eq!(l["parameter"], "voltage_top");
    let v = l["value"].as_f64().unwrap();
    eprintln!(
        "limit point {v} V, closed form {v_peak} V ({:.1e}); λ {} vs {}",
        (v - v_peak) / v_peak,
        l["probes"]["inplane_stretch"],
        peak.lambda
    );
    assert!((v - v_peak).abs() < 1e-5 * v_peak, "{v} vs {v_peak}");
    let lam = l["probes"]["inplane_stretch"].as_f64().unwrap();
    assert!((lam - peak.lambda).abs() < 1e-3, "{lam} vs {}", peak.lambda);
}

#[test]
fn charge_path_is_stable_and_lands_on_its_target_load() {
    let dir = tempdir("arc-charge");
    scenario(
        &dir,
        "charge = 3.6e-6",
        "[[stages]]\nname = \"path\"\nkind = \"continuation\"\nparameter = \"charge\"\n\
         steps = 20\ntarget = { load = 1.0 }\n",
    );
    let (code, err) = run(&dir);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("limit point"), "{err}");
    let (h, rows) = path_rows(&dir);
    let (c_s, c_q, c_stable, c_l, c_t) = (
        col(&h, "load_factor"),
        col(&h, "parameter"),
        col(&h, "stable"),
        col(&h, "probe:inplane_stretch"),
        col(&h, "probe:thickness_stretch"),
    );
    let f = film();
    let mut previous = 0.0;
    for r in &rows {
        assert_eq!(r[c_stable], "true", "{r:?}");
        let s: f64 = r[c_s].parse().unwrap();
        assert!(
            s > previous,
            "the charge rises monotonically: {s} after {previous}"
        );
        previous = s;
        let q: f64 = r[c_q].parse().unwrap();
        assert!((q - s * 3.6e-6).abs() < 1e-12, "{q}");
        let (state, _) = f.on_curve(r[c_t].parse().unwrap());
        let lam: f64 = r[c_l].parse().unwrap();
        assert!((lam - state.lambda).abs() < 1e-6 * state.lambda);
    }
    assert_eq!(previous, 1.0, "the target load factor is landed on exactly");
    assert!(rows.len() >= 20);
}

#[test]
fn bad_continuation_stages_are_refused() {
    let dir = tempdir("arc-bad");
    let cases = [
        ("", "stages.0.parameter"),
        (
            "parameter = \"heat\"\ntarget = { load = 1.0 }",
            "unknown parameter `heat`",
        ),
        ("parameter = \"voltage\"", "give one target"),
        (
            "parameter = \"voltage\"\ntarget = { load = 1.0, points = 3 }",
            "give one target",
        ),
        (
            "parameter = \"voltage\"\ntarget = { probe = \"nope\", value = 1.0 }",
            "no probe is named `nope`",
        ),
        (
            "parameter = \"voltage\"\nelectrode = \"side\"\ntarget = { load = 1.0 }",
            "no electrode is named `side`",
        ),
        (
            "parameter = \"charge\"\ntarget = { load = 1.0 }",
            "needs a charge-controlled electrode",
        ),
        (
            "parameter = \"pressure\"\ntarget = { load = 1.0 }",
            "needs a pressure load",
        ),
    ];
    for (keys, expect) in cases {
        scenario(
            &dir,
            "voltage = 40000.0",
            &format!("[[stages]]\nkind = \"continuation\"\n{keys}\n"),
        );
        let o = deasim(&["check", "s.toml", "--no-trial"], &dir);
        let err =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{keys}: {err}");
        assert!(
            err.contains(expect) && err.contains("s.toml"),
            "{keys}: {err}"
        );
    }
    // a parameter the stage does not change: the run fails with the reason
    scenario(
        &dir,
        "voltage = 0.0",
        "[[stages]]\nkind = \"continuation\"\nparameter = \"voltage\"\nelectrode = \"top\"\n\
         target = { load = 1.0 }\n",
    );
    let (code, err) = run(&dir);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("a continuation follows a load that its stage changes"),
        "{err}"
    );
}
