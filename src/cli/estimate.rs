//! `deasim check`'s estimate of a run's wall time and disk use: the first steps of the run are
//! solved in a scratch directory, and their time per step and field file size are scaled to the
//! whole run.

use crate::element::CellFields;
use crate::io::output::OutputWriter;
use crate::job::observer::Observer;
use crate::job::plan::Plan;
use crate::job::run::run_with;
use crate::job::state::RunSummary;
use crate::job::state::StepRecord;
use std::path::Path;
use std::time::{Duration, Instant};

/// Accepted steps the trial times at least in the last stage that takes steps.
const TRIAL_STEPS: usize = 5;
/// The trial stops after the first step that ends past this wall time.
const TRIAL_TIME: Duration = Duration::from_secs(10);
/// Wall time the trial spends in the last stage that takes steps (past its start-up transient).
const LAST_STAGE_TIME: Duration = Duration::from_secs(2);
/// An estimated run time above this gets a warning (s).
pub const LONG_RUN_S: f64 = 3600.0;
/// An estimated disk use above this gets a warning (bytes).
pub const LARGE_OUTPUT_BYTES: f64 = 2.0 * 1024.0 * 1024.0 * 1024.0;

/// What the trial measured and what it means for the whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Accepted steps the trial solved.
    pub trial_steps: usize,
    /// Stages the trial timed.
    pub stages_timed: usize,
    /// Estimated wall time of the run (s): each stage's nominal steps at its trial rate.
    pub run_s: f64,
    /// Nominal steps of the whole run.
    pub steps: usize,
    /// Size of the field files of one written state (bytes): the section's file and, for an
    /// axisymmetric model, its revolved view.
    pub field_file_bytes: u64,
    /// Field files the run writes.
    pub field_files: usize,
    /// Size of `history.csv` (bytes, estimated per record from the trial's file).
    pub history_bytes: u64,
    /// Why the trial's run failed before the trial was done, if it did.
    pub failure: Option<String>,
}

impl Estimate {
    /// Estimated disk use of the run's fields and history (bytes).
    pub fn disk_bytes(&self) -> f64 {
        self.field_file_bytes as f64 * self.field_files as f64 + self.history_bytes as f64
    }
}

/// The stage and wall time of every accepted step; asks the run to stop once the trial has timed
/// every stage (or its time is up).
struct Clock<'p> {
    plan: &'p Plan,
    /// Stage, step number in the stage and wall time of every record.
    times: Vec<(String, usize, Instant)>,
    deadline: Instant,
    stopped: bool,
}

impl Clock<'_> {
    /// Whether the steps so far time every stage that takes steps: the run is in the last such
    /// stage and has timed enough of its steps.
    fn enough(&self) -> bool {
        let Some((stage, ..)) = self.times.last() else {
            return false;
        };
        let last = self
            .plan
            .stages
            .iter()
            .rev()
            .find(|s| s.kind.nominal_steps(s.duration) > 0)
            .map(|s| s.name.as_str());
        let ours: Vec<&Instant> = self
            .times
            .iter()
            .filter(|(s, ..)| s == stage)
            .map(|t| &t.2)
            .collect();
        Some(stage.as_str()) == last
            && ours.len() > TRIAL_STEPS
            && ours[ours.len() - 1].duration_since(*ours[0]) >= LAST_STAGE_TIME
    }
}

impl Observer for Clock<'_> {
    fn step(&mut self, _plan: &Plan, record: &StepRecord, _state: &[f64], _f: &[CellFields]) {
        self.times
            .push((record.stage.clone(), record.step, Instant::now()));
        if !self.stopped && (self.enough() || Instant::now() > self.deadline) {
            self.stopped = true;
            crate::solve::interrupt::stop_here("trial done".into());
        }
    }

    fn finished(&mut self, _plan: &Plan, _summary: &RunSummary) {}
}

/// Mean wall time per step (s) of each stage the trial reached, from the intervals between
/// consecutive records of the same stage in the later half of those it saw (the first steps
/// also set the stage up and follow the load's first jump with more Newton iterations);
/// `None` for a stage it did not time.
fn stage_rates(plan: &Plan, times: &[(String, usize, Instant)]) -> Vec<Option<f64>> {
    plan.stages
        .iter()
        .map(|stage| {
            let ours: Vec<&(String, usize, Instant)> =
                times.iter().filter(|t| t.0 == stage.name).collect();
            let first = if ours.len() > 2 {
                (ours.len() / 2).max(1)
            } else {
                0
            };
            let (sum, n) = ours[first.min(ours.len().saturating_sub(1))..]
                .windows(2)
                .fold((0.0, 0usize), |(s, n), w| {
                    (s + (w[1].2 - w[0].2).as_secs_f64(), n + 1)
                });
            (n > 0).then(|| sum / n as f64)
        })
        .collect()
}

/// The records of the whole run, nominally: one per step and the initial state.
fn nominal_records(plan: &Plan) -> usize {
    1 + plan
        .stages
        .iter()
        .map(|s| s.kind.nominal_steps(s.duration))
        .sum::<usize>()
}

/// The field files a run writes, as the output writer decides: every `fields_every`-th record
/// counting from the first (the initial state, in the first stage), the last record of a stage
/// followed by another unless it was written already, and the last record of the run (the only
/// one with `fields_every = 0`).
fn field_files(plan: &Plan) -> usize {
    // the stage of every record: the initial state, then each stage's nominal steps
    let mut stage_of = Vec::new();
    for (i, s) in plan.stages.iter().enumerate() {
        let n = s.kind.nominal_steps(s.duration) + usize::from(i == 0);
        stage_of.extend(std::iter::repeat_n(i, n));
    }
    let every = plan.output.fields_every;
    if every == 0 {
        return 1;
    }
    let last = stage_of.len().saturating_sub(1);
    (0..stage_of.len())
        .filter(|&i| {
            i.is_multiple_of(every)
                || i == last
                || stage_of.get(i + 1).is_some_and(|&next| next != stage_of[i])
        })
        .count()
}

/// The largest regular file in `dir` whose name starts with `prefix` (bytes), 0 when there is
/// none.
fn largest_file(dir: &Path, prefix: &str) -> u64 {
    std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
                .filter_map(|e| e.metadata().ok())
                .filter(|m| m.is_file())
                .map(|m| m.len())
                .max()
                .unwrap_or(0)
        })
        .unwrap_or(0)
}

/// Why a trial gave no estimate.
#[derive(Debug, Clone, PartialEq)]
pub enum TrialError {
    /// The trial's run failed (a problem of the scenario).
    Failed(String),
    /// It solved no step for another reason (e.g. the scratch directory, or no stage that steps).
    NoSteps(String),
}

/// Solves the first steps of `plan` in a scratch directory and scales them to the whole run.
/// An error says why no estimate could be made (the trial failed before two steps).
pub fn estimate(plan: &Plan) -> Result<Estimate, TrialError> {
    // removed when dropped
    let scratch = tempfile::Builder::new()
        .prefix("deasim-check-")
        .tempdir()
        .map_err(|e| TrialError::NoSteps(format!("no scratch directory for the trial: {e}")))?;
    let mut trial = plan.clone();
    trial.output.plots = false;
    // the first record and the last state: one full field file to measure
    trial.output.fields_every = usize::MAX;
    let mut writer = OutputWriter::new(scratch.path())
        .map_err(|e| TrialError::NoSteps(format!("{}: {e}", scratch.path().display())))?;
    let mut clock = Clock {
        plan,
        times: Vec::new(),
        deadline: Instant::now() + TRIAL_TIME,
        stopped: false,
    };
    let summary = {
        let mut observers: Vec<&mut dyn Observer> = vec![&mut writer, &mut clock];
        run_with(&trial, &mut observers, None)
    };
    crate::solve::interrupt::clear_local();
    // the trial's own stop is no failure
    let failure = summary.error.clone().filter(|_| !clock.stopped);
    let rates = stage_rates(plan, &clock.times);
    let timed = rates.iter().flatten().count();
    if timed == 0 {
        return Err(match &failure {
            Some(e) => TrialError::Failed(format!("the trial solved no step: {e}")),
            None => TrialError::NoSteps(format!(
                "the trial solved no step: {}",
                summary.error.as_deref().unwrap_or("the run ended at once")
            )),
        });
    }
    // a stage the trial did not reach takes the rate of the nearest stage before it (else after)
    let mut run_s = 0.0;
    let mut steps = 0;
    for (i, stage) in plan.stages.iter().enumerate() {
        let n = stage.kind.nominal_steps(stage.duration);
        let rate = rates[..=i]
            .iter()
            .rev()
            .flatten()
            .next()
            .or_else(|| rates[i..].iter().flatten().next())
            .copied()
            .unwrap_or(0.0);
        run_s += rate * n as f64;
        steps += n;
    }
    let records = nominal_records(plan);
    let history = std::fs::metadata(scratch.path().join("history.csv"))
        .map(|m| m.len())
        .unwrap_or(0);
    Ok(Estimate {
        trial_steps: clock.times.len().saturating_sub(1),
        stages_timed: timed,
        run_s,
        steps,
        field_file_bytes: ["step_", "revolved_"]
            .iter()
            .map(|p| largest_file(&scratch.path().join("fields"), p))
            .sum(),
        field_files: field_files(plan),
        history_bytes: history / clock.times.len().max(1) as u64 * records as u64,
        failure,
    })
}

/// `bytes` with a binary prefix: `12.3 MiB`.
pub fn human_bytes(bytes: f64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes;
    let mut i = 0;
    while v >= 1024.0 && i + 1 < units.len() {
        v /= 1024.0;
        i += 1;
    }
    if i == 0 {
        format!("{v:.0} B")
    } else {
        format!("{v:.1} {}", units[i])
    }
}

/// `seconds` as `7.3 ms`, `2.50 s`, `14.0 min`, `3.2 h`.
pub fn human_duration(seconds: f64) -> String {
    if seconds < 1.0 {
        format!("{:.1} ms", seconds * 1e3)
    } else if seconds < 60.0 {
        format!("{seconds:.2} s")
    } else if seconds < 3600.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_durations_read_well() {
        assert_eq!(human_bytes(512.0), "512 B");
        assert_eq!(human_bytes(1536.0), "1.5 KiB");
        assert_eq!(human_bytes(3.0 * 1024.0 * 1024.0 * 1024.0), "3.0 GiB");
        assert_eq!(human_duration(2.5), "2.50 s");
        assert_eq!(human_duration(0.0073), "7.3 ms");
        assert_eq!(human_duration(840.0), "14.0 min");
        assert_eq!(human_duration(7200.0), "2.0 h");
    }

    #[test]
    fn trial_of_the_film_scales_to_its_fifteen_steps() {
        let plan = crate::cli::app::load(Some(Path::new("film")), &[]).unwrap();
        let e = estimate(&plan).unwrap();
        // the film's 15 steps take less than the trial's time: it runs them all
        assert_eq!((e.trial_steps, e.steps, e.stages_timed), (15, 15, 1));
        assert!(e.run_s > 0.0);
        // fields_every = 1: the 16 records (the last one ends the stage: written once)
        assert_eq!(e.field_files, 16);
        assert_eq!(e.failure, None);
        assert!(e.field_file_bytes > 1000, "{e:?}");
        assert!(e.history_bytes > 100);
        assert!(e.disk_bytes() > 17.0 * 1000.0);
    }

    /// The count of field files the writer really writes: every 10th of the film's 16 records
    /// (0 and 10) and the last; with `fields_every = 0` the last only.
    #[test]
    fn field_files_are_those_written() {
        let mut plan = crate::cli::app::load(Some(Path::new("film")), &[]).unwrap();
        plan.output.fields_every = 10;
        assert_eq!(field_files(&plan), 3);
        plan.output.fields_every = 0;
        assert_eq!(field_files(&plan), 1);
    }
}
