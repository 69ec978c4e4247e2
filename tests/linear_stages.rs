//! The small-signal stages of a run (`kind = "modes"` and `kind = "frequency-response"`) on the
//! `film-modes` example: they write `modes.csv`, the `modes` list of `summary.json` and
//! `frequency_response.csv` with the interface's columns, give the same numbers as the commands
//! `deasim modes` and `deasim response` about the same state, leave the state and the time
//! unchanged, and the modal method (modes with a static correction) follows the direct solves
//! below the kept modes.

mod common;
use common::{deasim, tempdir};
use std::path::Path;

/// Header and rows of a CSV file of numbers.
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let head = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    (head, rows)
}

fn column(head: &[String], name: &str) -> usize {
    head.iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column `{name}` in {head:?}"))
}

fn ok(o: &std::process::Output) {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn stages_match_the_commands_and_keep_the_state() {
    let dir = tempdir("linear-stages");
    std::fs::write(
        dir.join("f.toml"),
        deasim(&["example", "film-modes"], &dir).stdout,
    )
    .unwrap();
    ok(&deasim(&["run", "f.toml", "--out", "run"], &dir));
    // modes: the table and the summary's list agree, ascending, six of them
    let (head, rows) = csv(&dir.join("run/modes.csv"));
    assert_eq!(&head[..2], ["mode", "frequency_hz"]);
    let f: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    assert_eq!(f.len(), 6);
    assert!(f.windows(2).all(|w| w[0] <= w[1]) && f[0] > 0.0, "{f:?}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("run/summary.json")).unwrap())
            .unwrap();
    let listed: Vec<f64> = summary["modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(listed, f);
    let kinds: Vec<&str> = summary["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["static", "modes", "frequency-response"]);
    for i in 1..=6 {
        assert!(dir.join(format!("run/modes/mode_{i:02}.vtu")).exists());
    }
    // the command about the state after the static stage gives the same frequencies
    ok(&deasim(
        &["modes", "f.toml", "--count", "6", "--out", "cmd-modes"],
        &dir,
    ));
    let (_, cmd) = csv(&dir.join("cmd-modes/modes.csv"));
    for (a, b) in f.iter().zip(cmd.iter().map(|r| r[1])) {
        assert!((a / b - 1.0).abs() < 1e-9, "stage {a} vs command {b}");
    }
    // the response: interface columns, and the command's numbers at the same frequencies
    let (head, rows) = csv(&dir.join("run/frequency_response.csv"));
    assert_eq!(head[0], "frequency_hz");
    assert_eq!(rows.len(), 100);
    assert!((rows[0][0] - 10.0).abs() < 1e-9 && (rows[99][0] - 5000.0).abs() < 1e-9);
    let list: Vec<String> = [0, 37, 60, 99]
        .iter()
        .map(|&i| format!("{:e}", rows[i][0]))
        .collect();
    ok(&deasim(
        &[
            "response",
            "f.toml",
            "--electrode",
            "top",
            "--frequencies",
            &list.join(","),
            "--out",
            "cmd-frf",
        ],
        &dir,
    ));
    let (chead, crows) = csv(&dir.join("cmd-frf/frequency_response.csv"));
    for probe in ["thickness_stretch", "inplane_stretch", "charge"] {
        for part in ["magnitude", "phase_deg"] {
            let name = format!("{probe}:{part}");
            let (i, j) = (column(&head, &name), column(&chead, &name));
            for (k, &r) in [0, 37, 60, 99].iter().enumerate() {
                let (a, b) = (rows[r][i], crows[k][j]);
                let scale = if part == "phase_deg" { 1.0 } else { b.abs() };
                assert!(
                    (a - b).abs() <= 1e-6 * scale,
                    "{name} at {} Hz: stage {a} vs command {b}",
                    rows[r][0]
                );
            }
        }
    }
    // the peak of the thickness response lies at one of the modes
    let m = column(&head, "thickness_stretch:magnitude");
    let peak = rows
        .iter()
        .max_by(|a, b| a[m].total_cmp(&b[m]))
        .map(|r| r[0])
        .unwrap();
    assert!(
        f.iter().any(|&fm| (peak / fm - 1.0).abs() < 0.02),
        "peak at {peak} Hz, modes {f:?}"
    );
    // the linear stages add no step and no time: the last record is the biased state
    let history = std::fs::read_to_string(dir.join("run/history.csv")).unwrap();
    let last = history.lines().last().unwrap();
    assert!(last.contains(",bias,4,"), "{last}");
    assert_eq!(summary["frequency_response"][0]["electrode"], "top");
    assert_eq!(summary["frequency_response"][0]["bias_v"], 20e3);
}

/// Modes with a static correction follow the direct solves where the kept modes reach (the
/// film's viscosity is light); and a response about zero bias is refused by no one but warned of.
#[test]
fn modal_method_follows_the_direct_solves_and_zero_bias_is_warned() {
    let dir = tempdir("linear-modal");
    let text = String::from_utf8(deasim(&["example", "film-modes"], &dir).stdout).unwrap();
    std::fs::write(dir.join("direct.toml"), &text).unwrap();
    std::fs::write(
        dir.join("modal.toml"),
        text.replace("method = \"direct\"", "method = \"modal\"\ncount = 20"),
    )
    .unwrap();
    ok(&deasim(&["run", "direct.toml", "--out", "d"], &dir));
    ok(&deasim(&["run", "modal.toml", "--out", "m"], &dir));
    let (head, d) = csv(&dir.join("d/frequency_response.csv"));
    let (_, m) = csv(&dir.join("m/frequency_response.csv"));
    let (re, im) = (
        column(&head, "thickness_stretch:real"),
        column(&head, "thickness_stretch:imag"),
    );
    let mut worst: f64 = 0.0;
    for (a, b) in d.iter().zip(&m) {
        if a[0] > 1000.0 {
            break;
        }
        let err = (a[re] - b[re]).hypot(a[im] - b[im]) / a[re].hypot(a[im]);
        worst = worst.max(err);
    }
    assert!(worst < 0.02, "modal vs direct below 1 kHz: {worst}");
    // zero bias: the response is computed, the summary says why it vanishes
    std::fs::write(
        dir.join("zero.toml"),
        text.replace(
            "voltage = 20e3                # V: the DC bias",
            "voltage = 0.0",
        ),
    )
    .unwrap();
    let o = deasim(&["run", "zero.toml", "--out", "z"], &dir);
    ok(&o);
    let summary = std::fs::read_to_string(dir.join("z/summary.json")).unwrap();
    assert!(summary.contains("zero bias"), "{summary}");
}

/// Maxwell branches linearise into a complex modulus about the relaxed state: the response of a
/// one-cell film with one branch (g = μ, τ = 10 ms) at ωτ ≈ 1 equals the steady state of a
/// quasi-static run with a ±20 V sinusoid about 20 kV (1000 backward-Euler steps per period,
/// inertia negligible at 16 Hz), within 1 % of its amplitude; the branch matters: the relaxed
/// (low-frequency) response is far from it.
#[test]
fn branches_respond_with_their_complex_modulus() {
    let dir = tempdir("linear-branches");
    let base = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/film-branch.toml"),
    )
    .unwrap();
    let bias = "[[stages]]\nname = \"bias\"\nkind = \"static\"\nduration = 0.0625\nsteps = 4\n";
    std::fs::write(
        dir.join("td.toml"),
        format!(
            "{base}{bias}[[stages]]\nname = \"drive\"\nkind = \"quasi-static\"\nduration = 0.5\n\
             steps = 8000\n"
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("fr.toml"),
        format!(
            "{base}{bias}[[stages]]\nname = \"response\"\nkind = \"frequency-response\"\n\
             electrode = \"top\"\nfrequencies = [16.0, 0.016]\n"
        ),
    )
    .unwrap();
    ok(&deasim(&["run", "fr.toml", "--out", "fr"], &dir));
    ok(&deasim(&["run", "td.toml", "--out", "td"], &dir));
    let (head, rows) = csv(&dir.join("fr/frequency_response.csv"));
    let (re, im) = (
        column(&head, "thickness_stretch:real"),
        column(&head, "thickness_stretch:imag"),
    );
    let (fr, fi) = (rows[0][re], rows[0][im]);
    let relaxed = rows[1][re].hypot(rows[1][im]);
    // least-squares fit y = c₀ + c₁ sin ωt + c₂ cos ωt over the last two periods
    let text = std::fs::read_to_string(dir.join("td/history.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let (ti, si, pi) = (
        column(&head, "time"),
        column(&head, "stage"),
        column(&head, "probe:thickness_stretch"),
    );
    let w = 2.0 * std::f64::consts::PI * 16.0;
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for l in lines {
        let v: Vec<&str> = l.split(',').collect();
        let t = v[ti].parse::<f64>().unwrap() - 0.0625;
        if v[si] != "drive" || t <= 0.5 - 2.0 / 16.0 {
            continue;
        }
        let y: f64 = v[pi].parse().unwrap();
        let basis = nalgebra::Vector3::new(1.0, (w * t).sin(), (w * t).cos());
        a += basis * basis.transpose();
        b += basis * y;
    }
    let c = a.lu().solve(&b).unwrap();
    let (tr, ti) = (c[1] / 20.0, c[2] / 20.0);
    let err = (fr - tr).hypot(fi - ti) / tr.hypot(ti);
    assert!(
        err < 0.01,
        "response ({fr:e}, {fi:e}) vs time domain ({tr:e}, {ti:e}): {err}"
    );
    assert!(
        fi.abs() > 0.2 * fr.abs() && relaxed > 1.5 * fr.hypot(fi),
        "the branch should show: ({fr:e}, {fi:e}), relaxed {relaxed:e}"
    );
}
