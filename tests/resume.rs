//! Checkpoint and restart through the command line: writing checkpoints changes no number of a
//! run; a dynamic run killed with SIGKILL and resumed with `--resume` ends with the same
//! `history.csv` (byte for byte) and `summary.json` (everything but wall times) as an
//! uninterrupted run without checkpoints on the same thread count; the same for static ramps (with
//! cut-backs, pre-stretch and a stage change); corrupt, truncated, wrong-version and mismatched
//! checkpoints are refused with exit 2.
//!
//! Tolerance: none (bitwise). The run state holds where the reused (modified Newton) matrices were
//! factored, and a resumed run factors them there again, so it makes the same decisions.

mod common;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn deasim(args: &[&str], dir: &Path) -> Output {
    common::deasim_on_threads(args, dir, "2")
}

fn tempdir(name: &str) -> common::TempDir {
    common::TempDir::new(&format!("deasim-resume-{name}"))
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

fn example(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, deasim(&["example", name], dir).stdout).unwrap();
    p
}

fn checkpoints(out: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(out.join("checkpoint"))
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    v.sort();
    v
}

/// summary.json without its wall times and the linear solver's work counts (a resumed stage
/// factors its start again, and a static one counts its solves from the resume only).
fn summary(out: &Path) -> serde_json::Value {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("wall_s");
    v.as_object_mut().unwrap().remove("date");
    for s in v["stages"].as_array_mut().unwrap() {
        s.as_object_mut().unwrap().remove("wall_s");
        s.as_object_mut().unwrap().remove("linear");
    }
    v
}

/// Asserts that two output directories hold the same results (bitwise).
fn assert_same_results(a: &Path, b: &Path) {
    let ha = std::fs::read_to_string(a.join("history.csv")).unwrap();
    let hb = std::fs::read_to_string(b.join("history.csv")).unwrap();
    assert_eq!(ha.lines().count(), hb.lines().count(), "history rows");
    for (i, (x, y)) in ha.lines().zip(hb.lines()).enumerate() {
        assert_eq!(x, y, "history.csv line {i}");
    }
    assert_eq!(summary(a), summary(b));
    assert_eq!(
        std::fs::read_to_string(a.join("fields.pvd")).unwrap(),
        std::fs::read_to_string(b.join("fields.pvd")).unwrap()
    );
    let files = |d: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(d.join("fields"))
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        v.sort();
        v
    };
    assert_eq!(files(a), files(b), "field files");
}

/// The film-vibration example run for 40 ms (2000 steps of 20 µs) is killed with SIGKILL after
/// its first checkpoint (every 100 steps) and resumed; it ends exactly as an uninterrupted run.
#[test]
fn sigkill_then_resume_equals_an_uninterrupted_dynamic_run() {
    let dir = tempdir("kill");
    let scenario = example(&dir, "film-vibration");
    let args = |out: &str, every: &str| -> Vec<String> {
        [
            "run",
            scenario.to_str().unwrap(),
            "--out",
            out,
            "--checkpoint-every",
            every,
            "--set",
            "stages.0.duration=0.04",
            "--set",
            "output.fields_every=50",
            "--set",
            "output.plots=false",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    // the uninterrupted run writes no checkpoint (an interval longer than the run)
    let full = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(args("full", "1000000"))
        .current_dir(&dir)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap();
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
    assert!(text(&full).contains("2 thread(s)"), "{}", text(&full));

    assert!(checkpoints(&dir.join("full")).is_empty());
    let mut child = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(args("killed", "100"))
        .current_dir(&dir)
        .env("RAYON_NUM_THREADS", "2")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let out = dir.join("killed");
    let start = Instant::now();
    while checkpoints(&out).is_empty() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(!checkpoints(&out).is_empty(), "no checkpoint written");
    // some steps past the checkpoint, then SIGKILL (no handler can run)
    std::thread::sleep(Duration::from_millis(300));
    child.kill().unwrap();
    let status = child.wait().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(9), "the run ended before the kill");
    // the killed run's summary says it did not finish (and does not stop the resume)
    let killed = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(killed.contains("\"status\": \"running\""), "{killed}");
    let last = checkpoints(&out).last().unwrap().clone();
    let step: usize = last.file_stem().unwrap().to_str().unwrap()[11..]
        .parse()
        .unwrap();
    assert!(step > 0 && step < 2000, "{step}");
    eprintln!("killed after checkpoint {}", last.display());

    let resumed = deasim(&["run", "--resume", "killed"], &dir);
    assert_eq!(resumed.status.code(), Some(0), "{}", text(&resumed));
    assert!(text(&resumed).contains("resuming"), "{}", text(&resumed));
    assert_same_results(&dir.join("full"), &out);
    let s = summary(&out);
    assert_eq!(s["converged"], true);
    assert_eq!(s["stages"][0]["steps"], 2000);
}

/// A run that writes a checkpoint every 7 steps gives the same numbers, bit for bit, as one that
/// writes none: midpoint, Newmark and trapezoidal film vibration, and the default diaphragm's
/// pre-stretch, load and actuation stages (shortened).
#[test]
fn checkpoints_change_no_number() {
    let dir = tempdir("nochange");
    let cases: [(&str, &[&str]); 4] = [
        ("film-vibration", &["stages.0.duration=0.002"]),
        (
            "film-vibration",
            &["stages.0.duration=0.002", "stages.0.integrator=newmark"],
        ),
        (
            "film-vibration",
            &[
                "stages.0.duration=0.0005",
                "stages.0.integrator=trapezoidal",
                "stages.0.dt=1e-6",
            ],
        ),
        ("diaphragm", &["stages.1.duration=0.05"]),
    ];
    for (i, (name, sets)) in cases.iter().enumerate() {
        let path = example(&dir, name);
        let run = |out: &str, every: Option<&str>| {
            let mut args = vec![
                "run",
                path.to_str().unwrap(),
                "--out",
                out,
                "--set",
                "output.plots=false",
            ];
            for s in *sets {
                args.extend(["--set", s]);
            }
            if let Some(k) = every {
                args.extend(["--checkpoint-every", k]);
            }
            let o = deasim(&args, &dir);
            assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        };
        let (plain, with) = (format!("plain{i}"), format!("with{i}"));
        run(&plain, None);
        run(&with, Some("7"));
        // every integrator reports its linear work: a solve per Newton iteration at least (the
        // explicit scheme's come from its electrostatic solves), and some factorisation
        let full: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(&plain).join("summary.json")).unwrap(),
        )
        .unwrap();
        for stage in full["stages"].as_array().unwrap() {
            if stage["kind"] != "dynamic" {
                continue;
            }
            let count = |key: &str| stage["linear"][key].as_u64().unwrap();
            let newton = stage["newton_iterations"].as_u64().unwrap();
            assert!(newton > 0 && count("solves") >= newton, "{sets:?}: {stage}");
            assert!(
                count("factorizations") >= 1 && count("factorizations") <= count("solves"),
                "{sets:?}: {stage}"
            );
        }
        assert!(!checkpoints(&dir.join(&with)).is_empty(), "{name} {sets:?}");
        assert_same_results(&dir.join(&plain), &dir.join(&with));
    }
}

/// Runs `args` with checkpoints every `k` steps, then simulates a kill after the older of the two
/// kept checkpoints: the newest checkpoint, the summary and the last rows of history.csv are
/// removed and a stray field file is added; `--resume` must rebuild exactly the full results.
fn resume_from_older_checkpoint(name: &str, scenario: &str, k: &str, sets: &[&str]) -> Output {
    let dir = tempdir(name);
    let path = example(&dir, scenario);
    resume_older(&dir, &path, k, sets)
}

/// [`resume_from_older_checkpoint`] of the scenario file `path` in `dir`.
fn resume_older(dir: &Path, path: &Path, k: &str, sets: &[&str]) -> Output {
    let dir = dir.to_path_buf();
    let mut args = vec![
        "run",
        path.to_str().unwrap(),
        "--out",
        "full",
        "--checkpoint-every",
        k,
        "--set",
        "output.plots=false",
    ];
    for s in sets {
        args.extend(["--set", s]);
    }
    let full = deasim(&args, &dir);
    let ck = checkpoints(&dir.join("full"));
    assert_eq!(ck.len(), 2, "{}", text(&full));
    let copy = dir.join("cut");
    std::fs::create_dir_all(copy.join("checkpoint")).unwrap();
    std::fs::create_dir_all(copy.join("fields")).unwrap();
    std::fs::copy(
        &ck[0],
        copy.join("checkpoint").join(ck[0].file_name().unwrap()),
    )
    .unwrap();
    let history = std::fs::read_to_string(dir.join("full/history.csv")).unwrap();
    let kept: Vec<&str> = history.lines().collect();
    std::fs::write(copy.join("history.csv"), kept[..kept.len() - 1].join("\n")).unwrap();
    for e in std::fs::read_dir(dir.join("full/fields"))
        .unwrap()
        .flatten()
    {
        std::fs::copy(e.path(), copy.join("fields").join(e.file_name())).unwrap();
    }
    std::fs::write(copy.join("fields/step_99999.vtu"), "stale").unwrap();
    let resumed = deasim(&["run", "--resume", "cut"], &dir);
    assert_eq!(
        resumed.status.code(),
        full.status.code(),
        "{}",
        text(&resumed)
    );
    assert_same_results(&dir.join("full"), &copy);
    full
}

/// Two static stages (a ramp, then a hold) resumed from the checkpoint taken at the end of the
/// first: the field files hold the state at the end of every stage (here the 4th record, which
/// `fields_every = 3` alone would skip) in the uninterrupted and in the resumed run alike.
#[test]
fn stage_ends_are_in_the_field_files_also_after_a_resume() {
    let dir = tempdir("stage-ends");
    let path = example(&dir, "film");
    let scenario = std::fs::read_to_string(&path).unwrap().replace(
        "name = \"charge\"\nkind = \"static\"\nsteps = 15\n",
        "name = \"charge\"\nkind = \"static\"\nsteps = 4\n\n[[stages]]\nname = \"hold\"\n\
         kind = \"static\"\nsteps = 4\n",
    );
    assert!(scenario.contains("name = \"hold\""));
    std::fs::write(&path, scenario).unwrap();
    let full = resume_older(&dir, &path, "4", &["output.fields_every=3"]);
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
    let pvd = std::fs::read_to_string(dir.join("full/fields.pvd")).unwrap();
    let history = std::fs::read_to_string(dir.join("full/history.csv")).unwrap();
    let times: Vec<&str> = history
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(times.len(), 9, "{history}");
    // records 0, 3, 6 by `fields_every`, 4 and 8 as stage ends
    let entries = pvd.matches("<DataSet").count();
    assert_eq!(entries, 5, "{pvd}");
    let t4: f64 = times[4].parse().unwrap();
    assert!(
        pvd.contains(&format!("timestep=\"{t4}\"")),
        "no entry at the end of the first stage (t = {t4}): {pvd}"
    );
}

/// Static ramp of the film (15 load steps), resumed from the checkpoint at step 8.
#[test]
fn static_ramp_resumes_bitwise() {
    let full = resume_from_older_checkpoint("static", "film", "4", &[]);
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
}

/// A volume-controlled ramp: the pressure (the bordering unknown) continues from the checkpoint.
#[test]
fn volume_controlled_ramp_resumes_bitwise() {
    let full = resume_from_older_checkpoint("volume", "balloon-volume", "20", &[]);
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
}

/// The pull-in ramp (cut-backs near the limit point, ends with exit 1) resumed from a checkpoint
/// taken after cut-backs: the reduced increment is part of the checkpoint.
#[test]
fn pull_in_ramp_with_cutbacks_resumes_bitwise() {
    let full = resume_from_older_checkpoint("pullin", "film-pull-in", "3", &[]);
    assert_eq!(full.status.code(), Some(1), "{}", text(&full));
}

/// Newmark (consistent initial acceleration not recomputed on resume) and the explicit
/// trapezoidal scheme (no first projection on resume).
#[test]
fn newmark_and_trapezoidal_resume_bitwise() {
    resume_from_older_checkpoint(
        "newmark",
        "film-vibration",
        "40",
        &["stages.0.integrator=newmark", "stages.0.duration=0.004"],
    );
    resume_from_older_checkpoint(
        "trapezoidal",
        "film-vibration",
        "40",
        &[
            "stages.0.integrator=trapezoidal",
            "stages.0.duration=0.0004",
            "stages.0.dt=1e-6",
        ],
    );
}

/// Newton on the exact step Jacobian keeps a factor across steps: a resumed run re-factors where
/// it was made and takes the same decisions (a viscous film and the viscous diaphragm).
#[test]
fn exact_jacobian_runs_resume_bitwise() {
    resume_from_older_checkpoint(
        "exact-film",
        "film-vibration",
        "40",
        &[
            "solver.jacobian=exact",
            "materials.elastomer.viscosity=100",
            "stages.0.duration=0.004",
        ],
    );
    resume_from_older_checkpoint(
        "exact-diaphragm",
        "diaphragm",
        "100",
        &["solver.jacobian=exact", "stages.1.duration=0.25"],
    );
}

/// A corrupt newest checkpoint: the run continues from the older one kept for this case, with a
/// warning naming the corrupt file and why, to the same results. All checkpoints corrupt, another
/// format version, a mismatched scenario or overrides, a missing checkpoint: exit 2, a message
/// naming the problem, the directory's files untouched. A finished run is not resumed.
#[test]
fn bad_checkpoints_are_refused() {
    let dir = tempdir("bad");
    let path = example(&dir, "film");
    let full = deasim(
        &[
            "run",
            path.to_str().unwrap(),
            "--out",
            "o",
            "--checkpoint-every",
            "5",
            "--set",
            "output.plots=false",
        ],
        &dir,
    );
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
    // the run finished
    let done = deasim(&["run", "--resume", "o"], &dir);
    assert_eq!(done.status.code(), Some(2), "{}", text(&done));
    assert!(text(&done).contains("already finished"), "{}", text(&done));
    // from here on as after a kill -9 at the end: no summary.json
    std::fs::remove_file(dir.join("o/summary.json")).unwrap();
    let ck = checkpoints(&dir.join("o"));
    assert_eq!(ck.len(), 2);
    let (older, newest) = (ck[0].clone(), ck[1].clone());
    let good = std::fs::read(&newest).unwrap();
    let good_older = std::fs::read(&older).unwrap();
    let history = std::fs::read(dir.join("o/history.csv")).unwrap();
    let refuse = |bytes: &[u8], extra: &[&str], expect: &str| {
        std::fs::write(&newest, bytes).unwrap();
        let mut args = vec!["run", "--resume", "o"];
        args.extend(extra);
        let out = deasim(&args, &dir);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out));
        assert!(text(&out).contains(expect), "{expect}: {}", text(&out));
        assert!(!text(&out).contains("panicked"), "{}", text(&out));
        assert_eq!(std::fs::read(dir.join("o/history.csv")).unwrap(), history);
    };
    let fall_back = |bytes: &[u8], expect: &str| {
        std::fs::write(&newest, bytes).unwrap();
        let out = deasim(&["run", "--resume", "o"], &dir);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
        let t = text(&out);
        assert!(
            t.contains("warning: skipping a corrupt checkpoint")
                && t.contains(newest.file_name().unwrap().to_str().unwrap())
                && t.contains(expect)
                && t.contains(older.file_name().unwrap().to_str().unwrap()),
            "{expect}: {t}"
        );
        assert!(!t.contains("panicked"), "{t}");
        // resumed from the older checkpoint to the same results
        assert_eq!(std::fs::read(dir.join("o/history.csv")).unwrap(), history);
        std::fs::remove_file(dir.join("o/summary.json")).unwrap();
        std::fs::write(&older, &good_older).unwrap();
    };
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x01;
    fall_back(&flipped, "checksum");
    fall_back(&good[..good.len() - 7], "truncated");
    fall_back(&good[..5], "truncated");
    fall_back(
        b"not a checkpoint at all, just text",
        "not a deasim checkpoint",
    );
    // every checkpoint corrupt: refused, listing them and saying how to start over
    std::fs::write(&older, b"garbage").unwrap();
    std::fs::write(&newest, &flipped).unwrap();
    let out = deasim(&["run", "--resume", "o"], &dir);
    std::fs::write(&older, &good_older).unwrap();
    let t = text(&out);
    assert_eq!(out.status.code(), Some(2), "{t}");
    assert!(
        t.contains("no valid checkpoint")
            && t.contains(older.file_name().unwrap().to_str().unwrap())
            && t.contains(newest.file_name().unwrap().to_str().unwrap())
            && t.contains("without --resume"),
        "{t}"
    );
    let mut version = good.clone();
    version[8] = 99;
    refuse(&version, &[], "format version 99");
    // a different scenario or overrides given again
    let other = dir.join("other.toml");
    std::fs::write(&other, deasim(&["example", "film-pull-in"], &dir).stdout).unwrap();
    refuse(
        &good,
        &[other.to_str().unwrap()],
        "differs from the scenario",
    );
    // one space between the words of the message, not a run of blanks
    refuse(
        &good,
        &[other.to_str().unwrap()],
        "resume without a scenario argument",
    );
    refuse(
        &good,
        &["--set", "stages.0.steps=3"],
        "differs from the stored",
    );
    refuse(
        &good,
        &["--checkpoint-every", "7"],
        "differs from the interval",
    );
    // the same scenario file is accepted
    std::fs::write(&newest, &good).unwrap();
    let ok = deasim(&["run", "--resume", "o", path.to_str().unwrap()], &dir);
    assert_eq!(ok.status.code(), Some(0), "{}", text(&ok));
    // no checkpoint at all
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let out = deasim(&["run", "--resume", "empty"], &dir);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("no checkpoint"), "{}", text(&out));
    // a fresh run into the directory removes the old checkpoints
    let again = deasim(&["run", path.to_str().unwrap(), "--out", "o"], &dir);
    assert_eq!(again.status.code(), Some(0), "{}", text(&again));
    assert!(checkpoints(&dir.join("o")).is_empty());
}

/// SIGINT writes a checkpoint at the stop (exit 130); resuming from it completes the run
/// (exit 0) with every step recorded once. (Not bitwise: the uninterrupted run had no
/// re-factorisation at that step; the probes agree to the Newton tolerance.)
#[test]
fn sigint_checkpoint_resumes_to_completion() {
    let dir = tempdir("sigint");
    let scenario = example(&dir, "film-vibration");
    let child = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args([
            "run",
            scenario.to_str().unwrap(),
            "--out",
            "o",
            "--checkpoint-every",
            "100000",
            "--set",
            "stages.0.duration=0.02",
            "--set",
            "output.fields_every=100",
            "--set",
            "output.plots=false",
        ])
        .current_dir(&dir)
        .env("RAYON_NUM_THREADS", "2")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !dir.join("o/history.csv").exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(300));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", text(&out));
    let said = text(&out);
    assert!(
        said.contains("stopped on request") && !said.contains("FAILED"),
        "{said}"
    );
    assert_eq!(checkpoints(&dir.join("o")).len(), 1);
    let resumed = deasim(&["run", "--resume", "o"], &dir);
    assert_eq!(resumed.status.code(), Some(0), "{}", text(&resumed));
    // a log (not a terminal) shows the position, the share done and the time left
    let log = text(&resumed);
    assert!(
        log.contains(" steps, ") && log.contains(" %") && log.contains("ETA"),
        "{log}"
    );
    let h = std::fs::read_to_string(dir.join("o/history.csv")).unwrap();
    let steps: Vec<usize> = h
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(steps, (0..=1000).collect::<Vec<_>>());
    let s = summary(&dir.join("o"));
    assert_eq!(s["converged"], true);
    assert!(s.get("error").is_none(), "{s}");
}

/// Materials with internal variables: the pull-in ramp of the film with a Maxwell branch (cut-backs
/// near the rate-dependent limit point; the branches' state is part of the checkpoint) and the film
/// vibration with a fast branch (the branches evolve in the dynamic stage) both resume bit for bit.
#[test]
fn viscoelastic_runs_resume_bitwise() {
    let full = resume_from_older_checkpoint(
        "visco-pullin",
        "film-pull-in",
        "3",
        &["materials.elastomer.branches=[{mu=3e4,tau=0.1}]"],
    );
    assert_eq!(full.status.code(), Some(1), "{}", text(&full));
    resume_from_older_checkpoint(
        "visco-dynamic",
        "film-vibration",
        "40",
        &[
            "materials.elastomer.branches=[{mu=5e4,tau=1e-3}]",
            "stages.0.duration=0.004",
        ],
    );
}

/// The vibrating film driven through a circuit (20 kV behind 10⁸ Ω), resumed from the
/// checkpoint at step 60: the step matrix refactored at its factor point carries the circuit's
/// coupling as the run had it, so the resumed run continues bit for bit.
#[test]
fn a_circuit_driven_vibration_resumes_bitwise() {
    let step = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    vibration_resumes("circuit", |text| {
        common::circuit_instead_of(text, step, step, 1e8)
    });
}

/// `film-vibration`, its scenario changed by `edit`, run for 2 ms with Kelvin–Voigt damping and
/// resumed from the checkpoint at step 30 (in a directory named `name`): the same results.
fn vibration_resumes(name: &str, edit: impl Fn(&str) -> String) {
    let dir = tempdir(name);
    let path = example(&dir, "film-vibration");
    let original = std::fs::read_to_string(&path).unwrap();
    let scenario = edit(&original);
    assert_ne!(scenario, original);
    std::fs::write(&path, scenario).unwrap();
    let full = resume_older(
        &dir,
        &path,
        "30",
        &[
            "stages.0.duration=0.002",
            "materials.elastomer.viscosity=50",
        ],
    );
    assert_eq!(full.status.code(), Some(0), "{}", text(&full));
}

/// A vibration driven by a charge waveform resumes bit for bit: the drive gives each step its
/// charge from the stage time, and the energy balance's record of the source's work is in the
/// checkpoint.
#[test]
fn a_charge_driven_vibration_resumes_bitwise() {
    vibration_resumes("charge-drive", |text| {
        text.replace(
            "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }",
            "charge = { waveform = \"sine\", amplitude = 4e-8, offset = 2e-8, frequency = 500.0 }",
        )
    });
}
