//! Material-point calibration: fit a material's parameters (a hyperelastic base and Maxwell
//! branches) to measured homogeneous test curves (`deasim calibrate SPEC.toml`).
//!
//! [`spec`] reads the spec and its data; [`path`] runs each experiment's protocol on the material
//! point with the exact forward sensitivities of the stress in θ; [`lsq`] fits bounded
//! parameters to residual blocks with their Jacobians (the seam a device-level calibration, with
//! a finite element run in the loop, plugs into) and gives the Gauss–Newton statistics;
//! [`output`] writes `calibration.json`, `fitted.toml` and the plots. Nothing here prints:
//! warnings go through `log` and into [`Calibration::warnings`].

pub mod lsq;
pub mod output;
pub mod path;
pub mod spec;

use crate::io::scenario::InputError;
use crate::material::Material;
use lsq::{Block, Fitted, Statistics};
use rayon::prelude::*;
use spec::{Experiment, Problem};
use std::path::Path as FsPath;
use std::sync::Arc;

pub use spec::{read, DEVICE_OBJECTIVES};

/// Why a calibration could not be made.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The spec or its data are wrong (file, key or line, what was expected).
    #[error("{0}")]
    Input(InputError),
    /// The spec asks for what this version cannot do (device-level objectives).
    #[error("{0}")]
    Unsupported(String),
    /// The model could not be evaluated or the fit failed.
    #[error("{0}")]
    Failed(String),
}

/// Options of [`calibrate`] beyond the spec.
#[derive(Debug, Clone, Default)]
pub struct CalibrateOptions {
    /// Replaces the spec's `fit.starts`.
    pub starts: Option<usize>,
}

/// One fitted parameter's result.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterResult {
    /// `material.<key>`.
    pub path: String,
    pub initial: f64,
    pub fitted: f64,
    pub std_error: f64,
    pub ci95: [f64; 2],
}

/// One experiment at the fitted parameters: the measured points and the model there.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentResult {
    pub name: String,
    /// RMS of the unweighted residuals (Pa).
    pub rms: f64,
    /// RMS at the starting parameters (Pa).
    pub rms_initial: f64,
    pub stretch: Vec<f64>,
    pub time: Option<Vec<f64>>,
    pub measured: Vec<f64>,
    pub model: Vec<f64>,
    /// The model's whole path (time, stretch, stress) for the plots.
    pub path: path::Path,
}

/// The result of a calibration.
#[derive(Debug, Clone)]
pub struct Calibration {
    pub parameters: Vec<ParameterResult>,
    /// RMS of all unweighted residuals (Pa).
    pub rms: f64,
    pub experiments: Vec<ExperimentResult>,
    pub correlation: Vec<Vec<f64>>,
    pub statistics: Statistics,
    pub iterations: usize,
    pub converged: bool,
    pub reason: String,
    /// The start that gave the result (0: the spec's values).
    pub start: usize,
    pub warnings: Vec<String>,
    /// The fitted material table (the spec's `[material]` with the fitted values).
    pub model: String,
    pub fitted_params: crate::material::MaterialParams,
}

/// The material-point model of a problem: the residual blocks (weighted, Pa) of every experiment
/// with their exact Jacobians in the fitted parameters.
pub struct PointModel<'a> {
    problem: &'a Problem,
    picks: Vec<Vec<path::Pick>>,
}

impl<'a> PointModel<'a> {
    /// The model, its comparison rules fixed from the paths of the starting material (an error
    /// names the data file and line of a point outside its protocol).
    pub fn new(problem: &'a Problem) -> Result<Self, CalibrationError> {
        let picks = problem
            .experiments
            .iter()
            .map(|e| {
                let p = path::path(
                    problem.material.as_ref(),
                    e.mode,
                    &e.protocol,
                    e.steps,
                    false,
                )
                .map_err(|m| {
                    CalibrationError::Failed(format!(
                        "experiment `{}` with the starting parameters: {m}",
                        e.name
                    ))
                })?;
                path::picks(e, &p).map_err(|m| {
                    CalibrationError::Input(InputError {
                        file: e.data_path.display().to_string(),
                        position: None,
                        key: None,
                        message: m,
                    })
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(PointModel { problem, picks })
    }

    /// The material with the fitted parameters `theta`.
    pub fn material(&self, theta: &[f64]) -> Result<Arc<dyn Material>, String> {
        let mut full = self
            .problem
            .material
            .parameters()
            .ok_or("no parameter vector")?
            .values;
        for (p, &v) in self.problem.parameters.iter().zip(theta) {
            full[p.index] = v;
        }
        self.problem
            .material
            .with_parameters(&full)
            .map_err(|e| e.to_string())
    }

    /// The blocks at `theta` (with Jacobians when `jacobian`) and the model's paths.
    pub fn evaluate(
        &self,
        theta: &[f64],
        jacobian: bool,
    ) -> Result<Vec<(Block, path::Path)>, String> {
        let mat = self.material(theta)?;
        self.evaluate_material(mat.as_ref(), jacobian)
    }

    /// The blocks of a given material (e.g. a preset on the same data).
    pub fn evaluate_material(
        &self,
        mat: &dyn Material,
        jacobian: bool,
    ) -> Result<Vec<(Block, path::Path)>, String> {
        let n = self.problem.parameters.len();
        let exps: Vec<(&Experiment, &Vec<path::Pick>)> =
            self.problem.experiments.iter().zip(&self.picks).collect();
        exps.par_iter()
            .map(|(e, picks)| {
                let p = path::path(mat, e.mode, &e.protocol, e.steps, jacobian)
                    .map_err(|m| format!("experiment `{}`: {m}", e.name))?;
                let mut b = Block {
                    name: e.name.clone(),
                    residuals: Vec::with_capacity(picks.len()),
                    jacobian: Vec::with_capacity(if jacobian { picks.len() * n } else { 0 }),
                };
                for (i, pk) in picks.iter().enumerate() {
                    b.residuals
                        .push(e.weight * (pk.of(&p.stress) - e.data.stress[i]));
                    if jacobian {
                        for q in &self.problem.parameters {
                            let (sa, sb) =
                                (p.sensitivity[pk.a][q.index], p.sensitivity[pk.b][q.index]);
                            b.jacobian.push(e.weight * ((1.0 - pk.w) * sa + pk.w * sb));
                        }
                    }
                }
                Ok((b, p))
            })
            .collect()
    }

    /// RMS of the unweighted residuals per experiment and overall (Pa) of a material.
    pub fn rms(&self, mat: &dyn Material) -> Result<(Vec<f64>, f64), String> {
        let blocks = self.evaluate_material(mat, false)?;
        Ok(rms_of(self.problem, blocks.iter().map(|(b, _)| b)))
    }
}

fn rms_of<'b>(problem: &Problem, blocks: impl Iterator<Item = &'b Block>) -> (Vec<f64>, f64) {
    let (mut sum, mut count) = (0.0, 0usize);
    let per = blocks
        .zip(&problem.experiments)
        .map(|(b, e)| {
            let s: f64 = b.residuals.iter().map(|r| (r / e.weight).powi(2)).sum();
            sum += s;
            count += b.residuals.len();
            (s / b.residuals.len() as f64).sqrt()
        })
        .collect();
    (per, (sum / count as f64).sqrt())
}

/// Reads and checks the spec at `spec_path` and its data: a spec with device-level objectives
/// is [`CalibrationError::Unsupported`], any other fault [`CalibrationError::Input`].
pub fn read_problem(spec_path: &FsPath) -> Result<Problem, CalibrationError> {
    read_problem_with(spec_path, &[])
}

/// [`read_problem`] with `--set KEY=VALUE` overrides of the spec's keys applied first (an
/// override that is no such key is refused naming it, as the spec's own keys are).
pub fn read_problem_with(
    spec_path: &FsPath,
    overrides: &[String],
) -> Result<Problem, CalibrationError> {
    if let Ok(text) = std::fs::read_to_string(spec_path) {
        if spec::has_objectives(&text) {
            return Err(CalibrationError::Unsupported(format!(
                "{}: {DEVICE_OBJECTIVES}",
                spec_path.display()
            )));
        }
    }
    spec::read_with(spec_path, overrides).map_err(CalibrationError::Input)
}

/// Reads the spec at `spec_path` and fits it (the library's entry, `deasim::api::calibrate`).
pub fn calibrate_file(
    spec_path: &FsPath,
    options: &CalibrateOptions,
) -> Result<Calibration, CalibrationError> {
    calibrate(&read_problem(spec_path)?, options)
}

/// Fits a problem.
pub fn calibrate(
    problem: &Problem,
    options: &CalibrateOptions,
) -> Result<Calibration, CalibrationError> {
    let model = PointModel::new(problem)?;
    let mut fit_options = problem.options;
    if let Some(s) = options.starts {
        fit_options.starts = s.max(1);
    }
    let initial: Vec<f64> = problem.parameters.iter().map(|p| p.initial).collect();
    let start_blocks = model
        .evaluate(&initial, false)
        .map_err(CalibrationError::Failed)?;
    let (rms_initial, _) = rms_of(problem, start_blocks.iter().map(|(b, _)| b));
    let mut eval = |theta: &[f64]| -> Result<Vec<Block>, String> {
        Ok(model
            .evaluate(theta, true)?
            .into_iter()
            .map(|(b, _)| b)
            .collect())
    };
    let fitted: Fitted =
        lsq::fit(&mut eval, &problem.parameters, &fit_options).map_err(CalibrationError::Failed)?;
    let stats = lsq::statistics(&fitted, &problem.parameters);
    let at = model
        .evaluate(&fitted.theta, false)
        .map_err(CalibrationError::Failed)?;
    let (per, rms) = rms_of(problem, at.iter().map(|(b, _)| b));
    let experiments = problem
        .experiments
        .iter()
        .zip(at)
        .enumerate()
        .map(|(i, (e, (b, p)))| ExperimentResult {
            name: e.name.clone(),
            rms: per[i],
            rms_initial: rms_initial[i],
            stretch: e.data.stretch.clone(),
            time: e.data.time.clone(),
            measured: e.data.stress.clone(),
            model: b
                .residuals
                .iter()
                .zip(&e.data.stress)
                .map(|(r, s)| r / e.weight + s)
                .collect(),
            path: p,
        })
        .collect();
    let parameters = problem
        .parameters
        .iter()
        .enumerate()
        .map(|(k, p)| ParameterResult {
            path: p.path.clone(),
            initial: p.initial,
            fitted: fitted.theta[k],
            std_error: stats.std_error[k],
            ci95: stats.ci95[k],
        })
        .collect();
    let mut warnings = stats.warnings.clone();
    if !fitted.stop.converged() {
        warnings.insert(
            0,
            format!("the fit did not converge: {}", fitted.stop.describe()),
        );
    }
    for w in &warnings {
        log::warn!("warning: {w}");
    }
    let mut fitted_params = problem.params.clone();
    for (p, &v) in problem.parameters.iter().zip(&fitted.theta) {
        let key = &p.path["material.".len()..];
        fitted_params
            .set(key, v)
            .map_err(|e| CalibrationError::Failed(e.to_string()))?;
    }
    Ok(Calibration {
        parameters,
        rms,
        experiments,
        correlation: stats.correlation.clone(),
        statistics: stats,
        iterations: fitted.iterations,
        converged: fitted.stop.converged(),
        reason: fitted.stop.describe().to_string(),
        start: fitted.start,
        warnings,
        model: problem.model.clone(),
        fitted_params,
    })
}
