//! Optimal control: the knots of a scenario's `[[controls]]` that minimise its `[[objective]]`,
//! by the projected quasi-Newton method of [`crate::control`] on the reduced problem (each
//! evaluation one forward run and its adjoint); and the objective of a plain run.

use super::error::Error;
use super::gradient::json_number;
use super::gradient::{knots_csv, memory_budget, taped_run, ControlQuantity};
use super::response_model::{ResponseModel, Slot, PROBED_KNOT, PROBE_STEP};
use super::results::Results;
use super::simulation::{run_plan, RunOptions, Simulation};
use crate::adjoint::objective::{Objective, Term};
use crate::adjoint::sweep::{check_supported, gradient, read_objective};
use crate::adjoint::tape::Tape;
use crate::control::{minimize_with, Curvature, Feasible, Iteration, Options};
use crate::io::atomic::write_atomic;
use crate::io::plot::{line_plot, stacked_plot, PlotSpec, Series};
use crate::io::scenario::{apply_override, InputError, Scenario};
use crate::job::observer::Observer;
use crate::job::plan::{Plan, StageKind};
use crate::time::stage::Method;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How [`Simulation::control`] optimises and where it writes.
#[derive(Debug, Clone)]
pub struct ControlOptions {
    /// Write the optimised run's files here (as `deasim run`).
    pub out: Option<PathBuf>,
    pub overwrite: bool,
    /// Iterations at most (each one or more runs with their adjoints).
    pub max_iterations: usize,
    /// Converged when the projected gradient falls by this factor from the start.
    pub gradient_tolerance: f64,
    /// Converged when an iteration lowers J by less than this share of it.
    pub objective_tolerance: f64,
    /// Start the quasi-Newton recursion from a measured response model of the misfit terms
    /// (one extra run per control; see `response_model`), instead of a scalar.
    pub response_model: bool,
}

impl Default for ControlOptions {
    fn default() -> Self {
        let o = Options::default();
        ControlOptions {
            out: None,
            overwrite: false,
            max_iterations: o.max_iterations,
            gradient_tolerance: o.gradient_tolerance,
            objective_tolerance: o.objective_tolerance,
            response_model: true,
        }
    }
}

/// One optimised control: its knots and bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// Its index in `[[controls]]`, its stage (with the stage's start in the run's clock, s)
    /// and electrode.
    pub index: usize,
    pub stage: String,
    pub stage_start: f64,
    pub electrode: String,
    /// What the knots are: a voltage (V: an electrode's, or its circuit's source) or a charge
    /// (C: a charge-controlled electrode's).
    pub quantity: ControlQuantity,
    /// Knot times (stage time, s), the starting and the optimised values (V or C), and dJ/dV
    /// (or dJ/dQ) at the optimum.
    pub times: Vec<f64>,
    pub initial: Vec<f64>,
    pub values: Vec<f64>,
    pub gradient: Vec<f64>,
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub max_rate: Option<f64>,
}

/// The outcome of [`Simulation::control`].
#[derive(Debug, Clone)]
pub struct OptimalControl {
    /// J of the optimised drive (its own run).
    pub objective: f64,
    /// Per accepted iteration (the start first): J, the projected gradient's largest entry in
    /// the scaled knots, the runs made so far.
    pub history: Vec<Iteration>,
    pub converged: bool,
    pub reason: String,
    /// Runs with their adjoints (the plain runs of the starting and the optimised drive
    /// besides).
    pub evaluations: usize,
    pub wall_s: f64,
    pub drives: Vec<Drive>,
    /// The optimised run.
    pub results: Results,
    /// The run of the starting drive (for comparison).
    pub start: Results,
    /// `controlled.toml`: the scenario with the optimised knots as its controls' values.
    pub controlled: String,
}

/// Knot scale of a control (V or C): its bounds' range, else the largest of its |values|, its
/// bounds and `least` (1 kV, or 10 nC for a charge: a small film's charge at a few kV); the
/// optimiser works in knots divided by it.
fn scale(lower: Option<f64>, upper: Option<f64>, values: &[f64], least: f64) -> f64 {
    match (lower, upper) {
        (Some(l), Some(u)) => u - l,
        _ => values
            .iter()
            .chain(lower.iter())
            .chain(upper.iter())
            .fold(least, |m, v| m.max(v.abs())),
    }
}

/// The controls of a plan as optimisation variables: (stage index, position in the stage's
/// controls, spec index) and their scales.
struct Layout {
    slots: Vec<(usize, usize, usize, f64)>,
}

impl Layout {
    fn new(scenario: &Scenario, plan: &Plan) -> Layout {
        let mut slots = Vec::new();
        for (si, stage) in plan.stages.iter().enumerate() {
            for (ci, (electrode, knots)) in stage.controls.iter().enumerate() {
                let index = scenario
                    .controls
                    .iter()
                    .position(|s| {
                        s.electrode == *electrode
                            && s.stage.as_deref().is_none_or(|n| n == stage.name)
                    })
                    .unwrap_or(0);
                let spec = &scenario.controls[index];
                let values: Vec<f64> = knots.iter().map(|k| k.1).collect();
                let least = match ControlQuantity::of(plan, electrode) {
                    ControlQuantity::Charge => 1e-8,
                    ControlQuantity::Voltage => 1e3,
                };
                let s = scale(spec.lower, spec.upper, &values, least);
                slots.push((si, ci, index, s));
            }
        }
        Layout { slots }
    }

    /// The scaled knots of `plan`.
    fn variables(&self, plan: &Plan) -> Vec<f64> {
        self.slots
            .iter()
            .flat_map(|&(si, ci, _, s)| plan.stages[si].controls[ci].1.iter().map(move |k| k.1 / s))
            .collect()
    }

    /// `plan` with the knots `z` (scaled).
    fn apply(&self, plan: &mut Plan, z: &[f64]) {
        let mut at = 0;
        for &(si, ci, _, s) in &self.slots {
            for k in plan.stages[si].controls[ci].1.iter_mut() {
                k.1 = z[at] * s;
                at += 1;
            }
        }
    }

    /// The controls as the response model sees them: their variables, stages, knot times in the
    /// run's clock and scales.
    fn model_slots(&self, plan: &Plan) -> Vec<Slot> {
        let mut first = 0;
        self.slots
            .iter()
            .map(|&(si, ci, _, s)| {
                let knots = &plan.stages[si].controls[ci].1;
                let start = plan.stage_start(si);
                let drive_points = match plan.stages[si].kind {
                    StageKind::Dynamic {
                        scheme: Method::Implicit(scheme),
                        ..
                    } => scheme.drive_weights(),
                    _ => vec![(1.0, 1.0)],
                };
                let slot = Slot {
                    first,
                    stage: si,
                    start,
                    times: knots.iter().map(|k| start + k.0).collect(),
                    scale: s,
                    drive_points,
                };
                first += knots.len();
                slot
            })
            .collect()
    }

    /// The response model of the problem at the starting knots `z0`: the run there, and one
    /// with each control's probed knot moved by [`PROBE_STEP`] within its bounds. Only when
    /// every control drives a dynamic stage: there the inertia makes the problem ill
    /// conditioned (the pad's response rolls off as 1/ω²); a quasi-static stage's is well
    /// conditioned, and its response to a knot changes as the branches relax (measured on
    /// `diaphragm-creep-hold`: 24 iterations with the model, 11 without). And only when the
    /// objective prices the drive (a `drive-effort` term): without it the model's steps in the
    /// directions the misfit hardly sees are set by the damping alone (measured on
    /// `diaphragm-track`: J 0.29 after 77 runs with the model, 0.24 without).
    fn response_model(
        &self,
        plan: &Plan,
        objective: &Objective,
        set: &Feasible,
        z0: &[f64],
        budget: usize,
    ) -> Result<Option<ResponseModel>, Error> {
        let dynamic = |si: usize| matches!(plan.stages[si].kind, StageKind::Dynamic { .. });
        let priced = objective
            .terms
            .iter()
            .any(|t| matches!(t, Term::DriveEffort { weight, .. } if *weight > 0.0));
        if !priced || !self.slots.iter().all(|&(si, ..)| dynamic(si)) {
            return Ok(None);
        }
        let read = |z: &[f64]| -> Result<_, Error> {
            let mut p = plan.clone();
            self.apply(&mut p, z);
            let tape = taped_run(&p, budget)?;
            Ok(read_objective(&p, &tape, objective)
                .map_err(Error::Refused)?
                .0)
        };
        let slots = self.model_slots(plan);
        let base = read(z0)?;
        let mut responses = Vec::with_capacity(slots.len());
        for slot in &slots {
            let i = slot.first + PROBED_KNOT;
            let moved = if z0[i] + PROBE_STEP <= set.upper[i] {
                z0[i] + PROBE_STEP
            } else {
                z0[i] - PROBE_STEP
            };
            let mut z = z0.to_vec();
            z[i] = moved;
            responses.push((moved, read(&z)?));
        }
        Ok(ResponseModel::new(objective, &slots, z0, &base, &responses))
    }

    /// The bounds and rate chains in the scaled knots.
    fn feasible(&self, scenario: &Scenario, plan: &Plan) -> Feasible {
        let mut set = Feasible::default();
        for &(si, ci, index, s) in &self.slots {
            let spec = &scenario.controls[index];
            let knots = &plan.stages[si].controls[ci].1;
            let first = set.lower.len();
            for _ in knots {
                set.lower
                    .push(spec.lower.map_or(f64::NEG_INFINITY, |l| l / s));
                set.upper.push(spec.upper.map_or(f64::INFINITY, |u| u / s));
            }
            if let Some(r) = spec.max_rate {
                let limits = knots
                    .windows(2)
                    .map(|w| r * (w[1].0 - w[0].0) / s)
                    .collect();
                set.chains
                    .push(((first..first + knots.len()).collect(), limits));
            }
        }
        set
    }
}

impl Simulation {
    /// Optimises the knots of the scenario's `[[controls]]` for its `[[objective]]` within their
    /// bounds and rate limits, then runs the optimised drive (writing its files to
    /// `options.out`). `progress` sees every accepted iteration.
    pub fn control(
        &self,
        options: &ControlOptions,
        mut progress: impl FnMut(&Iteration),
    ) -> Result<OptimalControl, Error> {
        let start = Instant::now();
        let scenario = self.scenario()?;
        let plan = self.plan()?;
        let input =
            |key: &str, message: String| Error::Input(InputError::at_key(&self.name, key, message));
        if scenario.controls.is_empty() {
            return Err(input(
                "controls",
                "optimal control needs at least one [[controls]] entry (`electrode`, `stage`, \
                 `interval`, `lower`, `upper`)"
                    .into(),
            ));
        }
        if !(options.gradient_tolerance >= 0.0 && options.objective_tolerance >= 0.0) {
            return Err(Error::Refused(format!(
                "the tolerances must be numbers ≥ 0; got {:e} (projected gradient) and {:e} \
                 (objective change)",
                options.gradient_tolerance, options.objective_tolerance
            )));
        }
        check_supported(&plan).map_err(Error::Refused)?;
        let objective = Objective::build(&scenario, &plan, &self.name, self.base.as_deref())
            .map_err(Error::Input)?;
        let layout = Layout::new(&scenario, &plan);
        let set = layout.feasible(&scenario, &plan);
        let z0 = layout.variables(&plan);
        check_start(&layout, &set, &z0, &scenario, &plan)
            .map_err(|(key, message)| input(&key, message))?;
        let budget = memory_budget(&scenario, &self.name)?;
        let evaluate = |z: &[f64]| -> Result<(f64, Vec<f64>), Error> {
            let mut p = plan.clone();
            layout.apply(&mut p, z);
            let tape = taped_run(&p, budget)?;
            let g = gradient(&p, &tape, &objective, &[], &[]).map_err(Error::Refused)?;
            let mut dz = Vec::with_capacity(z.len());
            for &(si, ci, _, s) in &layout.slots {
                let name = &p.stages[si].controls[ci].0;
                let c = g
                    .controls
                    .iter()
                    .find(|c| c.stage == si && c.electrode == *name)
                    .ok_or_else(|| {
                        Error::Refused(format!("no gradient of the control of `{name}`"))
                    })?;
                dz.extend(c.gradient.iter().map(|d| d * s));
            }
            Ok((g.objective, dz))
        };
        let model = if options.response_model {
            layout.response_model(&plan, &objective, &set, &z0, budget)?
        } else {
            None
        };
        let hessian = model.as_ref().map(|m| move |z: &[f64]| m.hessian(z));
        let minimum = minimize_with(
            evaluate,
            &z0,
            &set,
            &Options {
                max_iterations: options.max_iterations,
                gradient_tolerance: options.gradient_tolerance,
                objective_tolerance: options.objective_tolerance,
                ..Options::default()
            },
            hessian.as_ref().map(|h| h as Curvature),
            &mut progress,
        )?;
        // the starting drive's run, to compare with
        let start_run = run_plan(&plan, RunOptions::default())?;
        // the optimised run, with its files
        let mut best = plan.clone();
        layout.apply(&mut best, &minimum.x);
        let mut tape = Tape::with_budget(&best, budget);
        let results = run_plan(
            &best,
            RunOptions {
                observers: vec![&mut tape],
                out: options.out.clone(),
                overwrite: options.overwrite,
                overrides: self.overrides.clone(),
                ..Default::default()
            },
        )?;
        let value = read_objective(&best, &tape, &objective)
            .map_err(Error::Refused)?
            .0
            .value;
        let mut at = 0;
        let drives: Vec<Drive> = layout
            .slots
            .iter()
            .map(|&(si, ci, index, s)| {
                let spec = &scenario.controls[index];
                let (electrode, knots) = &best.stages[si].controls[ci];
                let n = knots.len();
                let d = Drive {
                    index,
                    stage: best.stages[si].name.clone(),
                    stage_start: best.stage_start(si),
                    electrode: electrode.clone(),
                    quantity: ControlQuantity::of(&plan, electrode),
                    times: knots.iter().map(|k| k.0).collect(),
                    initial: plan.stages[si].controls[ci].1.iter().map(|k| k.1).collect(),
                    values: knots.iter().map(|k| k.1).collect(),
                    gradient: minimum.gradient[at..at + n].iter().map(|g| g / s).collect(),
                    lower: spec.lower,
                    upper: spec.upper,
                    max_rate: spec.max_rate,
                };
                at += n;
                d
            })
            .collect();
        let controlled = self.controlled_toml(&drives)?;
        Ok(OptimalControl {
            objective: value,
            history: minimum.history,
            converged: minimum.converged,
            reason: minimum.reason,
            evaluations: minimum.evaluations,
            wall_s: start.elapsed().as_secs_f64(),
            drives,
            results,
            start: start_run,
            controlled,
        })
    }

    /// The scenario with its overrides applied and each control's `values` set to `drives`,
    /// its relative file paths made absolute so that it runs from anywhere.
    fn controlled_toml(&self, drives: &[Drive]) -> Result<String, Error> {
        let text = self.scenario_toml(|table| {
            if let Some(controls) = table.get_mut("controls").and_then(|c| c.as_array_mut()) {
                for d in drives {
                    if let Some(c) = controls.get_mut(d.index).and_then(|c| c.as_table_mut()) {
                        let values = d.values.iter().map(|v| toml::Value::Float(*v)).collect();
                        c.insert("values".into(), toml::Value::Array(values));
                    }
                }
            }
        })?;
        Ok(format!(
            "# The scenario with the optimised drive: each control's `values` are the optimised \
             knots (V).\n{text}"
        ))
    }

    /// The scenario's TOML with its overrides applied and `edit` made, its relative file paths
    /// made absolute so that it runs from anywhere.
    pub(super) fn scenario_toml(
        &self,
        edit: impl FnOnce(&mut toml::Table),
    ) -> Result<String, Error> {
        let mut table: toml::Table = self.text.parse().map_err(|e: toml::de::Error| {
            Error::Input(InputError::at_key(&self.name, "", e.to_string()))
        })?;
        let refused = |(k, m): (String, String)| Error::Refused(format!("`{k}`: {m}"));
        for o in &self.overrides {
            apply_override(&mut table, o).map_err(refused)?;
        }
        edit(&mut table);
        if let Some(base) = &self.base {
            absolute_paths(&mut table, base);
        }
        toml::to_string(&table).map_err(|e| Error::Refused(e.to_string()))
    }

    /// The objective of a run: a [`Tape`] to observe it with, or `None` when the scenario has
    /// no `[[objective]]`.
    pub fn objective_tape(&self) -> Result<Option<ObjectiveTape>, Error> {
        let scenario = self.scenario()?;
        if scenario.objective.is_empty() {
            return Ok(None);
        }
        let plan = self.plan()?;
        let objective = Objective::build(&scenario, &plan, &self.name, self.base.as_deref())
            .map_err(Error::Input)?;
        let tape = Tape::with_budget(&plan, memory_budget(&scenario, &self.name)?);
        Ok(Some(ObjectiveTape {
            plan,
            objective,
            tape,
        }))
    }
}

/// A run's tape and its scenario's objective: observe the run with it, then read J.
pub struct ObjectiveTape {
    plan: Plan,
    objective: Objective,
    tape: Tape,
}

impl ObjectiveTape {
    /// The observer to run with.
    pub fn observer(&mut self) -> &mut dyn Observer {
        &mut self.tape
    }

    /// The most bytes its tape held (states and checkpoints), within the scenario's
    /// `gradient.memory` plus two steps.
    pub fn peak_bytes(&self) -> usize {
        self.tape.peak_bytes()
    }

    /// J of the observed run (its steps recomputed from checkpoints where the run went beyond
    /// the scenario's `gradient.memory`).
    pub fn value(&self) -> Result<f64, Error> {
        read_objective(&self.plan, &self.tape, &self.objective)
            .map(|(e, _)| e.value)
            .map_err(Error::Refused)
    }
}

/// Makes the relative paths of the keys `file` and `data` absolute against `base`.
fn absolute_paths(table: &mut toml::Table, base: &Path) {
    for (key, value) in table.iter_mut() {
        match value {
            toml::Value::String(s)
                if (key == "file" || key == "data") && Path::new(s.as_str()).is_relative() =>
            {
                *s = base.join(s.as_str()).display().to_string();
            }
            toml::Value::Table(t) => absolute_paths(t, base),
            toml::Value::Array(a) => {
                for v in a {
                    if let toml::Value::Table(t) = v {
                        absolute_paths(t, base);
                    }
                }
            }
            _ => {}
        }
    }
}

/// The key and reason where the starting drive breaks a bound or a rate limit.
fn check_start(
    layout: &Layout,
    set: &Feasible,
    z0: &[f64],
    scenario: &Scenario,
    plan: &Plan,
) -> Result<(), (String, String)> {
    let mut at = 0;
    for &(si, ci, index, s) in &layout.slots {
        let spec = &scenario.controls[index];
        let knots = &plan.stages[si].controls[ci].1;
        let key = |k: &str| format!("controls.{index}.{k}");
        let u = ControlQuantity::of(plan, &plan.stages[si].controls[ci].0).unit();
        for (k, &(t, v)) in knots.iter().enumerate() {
            let tol = 1e-12 * s;
            if let Some(l) = spec.lower.filter(|l| v < l - tol) {
                return Err((
                    key("lower"),
                    format!(
                        "the starting drive ({v:e} {u} at {t:e} s of stage `{}`) lies below \
                         `lower` ({l:e} {u}): give `values` inside the bounds, or other bounds",
                        plan.stages[si].name
                    ),
                ));
            }
            if let Some(up) = spec.upper.filter(|up| v > up + tol) {
                return Err((
                    key("upper"),
                    format!(
                        "the starting drive ({v:e} {u} at {t:e} s of stage `{}`) lies above \
                         `upper` ({up:e} {u}): give `values` inside the bounds, or other bounds",
                        plan.stages[si].name
                    ),
                ));
            }
            if let (Some(r), Some(&(t1, v1))) = (spec.max_rate, knots.get(k + 1)) {
                let rate = (v1 - v) / (t1 - t);
                if rate.abs() > r * (1.0 + 1e-12) {
                    return Err((
                        key("max_rate"),
                        format!(
                            "the starting drive changes at {rate:e} {u}/s between {t:e} and \
                             {t1:e} s of stage `{}`, faster than `max_rate` ({r:e} {u}/s)",
                            plan.stages[si].name
                        ),
                    ));
                }
            }
        }
        at += knots.len();
    }
    debug_assert!(at == z0.len() && set.lower.len() == at);
    Ok(())
}

impl OptimalControl {
    /// The document of `control.json`.
    pub fn to_json(&self) -> serde_json::Value {
        let num = json_number;
        serde_json::json!({
            "objective": self.history.iter().map(|i| num(i.objective)).collect::<Vec<_>>(),
            "final_objective": num(self.objective),
            "gradient_norm": self.history.iter().map(|i| num(i.projected_gradient)).collect::<Vec<_>>(),
            "evaluations_per_iteration": self.history.iter().map(|i| i.evaluations).collect::<Vec<_>>(),
            "iterations": self.history.len() - 1,
            "evaluations": self.evaluations,
            "converged": self.converged,
            "reason": self.reason,
            "wall_s": self.wall_s,
            "controls": self.drives.iter().map(|d| serde_json::json!({
                "index": d.index,
                "electrode": d.electrode,
                "quantity": d.quantity.name(),
                "stage": d.stage,
                "knots": d.times.len(),
                "lower": d.lower,
                "upper": d.upper,
                "max_rate": d.max_rate,
            })).collect::<Vec<_>>(),
        })
    }

    /// Writes `control.json`, `control.csv` (`time` in the run's clock, s, then
    /// `voltage:<electrode>` per control in V, or `charge:<electrode>` in C for a
    /// charge-controlled electrode), `controlled.toml` and, with `plot_format`, the
    /// plots `control.<format>` (the drive, starting and optimised) and `tracking.<format>` (each
    /// probe the objective reads against its target). Returns the paths written.
    pub fn write(&self, dir: &Path, plot_format: Option<&str>) -> Result<Vec<PathBuf>, Error> {
        let io = |path: &Path, e: String| Error::Io {
            path: path.to_path_buf(),
            message: e,
        };
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e.to_string()))?;
        let mut written = Vec::new();
        let mut put = |name: &str, text: &str| -> Result<(), Error> {
            let path = dir.join(name);
            write_atomic(&path, text.as_bytes()).map_err(|e| io(&path, e.to_string()))?;
            written.push(path);
            Ok(())
        };
        put(
            "control.json",
            &(serde_json::to_string_pretty(&self.to_json()).unwrap_or_default() + "\n"),
        )?;
        let header: Vec<String> = self
            .drives
            .iter()
            .map(|d| {
                if self
                    .drives
                    .iter()
                    .filter(|o| o.electrode == d.electrode)
                    .count()
                    > 1
                {
                    format!("{}:{}@{}", d.quantity.name(), d.electrode, d.stage)
                } else {
                    format!("{}:{}", d.quantity.name(), d.electrode)
                }
            })
            .collect();
        let columns: Vec<(f64, &[f64], &[f64])> = self
            .drives
            .iter()
            .map(|d| (d.stage_start, d.times.as_slice(), d.values.as_slice()))
            .collect();
        put("control.csv", &knots_csv(&header, &columns))?;
        put("controlled.toml", &self.controlled)?;
        if let Some(format) = plot_format {
            let mut series = Vec::new();
            for (d, name) in self.drives.iter().zip(&header) {
                let x: Vec<f64> = d.times.iter().map(|t| d.stage_start + t).collect();
                series.push(Series {
                    label: format!("{name} (start)"),
                    x: x.clone(),
                    y: d.initial.clone(),
                });
                series.push(Series {
                    label: format!("{name} (optimised)"),
                    x,
                    y: d.values.clone(),
                });
            }
            let path = dir.join(format!("control.{format}"));
            let charges = self
                .drives
                .iter()
                .filter(|d| d.quantity == ControlQuantity::Charge)
                .count();
            let y_label = match charges {
                0 => "voltage [V]",
                n if n == self.drives.len() => "charge [C]",
                _ => "voltage [V], charge [C]",
            };
            line_plot(
                &path,
                &PlotSpec {
                    title: "the controlled drive",
                    x_label: "time [s]",
                    y_label,
                    series: &series,
                },
            )
            .map_err(|e| io(&path, e.to_string()))?;
            written.push(path);
        }
        Ok(written)
    }

    /// The plot of each probe an objective term reads (in the optimised run and in the run of
    /// the starting drive) against its target, one panel per term, into `path`; `false` when no term reads a probe.
    pub fn plot_tracking(&self, sim: &Simulation, path: &Path) -> Result<bool, Error> {
        let scenario = sim.scenario()?;
        let plan = sim.plan()?;
        let objective = Objective::build(&scenario, &plan, &sim.name, sim.base.as_deref())
            .map_err(Error::Input)?;
        let mut panels: Vec<(String, String, Vec<Series>)> = Vec::new();
        for term in &objective.terms {
            let (probe, stage, relative) = match term {
                Term::ProbeMisfit {
                    probe,
                    stage,
                    relative,
                    ..
                }
                | Term::ProbeFinal {
                    probe,
                    stage,
                    relative,
                    ..
                } => (*probe, *stage, *relative),
                _ => continue,
            };
            let (name, spec) = &plan.probes[probe];
            let t0 = plan.stage_start(stage);
            let t1 = t0 + plan.stages[stage].duration;
            // a run's probe over the stage, and its value at the stage's start (the last row
            // before the stage's first step)
            let curve = |r: &Results| -> Option<(Vec<f64>, Vec<f64>, f64)> {
                let time = r.history.column("time")?;
                let values = r.history.column(&format!("probe:{name}"))?;
                let (x, y): (Vec<f64>, Vec<f64>) = time
                    .iter()
                    .zip(values)
                    .filter(|(t, _)| **t >= t0 - 1e-12 && **t <= t1 + 1e-12)
                    .map(|(t, v)| (*t, *v))
                    .unzip();
                let first = time
                    .iter()
                    .position(|t| *t > t0 + 1e-12 * t1.abs().max(1.0));
                let v0 = match first {
                    Some(i) if relative && i > 0 => values[i - 1],
                    _ => 0.0,
                };
                Some((x, y, v0))
            };
            let Some((x, y, v0)) = curve(&self.results) else {
                continue;
            };
            let target: Vec<(f64, f64)> = match term {
                Term::ProbeMisfit { target, .. } => {
                    x.iter().map(|t| (*t, v0 + target.at(*t))).collect()
                }
                Term::ProbeFinal { target, .. } => vec![(t1, v0 + target)],
                _ => continue,
            };
            let mut series = vec![Series {
                label: format!("{name} (optimised drive)"),
                x,
                y,
            }];
            if let Some((x, y, _)) = curve(&self.start) {
                series.push(Series {
                    label: format!("{name} (starting drive)"),
                    x,
                    y,
                });
            }
            series.push(Series {
                label: "target".into(),
                x: target.iter().map(|p| p.0).collect(),
                y: target.iter().map(|p| p.1).collect(),
            });
            panels.push((
                format!("{name} in stage {}", plan.stages[stage].name),
                spec.unit.clone(),
                series,
            ));
        }
        if panels.is_empty() {
            return Ok(false);
        }
        let labels: Vec<String> = panels.iter().map(|p| format!("[{}]", p.1)).collect();
        let specs: Vec<PlotSpec> = panels
            .iter()
            .zip(&labels)
            .map(|(p, l)| PlotSpec {
                title: &p.0,
                x_label: "time [s]",
                y_label: l,
                series: &p.2,
            })
            .collect();
        stacked_plot(path, &specs).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The response model against the Gauss–Newton curvature of measured responses on
    /// `diaphragm-control` (a 40-ms stage): the entries w·Σₖ(∂yₖ/∂zᵢ)(∂yₖ/∂zⱼ) of the first
    /// knot (half a hat: the measured one), of knots in the middle and of pairs of them, by
    /// finite differences of runs, at the starting drive (the kernel's shift in time) and at a
    /// drive 0.6 times it (its factor 2V), plus the slew price's s²·w_e·(2 or 1)/Δt on the
    /// diagonal (s the knots' scale, Δt their interval). With a knot every step (the midpoint
    /// rule, and Newmark, which takes the drive at the steps' ends) and every two steps (hats
    /// over two steps, deconvolved).
    #[test]
    fn the_response_model_predicts_the_curvature_of_the_knots() {
        for (sets, interval, knots) in [
            (vec![], 1e-3, [0, 5, 20, 35]),
            (
                vec!["stages.1.integrator=\"newmark\""],
                1e-3,
                [0, 5, 20, 35],
            ),
            (vec!["controls.0.interval=2e-3"], 2e-3, [0, 3, 10, 17]),
        ] {
            model_against_runs(&sets, interval, &knots);
        }
    }

    fn model_against_runs(sets: &[&str], interval: f64, knots: &[usize]) {
        let mut overrides = vec!["stages.1.duration=0.04".to_string()];
        overrides.extend(sets.iter().map(|s| s.to_string()));
        let sim = Simulation::from_example("diaphragm-control")
            .unwrap()
            .with_overrides(&overrides);
        let (scenario, plan) = (sim.scenario().unwrap(), sim.plan().unwrap());
        let objective = Objective::build(&scenario, &plan, "test", None).unwrap();
        let layout = Layout::new(&scenario, &plan);
        let set = layout.feasible(&scenario, &plan);
        let z0 = layout.variables(&plan);
        assert_eq!(z0.len(), (0.04 / interval).round() as usize + 1);
        let model = layout
            .response_model(&plan, &objective, &set, &z0, usize::MAX)
            .unwrap()
            .expect("a misfit term: a model");
        let values = |z: &[f64]| -> Vec<(f64, f64)> {
            let mut p = plan.clone();
            layout.apply(&mut p, z);
            let tape = taped_run(&p, usize::MAX).unwrap();
            let f = read_objective(&p, &tape, &objective).unwrap().0;
            f.readings.iter().map(|r| (r.value, r.weight)).collect()
        };
        let h = 1e-4;
        for z in [z0.clone(), z0.iter().map(|v| 0.6 * v).collect()] {
            let b = model.hessian(&z);
            let base = values(&z);
            // the readings' derivatives in each knot, and their weights
            let derivatives: Vec<Vec<f64>> = knots
                .iter()
                .map(|&j| {
                    let mut moved = z.clone();
                    moved[j] += h;
                    values(&moved)
                        .iter()
                        .zip(&base)
                        .map(|(m, r)| (m.0 - r.0) / h)
                        .collect()
                })
                .collect();
            let gauss_newton = |a: usize, c: usize| -> f64 {
                (0..base.len())
                    .map(|k| base[k].1 * derivatives[a][k] * derivatives[c][k])
                    .sum()
            };
            for (a, &i) in knots.iter().enumerate() {
                for (c, &j) in knots.iter().enumerate() {
                    // the effort term has no readings: its Hessian is exact (the first knot
                    // has one interval, the others two)
                    let intervals = if j == 0 { 1.0 } else { 2.0 };
                    let effort = if i == j {
                        5000f64.powi(2) * 1e-11 * intervals / interval
                    } else {
                        0.0
                    };
                    let measured = gauss_newton(a, c) + effort;
                    let size = ((gauss_newton(a, a) + effort) * (gauss_newton(c, c) + effort))
                        .sqrt()
                        .max(measured.abs());
                    let modelled = b[(i, j)];
                    // measured: at most 5.0 % (the last knots at the starting drive, whose run
                    // rings after the step), 1.2 % for the first knot (a model of a whole hat's
                    // response there was 2–4 times too large)
                    assert!(
                        (modelled - measured).abs() < 0.06 * size,
                        "{sets:?}: knots {i}, {j} at {:.0} V: model {modelled:e}, measured {measured:e}",
                        z[j] * 5000.0
                    );
                }
            }
        }
    }
}
