//! The library's interface for programs: build a [`Simulation`] from a scenario (a file, a TOML
//! text or an embedded example) with overrides by key path (the strings `--set` takes), run it
//! with observers and a [`Cancel`] token (in this process, or on the MPI ranks a launcher
//! started, writing the files of `deasim run`), resume a checkpointed run, and read its
//! [`Results`]; every failure is one [`Error`] that keeps its kind. Nothing here prints; the
//! command line and the Python package are front ends on it.

mod control;
mod device;
mod error;
mod gradient;
mod linear;
mod ranks;
mod response_model;
mod results;
mod simulation;

pub use crate::calibrate::{
    calibrate_file as calibrate, CalibrateOptions, Calibration, CalibrationError,
};
pub use crate::control::Iteration as ControlIteration;
pub use control::{ControlOptions, Drive, ObjectiveTape, OptimalControl};
pub use device::{DeviceCalibration, FitCurve, FittedParameter};
pub use error::Error;
pub use gradient::{
    ControlQuantity, ControlReport, GradientOptions, GradientReport, ParameterGradient, TaylorTest,
    DEFAULT_MEMORY,
};
pub use linear::{
    check_biasable, loaded_modes, loaded_modes_of_harmonics, modes_plan, prepare, LoadedModes,
    Prepared,
};
pub use ranks::{launched_rank, launched_size, read_checkpoint, RankOptions, RankRun, Resume};
pub use results::{FieldsKept, History, ProbeStatistics, Results, StepFields};
pub use simulation::{prepare_output, read_scenario, run_plan, Cancel, RunOptions, Simulation};
