//! Determinism through the command line (docs/architecture.md, determinism): the same
//! scenario on 1 and 2 rayon threads (`RAYON_NUM_THREADS`) gives the same history and probes to
//! 1e-12 relative (round-off of the parallel factorisation), and two runs on the same thread
//! count give byte-identical `history.csv` and `summary.json` (wall times aside).
//!
//! Tolerance 1e-12: each value is compared relative to the largest magnitude of its column
//! (values that cross zero have no relative error of their own); a dynamic run amplifies
//! round-off over its steps, and 200 steps of the film vibration stay far below this.

mod common;
use common::deasim_on_threads as deasim;
use std::path::Path;
use std::process::Output;

fn tempdir(name: &str) -> common::TempDir {
    common::TempDir::new(&format!("deasim-det-{name}"))
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// summary.json without wall times.
fn summary(out: &Path) -> serde_json::Value {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("wall_s");
    v.as_object_mut().unwrap().remove("date");
    for s in v["stages"].as_array_mut().unwrap() {
        s.as_object_mut().unwrap().remove("wall_s");
    }
    v
}

/// Numeric columns of history.csv (the stage-name column dropped).
fn history(out: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let t = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = t.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| header[*i] != "stage")
                .map(|(_, v)| v.parse::<f64>().unwrap())
                .collect()
        })
        .collect();
    (header.into_iter().filter(|h| h != "stage").collect(), rows)
}

/// Runs `scenario` with `sets` on 1, 2 and again 2 threads; returns the largest relative
/// difference between the 1- and 2-thread histories and asserts the two 2-thread runs are
/// identical.
fn compare_threads(name: &str, scenario: &str, sets: &[&str]) -> f64 {
    let dir = tempdir(name);
    let path = dir.join("s.toml");
    std::fs::write(&path, deasim(&["example", scenario], &dir, "1").stdout).unwrap();
    let run = |out: &str, threads: &str| {
        let mut args = vec![
            "run",
            path.to_str().unwrap(),
            "--out",
            out,
            "--set",
            "output.plots=false",
        ];
        for s in sets {
            args.extend(["--set", s]);
        }
        let o = deasim(&args, &dir, threads);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        assert!(
            text(&o).contains(&format!("; {threads} thread(s);")),
            "RAYON_NUM_THREADS not honoured: {}",
            text(&o)
        );
        dir.join(out)
    };
    let one = run("t1", "1");
    let two = run("t2", "2");
    let again = run("t2b", "2");
    assert_eq!(
        std::fs::read(two.join("history.csv")).unwrap(),
        std::fs::read(again.join("history.csv")).unwrap(),
        "two runs on 2 threads differ"
    );
    assert_eq!(summary(&two), summary(&again));

    let (header, a) = history(&one);
    let (_, b) = history(&two);
    assert_eq!(a.len(), b.len(), "step counts differ");
    let mut worst = 0.0f64;
    for c in 0..header.len() {
        // NaN (capacitance at 0 V) must be NaN in both
        for (ra, rb) in a.iter().zip(&b) {
            assert_eq!(ra[c].is_nan(), rb[c].is_nan(), "{}", header[c]);
        }
        let finite = |r: &Vec<f64>| r[c].is_finite();
        let scale = a
            .iter()
            .filter(|r| finite(r))
            .map(|r| r[c].abs())
            .fold(0.0, f64::max);
        if scale == 0.0 {
            assert!(
                b.iter().all(|r| r[c] == 0.0 || r[c].is_nan()),
                "{}",
                header[c]
            );
            continue;
        }
        for (ra, rb) in a.iter().zip(&b).filter(|(ra, _)| finite(ra)) {
            let d = (ra[c] - rb[c]).abs() / scale;
            assert!(d <= 1e-12, "{}: {} vs {} ({d:e})", header[c], ra[c], rb[c]);
            worst = worst.max(d);
        }
    }
    // the final probes of summary.json, relative to each value
    let (pa, pb) = (
        summary(&one)["probes"].clone(),
        summary(&two)["probes"].clone(),
    );
    for (k, va) in pa.as_object().unwrap() {
        let (x, y) = (va.as_f64().unwrap(), pb[k].as_f64().unwrap());
        let d = (x - y).abs() / x.abs().max(f64::MIN_POSITIVE);
        assert!(d <= 1e-12, "probe {k}: {x} vs {y}");
    }
    eprintln!("{name}: largest 1-vs-2-thread difference {worst:e} (relative to column scale)");
    worst
}

/// The film vibration (midpoint, modified Newton), 4 ms = 200 steps, on a 6 × 6 × 2 mesh.
#[test]
fn dynamic_run_is_deterministic_across_thread_counts() {
    compare_threads(
        "vibration",
        "film-vibration",
        &["stages.0.duration=0.004", "mesh.divisions=[6, 6, 2]"],
    );
}

/// The static film ramp (15 load steps, tangent predictor).
#[test]
fn static_run_is_deterministic_across_thread_counts() {
    compare_threads("film", "film", &["mesh.divisions=[8, 8, 2]"]);
}

/// The film vibration with a fast Maxwell branch (the point states evolve in every step).
#[test]
fn viscoelastic_run_is_deterministic_across_thread_counts() {
    compare_threads(
        "visco",
        "film-vibration",
        &[
            "stages.0.duration=0.002",
            "mesh.divisions=[6, 6, 2]",
            "materials.elastomer.branches=[{mu=5e4,tau=1e-3}]",
        ],
    );
}
