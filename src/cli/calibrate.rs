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
    /// `--set KEY=VALUE` overrides of the spec's (or the scenario's) keys.
    pub set: Vec<String>,
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
    // a scenario with objectives: its device's parameters, the finite element run in the loop
    if std::fs::read_to_string(&args.spec).is_ok_and(|t| crate::calibrate::spec::is_device(&t)) {
        return device(args, &dir);
    }
    // the spec and its data are checked before the output directory is touched
    let problem = match crate::calibrate::read_problem_with(&args.spec, &args.set) {
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

/// `deasim calibrate SCENARIO.toml` for a scenario with `[[parameters]]` and `[[objective]]`:
/// `calibration.json`, `fitted.toml` and the table.
fn device(args: &CalibrateArgs, dir: &Path) -> i32 {
    use crate::api::{Error, Simulation};
    let cal = match Simulation::from_file(&args.spec).and_then(|s| {
        s.with_overrides(&args.set)
            .calibrate_device_starts(args.starts.unwrap_or(1))
    }) {
        Ok(c) => c,
        Err(e) => return crate::cli::app::fail(&e),
    };
    let what = args.spec.display().to_string();
    let mut results = match ResultsDir::open(dir, "calibrate", &what, "", args.overwrite) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let write = || -> Result<(), Error> {
        let io = |p: &Path, e: std::io::Error| Error::Io {
            path: p.to_path_buf(),
            message: e.to_string(),
        };
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        let json = serde_json::to_string_pretty(&cal.to_json()).unwrap_or_default() + "\n";
        let path = dir.join("calibration.json");
        crate::io::atomic::write_atomic(&path, json.as_bytes()).map_err(|e| io(&path, e))?;
        let path = dir.join("fitted.toml");
        crate::io::atomic::write_atomic(&path, cal.fitted.as_bytes()).map_err(|e| io(&path, e))?;
        device_plots(&cal, dir).map_err(|e| io(dir, std::io::Error::other(e)))?;
        Ok(())
    };
    if let Err(e) = write() {
        return crate::cli::app::fail(&e);
    }
    if let Err(e) = results.record() {
        eprintln!("error: {e}");
        return EXIT_SOLVE_FAILED;
    }
    println!(
        "{:<40} {:>14} {:>14} {:>12} {:>27}",
        "parameter", "initial", "fitted", "std. error", "95 % interval"
    );
    for p in &cal.parameters {
        println!(
            "{:<40} {:>14.6e} {:>14.6e} {:>12.3e} [{:>12.5e}, {:>12.5e}]",
            p.path, p.initial, p.fitted, p.std_error, p.ci95[0], p.ci95[1]
        );
    }
    for (name, r) in &cal.rms_by_term {
        println!("RMS of {name}: {r:.6e}");
    }
    println!(
        "{} after {} iterations: {}",
        if cal.converged {
            "converged"
        } else {
            "NOT converged"
        },
        cal.iterations,
        cal.reason
    );
    for w in &cal.warnings {
        println!("warning: {w}");
    }
    println!("results in {}", dir.display());
    EXIT_OK
}

/// The plots of a device fit: for each probe term the measured values against the fitted run's
/// (`fit_objective_<i>.png`, over the run's clock), the residuals of every term, and the
/// parameters' correlations.
fn device_plots(cal: &crate::api::DeviceCalibration, dir: &Path) -> Result<(), String> {
    use crate::io::plot::{line_plot, PlotSpec, Series};
    let mut residuals = Vec::new();
    for c in cal.curves.iter().filter(|c| !c.time.is_empty()) {
        let rms = cal
            .rms_by_term
            .iter()
            .find(|(n, _)| *n == c.term)
            .map_or(f64::NAN, |r| r.1);
        let title = format!("{} ({}): RMS {rms:.4e}", c.term, c.probe);
        let y_label = format!("{} [probe unit]", c.probe);
        let single = c.time.len() == 1;
        let series = [
            Series {
                label: if single { "target" } else { "measured" }.into(),
                x: c.time.clone(),
                y: c.measured.clone(),
            },
            Series {
                label: "fitted model".into(),
                x: c.time.clone(),
                y: c.fitted.clone(),
            },
        ];
        line_plot(
            &dir.join(format!("fit_{}.png", c.term.replace('.', "_"))),
            &PlotSpec {
                title: &title,
                x_label: "time [s]",
                y_label: &y_label,
                series: &series,
            },
        )
        .map_err(|e| e.to_string())?;
        residuals.push(Series {
            label: c.term.clone(),
            x: c.time.clone(),
            y: c.fitted
                .iter()
                .zip(&c.measured)
                .map(|(f, m)| f - m)
                .collect(),
        });
    }
    if !residuals.is_empty() {
        line_plot(
            &dir.join("residuals.png"),
            &PlotSpec {
                title: "residuals (model − measured)",
                x_label: "time [s]",
                y_label: "residual [probe unit]",
                series: &residuals,
            },
        )
        .map_err(|e| e.to_string())?;
    }
    let names: Vec<&str> = cal.parameters.iter().map(|p| p.path.as_str()).collect();
    crate::calibrate::output::correlation_plot(dir, &names, &cal.correlation)
}
