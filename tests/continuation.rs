//! Arc-length continuation stages (`kind = "continuation"`) on the film of the `film` example
//! (one cell: the homogeneous state).
//!
//! - In voltage, the path runs through the voltage maximum (pull-in) to λ = 2.5. Every point lies
//!   on the compressible closed-form curve to 1e-6. The limit point is located at the
//!   closed-form pull-in voltage (1e-5) and stretch (1e-3). The points before it are stable and
//!   those past it unstable under voltage control (one more negative pivot).
//! - In charge, the same curve has no limit point of the charge, and every point is stable.
//!   A load-factor target is landed on exactly.
//! - In force (the dead loads' factor), the film under a voltage and a dead equibiaxial tension
//!   that grow together passes their combined limit point, located at the closed form's.
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
        (
            "parameter = \"force\"\ntarget = { load = 1.0 }",
            "`force` needs dead loads",
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

/// The film under proportional loading: at load factor s its top electrode holds s·V̄ and its
/// lateral faces x1, y1 carry the dead nominal traction s·P̄. The path in the dead-load factor has a
/// maximum where the film pulls in under the combined load. Closed form: for each λ the two
/// stationarity conditions μ(λ − 1/λ) + Λ ln J/λ − (ε/2)E₀²λ/t = sP̄ and
/// μ(t − 1/t) + Λ ln J/t + (ε/2)E₀²λ²/t² = 0, E₀ = sV̄/H, give (t, s).
#[test]
fn force_path_passes_the_combined_limit_of_voltage_and_dead_tension() {
    let dir = tempdir("arc-force");
    let (v_bar, p_bar) = (30e3, 2e4);
    scenario(
        &dir,
        &format!("voltage = {v_bar}"),
        &format!(
            "[[tractions]]\nset = \"x1\"\nvalue = [{p_bar}, 0.0, 0.0]\n\
             [[tractions]]\nset = \"y1\"\nvalue = [0.0, {p_bar}, 0.0]\n\
             [[stages]]\nname = \"path\"\nkind = \"continuation\"\nparameter = \"force\"\n\
             steps = 40\ntarget = {{ probe = \"inplane_stretch\", value = 1.8 }}\n"
        ),
    );
    let (code, err) = run(&dir);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("limit point: maximum of dead_load_factor"),
        "{err}"
    );
    // the closed form: (t, s) at λ by Newton, continued in λ
    let f = film();
    let h = 1e-3;
    let residual = |l: f64, t: f64, s: f64| {
        let lnj = (l * l * t).ln();
        let e2 = (s * v_bar / h).powi(2);
        [
            f.mu * (l - 1.0 / l) + f.lambda * lnj / l - 0.5 * f.eps * e2 * l / t - s * p_bar,
            f.mu * (t - 1.0 / t) + f.lambda * lnj / t + 0.5 * f.eps * e2 * l * l / (t * t),
        ]
    };
    // (t, s) at λ by Newton from `start`
    let solve = |l: f64, start: (f64, f64)| -> (f64, f64) {
        let (mut t, mut s) = start;
        for _ in 0..100 {
            let r = residual(l, t, s);
            let d = 1e-8;
            let rt = residual(l, t + d, s);
            let rs = residual(l, t, s + d);
            let j = [
                [(rt[0] - r[0]) / d, (rs[0] - r[0]) / d],
                [(rt[1] - r[1]) / d, (rs[1] - r[1]) / d],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            let dt = (r[0] * j[1][1] - r[1] * j[0][1]) / det;
            let ds = (j[0][0] * r[1] - j[1][0] * r[0]) / det;
            t -= dt;
            s -= ds;
            if dt.abs() < 1e-15 && ds.abs() < 1e-15 {
                break;
            }
        }
        (t, s)
    };
    // the curve from λ = 1 in steps of 10⁻³ (each solve starts from the previous point)
    let mut curve = vec![(1.0, (1.0, 0.0))];
    while curve.last().unwrap().0 < 1.8 {
        let (l, start) = *curve.last().unwrap();
        curve.push((l + 1e-3, solve(l + 1e-3, start)));
    }
    let near = |l: f64| {
        curve
            .iter()
            .min_by(|a, b| (a.0 - l).abs().total_cmp(&(b.0 - l).abs()))
            .unwrap()
            .1
    };
    let at = |l: f64| solve(l, near(l)).1;
    // the maximum of s(λ): golden section around the best point of the curve
    let best = curve
        .iter()
        .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
        .unwrap()
        .0;
    let (mut a, mut b) = (best - 2e-3, best + 2e-3);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    while b - a > 1e-10 {
        let (x1, x2) = (b - g * (b - a), a + g * (b - a));
        if at(x1) > at(x2) {
            b = x2;
        } else {
            a = x1;
        }
    }
    let (l_max, s_max) = (0.5 * (a + b), at(0.5 * (a + b)));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    let limits = summary["limit_points"].as_array().unwrap();
    assert_eq!(limits.len(), 1, "{limits:?}");
    let lp = &limits[0];
    let (value, stretch) = (
        lp["value"].as_f64().unwrap(),
        lp["probes"]["inplane_stretch"].as_f64().unwrap(),
    );
    eprintln!(
        "force: limit at dead-load factor {value:.8} (λ {stretch:.5}); closed form {s_max:.8} at \
         λ {l_max:.5}"
    );
    assert_eq!(lp["parameter"], "dead_load_factor");
    assert_eq!(lp["kind"], "maximum");
    assert!((value / s_max - 1.0).abs() < 1e-5, "{value} vs {s_max}");
    assert!(
        (stretch - l_max).abs() < 1e-3 * l_max,
        "{stretch} vs {l_max}"
    );
    // every point on the closed form; stable before the maximum, unstable after
    let (hd, rows) = path_rows(&dir);
    let (c_s, c_l, c_stable) = (
        col(&hd, "parameter"),
        col(&hd, "probe:inplane_stretch"),
        col(&hd, "stable"),
    );
    for r in &rows {
        let (s, lam) = (
            r[c_s].parse::<f64>().unwrap(),
            r[c_l].parse::<f64>().unwrap(),
        );
        let s_cf = at(lam);
        assert!((s - s_cf).abs() < 1e-6, "λ {lam}: {s} vs {s_cf}");
        assert_eq!(r[c_stable] == "true", lam < l_max, "λ {lam}");
    }
    assert!(rows.len() > 5);
}
