//! A simulation: a scenario with its overrides, built into a plan and run.

use super::error::Error;
use super::results::{Collector, FieldsKept, Results};
use crate::io::build::{build, Plan};
use crate::io::examples::{example, DEFAULT, EXAMPLES};
use crate::io::output::OutputWriter;
use crate::io::results::ResultsDir;
use crate::io::scenario::{blame_override, parse, InputError, Scenario, MAX_SCENARIO_BYTES};
use crate::job::observer::Observer;
use crate::job::run::{run_with, RunState};
use crate::solve::interrupt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A scenario and its overrides: what [`Simulation::plan`] builds and [`Simulation::run`] runs.
#[derive(Debug, Clone)]
pub struct Simulation {
    pub(super) text: String,
    /// The name the scenario is read under (its path, `<embedded NAME>`, `<text>`), in errors.
    pub(super) name: String,
    /// The directory its relative paths (meshes, data) are read from.
    pub(super) base: Option<PathBuf>,
    pub(super) overrides: Vec<String>,
}

impl Simulation {
    /// The scenario of file `path`.
    pub fn from_file(path: &Path) -> Result<Simulation, Error> {
        std::fs::metadata(path).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            message: format!("cannot read the scenario: {e}"),
        })?;
        let (text, name, base) = read_scenario(Some(path))?;
        Ok(Simulation {
            text,
            name,
            base,
            overrides: Vec::new(),
        })
    }

    /// The scenario as the command line reads it ([`read_scenario`]): the file `path`, `-` for
    /// standard input, the name of an embedded example when no such file exists, or the
    /// default example when `None`.
    pub fn read(path: Option<&Path>) -> Result<Simulation, Error> {
        let (text, name, base) = read_scenario(path)?;
        Ok(Simulation {
            text,
            name,
            base,
            overrides: Vec::new(),
        })
    }

    /// A scenario given as TOML text; relative paths in it are read from `base` (the working
    /// directory when `None`).
    pub fn from_toml(text: &str, base: Option<&Path>) -> Simulation {
        Simulation {
            text: text.to_string(),
            name: "<text>".into(),
            base: base.map(Path::to_path_buf),
            overrides: Vec::new(),
        }
    }

    /// The embedded example `name` (see `deasim example`).
    pub fn from_example(name: &str) -> Result<Simulation, Error> {
        let text = example(name).ok_or_else(|| {
            let names: Vec<&str> = EXAMPLES.iter().map(|(n, _)| *n).collect();
            Error::Input(InputError {
                file: format!("<embedded {name}>"),
                position: None,
                key: None,
                message: format!("no such example; the examples are {}", names.join(", ")),
            })
        })?;
        Ok(Simulation {
            text: text.to_string(),
            name: format!("<embedded {name}>"),
            base: None,
            overrides: Vec::new(),
        })
    }

    /// Sets `key` (a dotted key path, as `--set` takes) to `value`, a TOML value (`30e3`,
    /// `"vhb"`, `[1, 2]`). Checked when the plan is built.
    pub fn set(mut self, key: &str, value: &str) -> Simulation {
        self.overrides.push(format!("{key}={value}"));
        self
    }

    /// Adds overrides `key=value`, as `--set` takes them.
    pub fn with_overrides(mut self, overrides: &[String]) -> Simulation {
        self.overrides.extend_from_slice(overrides);
        self
    }

    /// The same scenario without its overrides.
    pub fn without_overrides(&self) -> Simulation {
        Simulation {
            overrides: Vec::new(),
            ..self.clone()
        }
    }

    /// The overrides, in the order they apply.
    pub fn overrides(&self) -> &[String] {
        &self.overrides
    }

    /// The scenario's text, before the overrides.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The scenario with the overrides applied, checked against the schema.
    pub fn scenario(&self) -> Result<Scenario, Error> {
        parse(&self.text, &self.name, &self.overrides)
            .map_err(|e| Error::Input(blame_override(e, &self.overrides)))
    }

    /// The validated plan of the run.
    pub fn plan(&self) -> Result<Plan, Error> {
        let scenario = self.scenario()?;
        build(&scenario, &self.name, self.base.as_deref())
            .map_err(|e| Error::Input(blame_override(e, &self.overrides)))
    }

    /// Builds the plan and runs it.
    pub fn run(&self, mut options: RunOptions) -> Result<Results, Error> {
        let plan = self.plan()?;
        options.overrides.clone_from(&self.overrides);
        run_plan(&plan, options)
    }
}

/// A token that stops a run from another thread: the run ends after its current step, with
/// every accepted step in its results ([`Error::Interrupted`]).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A token not yet cancelled.
    pub fn new() -> Cancel {
        Cancel::default()
    }

    /// Asks the run to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether [`Cancel::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// How to run: observers beside the results' own, a cancel token, the fields to keep, an
/// output directory, a state to continue from.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Further observers (progress, writers, checkpoints), called in order.
    pub observers: Vec<&'a mut dyn Observer>,
    /// Stops the run when cancelled.
    pub cancel: Option<Cancel>,
    /// The steps whose nodal values and cell fields the results keep.
    pub fields: FieldsKept,
    /// Writes the files of `deasim run` into this directory.
    pub out: Option<PathBuf>,
    /// Replace another command's or scenario's results in `out`.
    pub overwrite: bool,
    /// Continue from this run state (checked against the plan by the caller).
    pub start: Option<RunState>,
    /// The overrides the plan was built with, recorded with the outputs of `out`.
    pub overrides: Vec<String>,
}

/// Runs `plan`: the results of a converged run, or the error with every step accepted before
/// (an output of `out` that could not be written: [`Error::Output`]).
pub fn run_plan(plan: &Plan, options: RunOptions) -> Result<Results, Error> {
    let RunOptions {
        mut observers,
        cancel,
        fields,
        out,
        overwrite,
        start,
        overrides,
    } = options;
    let mut output = match &out {
        Some(dir) => {
            let (results, mut writer) =
                prepare_output(dir, plan, overwrite).map_err(|message| Error::Io {
                    path: dir.clone(),
                    message,
                })?;
            writer.overrides = overrides;
            Some((results, writer))
        }
        None => None,
    };
    let mut collector = Collector::new(fields);
    interrupt::watch(cancel.map(|c| c.0));
    let summary = {
        let mut all: Vec<&mut dyn Observer> = Vec::new();
        if let Some((results, writer)) = output.as_mut() {
            all.push(writer);
            all.push(results);
        }
        for o in observers.iter_mut() {
            all.push(&mut **o);
        }
        all.push(&mut collector);
        run_with(plan, &mut all, start)
    };
    interrupt::watch(None);
    let results = collector.results(plan, summary.clone());
    if let (Some((mut dir, writer)), Some(path)) = (output, out) {
        let mut results = results;
        results
            .summary
            .warnings
            .extend(writer.errors.iter().cloned());
        if let Some(message) = writer.write_failure().or(dir.record().err()) {
            return Err(Error::Output {
                path,
                message,
                results: Box::new(results),
            });
        }
        return outcome(results);
    }
    outcome(results)
}

/// The results of a run, or its error.
pub(super) fn outcome(results: Results) -> Result<Results, Error> {
    let summary = &results.summary;
    if summary.interrupted {
        let reason = summary
            .error
            .clone()
            .unwrap_or_else(|| interrupt::MESSAGE.to_string());
        return Err(Error::Interrupted {
            reason,
            results: Box::new(results),
        });
    }
    if !summary.converged {
        let reason = summary
            .error
            .clone()
            .unwrap_or_else(|| "the solve failed".to_string());
        return Err(Error::Solve {
            reason,
            results: Box::new(results),
        });
    }
    Ok(results)
}

/// Locks the output directory `dir` of `plan`, clears deasim's files of an earlier run of it
/// (refused for another command's or scenario's results unless `overwrite`,
/// [`ResultsDir::open`]) and creates the writer.
pub fn prepare_output(
    dir: &Path,
    plan: &Plan,
    overwrite: bool,
) -> Result<(ResultsDir, OutputWriter), String> {
    let hash = format!("{:016x}", plan.fingerprint());
    let results = ResultsDir::open(dir, "run", &plan.name, &hash, overwrite)?;
    // checkpoints of an earlier run in this directory belong to other results
    for (_, _, old) in crate::io::checkpoint::checkpoint_files(dir) {
        std::fs::remove_file(&old).map_err(|e| format!("{}: {e}", old.display()))?;
    }
    let writer = OutputWriter::new(dir)
        .map_err(|e| format!("cannot create the output directory {}: {e}", dir.display()))?;
    Ok((results, writer))
}

/// The text of a scenario file (or of the default example), the name it is read under and its
/// directory.
pub fn read_scenario(path: Option<&Path>) -> Result<(String, String, Option<PathBuf>), InputError> {
    Ok(match path {
        None => (
            example(DEFAULT)
                .expect("the default example is embedded")
                .to_string(),
            format!("<embedded {DEFAULT}>"),
            None,
        ),
        // `-`: the scenario from standard input
        Some(p) if p.as_os_str() == "-" => {
            use std::io::Read as _;
            let mut bytes = Vec::new();
            let read = std::io::stdin()
                .take(MAX_SCENARIO_BYTES as u64 + 1)
                .read_to_end(&mut bytes);
            let fail = |message: String| InputError {
                file: "<stdin>".into(),
                position: None,
                key: None,
                message,
            };
            read.map_err(|e| fail(format!("cannot read the scenario: {e}")))?;
            if bytes.len() > MAX_SCENARIO_BYTES {
                return Err(fail(format!(
                    "input too large (more than {MAX_SCENARIO_BYTES} bytes)"
                )));
            }
            let text = String::from_utf8(bytes).map_err(|e| {
                fail(format!(
                    "not UTF-8 text (invalid byte at offset {}): expected TOML",
                    e.utf8_error().valid_up_to()
                ))
            })?;
            (text, "<stdin>".into(), None)
        }
        // the name of an embedded example, when no such file exists
        Some(p) if !p.exists() && p.to_str().and_then(example).is_some() => {
            let name = p.to_str().unwrap_or_default();
            (
                example(name).unwrap_or_default().to_string(),
                format!("<embedded {name}>"),
                None,
            )
        }
        Some(p) => {
            let name = p.display().to_string();
            let meta = std::fs::metadata(p).map_err(|e| InputError {
                file: name.clone(),
                position: None,
                key: None,
                message: format!("cannot read the scenario: {e}"),
            })?;
            if meta.len() > MAX_SCENARIO_BYTES as u64 {
                return Err(InputError {
                    file: name,
                    position: None,
                    key: None,
                    message: format!(
                        "file too large ({} bytes, at most {MAX_SCENARIO_BYTES})",
                        meta.len()
                    ),
                });
            }
            let bytes = std::fs::read(p).map_err(|e| InputError {
                file: name.clone(),
                position: None,
                key: None,
                message: format!("cannot read the scenario: {e}"),
            })?;
            let text = String::from_utf8(bytes).map_err(|e| InputError {
                file: name.clone(),
                position: None,
                key: None,
                message: format!(
                    "not a UTF-8 text file (invalid byte at offset {}): expected TOML",
                    e.utf8_error().valid_up_to()
                ),
            })?;
            (text, name, p.parent().map(Path::to_path_buf))
        }
    })
}
