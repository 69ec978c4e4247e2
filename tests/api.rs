//! The library interface as a program uses it: build a simulation, override keys, run it, cancel
//! it, read its results, and receive each kind of error, without the command line.

use deasim::api::{
    read_checkpoint, run_plan, Cancel, Error, FieldsKept, History, RankOptions, RankRun,
    RunOptions, Simulation,
};
use deasim::element::CellFields;
use deasim::job::observer::Observer;
use deasim::job::plan::Plan;
use deasim::job::state::{RunSummary, StepRecord};

/// The film example, ramped in 15 steps to 30 kV below its pull-in voltage 33.695 kV.
fn film() -> Simulation {
    Simulation::from_example("film").expect("the film example is embedded")
}

#[test]
fn a_run_gives_its_history_probes_and_fields() {
    let results = film()
        .set("stages.0.steps", "5")
        .run(RunOptions {
            fields: FieldsKept::Last,
            ..RunOptions::default()
        })
        .expect("the film converges");
    assert!(results.summary.converged);
    // the state the stage starts from and its five steps
    assert_eq!(results.records.len(), 6);
    let time = results.history.column("time").expect("a time column");
    assert_eq!(time.len(), 6);
    let voltage = results.history.column("voltage").unwrap();
    assert!((voltage[5] - 30e3).abs() < 1e-6, "{voltage:?}");
    // the probes' columns and statistics agree with the records
    let stretch = results.history.column("probe:thickness_stretch").unwrap();
    let stats = results.probe("thickness_stretch").unwrap();
    assert_eq!(stats.first, stretch[0]);
    assert_eq!(stats.last, stretch[5]);
    assert_eq!(stats.min, stats.last, "the film thins monotonically");
    assert!(stats.last < 0.9 && stats.last > 0.5, "{stats:?}");
    assert_eq!(results.history.stage, vec!["charge".to_string(); 6]);
    // the last step's nodal values and cell fields
    assert_eq!(results.fields.len(), 1);
    let last = &results.fields[0];
    assert_eq!(last.record, 5);
    let plan = film().plan().unwrap();
    assert_eq!(last.nodal.len(), plan.model.mesh.n_nodes() * 4);
    assert_eq!(last.cells.len(), plan.model.mesh.n_cells());
    assert!(last.cells.iter().all(|c| c.j > 0.0 && c.e_max > 0.0));
}

#[test]
fn an_override_changes_the_run() {
    let low = film()
        .set("electrodes.top.voltage.amplitude", "10e3")
        .set("stages.0.steps", "2")
        .run(RunOptions::default())
        .unwrap();
    let high = film()
        .set("stages.0.steps", "2")
        .run(RunOptions::default())
        .unwrap();
    let v = |r: &deasim::api::Results| *r.history.column("voltage").unwrap().last().unwrap();
    assert!((v(&low) - 10e3).abs() < 1e-6 && (v(&high) - 30e3).abs() < 1e-6);
    let t = |r: &deasim::api::Results| r.probe("thickness_stretch").unwrap().last;
    assert!(t(&low) > t(&high));
}

/// Cancels the run when it has seen `after` steps.
struct CancelAfter {
    cancel: Cancel,
    after: usize,
    seen: usize,
}

impl Observer for CancelAfter {
    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[CellFields]) {
        self.seen += 1;
        if self.seen == self.after {
            self.cancel.cancel();
        }
    }
    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}

#[test]
fn a_cancelled_run_keeps_its_accepted_steps() {
    let cancel = Cancel::new();
    let mut watcher = CancelAfter {
        cancel: cancel.clone(),
        after: 3,
        seen: 0,
    };
    let error = film()
        .run(RunOptions {
            observers: vec![&mut watcher],
            cancel: Some(cancel.clone()),
            ..RunOptions::default()
        })
        .expect_err("the run is cancelled");
    let Error::Interrupted { reason, results } = &error else {
        panic!("not an interruption: {error:?}");
    };
    assert!(reason.contains("cancelled"), "{reason}");
    assert!(results.summary.interrupted && !results.summary.converged);
    // the step that saw the cancel was accepted; none after it
    assert_eq!(results.records.len(), 3);
    assert_eq!(watcher.seen, 3);
    assert!(cancel.is_cancelled());
    // the token belongs to that run: the next run on this thread is not cancelled
    let again = film().set("stages.0.steps", "1").run(RunOptions::default());
    assert!(again.is_ok(), "{:?}", again.err());
}

#[test]
fn bad_input_names_its_key() {
    let error = film()
        .set("materials.elastomer.mu", "-1")
        .plan()
        .expect_err("a negative modulus is refused");
    assert!(matches!(error, Error::Input(_)), "{error:?}");
    assert_eq!(error.key(), Some("materials.elastomer.mu"));
    let unknown = film()
        .set("materials.elastomer.muu", "1")
        .plan()
        .unwrap_err();
    assert!(matches!(unknown, Error::Input(_)));
    assert!(unknown.to_string().contains("muu"), "{unknown}");
    let example = Simulation::from_example("no-such-example").unwrap_err();
    assert!(example.to_string().contains("film"), "{example}");
    let text = Simulation::from_toml("name = 3", None).plan().unwrap_err();
    assert!(matches!(text, Error::Input(_)), "{text:?}");
}

/// Dropping the overrides gives the scenario as read: its text, its name in errors and its
/// base directory stay.
#[test]
fn without_overrides_keeps_the_scenario_as_read() {
    let bad = film().set("materials.elastomer.mu", "-1");
    assert!(bad.plan().is_err());
    let plain = bad.without_overrides();
    assert!(plain.overrides().is_empty());
    assert_eq!(plain.text(), bad.text());
    assert!(plain.plan().is_ok());
    let again = plain
        .with_overrides(&["materials.elastomer.muu=1".into()])
        .plan()
        .unwrap_err();
    assert!(again.to_string().starts_with("<embedded film>"), "{again}");
}

#[test]
fn a_missing_file_is_an_io_error() {
    let path = std::path::Path::new("/nonexistent/deasim/scenario.toml");
    match Simulation::from_file(path) {
        Err(Error::Io { path: p, message }) => {
            assert_eq!(p, path);
            assert!(message.contains("cannot read"), "{message}");
        }
        other => panic!("not an I/O error: {other:?}"),
    }
    // an output directory that cannot be created
    let scratch = tempfile::tempdir().unwrap();
    let blocker = scratch.path().join("blocker");
    std::fs::write(&blocker, "a file, not a directory").unwrap();
    let error = film()
        .set("stages.0.steps", "1")
        .run(RunOptions {
            out: Some(blocker.join("out")),
            ..RunOptions::default()
        })
        .unwrap_err();
    assert!(matches!(error, Error::Io { .. }), "{error:?}");
}

#[test]
fn a_failed_solve_gives_its_reason_and_the_steps_before() {
    // beyond the closed-form pull-in voltage 33.695 kV
    let error = film()
        .set("electrodes.top.voltage.amplitude", "40e3")
        .set("stages.0.steps", "8")
        .run(RunOptions::default())
        .expect_err("the film pulls in");
    let Error::Solve { reason, results } = &error else {
        panic!("not a solve failure: {error:?}");
    };
    assert!(reason.contains("pull-in"), "{reason}");
    assert!(!results.summary.converged);
    let v = results.history.column("voltage").unwrap();
    // the last converged voltage lies just below the closed-form pull-in voltage
    let last = *v.last().unwrap();
    assert!(last > 33.6e3 && last < 33.7e3, "{v:?}");
}

#[test]
fn a_run_with_an_output_directory_writes_the_files_of_deasim_run() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("out");
    let results = film()
        .set("stages.0.steps", "2")
        .run(RunOptions {
            out: Some(dir.clone()),
            ..RunOptions::default()
        })
        .unwrap();
    let history = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 1 + results.records.len());
    let summary = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    assert!(summary.contains("stages.0.steps=2"), "{summary}");
}

#[test]
fn newton_and_step_control_come_from_the_scenario() {
    let plan = film()
        .set("solver.newton_rtol", "1e-6")
        .set("solver.newton_max_iterations", "40")
        .set("solver.line_search_halvings", "3")
        .set("solver.min_step_fraction", "0.01")
        .plan()
        .unwrap();
    assert_eq!(plan.newton.rtol, 1e-6);
    assert_eq!(plan.newton.max_iterations, 40);
    assert_eq!(plan.newton.max_backtracks, 3);
    assert_eq!(plan.step_control.min_fraction, 0.01);
    // a looser tolerance takes fewer iterations to the same voltages
    let iterations = |sim: Simulation| -> f64 {
        let r = sim
            .set("stages.0.steps", "3")
            .run(RunOptions::default())
            .unwrap();
        r.history.column("newton_iterations").unwrap().iter().sum()
    };
    assert!(iterations(film().set("solver.newton_rtol", "1e-4")) < iterations(film()));
    // one iteration per step cannot follow the nonlinear film: the stages use the plan's Newton
    let error = film()
        .set("solver.newton_max_iterations", "1")
        .set("solver.min_step_fraction", "0.5")
        .run(RunOptions::default())
        .unwrap_err();
    assert!(matches!(error, Error::Solve { .. }), "{error:?}");
    for (key, value) in [
        ("solver.newton_rtol", "2"),
        ("solver.newton_max_iterations", "0"),
        ("solver.line_search_halvings", "-1"),
        ("solver.min_step_fraction", "0"),
    ] {
        let e = film().set(key, value).plan().unwrap_err();
        assert_eq!(e.key(), Some(key), "{e}");
    }
    // the exact step Jacobian is preconditioned by a factor: not with an iterative solver
    let e = film()
        .set("solver.jacobian", "\"exact\"")
        .set("solver.kind", "\"iterative\"")
        .plan()
        .unwrap_err();
    assert_eq!(e.key(), Some("solver.jacobian"), "{e}");
    assert!(e.to_string().contains("auto"), "{e}");
}

#[test]
fn the_small_signal_base_state_uses_the_plans_newton() {
    // the film with a Maxwell branch, charged instantaneously: its relaxed state, about which
    // the small-signal analyses linearise, lies a static solve away
    let visco = |max_iterations: &str| {
        film()
            .set("materials.elastomer.branches", "[{ mu = 1e5, tau = 1.0 }]")
            .set("stages.0.steps", "2")
            .set("electrodes.top.voltage.amplitude", "15e3")
            .set("solver.newton_max_iterations", max_iterations)
            .set("solver.min_step_fraction", "1")
    };
    let charged = visco("25")
        .run(RunOptions {
            fields: FieldsKept::Last,
            ..RunOptions::default()
        })
        .unwrap();
    let state = &charged.fields[0].nodal;
    let (_, relaxed) = deasim::job::linear::base_state(&visco("25").plan().unwrap(), state)
        .expect("the relaxed state converges");
    let moved = relaxed
        .iter()
        .zip(state)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-6, "the relaxed state is another state: {moved}");
    let error = deasim::job::linear::base_state(&visco("1").plan().unwrap(), state).unwrap_err();
    assert!(error.contains("relaxed state was not reached"), "{error}");
}

/// Asserts that two histories are the same, bit for bit (a NaN equals a NaN).
fn assert_same_history(a: &History, b: &History) {
    assert_eq!(a.stage, b.stage);
    assert_eq!(a.names(), b.names());
    for ((name, x), (_, y)) in a.columns.iter().zip(&b.columns) {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(x), bits(y), "column {name}: {x:?} vs {y:?}");
    }
}

/// The film ramped in 8 steps with plots off: the scenario of the checkpoint tests.
fn film_to_resume() -> Simulation {
    film()
        .set("stages.0.steps", "8")
        .set("output.plots", "false")
}

/// Runs [`film_to_resume`] into `dir` with a checkpoint every 3 steps, cancelled after
/// `after` accepted steps (no cancel: `None`).
fn checkpointed_run(dir: &std::path::Path, after: Option<usize>) -> RankRun {
    let cancel = Cancel::new();
    let mut watcher = CancelAfter {
        cancel: cancel.clone(),
        after: after.unwrap_or(usize::MAX),
        seen: 0,
    };
    film_to_resume()
        .run_on_ranks(RankOptions {
            out: Some(dir.to_path_buf()),
            checkpoint_every: Some(3),
            observers: vec![&mut watcher],
            cancel: Some(cancel),
            ..RankOptions::default()
        })
        .expect("the run starts")
}

#[test]
fn a_run_on_the_ranks_of_one_process_writes_the_files_of_deasim_run() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("out");
    let run = checkpointed_run(&dir, None);
    assert_eq!((run.rank, run.ranks), (0, 1));
    assert_eq!(run.dir, dir);
    let results = run.outcome.expect("the film converges");
    assert_eq!(results.records.len(), 9);
    let history = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 1 + results.records.len());
    let summary = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    assert!(summary.contains("stages.0.steps=8"), "{summary}");
    assert!(dir.join("checkpoint").is_dir(), "no checkpoints written");
    // a finished run has nothing to resume
    let error = read_checkpoint(&dir).expect_err("the run finished");
    assert!(matches!(error, Error::Refused(_)), "{error:?}");
    assert!(error.to_string().contains("already finished"), "{error}");
    // another scenario's results are refused without `overwrite`
    let error = Simulation::from_example("diaphragm")
        .unwrap()
        .run_on_ranks(RankOptions {
            out: Some(dir.clone()),
            ..RankOptions::default()
        })
        .expect_err("the directory holds the film's results");
    assert!(matches!(error, Error::Refused(_)), "{error:?}");
    // a directory that does not exist holds no checkpoint
    let error = read_checkpoint(&scratch.path().join("none")).unwrap_err();
    assert!(error.to_string().contains("no such directory"), "{error}");
}

#[test]
fn a_run_resumed_through_the_library_equals_the_uninterrupted_run() {
    let uninterrupted = film_to_resume().run(RunOptions::default()).unwrap();
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("cut");
    let run = checkpointed_run(&dir, Some(5));
    let Err(Error::Interrupted { results, .. }) = run.outcome else {
        panic!("not cancelled: {:?}", run.outcome);
    };
    assert_eq!(results.records.len(), 5);
    // in this process: the state from the checkpoint, checked against the rebuilt plan
    let resume = read_checkpoint(&dir).expect("a checkpoint to resume from");
    assert!(resume.state().accepted >= 3, "{resume:?}");
    assert_eq!(resume.every(), 3);
    let sim = resume.simulation();
    assert_eq!(sim.overrides(), film_to_resume().overrides());
    let plan = sim.plan().unwrap();
    let start = resume.start(&plan).expect("the checkpoint fits its plan");
    let resumed = run_plan(
        &plan,
        RunOptions {
            start: Some(start),
            ..RunOptions::default()
        },
    )
    .expect("the resumed run converges");
    assert_same_history(&resumed.history, &uninterrupted.history);
    assert_eq!(resumed.records.len(), 9);
    // the plan of another model does not take the checkpoint's state
    let other = film_to_resume()
        .set("mesh.divisions", "[4, 4, 3]")
        .plan()
        .unwrap();
    let Err(error) = resume.start(&other) else {
        panic!("the state of a 4 × 4 × 2 mesh taken by a 4 × 4 × 3 one");
    };
    assert!(matches!(error, Error::Refused(_)), "{error:?}");
    assert!(error.to_string().contains("does not match"), "{error}");
    // the interval of the checkpoints is the run's own
    let error = resume
        .run_on_ranks(RankOptions {
            checkpoint_every: Some(4),
            ..RankOptions::default()
        })
        .expect_err("another interval");
    assert!(error.to_string().contains("interval"), "{error}");
    // in its output directory, as `deasim run --resume`: the files of an uninterrupted run
    let resume = read_checkpoint(&dir).unwrap();
    let run = resume.run_on_ranks(RankOptions::default()).unwrap();
    let results = run.outcome.expect("the resumed run converges");
    assert_same_history(&results.history, &uninterrupted.history);
    let whole = scratch.path().join("whole");
    checkpointed_run(&whole, None).outcome.unwrap();
    let csv = |d: &std::path::Path| std::fs::read_to_string(d.join("history.csv")).unwrap();
    assert_eq!(csv(&dir), csv(&whole));
}

/// Keeps the messages the library reports through the `log` facade.
struct Captured(std::sync::Mutex<Vec<String>>);

impl log::Log for Captured {
    fn enabled(&self, _: &log::Metadata) -> bool {
        true
    }
    fn log(&self, record: &log::Record) {
        if let Ok(mut lines) = self.0.lock() {
            lines.push(record.args().to_string());
        }
    }
    fn flush(&self) {}
}

static CAPTURED: Captured = Captured(std::sync::Mutex::new(Vec::new()));

#[test]
fn a_run_on_the_ranks_reports_through_the_log_facade() {
    log::set_logger(&CAPTURED).expect("the only logger of these tests");
    log::set_max_level(log::LevelFilter::Info);
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("logged");
    checkpointed_run(&dir, Some(2)).outcome.unwrap_err();
    read_checkpoint(&dir)
        .unwrap()
        .run_on_ranks(RankOptions::default())
        .unwrap()
        .outcome
        .unwrap();
    let lines = CAPTURED.0.lock().unwrap().clone();
    let of_this_run = |start: &str| {
        lines
            .iter()
            .any(|l| l.starts_with(start) && l.contains(&dir.display().to_string()))
    };
    assert!(
        of_this_run("deasim: scenario `film`: 75 nodes, 32 hex8 cells, 300 dofs"),
        "{lines:#?}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("deasim: linear solver: ")),
        "{lines:#?}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("deasim: resuming `film` from step 1 (stage 0, 2 steps")),
        "{lines:#?}"
    );
}
