//! The gradient of a scenario's objective in its parameters: the forward run taped, its adjoint,
//! and on request a check against central finite differences and a Taylor remainder test.

use super::error::Error;
use super::simulation::{run_plan, RunOptions, Simulation};
use crate::adjoint::objective::Objective;
use crate::adjoint::sweep::{check_supported, gradient};
use crate::adjoint::tape::Tape;
use crate::io::build::parameter;
use crate::io::scenario::InputError;
use std::path::PathBuf;
use std::time::Instant;

/// What [`Simulation::gradient`] does besides the gradient.
#[derive(Debug, Clone, Default)]
pub struct GradientOptions {
    /// Write the forward run's files here (as `deasim run`).
    pub out: Option<PathBuf>,
    pub overwrite: bool,
    /// Compare each derivative with a central finite difference and run a Taylor test.
    pub check: bool,
}

/// One parameter's derivative.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterGradient {
    /// Its key path.
    pub path: String,
    /// Its value in the scenario (SI).
    pub value: f64,
    /// dJ/dp by the adjoint.
    pub gradient: f64,
    /// The central finite difference (J(p+h) − J(p−h))/2h and its step h, when checked.
    pub finite_difference: Option<(f64, f64)>,
}

/// The Taylor remainder test in one direction δ: |J(p + hδ) − J(p) − h ∇J·δ| at halving h,
/// which falls as h² when the gradient is right (Farrell et al. 2013).
#[derive(Debug, Clone, PartialEq)]
pub struct TaylorTest {
    /// (h, remainder) from the largest h down.
    pub remainders: Vec<(f64, f64)>,
    /// log₂ of the ratio of consecutive remainders (≈ 2).
    pub orders: Vec<f64>,
}

/// The outcome of [`Simulation::gradient`].
#[derive(Debug, Clone, PartialEq)]
pub struct GradientReport {
    /// J.
    pub objective: f64,
    pub parameters: Vec<ParameterGradient>,
    /// Wall times (s) of the forward run and of the adjoint sweep.
    pub forward_s: f64,
    pub adjoint_s: f64,
    /// The bytes of the taped states.
    pub tape_bytes: usize,
    pub taylor: Option<TaylorTest>,
}

impl GradientReport {
    /// The document of `gradient.json`: `objective`, `gradient` (key path → dJ/dp),
    /// `forward_s`, `adjoint_s`, `peak_memory` (bytes of the taped states), and when checked
    /// the finite differences (`check`) and the Taylor test (`taylor`); a non-finite number is
    /// null.
    pub fn to_json(&self) -> serde_json::Value {
        let num = |x: f64| {
            serde_json::Number::from_f64(x)
                .map_or(serde_json::Value::Null, serde_json::Value::Number)
        };
        let mut gradient = serde_json::Map::new();
        let mut check = serde_json::Map::new();
        for p in &self.parameters {
            gradient.insert(p.path.clone(), num(p.gradient));
            if let Some((fd, h)) = p.finite_difference {
                check.insert(
                    p.path.clone(),
                    serde_json::json!({"finite_difference": num(fd), "h": h}),
                );
            }
        }
        let mut doc = serde_json::json!({
            "objective": num(self.objective),
            "gradient": gradient,
            "forward_s": self.forward_s,
            "adjoint_s": self.adjoint_s,
            "peak_memory": self.tape_bytes,
        });
        if let Some(t) = &self.taylor {
            doc["check"] = serde_json::Value::Object(check);
            doc["taylor"] = serde_json::json!({
                "h": t.remainders.iter().map(|x| x.0).collect::<Vec<_>>(),
                "remainder": t.remainders.iter().map(|x| num(x.1)).collect::<Vec<_>>(),
                "order": t.orders.iter().map(|&o| num(o)).collect::<Vec<_>>(),
            });
        }
        doc
    }
}

impl Simulation {
    /// Runs the scenario, taping its accepted steps, and computes its objective's gradient in
    /// its `[[parameters]]` by the discrete adjoint ([`crate::adjoint`]).
    pub fn gradient(&self, options: &GradientOptions) -> Result<GradientReport, Error> {
        let scenario = self.scenario()?;
        let plan = self.plan()?;
        let file = self.name.clone();
        let input = |e: InputError| Error::Input(e);
        if scenario.parameters.is_empty() {
            return Err(input(InputError::at_key(
                &file,
                "parameters",
                "a gradient needs at least one [[parameters]] entry with `path`, a key path \
                 such as `materials.<name>.mu`",
            )));
        }
        let mut parameters = Vec::new();
        for (i, p) in scenario.parameters.iter().enumerate() {
            let param = parameter(&scenario, &file, &p.path).map_err(|mut e| {
                e.key = Some(format!("parameters.{i}.path ({})", p.path));
                input(e)
            })?;
            parameters.push((p.path.clone(), param));
        }
        check_supported(&plan, &parameters).map_err(Error::Refused)?;
        let objective =
            Objective::build(&scenario, &plan, &file, self.base.as_deref()).map_err(input)?;
        let start = Instant::now();
        let mut tape = Tape::new(&plan);
        run_plan(
            &plan,
            RunOptions {
                observers: vec![&mut tape],
                out: options.out.clone(),
                overwrite: options.overwrite,
                overrides: self.overrides.clone(),
                ..Default::default()
            },
        )?;
        let forward_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let supports = self.support_sensitivities(&plan, &parameters)?;
        let g =
            gradient(&plan, &tape, &objective, &parameters, &supports).map_err(Error::Refused)?;
        let adjoint_s = start.elapsed().as_secs_f64();
        let mut report = GradientReport {
            objective: g.objective,
            parameters: parameters
                .iter()
                .zip(&g.gradient)
                .map(|((path, p), &d)| ParameterGradient {
                    path: path.clone(),
                    value: p.value(),
                    gradient: d,
                    finite_difference: None,
                })
                .collect(),
            forward_s,
            adjoint_s,
            tape_bytes: tape.state_bytes(),
            taylor: None,
        };
        if options.check {
            self.check_gradient(&mut report)?;
        }
        Ok(report)
    }

    /// The derivatives of the plan's support values in each parameter (empty where they do not
    /// move): only a pre-stretch's targets depend on parameters, (λ − 1)x in-plane and
    /// (λₜ − 1)z across a clamped face, λₜ the thickness stretch of the material's equibiaxial
    /// state (solved to round-off). They are central differences of the built supports with
    /// h = 10⁻⁶·|p|, exact for the linear targets and within about 10⁻¹⁰ for λₜ: rebuilding
    /// is cheap, and no derivative of the homogeneous solution is written twice.
    fn support_sensitivities(
        &self,
        plan: &crate::job::plan::Plan,
        parameters: &[(String, crate::io::build::Parameter)],
    ) -> Result<Vec<Vec<f64>>, Error> {
        if plan.prestretch.is_none() {
            return Ok(vec![Vec::new(); parameters.len()]);
        }
        let values = |v: f64, path: &str| -> Result<Vec<f64>, Error> {
            let p = self.clone().set(path, &format!("{v:e}")).plan()?;
            if p.supports.len() != plan.supports.len() {
                return Err(Error::Refused(format!(
                    "the supports change with `{path}`: no derivative of their values"
                )));
            }
            Ok(p.supports.iter().map(|d| d.value).collect())
        };
        let mut out = Vec::with_capacity(parameters.len());
        for (path, p) in parameters {
            if !matches!(
                p,
                crate::io::build::Parameter::Material(_)
                    | crate::io::build::Parameter::Prestretch { .. }
            ) {
                out.push(Vec::new());
                continue;
            }
            let v = p.value();
            let h = if v == 0.0 { 1e-6 } else { 1e-6 * v.abs() };
            let (up, down) = (values(v + h, path)?, values(v - h, path)?);
            let d: Vec<f64> = up
                .iter()
                .zip(&down)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect();
            out.push(if d.iter().all(|x| *x == 0.0) {
                Vec::new()
            } else {
                d
            });
        }
        Ok(out)
    }

    /// J with the parameters of `report` moved by `delta` (SI, in their order).
    fn objective_at(&self, report: &GradientReport, delta: &[f64]) -> Result<f64, Error> {
        let mut sim = self.clone();
        for (p, d) in report.parameters.iter().zip(delta) {
            if *d != 0.0 {
                sim = sim.set(&p.path, &format!("{:e}", p.value + d));
            }
        }
        let scenario = sim.scenario()?;
        let plan = sim.plan()?;
        let objective = Objective::build(&scenario, &plan, &sim.name, sim.base.as_deref())
            .map_err(Error::Input)?;
        let mut tape = Tape::new(&plan);
        run_plan(
            &plan,
            RunOptions {
                observers: vec![&mut tape],
                ..Default::default()
            },
        )?;
        objective
            .evaluate(&plan, &tape)
            .map(|e| e.value)
            .map_err(Error::Refused)
    }

    /// Central differences with h = 10⁻⁴·|p| (10⁻⁴ for p = 0) for each parameter, and the
    /// Taylor test in the direction δ = h·(±1, ∓1, …) relative to each value, at h, h/2, h/4.
    fn check_gradient(&self, report: &mut GradientReport) -> Result<(), Error> {
        let n = report.parameters.len();
        let step = |v: f64| if v == 0.0 { 1e-4 } else { 1e-4 * v.abs() };
        for i in 0..n {
            let h = step(report.parameters[i].value);
            let mut d = vec![0.0; n];
            d[i] = h;
            let up = self.objective_at(report, &d)?;
            d[i] = -h;
            let down = self.objective_at(report, &d)?;
            report.parameters[i].finite_difference = Some(((up - down) / (2.0 * h), h));
        }
        // a direction that moves every parameter by a share of its own size
        let direction: Vec<f64> = report
            .parameters
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                sign * 1e2 * step(p.value)
            })
            .collect();
        let slope: f64 = report
            .parameters
            .iter()
            .zip(&direction)
            .map(|(p, d)| p.gradient * d)
            .sum();
        let mut remainders = Vec::new();
        for k in 0..4 {
            let h = 0.5f64.powi(k);
            let d: Vec<f64> = direction.iter().map(|v| h * v).collect();
            let j = self.objective_at(report, &d)?;
            remainders.push((h, (j - report.objective - h * slope).abs()));
        }
        let orders = remainders
            .windows(2)
            .map(|w| (w[0].1 / w[1].1).log2())
            .collect();
        report.taylor = Some(TaylorTest { remainders, orders });
        Ok(())
    }
}
