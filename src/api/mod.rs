//! The library's interface for programs: build a [`Simulation`] from a scenario (a file, a TOML
//! text or an embedded example) with overrides by key path (the strings `--set` takes), run it
//! with observers and a [`Cancel`] token, and read its [`Results`]; every failure is one
//! [`Error`] that keeps its kind. Nothing here prints; the command line and the Python package
//! are front ends on it.

mod error;
mod results;
mod simulation;

pub use error::Error;
pub use results::{FieldsKept, History, ProbeStatistics, Results, StepFields};
pub use simulation::{prepare_output, read_scenario, run_plan, Cancel, RunOptions, Simulation};
