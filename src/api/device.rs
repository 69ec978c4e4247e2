//! Device calibration: a scenario's `[[parameters]]` fitted to its probe terms (`probe-final`,
//! `probe-misfit`) with the finite element run in the loop, by the bounded Levenberg–Marquardt
//! method of [`crate::calibrate::lsq`]; each residual's row of the Jacobian is one adjoint sweep
//! over the run's tape.

use super::error::Error;
use super::gradient::{json_number, memory_budget, taped_run};
use super::simulation::Simulation;
use crate::adjoint::objective::{Objective, Term};
use crate::adjoint::sweep::{check_supported, gradient, read_objective};
use crate::calibrate::lsq::{fit, statistics, Block};
use crate::calibrate::spec::{FitOptions, FitParameter, Scale};
use crate::io::build::parameter;
use crate::io::scenario::InputError;

/// One fitted parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedParameter {
    pub path: String,
    pub initial: f64,
    pub fitted: f64,
    pub std_error: f64,
    pub ci95: [f64; 2],
}

/// A probe term's measured and fitted values at the steps it reads, at the fitted parameters:
/// what the plots of a device fit draw.
#[derive(Debug, Clone, PartialEq)]
pub struct FitCurve {
    /// The term (`objective.<i>`) and its probe.
    pub term: String,
    pub probe: String,
    /// The run's clock (s) at each reading, the target there (the data interpolated, or the
    /// target value) and the fitted model's probe value (less its value at the stage's start
    /// for a relative term).
    pub time: Vec<f64>,
    pub measured: Vec<f64>,
    pub fitted: Vec<f64>,
}

/// The outcome of [`Simulation::calibrate_device`].
#[derive(Debug, Clone)]
pub struct DeviceCalibration {
    pub parameters: Vec<FittedParameter>,
    /// RMS of the unweighted misfit (the probes' unit), over all terms and per term
    /// (`objective.<i>`).
    pub rms: f64,
    pub rms_by_term: Vec<(String, f64)>,
    pub correlation: Vec<Vec<f64>>,
    pub iterations: usize,
    pub converged: bool,
    pub reason: String,
    pub warnings: Vec<String>,
    /// `fitted.toml`: the scenario with the fitted values.
    pub fitted: String,
    /// Each probe term's measured and fitted values.
    pub curves: Vec<FitCurve>,
    /// The start the kept fit came from (0: the scenario's values).
    pub start: usize,
}

impl DeviceCalibration {
    /// The document of `calibration.json`.
    pub fn to_json(&self) -> serde_json::Value {
        let num = json_number;
        let mut parameters = serde_json::Map::new();
        for p in &self.parameters {
            parameters.insert(
                p.path.clone(),
                serde_json::json!({
                    "initial": num(p.initial),
                    "fitted": num(p.fitted),
                    "std_error": num(p.std_error),
                    "ci95": [num(p.ci95[0]), num(p.ci95[1])],
                }),
            );
        }
        let mut by = serde_json::Map::new();
        for (name, r) in &self.rms_by_term {
            by.insert(name.clone(), num(*r));
        }
        serde_json::json!({
            "parameters": parameters,
            "rms": num(self.rms),
            "rms_by_experiment": by,
            "correlation": self.correlation.iter().map(|r| r.iter().map(|x| num(*x)).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "iterations": self.iterations,
            "start": self.start,
            "converged": self.converged,
            "reason": self.reason,
            "warnings": self.warnings,
        })
    }
}

impl Simulation {
    /// Fits the scenario's `[[parameters]]` (starting at their values in the scenario, within
    /// `lower` and `upper`, `scale` linear or log) to its `[[objective]]` probe terms: the
    /// residuals √weight·(probe − target) at the steps each term reads.
    pub fn calibrate_device(&self) -> Result<DeviceCalibration, Error> {
        self.calibrate_device_starts(1)
    }

    /// [`Simulation::calibrate_device`] from `starts` starting points: the scenario's values,
    /// then points spread over the parameters' boxes (in their scales) by the low-discrepancy
    /// sequence of the material-point fit; the fit with the smallest sum of squares is kept
    /// (`start` says which). Each start costs a fit.
    pub fn calibrate_device_starts(&self, starts: usize) -> Result<DeviceCalibration, Error> {
        let scenario = self.scenario()?;
        let plan = self.plan()?;
        let input = |key: String, m: String| Error::Input(InputError::at_key(&self.name, key, m));
        if scenario.parameters.is_empty() {
            return Err(input(
                "parameters".into(),
                "a device calibration needs [[parameters]] entries to fit".into(),
            ));
        }
        let objective = Objective::build(&scenario, &plan, &self.name, self.base.as_deref())
            .map_err(Error::Input)?;
        for (i, t) in objective.terms.iter().enumerate() {
            if !matches!(t, Term::ProbeFinal { .. } | Term::ProbeMisfit { .. }) {
                return Err(input(
                    format!("objective.{i}.kind"),
                    "a device calibration fits probes to data: `probe-final` and \
                     `probe-misfit` terms only"
                        .into(),
                ));
            }
        }
        let mut params = Vec::new();
        for (i, p) in scenario.parameters.iter().enumerate() {
            let built = parameter(&scenario, &self.name, &p.path).map_err(|mut e| {
                e.key = Some(format!("parameters.{i}.path ({})", p.path));
                Error::Input(e)
            })?;
            let scale = match p.scale.as_deref() {
                None | Some("linear") => Scale::Linear,
                Some("log") => Scale::Log,
                Some(other) => {
                    return Err(input(
                        format!("parameters.{i}.scale"),
                        format!("expected \"linear\" or \"log\"; got \"{other}\""),
                    ))
                }
            };
            let initial = built.value();
            let lower = p.lower.unwrap_or(if scale == Scale::Log {
                initial * 1e-3
            } else {
                f64::NEG_INFINITY
            });
            let upper = p.upper.unwrap_or(if scale == Scale::Log {
                initial * 1e3
            } else {
                f64::INFINITY
            });
            if !(lower <= initial && initial <= upper) || (scale == Scale::Log && lower <= 0.0) {
                return Err(input(
                    format!("parameters.{i}"),
                    format!(
                        "the starting value {initial:e} must lie within [lower, upper] = \
                         [{lower:e}, {upper:e}] (positive for a log scale)"
                    ),
                ));
            }
            params.push(FitParameter {
                path: p.path.clone(),
                index: i,
                initial,
                lower,
                upper,
                scale,
            });
        }
        let names: Vec<String> = (0..objective.terms.len())
            .map(|i| format!("objective.{i}"))
            .collect();
        let mut eval = |theta: &[f64]| -> Result<Vec<Block>, String> {
            self.device_blocks(theta, &params, &names)
                .map_err(|e| e.to_string())
        };
        let options = FitOptions {
            starts: starts.max(1),
            ..FitOptions::default()
        };
        let fitted = fit(&mut eval, &params, &options).map_err(Error::Refused)?;
        let stats = statistics(&fitted, &params);
        let weights: Vec<f64> = objective
            .terms
            .iter()
            .map(|t| match t {
                Term::ProbeFinal { weight, .. } | Term::ProbeMisfit { weight, .. } => *weight,
                _ => 1.0,
            })
            .collect();
        let (mut sum, mut count) = (0.0, 0usize);
        let mut rms_by_term = Vec::new();
        for (b, w) in fitted.blocks.iter().zip(&weights) {
            let w = w.max(f64::MIN_POSITIVE);
            let s: f64 = b.residuals.iter().map(|r| r * r / w).sum();
            sum += s;
            count += b.residuals.len();
            rms_by_term.push((b.name.clone(), (s / b.residuals.len().max(1) as f64).sqrt()));
        }
        let mut fitted_text = self.clone();
        for (p, v) in params.iter().zip(&fitted.theta) {
            fitted_text = fitted_text.set(&p.path, &format!("{v:e}"));
        }
        let mut warnings = stats.warnings.clone();
        let mut std_error = stats.std_error.clone();
        if count <= params.len() {
            // no residual variance: the data determine the parameters, not their spread
            std_error.iter_mut().for_each(|s| *s = f64::NAN);
            warnings.push(format!(
                "{count} residuals for {} parameters: no residual variance, so no standard \
                 errors or intervals",
                params.len()
            ));
        }
        if !fitted.stop.converged() {
            warnings.insert(
                0,
                format!("the fit did not converge: {}", fitted.stop.describe()),
            );
        }
        let curves = self.fit_curves(&fitted.theta, &params, &names)?;
        Ok(DeviceCalibration {
            curves,
            start: fitted.start,
            parameters: params
                .iter()
                .enumerate()
                .map(|(k, p)| FittedParameter {
                    path: p.path.clone(),
                    initial: p.initial,
                    fitted: fitted.theta[k],
                    std_error: std_error[k],
                    ci95: stats.ci95[k],
                })
                .collect(),
            rms: (sum / count.max(1) as f64).sqrt(),
            rms_by_term,
            correlation: stats.correlation.clone(),
            iterations: fitted.iterations,
            converged: fitted.stop.converged(),
            reason: fitted.stop.describe().to_string(),
            warnings,
            fitted: fitted_text.scenario_toml(|_| {})?,
        })
    }

    /// The simulation with the parameters at θ, its scenario, plan and objective.
    fn at(
        &self,
        theta: &[f64],
        params: &[FitParameter],
    ) -> Result<
        (
            Simulation,
            crate::io::scenario::Scenario,
            crate::job::plan::Plan,
            Objective,
        ),
        Error,
    > {
        let mut sim = self.clone();
        for (p, v) in params.iter().zip(theta) {
            sim = sim.set(&p.path, &format!("{v:e}"));
        }
        let scenario = sim.scenario()?;
        let plan = sim.plan()?;
        let objective = Objective::build(&scenario, &plan, &sim.name, sim.base.as_deref())
            .map_err(Error::Input)?;
        Ok((sim, scenario, plan, objective))
    }

    /// The readings of each probe term of the objective at θ (one run): its [`FitCurve`].
    fn fit_curves(
        &self,
        theta: &[f64],
        params: &[FitParameter],
        names: &[String],
    ) -> Result<Vec<FitCurve>, Error> {
        let (sim, scenario, plan, objective) = self.at(theta, params)?;
        let tape = taped_run(&plan, memory_budget(&scenario, &sim.name)?)?;
        let (eval, _) = read_objective(&plan, &tape, &objective).map_err(Error::Refused)?;
        let mut curves: Vec<FitCurve> = names
            .iter()
            .zip(&objective.terms)
            .map(|(name, t)| FitCurve {
                term: name.clone(),
                probe: match t {
                    Term::ProbeFinal { probe, .. } | Term::ProbeMisfit { probe, .. } => {
                        plan.probes[*probe].0.clone()
                    }
                    _ => String::new(),
                },
                time: Vec::new(),
                measured: Vec::new(),
                fitted: Vec::new(),
            })
            .collect();
        for r in &eval.readings {
            let c = &mut curves[r.term];
            c.time.push(r.time);
            c.measured.push(r.target);
            c.fitted.push(r.value);
        }
        Ok(curves)
    }

    /// The residual blocks (one per objective term) and their Jacobians at θ: one run, then one
    /// adjoint sweep per residual, of ½(probe − c)² with c one unit below the probe, whose
    /// gradient is the probe's.
    fn device_blocks(
        &self,
        theta: &[f64],
        params: &[FitParameter],
        names: &[String],
    ) -> Result<Vec<Block>, Error> {
        let (sim, scenario, plan, objective) = self.at(theta, params)?;
        let mut parameters = Vec::new();
        for p in params {
            parameters.push((
                p.path.clone(),
                parameter(&scenario, &sim.name, &p.path).map_err(Error::Input)?,
            ));
        }
        check_supported(&plan).map_err(Error::Refused)?;
        let supports = sim.support_sensitivities(&plan, &parameters)?;
        let tape = taped_run(&plan, memory_budget(&scenario, &sim.name)?)?;
        let (eval, _) = read_objective(&plan, &tape, &objective).map_err(Error::Refused)?;
        let n = params.len();
        let mut blocks: Vec<Block> = names
            .iter()
            .map(|name| Block {
                name: name.clone(),
                ..Default::default()
            })
            .collect();
        for r in &eval.readings {
            let (probe, relative) = match &objective.terms[r.term] {
                Term::ProbeFinal {
                    probe, relative, ..
                }
                | Term::ProbeMisfit {
                    probe, relative, ..
                } => (*probe, *relative),
                _ => continue,
            };
            let single = Objective {
                terms: vec![Term::ProbeFinal {
                    probe,
                    stage: r.stage,
                    target: r.value - 1.0,
                    weight: 1.0,
                    relative,
                    step: Some(r.step),
                }],
            };
            let g =
                gradient(&plan, &tape, &single, &parameters, &supports).map_err(Error::Refused)?;
            let sw = r.weight.sqrt();
            let b = &mut blocks[r.term];
            b.residuals.push(sw * (r.value - r.target));
            b.jacobian.extend(g.gradient.iter().map(|d| sw * d));
            debug_assert_eq!(b.jacobian.len(), b.residuals.len() * n);
        }
        Ok(blocks)
    }
}
