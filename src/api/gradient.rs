//! The gradient of a scenario's objective in its parameters: the forward run taped, its adjoint,
//! and on request a check against central finite differences and a Taylor remainder test.

use super::error::Error;
use super::simulation::{run_plan, RunOptions, Simulation};
use crate::adjoint::objective::Objective;
use crate::adjoint::sweep::{check_supported, gradient, read_objective};
use crate::adjoint::tape::Tape;
use crate::io::atomic::write_atomic;
use crate::io::build::parameter;
use crate::io::plot::{line_plot, PlotSpec, Series};
use crate::io::scenario::InputError;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What [`Simulation::gradient`] does besides the gradient.
#[derive(Debug, Clone, Default)]
pub struct GradientOptions {
    /// Write the forward run's files here (as `deasim run`).
    pub out: Option<PathBuf>,
    pub overwrite: bool,
    /// Compare each derivative with a central finite difference and run a Taylor test.
    pub check: bool,
    /// The finite differences' step relative to each value (default 10⁻⁴): smaller where J is
    /// strongly nonlinear in a parameter (the truncation error falls as its square), larger
    /// where the solves' tolerance makes J noisy.
    pub fd_step: Option<f64>,
    /// The memory budget of the tape in bytes (default: the scenario's `gradient.memory`, else
    /// [`DEFAULT_MEMORY`]): beyond it the dynamic stages are recomputed from checkpoints.
    pub memory: Option<usize>,
}

/// The default memory budget of a gradient's tape: 1 GiB.
pub const DEFAULT_MEMORY: usize = 1 << 30;

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

/// dJ/dV (or dJ/dQ) at the knots of one control (`[[controls]]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ControlReport {
    /// Its index in the scenario's `[[controls]]`, its stage and electrode.
    pub index: usize,
    pub stage: String,
    /// The stage's start in the run's clock (s).
    pub stage_start: f64,
    pub electrode: String,
    /// What the knots are: a voltage (V) or a charge (C, a charge-controlled electrode's).
    pub quantity: ControlQuantity,
    /// The knots' stage times (s) and values (V or C).
    pub times: Vec<f64>,
    pub values: Vec<f64>,
    /// dJ/dV (or dJ/dQ) at each knot (the unit of J per V or per C).
    pub gradient: Vec<f64>,
    /// When checked: (knot, central finite difference, its step h in V or C) at a few knots.
    pub finite_differences: Vec<(usize, f64, f64)>,
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
    pub controls: Vec<ControlReport>,
    /// Wall times (s) of the forward run and of the adjoint sweep.
    pub forward_s: f64,
    pub adjoint_s: f64,
    /// The most bytes the tape held (states, checkpoints and the recomputed ones), its budget,
    /// and the steps the adjoint recomputed from checkpoints (0 when every state fitted).
    pub tape_bytes: usize,
    pub memory_budget: usize,
    pub recomputed_steps: usize,
    /// The bytes of the largest taped time step and checkpoint: `tape_bytes` stays within
    /// `memory_budget` plus twice the larger ([`Tape::unit_bytes`]).
    pub unit_bytes: (usize, usize),
    /// The adjoint's linear solves: factorisations of a transposed Jacobian, and GMRES
    /// iterations preconditioned by a held one.
    pub adjoint_factorizations: usize,
    pub adjoint_krylov_iterations: usize,
    pub taylor: Option<TaylorTest>,
}

impl GradientReport {
    /// The document of `gradient.json`: `objective`, `gradient` (key path → dJ/dp),
    /// `forward_s`, `adjoint_s`, `peak_memory` (the most bytes the tape held: states and
    /// checkpoints), `memory_budget` (bytes), `recomputed_steps`, `adjoint_factorizations`,
    /// `adjoint_krylov_iterations`, and when checked
    /// the finite differences (`check`) and the Taylor test (`taylor`); a non-finite number is
    /// null.
    pub fn to_json(&self) -> serde_json::Value {
        let num = json_number;
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
            "memory_budget": self.memory_budget,
            "recomputed_steps": self.recomputed_steps,
            "adjoint_factorizations": self.adjoint_factorizations,
            "adjoint_krylov_iterations": self.adjoint_krylov_iterations,
        });
        if !self.controls.is_empty() {
            doc["controls"] = serde_json::Value::Array(
                self.controls
                    .iter()
                    .map(|c| {
                        let mut v = serde_json::json!({
                            "stage": c.stage,
                            "electrode": c.electrode,
                            "quantity": c.quantity.name(),
                            "time": c.times,
                            "value": c.values,
                            "gradient": c.gradient.iter().map(|&g| num(g)).collect::<Vec<_>>(),
                        });
                        if !c.finite_differences.is_empty() {
                            v["check"] = c
                                .finite_differences
                                .iter()
                                .map(|&(k, fd, h)| {
                                    serde_json::json!({"knot": k, "finite_difference": num(fd), "h": h})
                                })
                                .collect();
                        }
                        v
                    })
                    .collect(),
            );
        }
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

impl GradientReport {
    /// Writes `gradient.json` into `dir` and, when the scenario has controls, `controls.csv`
    /// (the run's time in s, then dJ/dV, or dJ/dQ, of each control at its knots, a column
    /// `<electrode>@<stage>` each, empty where a control has no knot) and, with `plot_format`
    /// (`png` or `svg`), the plot `controls.<format>` of those derivatives. Returns the paths
    /// written.
    pub fn write(&self, dir: &Path, plot_format: Option<&str>) -> Result<Vec<PathBuf>, Error> {
        let io = |path: &Path, e: String| Error::Io {
            path: path.to_path_buf(),
            message: e,
        };
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e.to_string()))?;
        let mut written = Vec::new();
        let path = dir.join("gradient.json");
        let text = serde_json::to_string_pretty(&self.to_json()).unwrap_or_default() + "\n";
        write_atomic(&path, text.as_bytes()).map_err(|e| io(&path, e.to_string()))?;
        written.push(path);
        if self.controls.is_empty() {
            return Ok(written);
        }
        let header: Vec<String> = self
            .controls
            .iter()
            .map(|c| format!("{}@{}", c.electrode, c.stage))
            .collect();
        let columns: Vec<(f64, &[f64], &[f64])> = self
            .controls
            .iter()
            .map(|c| (c.stage_start, c.times.as_slice(), c.gradient.as_slice()))
            .collect();
        let csv = knots_csv(&header, &columns);
        let path = dir.join("controls.csv");
        write_atomic(&path, csv.as_bytes()).map_err(|e| io(&path, e.to_string()))?;
        written.push(path);
        if let Some(format) = plot_format {
            let series: Vec<Series> = self
                .controls
                .iter()
                .map(|c| Series {
                    label: format!("{} in {}", c.electrode, c.stage),
                    x: c.times.iter().map(|t| c.stage_start + t).collect(),
                    y: c.gradient.clone(),
                })
                .collect();
            let path = dir.join(format!("controls.{format}"));
            line_plot(
                &path,
                &PlotSpec {
                    title: "the objective's gradient in the controlled drives",
                    x_label: "time [s]",
                    y_label: "dJ/dV (or dJ/dQ) at the knots [unit of J per V or C]",
                    series: &series,
                },
            )
            .map_err(|e| io(&path, e.to_string()))?;
            written.push(path);
        }
        Ok(written)
    }
}

/// A JSON number, or null for a non-finite one.
pub(super) fn json_number(x: f64) -> serde_json::Value {
    serde_json::Number::from_f64(x).map_or(serde_json::Value::Null, serde_json::Value::Number)
}

/// What the knots of a control set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlQuantity {
    /// An electrode's voltage, or its circuit's source (V).
    Voltage,
    /// A charge-controlled electrode's charge (C).
    Charge,
}

impl ControlQuantity {
    /// The quantity of a control of `electrode`: its charge under charge control, else a
    /// voltage.
    pub(super) fn of(plan: &crate::job::plan::Plan, electrode: &str) -> ControlQuantity {
        let charged = plan
            .electrodes
            .iter()
            .any(|e| e.name == electrode && e.charge.is_some());
        if charged {
            ControlQuantity::Charge
        } else {
            ControlQuantity::Voltage
        }
    }

    /// Its name in the outputs: `voltage` or `charge`.
    pub fn name(self) -> &'static str {
        match self {
            ControlQuantity::Voltage => "voltage",
            ControlQuantity::Charge => "charge",
        }
    }

    /// Its unit: `V` or `C`.
    pub fn unit(self) -> &'static str {
        match self {
            ControlQuantity::Voltage => "V",
            ControlQuantity::Charge => "C",
        }
    }
}

/// A CSV of values at the knots of several controls: `time` (the run's clock, s) then one
/// column per control (`header`), a row per distinct knot time, a cell empty where a control has
/// no knot. Each column is (its stage's start, its knots' stage times, its values).
pub(super) fn knots_csv(header: &[String], columns: &[(f64, &[f64], &[f64])]) -> String {
    let mut rows: Vec<(f64, usize, usize)> = columns
        .iter()
        .enumerate()
        .flat_map(|(ci, (start, times, _))| {
            times
                .iter()
                .enumerate()
                .map(move |(k, t)| (start + t, ci, k))
        })
        .collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut csv = String::from("time");
    for h in header {
        csv += &format!(",{h}");
    }
    csv.push('\n');
    let mut i = 0;
    while i < rows.len() {
        let t = rows[i].0;
        let mut cells = vec![String::new(); columns.len()];
        while i < rows.len() && rows[i].0 == t {
            let (_, ci, k) = rows[i];
            cells[ci] = format!("{:e}", columns[ci].2[k]);
            i += 1;
        }
        csv += &format!("{t:e},{}\n", cells.join(","));
    }
    csv
}

impl Simulation {
    /// Runs the scenario, taping its accepted steps, and computes its objective's gradient in
    /// its `[[parameters]]` by the discrete adjoint ([`crate::adjoint`]).
    pub fn gradient(&self, options: &GradientOptions) -> Result<GradientReport, Error> {
        let scenario = self.scenario()?;
        let plan = self.plan()?;
        let file = self.name.clone();
        let input = |e: InputError| Error::Input(e);
        if scenario.parameters.is_empty() && scenario.controls.is_empty() {
            return Err(input(InputError::at_key(
                &file,
                "parameters",
                "a gradient needs at least one [[parameters]] entry with `path`, a key path \
                 such as `materials.<name>.mu`, or a [[controls]] entry",
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
        check_supported(&plan).map_err(Error::Refused)?;
        let objective =
            Objective::build(&scenario, &plan, &file, self.base.as_deref()).map_err(input)?;
        let memory = match options.memory {
            Some(m) => m,
            None => memory_budget(&scenario, &file)?,
        };
        let start = Instant::now();
        let mut tape = Tape::with_budget(&plan, memory);
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
        let controls = g
            .controls
            .iter()
            .map(|c| {
                let stage = plan.stages[c.stage].name.clone();
                let index = scenario
                    .controls
                    .iter()
                    .position(|s| {
                        s.electrode == c.electrode && s.stage.as_deref().is_none_or(|n| n == stage)
                    })
                    .unwrap_or(0);
                ControlReport {
                    index,
                    stage,
                    stage_start: plan.stage_start(c.stage),
                    electrode: c.electrode.clone(),
                    quantity: ControlQuantity::of(&plan, &c.electrode),
                    times: c.knots.iter().map(|k| k.0).collect(),
                    values: c.knots.iter().map(|k| k.1).collect(),
                    gradient: c.gradient.clone(),
                    finite_differences: Vec::new(),
                }
            })
            .collect();
        // a control without `values` starts at its electrode's waveform, whose amplitude and
        // offset (or constant charge) then move its knots
        let mut derivatives = g.gradient.clone();
        for c in &g.controls {
            let spec = scenario
                .controls
                .iter()
                .find(|s| s.electrode == c.electrode);
            if spec.is_some_and(|s| s.values.is_some()) {
                continue;
            }
            let stage = &plan.stages[c.stage];
            let Some(e) = plan.electrodes.iter().find(|e| e.name == c.electrode) else {
                continue;
            };
            for ((_, p), d) in parameters.iter().zip(derivatives.iter_mut()) {
                if let crate::io::build::Parameter::Charge {
                    electrode, scalar, ..
                } = p
                {
                    // each knot starts at the charge's waveform
                    if let (true, Some(w)) = (*electrode == c.electrode, &e.charge) {
                        *d += c
                            .knots
                            .iter()
                            .zip(&c.gradient)
                            .map(|(k, g)| g * w.derivative(k.0, *scalar))
                            .sum::<f64>();
                    }
                }
                if let crate::io::build::Parameter::Voltage {
                    electrode,
                    scalar,
                    source: false,
                    ..
                } = p
                {
                    if *electrode == c.electrode {
                        let w = stage.waveform(&e.voltage);
                        *d += c
                            .knots
                            .iter()
                            .zip(&c.gradient)
                            .map(|(k, g)| g * w.derivative(k.0, *scalar))
                            .sum::<f64>();
                    }
                }
            }
        }
        let mut report = GradientReport {
            objective: g.objective,
            controls,
            parameters: parameters
                .iter()
                .zip(&derivatives)
                .map(|((path, p), &d)| ParameterGradient {
                    path: path.clone(),
                    value: p.value(),
                    gradient: d,
                    finite_difference: None,
                })
                .collect(),
            forward_s,
            adjoint_s,
            tape_bytes: g.peak_bytes,
            memory_budget: memory,
            recomputed_steps: g.recomputed_steps,
            unit_bytes: tape.unit_bytes(),
            adjoint_factorizations: g.solves.factorizations,
            adjoint_krylov_iterations: g.solves.iterations,
            taylor: None,
        };
        if options.check {
            if let Some(h) = options.fd_step.filter(|h| !(h.is_finite() && *h > 0.0)) {
                return Err(Error::Refused(format!(
                    "the finite differences' relative step must be a positive number; got {h}"
                )));
            }
            self.check_gradient(&mut report, options.fd_step)?;
        }
        Ok(report)
    }

    /// The derivatives of the plan's support values in each parameter (empty where they do not
    /// move): only a pre-stretch's targets depend on parameters, (λ − 1)x in-plane and
    /// (λₜ − 1)z across a clamped face, λₜ the thickness stretch of the material's equibiaxial
    /// state (solved to round-off). They are central differences of the built supports with
    /// h = 10⁻⁶·|p|, exact for the linear targets and within about 10⁻¹⁰ for λₜ: rebuilding
    /// is cheap, and no derivative of the homogeneous solution is written twice.
    pub(super) fn support_sensitivities(
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

    /// J with the parameters of `report` moved by `delta` (SI, in their order) and the knots
    /// of its controls by `knots` (V, control by control; empty: unmoved).
    fn objective_at(
        &self,
        report: &GradientReport,
        delta: &[f64],
        knots: &[Vec<f64>],
    ) -> Result<f64, Error> {
        let mut sim = self.clone();
        for (p, d) in report.parameters.iter().zip(delta) {
            if *d != 0.0 {
                sim = sim.set(&p.path, &format!("{:e}", p.value + d));
            }
        }
        // the knots as the moved parameters place them (a control without `values` starts at
        // its electrode's waveform), moved by `knots`
        let moved = if knots.iter().any(|k| !k.is_empty()) {
            Some(sim.plan()?)
        } else {
            None
        };
        for (c, d) in report.controls.iter().zip(knots) {
            let Some(plan) = moved.as_ref().filter(|_| !d.is_empty()) else {
                continue;
            };
            let base: Vec<f64> = plan
                .stages
                .iter()
                .find(|s| s.name == c.stage)
                .and_then(|s| s.controls.iter().find(|k| k.0 == c.electrode))
                .map(|k| k.1.iter().map(|p| p.1).collect())
                .unwrap_or_else(|| c.values.clone());
            let values: Vec<String> = base
                .iter()
                .zip(d)
                .map(|(v, x)| format!("{:e}", v + x))
                .collect();
            sim = sim.set(
                &format!("controls.{}.values", c.index),
                &format!("[{}]", values.join(", ")),
            );
        }
        let scenario = sim.scenario()?;
        let plan = sim.plan()?;
        let objective = Objective::build(&scenario, &plan, &sim.name, sim.base.as_deref())
            .map_err(Error::Input)?;
        let tape = taped_run(&plan, memory_budget(&scenario, &sim.name)?)?;
        read_objective(&plan, &tape, &objective)
            .map(|(j, _)| j.value)
            .map_err(Error::Refused)
    }

    /// Central differences with h = ε·|p| (ε for p = 0; ε = `fd_step`, default 10⁻⁴) for each
    /// parameter and at three knots of each control (the second, the middle and the last but
    /// one, h = ε times the control's largest voltage, 1 V at least), and the Taylor test in the direction
    /// δ = 10²h·(±1, ∓1, …) over every parameter and knot, at 1, 1/2, 1/4, 1/8 of it.
    fn check_gradient(
        &self,
        report: &mut GradientReport,
        fd_step: Option<f64>,
    ) -> Result<(), Error> {
        let n = report.parameters.len();
        let rel = fd_step.unwrap_or(1e-4);
        let step = |v: f64| if v == 0.0 { rel } else { rel * v.abs() };
        let none: Vec<Vec<f64>> = vec![Vec::new(); report.controls.len()];
        for i in 0..n {
            let h = step(report.parameters[i].value);
            let mut d = vec![0.0; n];
            d[i] = h;
            let up = self.objective_at(report, &d, &none)?;
            d[i] = -h;
            let down = self.objective_at(report, &d, &none)?;
            report.parameters[i].finite_difference = Some(((up - down) / (2.0 * h), h));
        }
        // ε times the control's largest value (1 V, or 1 nC, where every knot is at zero)
        let knot_step = |c: &ControlReport| {
            let largest = c.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let unit = match c.quantity {
                ControlQuantity::Charge => 1e-9,
                ControlQuantity::Voltage => 1.0,
            };
            rel * if largest > 0.0 { largest } else { unit }
        };
        for ci in 0..report.controls.len() {
            let c = &report.controls[ci];
            let m = c.values.len();
            let h = knot_step(c);
            let mut picks = vec![1.min(m - 1), m / 2, m.saturating_sub(2)];
            picks.dedup();
            let mut fds = Vec::new();
            for k in picks {
                let mut knots = none.clone();
                knots[ci] = vec![0.0; m];
                knots[ci][k] = h;
                let up = self.objective_at(report, &vec![0.0; n], &knots)?;
                knots[ci][k] = -h;
                let down = self.objective_at(report, &vec![0.0; n], &knots)?;
                fds.push((k, (up - down) / (2.0 * h), h));
            }
            report.controls[ci].finite_differences = fds;
        }
        // a direction that moves every parameter by a share of its own size
        let sign = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        let direction: Vec<f64> = report
            .parameters
            .iter()
            .enumerate()
            .map(|(i, p)| sign(i) * 1e2 * step(p.value))
            .collect();
        let knot_direction: Vec<Vec<f64>> = report
            .controls
            .iter()
            .map(|c| {
                let h = knot_step(c);
                (0..c.values.len()).map(|k| sign(k + 1) * 1e2 * h).collect()
            })
            .collect();
        let slope: f64 = report
            .parameters
            .iter()
            .zip(&direction)
            .map(|(p, d)| p.gradient * d)
            .sum::<f64>()
            + report
                .controls
                .iter()
                .zip(&knot_direction)
                .map(|(c, d)| c.gradient.iter().zip(d).map(|(g, x)| g * x).sum::<f64>())
                .sum::<f64>();
        let mut remainders = Vec::new();
        for k in 0..4 {
            let h = 0.5f64.powi(k);
            let d: Vec<f64> = direction.iter().map(|v| h * v).collect();
            let knots: Vec<Vec<f64>> = knot_direction
                .iter()
                .map(|c| c.iter().map(|v| h * v).collect())
                .collect();
            let j = self.objective_at(report, &d, &knots)?;
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

/// The memory budget of a scenario's taped states (bytes): its `gradient.memory`, else
/// [`DEFAULT_MEMORY`].
pub(crate) fn memory_budget(
    scenario: &crate::io::scenario::Scenario,
    file: &str,
) -> Result<usize, Error> {
    match scenario.gradient.as_ref().and_then(|g| g.memory.as_ref()) {
        Some(m) => m
            .bytes()
            .map_err(|m| Error::Input(InputError::at_key(file, "gradient.memory", m))),
        None => Ok(DEFAULT_MEMORY),
    }
}

/// Runs `plan` without files, with a tape of its accepted steps for an adjoint or an objective
/// within `budget` bytes.
pub(crate) fn taped_run(plan: &crate::job::plan::Plan, budget: usize) -> Result<Tape, Error> {
    let mut tape = Tape::with_budget(plan, budget);
    run_plan(
        plan,
        RunOptions {
            observers: vec![&mut tape],
            ..Default::default()
        },
    )?;
    Ok(tape)
}
