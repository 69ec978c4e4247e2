//! The output directory is safe to use: the scenario name is one plain directory name, a
//! directory is locked while a run writes there, a write failure ends the run with exit 1 and
//! names the file once, a new run clears deasim's own files of the earlier one, and the README's
//! checkpoint example works as written.

mod common;

use common::{deasim, tempdir};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

fn example(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, deasim(&["example", name], dir).stdout).unwrap();
    p
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// `name = ".."` wrote into the current directory, `"."` into `deasim-out/` itself: refused.
#[test]
fn scenario_names_that_are_not_a_plain_directory_are_refused() {
    let dir = tempdir("names");
    example(&dir, "film");
    for bad in ["..", ".", "a/b", "a\\\\b", "", "-rf", "../x"] {
        let out = deasim(
            &["run", "film.toml", "--set", &format!("name=\"{bad}\"")],
            &dir,
        );
        assert_eq!(out.status.code(), Some(2), "{bad}: {}", text(&out));
        assert!(text(&out).contains("name"), "{bad}: {}", text(&out));
        assert!(!text(&out).contains("panicked"), "{}", text(&out));
        assert!(!dir.join("summary.json").exists(), "{bad}");
        assert!(!dir.join("deasim-out/summary.json").exists(), "{bad}");
        let check = deasim(
            &["check", "film.toml", "--set", &format!("name=\"{bad}\"")],
            &dir,
        );
        assert_eq!(check.status.code(), Some(2), "{bad}: {}", text(&check));
    }
    assert!(!dir.join("history.csv").exists());
}

/// A live lock refuses a second run (exit 2, naming the directory and the process); a stale one
/// is taken over with a warning and removed at the end; two real runs at once: the second is
/// refused while the first writes.
#[test]
fn output_directory_is_locked_during_a_run() {
    let dir = tempdir("lock");
    example(&dir, "film");
    std::fs::create_dir_all(dir.join("o")).unwrap();
    let me = std::process::id().to_string();
    std::fs::write(dir.join("o/.deasim.lock"), format!("{me}\n")).unwrap();
    let out = deasim(&["run", "film.toml", "--out", "o"], &dir);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        text(&out).contains("o is in use") && text(&out).contains(&format!("process {me}")),
        "{}",
        text(&out)
    );
    assert!(!dir.join("o/history.csv").exists());
    let resume = deasim(&["run", "--resume", "o"], &dir);
    assert_eq!(resume.status.code(), Some(2), "{}", text(&resume));
    assert!(text(&resume).contains("in use"), "{}", text(&resume));
    // a process id that cannot be running
    std::fs::write(dir.join("o/.deasim.lock"), "2147483600\n").unwrap();
    let out = deasim(&["run", "film.toml", "--out", "o"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(text(&out).contains("stale lock"), "{}", text(&out));
    assert!(!dir.join("o/.deasim.lock").exists());
    // two runs at once
    example(&dir, "film-vibration");
    let mut first = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args([
            "run",
            "film-vibration.toml",
            "--out",
            "v",
            "--set",
            "output.plots=false",
        ])
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !dir.join("v/history.csv").exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let running = first.try_wait().unwrap().is_none();
    let second = deasim(
        &[
            "run",
            "film-vibration.toml",
            "--out",
            "v",
            "--set",
            "output.plots=false",
        ],
        &dir,
    );
    let _ = first.kill();
    let _ = first.wait();
    if running {
        assert_eq!(second.status.code(), Some(2), "{}", text(&second));
        assert!(
            text(&second).contains(&format!("process {}", first.id())),
            "{}",
            text(&second)
        );
    }
}

/// `fields/` is a regular file: every field write fails. The run ends with exit 1, the failure
/// is named once (not a warning per step), and history.csv and summary.json are written.
#[test]
fn a_write_failure_ends_with_exit_1_and_names_the_file_once() {
    let dir = tempdir("writefail");
    example(&dir, "film");
    std::fs::create_dir_all(dir.join("o")).unwrap();
    std::fs::write(dir.join("o/fields"), "not a directory").unwrap();
    let out = deasim(&["run", "film.toml", "--out", "o"], &dir);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(1), "{t}");
    assert!(
        t.contains("error: could not write") && t.contains("fields"),
        "{t}"
    );
    assert_eq!(t.matches("could not write").count(), 1, "{t}");
    assert!(!t.contains("warning: "), "{t}");
    assert!(!t.contains("panicked"), "{t}");
    // the terminal does not call it finished; the summary says what is missing
    assert!(!t.contains("finished"), "{t}");
    assert!(t.contains("the outputs are incomplete"), "{t}");
    let h = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    assert_eq!(h.lines().count(), 17, "header, initial state and 15 steps");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(s["status"], "incomplete-outputs", "{s}");
    assert_eq!(s["outputs"]["complete"], false, "{s}");
    let reason = s["outputs"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("could not write") && reason.contains("fields"),
        "{s}"
    );
    let w = s["warnings"].as_array().unwrap();
    assert_eq!(
        w.iter()
            .filter(|w| w.as_str().unwrap().contains("could not write"))
            .count(),
        1,
        "{s}"
    );
}

/// Every command that writes results refuses a directory holding another command's results
/// (naming the directory, what it holds, --overwrite and --out) and deletes nothing there;
/// `--overwrite` removes all of them and no file deasim did not write; a rerun of the same
/// command and scenario replaces its own results without --overwrite.
#[test]
fn another_commands_results_are_refused_and_overwrite_removes_them_all() {
    let dir = tempdir("other-command");
    example(&dir, "film");
    let modes = deasim(
        &[
            "modes",
            "film.toml",
            "--count",
            "2",
            "--out",
            "o",
            "--set",
            MASS,
        ],
        &dir,
    );
    assert_eq!(modes.status.code(), Some(0), "{}", text(&modes));
    let written = names(&dir.join("o"));
    assert!(written.contains(&"modes.csv".to_string()), "{written:?}");
    let shapes = names(&dir.join("o/modes"));
    assert!(!shapes.is_empty());
    std::fs::write(dir.join("o/notes.txt"), "mine").unwrap();
    // the same command and scenario again: its own results, replaced
    let again = deasim(
        &[
            "modes",
            "film.toml",
            "--count",
            "2",
            "--out",
            "o",
            "--set",
            MASS,
        ],
        &dir,
    );
    assert_eq!(again.status.code(), Some(0), "{}", text(&again));
    let refuse = |args: &[&str]| {
        let out = deasim(args, &dir);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {t}");
        assert!(
            t.contains("o holds the results of `deasim modes` for `film`")
                && t.contains("--overwrite")
                && t.contains("--out"),
            "{args:?}: {t}"
        );
        assert!(!t.contains("panicked"), "{t}");
        assert_eq!(
            names(&dir.join("o")),
            written_with_notes(&written),
            "{args:?}"
        );
        assert_eq!(names(&dir.join("o/modes")), shapes, "{args:?}");
    };
    refuse(&["run", "film.toml", "--out", "o"]);
    refuse(&["lumped", "--out", "o"]);
    refuse(&[
        "modes",
        "film.toml",
        "--count",
        "2",
        "--out",
        "o",
        "--set",
        MASS,
        "--set",
        "name=\"other\"",
    ]);
    refuse(&[
        "response",
        "film.toml",
        "--points",
        "2",
        "--out",
        "o",
        "--set",
        MASS,
    ]);
    // --overwrite: all of the modes' files go, the notes stay
    let run = deasim(
        &[
            "run",
            "film.toml",
            "--out",
            "o",
            "--overwrite",
            "--set",
            "output.plots=false",
        ],
        &dir,
    );
    assert_eq!(run.status.code(), Some(0), "{}", text(&run));
    let now = names(&dir.join("o"));
    assert!(now.contains(&"notes.txt".to_string()), "{now:?}");
    assert!(
        !now.iter().any(|n| n.starts_with("modes")),
        "modes results left: {now:?}"
    );
    // and the run's results are refused to the modes command in turn
    let modes = deasim(
        &[
            "modes",
            "film.toml",
            "--count",
            "2",
            "--out",
            "o",
            "--set",
            MASS,
        ],
        &dir,
    );
    assert_eq!(modes.status.code(), Some(2), "{}", text(&modes));
    assert!(
        text(&modes).contains("holds the results of `deasim run` for `film`"),
        "{}",
        text(&modes)
    );
    assert!(dir.join("o/history.csv").exists());
}

/// The film example has no mass; `modes` and `response` need one.
const MASS: &str = "materials.elastomer.density=1000.0";

fn written_with_notes(written: &[String]) -> Vec<String> {
    let mut v = written.to_vec();
    v.push("notes.txt".into());
    v.sort();
    v
}

/// `modes`, `lumped`, `response` and `material` take the directory's lock: a live lock
/// refuses them (exit 2, naming the process) and they write nothing there.
#[test]
fn every_command_takes_the_directory_lock() {
    let dir = tempdir("lock-all");
    example(&dir, "film");
    std::fs::create_dir_all(dir.join("o")).unwrap();
    let me = std::process::id().to_string();
    std::fs::write(dir.join("o/.deasim.lock"), format!("{me}\n")).unwrap();
    for args in [
        &[
            "modes",
            "film.toml",
            "--count",
            "2",
            "--out",
            "o",
            "--set",
            MASS,
        ][..],
        &["lumped", "--out", "o"],
        &[
            "response",
            "film.toml",
            "--points",
            "2",
            "--out",
            "o",
            "--set",
            MASS,
        ],
        &[
            "material",
            "vhb4910-wang2016",
            "--steps",
            "10",
            "--out",
            "o",
        ],
    ] {
        let out = deasim(args, &dir);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {t}");
        assert!(
            t.contains("o is in use") && t.contains(&format!("process {me}")),
            "{args:?}: {t}"
        );
        assert_eq!(names(&dir.join("o")), [".deasim.lock"], "{args:?}");
    }
}

/// A new run (same scenario with fewer probes, or another one with --overwrite) leaves none of
/// the earlier run's plots, field files or results behind; other files stay.
#[test]
fn a_new_run_clears_the_earlier_runs_files() {
    let dir = tempdir("clear");
    example(&dir, "film");
    example(&dir, "film-vibration");
    let first = deasim(&["run", "film.toml", "--out", "o"], &dir);
    assert_eq!(first.status.code(), Some(0), "{}", text(&first));
    let plots_before = names(&dir.join("o/plots"));
    assert!(plots_before.iter().any(|p| p.starts_with("voltage")));
    std::fs::write(dir.join("o/plots/notes.txt"), "mine").unwrap();
    let other = deasim(
        &[
            "run",
            "film-vibration.toml",
            "--out",
            "o",
            "--overwrite",
            "--set",
            "stages.0.duration=1e-4",
            "--set",
            "output.plots=false",
            "--set",
            "output.fields_every=0",
        ],
        &dir,
    );
    assert_eq!(other.status.code(), Some(0), "{}", text(&other));
    assert_eq!(names(&dir.join("o/plots")), vec!["notes.txt".to_string()]);
    assert_eq!(
        names(&dir.join("o/fields")),
        vec!["step_00000.vtu".to_string()]
    );
    let pvd = std::fs::read_to_string(dir.join("o/fields.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 1, "{pvd}");
}

/// The README's checkpoint example, as written; `--resume` on the finished run says so.
#[test]
fn readme_checkpoint_example_works_as_written() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let line = |prefix: &str| -> Vec<String> {
        let l = readme
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("README has no line `{prefix}…`"));
        let cmd = l.split('#').next().unwrap();
        cmd.split_whitespace().skip(1).map(String::from).collect()
    };
    let run = line("deasim run film.toml --out out --checkpoint-every");
    let resume = line("deasim run --resume out");
    let dir = tempdir("readme");
    example(&dir, "film");
    let args: Vec<&str> = run.iter().map(String::as_str).collect();
    let out = deasim(&args, &dir);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(
        !names(&dir.join("out/checkpoint")).is_empty(),
        "no checkpoint written by {run:?}"
    );
    // the run finished: resuming it says so
    let args: Vec<&str> = resume.iter().map(String::as_str).collect();
    let done = deasim(&args, &dir);
    assert_eq!(done.status.code(), Some(2), "{}", text(&done));
    assert!(text(&done).contains("already finished"), "{}", text(&done));
    // a killed run (no summary yet, the last rows missing) continues to the same results
    let history = std::fs::read_to_string(dir.join("out/history.csv")).unwrap();
    std::fs::remove_file(dir.join("out/summary.json")).unwrap();
    let cut: Vec<&str> = history.lines().take(5).collect();
    std::fs::write(dir.join("out/history.csv"), cut.join("\n") + "\n").unwrap();
    let resumed = deasim(&args, &dir);
    assert_eq!(resumed.status.code(), Some(0), "{}", text(&resumed));
    assert_eq!(
        std::fs::read_to_string(dir.join("out/history.csv")).unwrap(),
        history
    );
}

/// `summary.json` carries the version, the overrides, the solver and per probe `final`, `min`,
/// `max` and, under a periodic drive, the `mean` and `peak_to_peak` of the last full period — the
/// last row of `periods.csv` and the extremes of `history.csv`.
#[test]
fn summary_states_probe_statistics_version_overrides_and_solver() {
    let dir = tempdir("summary-stats");
    let path = example(&dir, "film-vibration");
    let scenario = std::fs::read_to_string(&path).unwrap().replace(
        "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }",
        "voltage = { waveform = \"sine\", amplitude = 20e3, frequency = 400.0 }",
    );
    std::fs::write(&path, scenario).unwrap();
    let o = deasim(
        &[
            "run",
            "film-vibration.toml",
            "--out",
            "o",
            "--set",
            "output.plots=false",
        ],
        &dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(summary["overrides"][0], "output.plots=false");
    assert!(summary["solver"].as_str().is_some_and(|s| !s.is_empty()));
    let date = summary["date"].as_str().unwrap();
    assert!(
        date.len() == 20 && date.ends_with('Z') && &date[10..11] == "T",
        "{date}"
    );
    let hash = summary["scenario_hash"].as_str().unwrap();
    assert!(
        hash.len() == 16 && hash.bytes().all(|b| b.is_ascii_hexdigit()),
        "{hash}"
    );
    let history = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let mut lines = history.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = head
        .iter()
        .position(|h| *h == "probe:thickness_stretch")
        .unwrap();
    let values: Vec<f64> = lines
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    let stats = &summary["probe_stats"]["thickness_stretch"];
    let get = |k: &str| {
        stats[k]
            .as_f64()
            .unwrap_or_else(|| panic!("{k} in {stats}"))
    };
    assert_eq!(get("final"), *values.last().unwrap());
    assert_eq!(get("final"), summary["probes"]["thickness_stretch"]);
    assert_eq!(
        get("min"),
        values.iter().copied().fold(f64::INFINITY, f64::min)
    );
    assert_eq!(
        get("max"),
        values.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    );
    let periods = std::fs::read_to_string(dir.join("o/periods.csv")).unwrap();
    let mut rows = periods.lines();
    let phead: Vec<&str> = rows.next().unwrap().split(',').collect();
    let last: Vec<&str> = rows.last().unwrap().split(',').collect();
    let at = |name: &str| -> f64 {
        let i = phead.iter().position(|h| *h == name).unwrap();
        last[i].parse().unwrap()
    };
    assert!((get("mean") - at("thickness_stretch:mean")).abs() <= 1e-12 * get("mean").abs());
    assert!(
        (get("peak_to_peak") - at("thickness_stretch:peak_to_peak")).abs()
            <= 1e-9 * get("peak_to_peak").abs()
    );
    assert!(get("peak_to_peak") > 0.0);
}

/// Plot axes carry units with metric prefixes and the probe's meaning; a static ramp is drawn
/// against its load factor; a probe is drawn against the voltage only when the voltage moves
/// continuously (under a square wave it jumps, and such a plot would be vertical lines).
#[test]
fn plots_name_units_prefixes_and_the_load_factor() {
    let dir = tempdir("plot-axes");
    example(&dir, "film");
    let set = |k: &str| vec!["--set".to_string(), k.to_string()];
    let run = |out: &str, extra: &[String]| {
        let mut args: Vec<String> = ["run", "film.toml", "--out", out]
            .iter()
            .map(|s| s.to_string())
            .collect();
        args.extend(set("output.plot_format=\"svg\""));
        args.extend(extra.iter().cloned());
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = deasim(&args, &dir);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    };
    let svg = |out: &str, name: &str| {
        std::fs::read_to_string(dir.join(out).join("plots").join(name)).unwrap_or_default()
    };
    run("ramp", &[]);
    let v = svg("ramp", "voltage.svg");
    assert!(v.contains("load factor [-]"), "{v}");
    assert!(v.contains("voltage [kV]"));
    let t = svg("ramp", "thickness_stretch.svg");
    assert!(t.contains("thickness_stretch: 1 + 1000 × mean uz over z1"));
    assert!(t.contains("thickness_stretch [-]"));
    let q = svg("ramp", "charge_vs_voltage.svg");
    assert!(
        q.contains("charge [nC]") && q.contains("voltage [kV]"),
        "{q}"
    );
    assert!(svg("ramp", "capacitance.svg").contains("capacitance [pF]"));

    // the same film driven in real time: a sine (continuous), then a square wave
    let mut drive = set("stages.0.kind=\"quasi-static\"");
    drive.extend(set("stages.0.duration=0.05"));
    let mut sine = drive.clone();
    sine.extend(set(
        "electrodes.top.voltage={waveform=\"sine\",amplitude=20e3,frequency=20.0}",
    ));
    run("sine", &sine);
    assert!(svg("sine", "voltage.svg").contains("time [ms]"));
    assert!(dir.join("sine/plots/charge_vs_voltage.svg").exists());
    let mut square = drive;
    square.extend(set(
        "electrodes.top.voltage={waveform=\"square\",amplitude=20e3,frequency=20.0}",
    ));
    run("square", &square);
    let plots = names(&dir.join("square/plots"));
    assert!(plots.contains(&"charge.svg".to_string()), "{plots:?}");
    assert!(
        !plots.iter().any(|p| p.contains("_vs_voltage")),
        "{plots:?}"
    );
}

/// A run writes `summary.json` with `status = "running"` from its first step on, so that a killed
/// run (SIGKILL: no chance to write the final summary) leaves one that says it did not finish;
/// a finished run's summary says `finished`.
#[test]
fn a_killed_run_leaves_a_summary_that_says_running() {
    let dir = tempdir("killed");
    example(&dir, "diaphragm");
    let mut child = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(["run", "diaphragm.toml", "--out", "d"])
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let path = dir.join("d/summary.json");
    let start = Instant::now();
    while !path.exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(v["status"], "running", "{v}");
    assert_eq!(v["converged"], false);
    assert!(v["error"].as_str().unwrap().contains("has not finished"));
    assert_eq!(v["scenario"], "diaphragm");
    // the film finishes: its summary says so
    example(&dir, "film");
    let out = deasim(&["run", "film.toml", "--out", "f"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("f/summary.json")).unwrap())
            .unwrap();
    assert_eq!(v["status"], "finished");
}
