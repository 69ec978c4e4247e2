//! `deasim calibrate SPEC.toml`: fits a material's parameters to measured homogeneous test
//! curves (a thin front end on [`crate::calibrate`]): the table on the terminal, the files in the
//! output directory.

use crate::calibrate::{calibrate, output, CalibrateOptions, CalibrationError};
use crate::cli::app::{EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::io::results::ResultsDir;
use std::path::{Path, PathBuf};

/// The command line's arguments.
#[derive(Debug, Clone)]
pub struct CalibrateArgs {
    pub spec: PathBuf,
    pub out: Option<PathBuf>,
    pub overwrite: bool,
    /// Replaces the spec's `fit.starts`.
    pub starts: Option<usize>,
}

/// Runs the command; returns the exit status.
pub fn cmd_calibrate(args: &CalibrateArgs) -> i32 {
    let stem = args
        .spec
        .file_stem()
        .map_or("spec".into(), |s| s.to_string_lossy().into_owned());
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("calibrate-{stem}")));
    let options = CalibrateOptions {
        starts: args.starts,
    };
    // the spec and its data are checked before the output directory is touched
    let problem = match crate::calibrate::read_problem(&args.spec) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let cal = match calibrate(&problem, &options) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return match e {
                CalibrationError::Input(_) | CalibrationError::Unsupported(_) => EXIT_BAD_INPUT,
                CalibrationError::Failed(_) => EXIT_SOLVE_FAILED,
            };
        }
    };
    let what = args.spec.display().to_string();
    let mut results = match ResultsDir::open(&dir, "calibrate", &what, "", args.overwrite) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    match output::write(&cal, &dir).and_then(|()| results.record()) {
        Ok(()) => {
            print!("{}", output::table(&cal));
            println!("results in {}", dir.display());
            EXIT_OK
        }
        Err(e) => {
            eprintln!("error: {e}");
            EXIT_SOLVE_FAILED
        }
    }
}
