//! The job: runs the stages of a plan one after the other and reports every accepted step to an
//! observer (writers, progress display). It never reports a state that did not converge.

use super::probes::ProbeInput;
use super::statics::{cell_fields, energies, nodal_reactions, solve_static};
use crate::dofs::{constrained_flags, Dirichlet, Field, FIELDS};
use crate::element::CellFields;
use crate::io::build::{Plan, StageKind};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use crate::time::integrator::TimeLevel;
use crate::time::mass::NodalMass;
use crate::time::stage::{run_dynamic, DynamicInputs, DynamicSettings};
use std::time::Instant;

/// Energies of a state (J), as in `history.csv`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Energies {
    pub kinetic: f64,
    pub stored: f64,
    pub electric: f64,
    pub gravity: f64,
    pub dissipated: f64,
    /// Residual of the energy balance (see `docs/theory.md`).
    pub energy_error: f64,
}

/// One accepted step.
#[derive(Debug, Clone)]
pub struct StepRecord {
    /// Time (s); pseudo-time in static stages.
    pub time: f64,
    pub stage: String,
    /// Step number within the stage (0: the state the stage starts from).
    pub step: usize,
    /// Largest electrode voltage (by magnitude, V).
    pub voltage: f64,
    pub newton_iterations: usize,
    /// Step size (s; the pseudo-time increment in static stages).
    pub dt: f64,
    pub energies: Energies,
    /// Probe values in plan order.
    pub probes: Vec<f64>,
    /// Largest spatial electric field magnitude at a quadrature point (V/m).
    pub max_electric_field: f64,
}

/// What a finished stage reports.
#[derive(Debug, Clone)]
pub struct StageSummary {
    pub name: String,
    pub kind: String,
    pub steps: usize,
    pub newton_iterations: usize,
    pub wall_s: f64,
    pub converged: bool,
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub converged: bool,
    pub error: Option<String>,
    pub stages: Vec<StageSummary>,
    pub wall_s: f64,
    pub dofs: usize,
    pub warnings: Vec<String>,
    /// The run stopped because a stop was requested (SIGINT/SIGTERM).
    pub interrupted: bool,
}

/// Receives the progress of a run.
pub trait Observer {
    /// A stage begins.
    fn stage_started(&mut self, _index: usize, _name: &str) {}
    /// A step was accepted; `state` holds u (m) and Φ (V), 4 per node; `fields` the cell fields.
    fn step(&mut self, plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]);
    /// The run ended (converged or not).
    fn finished(&mut self, plan: &Plan, summary: &RunSummary);
}

/// Accumulates the work of the prescribed values and evaluates records.
struct Recorder<'p> {
    plan: &'p Plan,
    prev_reactions: Vec<f64>,
    prev_state: Vec<f64>,
    boundary_work: f64,
    initial_potential: Option<f64>,
    /// Nodal forces of the tractions at full value (empty without tractions).
    traction: Vec<f64>,
    /// Load factor of the tractions at the state being recorded.
    external_factor: f64,
    prev_external: Vec<f64>,
}

impl<'p> Recorder<'p> {
    /// Evaluates the record of an accepted state. `prescribed` flags the dofs whose values are
    /// prescribed (their reactions do work on the body); `kinetic` and `dissipated` come from the
    /// time integrator (0 in statics).
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        state: &[f64],
        prescribed: &[bool],
        time: f64,
        stage: &str,
        step: usize,
        iterations: usize,
        dt: f64,
        kinetic: f64,
        dissipated: f64,
    ) -> Result<(StepRecord, Vec<CellFields>), String> {
        let model = &self.plan.model;
        let reactions = nodal_reactions(model, state)?;
        let (stored, electric) = energies(model, state)?;
        // work done on the body, by the trapezoidal rule: reactions at prescribed dofs
        // Σ ½(R₀ + R₁)·(x₁ − x₀) and external (traction) forces at free dofs
        let external: Vec<f64> = self
            .traction
            .iter()
            .map(|t| t * self.external_factor)
            .collect();
        if !self.prev_state.is_empty() {
            for d in 0..state.len() {
                if !prescribed[d] && !external.is_empty() {
                    let prev = self.prev_external.get(d).copied().unwrap_or(0.0);
                    self.boundary_work +=
                        0.5 * (prev + external[d]) * (state[d] - self.prev_state[d]);
                }
                if prescribed[d] {
                    self.boundary_work += 0.5
                        * (self.prev_reactions[d] + reactions[d])
                        * (state[d] - self.prev_state[d]);
                }
            }
        }
        let total = kinetic + stored - electric + dissipated;
        let initial = *self.initial_potential.get_or_insert(total);
        let energy_error = total - initial - self.boundary_work;
        let voltages: Vec<(&[usize], f64)> = self
            .plan
            .electrodes
            .iter()
            .map(|e| (e.nodes.as_slice(), state[e.nodes[0] * FIELDS + 3]))
            .collect();
        let voltage = voltages
            .iter()
            .map(|v| v.1)
            .fold(0.0, |m: f64, v| if v.abs() > m.abs() { v } else { m });
        let input = ProbeInput {
            state,
            reactions: &reactions,
            electrodes: &voltages,
            stored,
            electric,
        };
        let probes = self
            .plan
            .probes
            .iter()
            .map(|(_, p)| p.evaluate(&input))
            .collect();
        let fields = cell_fields(model, state)?;
        let max_electric_field = fields.iter().map(|f| f.e_max).fold(0.0, f64::max);
        self.prev_reactions = reactions;
        self.prev_external = external;
        self.prev_state = state.to_vec();
        Ok((
            StepRecord {
                time,
                stage: stage.to_string(),
                step,
                voltage,
                newton_iterations: iterations,
                dt,
                energies: Energies {
                    kinetic,
                    stored,
                    electric,
                    dissipated,
                    energy_error,
                    ..Default::default()
                },
                probes,
                max_electric_field,
            },
            fields,
        ))
    }
}

/// Runs every stage of the plan. `newton` applies to every stage.
pub fn run(plan: &Plan, newton: &NewtonSettings, observer: &mut dyn Observer) -> RunSummary {
    let start = Instant::now();
    let mut model = plan.model.clone();
    let n_nodes = model.mesh.n_nodes();
    let mut state = vec![0.0; n_nodes * FIELDS];
    let mut velocity = vec![0.0; n_nodes * FIELDS];
    let mut acceleration = vec![0.0; n_nodes * FIELDS];
    let mut summary = RunSummary {
        converged: true,
        error: None,
        stages: Vec::new(),
        wall_s: 0.0,
        dofs: n_nodes * FIELDS,
        warnings: plan.warnings.clone(),
        interrupted: false,
    };
    let mut rec = Recorder {
        plan,
        prev_reactions: Vec::new(),
        prev_state: Vec::new(),
        boundary_work: 0.0,
        initial_potential: None,
        traction: if plan.model.tractions.is_empty() {
            Vec::new()
        } else {
            crate::loads::traction_forces(&plan.model.mesh, &plan.model.tractions, 1.0)
        },
        external_factor: 0.0,
        prev_external: Vec::new(),
    };
    let mut time = 0.0;
    let mut dissipated = 0.0;
    for (si, stage) in plan.stages.iter().enumerate() {
        observer.stage_started(si, &stage.name);
        let stage_start = Instant::now();
        let t_end = time + stage.duration;
        model.dirichlet = plan.supports.clone();
        for e in &plan.electrodes {
            model.dirichlet.push(Dirichlet {
                nodes: e.nodes.clone(),
                field: Field::Phi,
                value: e.voltage.value(t_end),
            });
        }
        let prescribed = constrained_flags(n_nodes, &model.dirichlet);
        if si == 0 {
            match rec.record(&state, &prescribed, time, &stage.name, 0, 0, 0.0, 0.0, 0.0) {
                Ok((r, f)) => observer.step(plan, &r, &state, &f),
                Err(e) => {
                    summary.converged = false;
                    summary.error = Some(format!("initial state: {e}"));
                    break;
                }
            }
        }
        let mut stage_summary = StageSummary {
            name: stage.name.clone(),
            kind: String::new(),
            steps: 0,
            newton_iterations: 0,
            wall_s: 0.0,
            converged: true,
        };
        let mut record_error: Option<String> = None;
        let failure: Option<String> = match stage.kind {
            StageKind::Static { steps } => {
                stage_summary.kind = "static".into();
                velocity.iter_mut().for_each(|v| *v = 0.0);
                acceleration.iter_mut().for_each(|v| *v = 0.0);
                let start_voltages: Vec<f64> = plan
                    .electrodes
                    .iter()
                    .map(|e| state[e.nodes[0] * FIELDS + 3])
                    .collect();
                let targets: Vec<f64> = plan
                    .electrodes
                    .iter()
                    .map(|e| e.voltage.value(t_end))
                    .collect();
                let voltage_at = |s: f64| -> f64 {
                    start_voltages
                        .iter()
                        .zip(&targets)
                        .map(|(a, b)| a + s * (b - a))
                        .fold(0.0, |m: f64, v| if v.abs() > m.abs() { v } else { m })
                };
                let control = StepControl {
                    steps,
                    ..Default::default()
                };
                let mut step_no = 0;
                let mut last_load = 0.0;
                let outcome =
                    solve_static(&model, Some(state.clone()), &control, newton, |p, acc| {
                        step_no += 1;
                        let t = time + acc.load * stage.duration;
                        let dt = (acc.load - last_load) * stage.duration;
                        last_load = acc.load;
                        rec.external_factor =
                            model.traction_start + acc.load * (1.0 - model.traction_start);
                        match rec.record(
                            &p.state,
                            &prescribed,
                            t,
                            &stage.name,
                            step_no,
                            acc.newton.iterations,
                            dt,
                            0.0,
                            dissipated,
                        ) {
                            Ok((r, f)) => observer.step(plan, &r, &p.state, &f),
                            Err(e) => {
                                record_error.get_or_insert(e);
                            }
                        }
                    });
                state = outcome.state;
                stage_summary.steps = step_no;
                match outcome.result {
                    Ok(r) => {
                        stage_summary.newton_iterations = r.newton_iterations;
                        // the tractions are now fully applied; later static stages keep them
                        model.traction_start = 1.0;
                        None
                    }
                    Err(f) => {
                        stage_summary.newton_iterations = f.newton_iterations;
                        let electric = start_voltages.iter().zip(&targets).any(|(a, b)| a != b);
                        let what = if f.limit_point && electric {
                            "electromechanical instability (pull-in)"
                        } else if f.limit_point {
                            "limit point (loss of stability)"
                        } else if f.reason == crate::solve::interrupt::MESSAGE {
                            "interrupted by a signal (the last accepted step is in the outputs)"
                        } else {
                            "solve failed"
                        };
                        Some(format!(
                            "{what} in stage `{}` at t = {:.6} s: no stable equilibrium beyond load factor {:.6} \
                             (tried {:.6}); last converged voltage {:.2} V, failed at {:.2} V; last failure: {}",
                            stage.name,
                            time + f.last_converged * stage.duration,
                            f.last_converged,
                            f.attempted,
                            voltage_at(f.last_converged),
                            voltage_at(f.attempted),
                            f.reason
                        ))
                    }
                }
            }
            StageKind::Dynamic {
                dt,
                scheme,
                mass: mass_kind,
            } => {
                stage_summary.kind = "dynamic".into();
                let mass = NodalMass::new(&model, &plan.densities, mass_kind);
                model.dirichlet = plan.supports.clone();
                let inputs = DynamicInputs {
                    mass: &mass,
                    viscosity: plan.viscosities.clone(),
                    body_force: vec![[0.0; 3]; plan.densities.len()],
                    electrodes: plan
                        .electrodes
                        .iter()
                        .map(|e| (e.nodes.clone(), e.voltage.clone()))
                        .collect(),
                };
                let settings = DynamicSettings {
                    duration: stage.duration,
                    dt,
                    scheme,
                    min_fraction: 1.0 / 1024.0,
                    easy_iterations: 6,
                    reuse_factorization: true,
                };
                let start_level = TimeLevel {
                    t: time,
                    q: state.clone(),
                    v: velocity.clone(),
                    a: acceleration.clone(),
                };
                let mut step_no = 0;
                let mut mv = vec![0.0; state.len()];
                let outcome = run_dynamic(
                    &model,
                    &inputs,
                    start_level,
                    &settings,
                    newton,
                    |level, info| {
                        step_no += 1;
                        dissipated += info.dissipated;
                        mass.mul(&level.v, &mut mv);
                        let kinetic =
                            0.5 * level.v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
                        rec.external_factor = 1.0;
                        match rec.record(
                            &level.q,
                            &prescribed,
                            level.t,
                            &stage.name,
                            step_no,
                            info.newton_iterations,
                            info.dt,
                            kinetic,
                            dissipated,
                        ) {
                            Ok((r, f)) => observer.step(plan, &r, &level.q, &f),
                            Err(e) => {
                                record_error.get_or_insert(e);
                            }
                        }
                    },
                );
                stage_summary.steps = step_no;
                let (level, failure) = match outcome {
                    Ok((level, its)) => {
                        stage_summary.newton_iterations = its;
                        (level, None)
                    }
                    Err((level, f)) => {
                        stage_summary.newton_iterations = f.newton_iterations;
                        (
                            level,
                            Some(format!(
                                "dynamic stage `{}` stopped at t = {:.6e} s: {}",
                                stage.name, f.t, f.reason
                            )),
                        )
                    }
                };
                state = level.q;
                model.traction_start = 1.0;
                velocity = level.v;
                acceleration = level.a;
                failure
            }
        };
        stage_summary.wall_s = stage_start.elapsed().as_secs_f64();
        if let Some(e) = record_error {
            summary.warnings.push(format!(
                "stage `{}`: output evaluation failed: {e}",
                stage.name
            ));
        }
        if let Some(f) = failure {
            stage_summary.converged = false;
            summary.converged = false;
            summary.error = Some(f);
        }
        summary.stages.push(stage_summary);
        if !summary.converged {
            break;
        }
        time = t_end;
    }
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.interrupted = crate::solve::interrupt::requested() && !summary.converged;
    observer.finished(plan, &summary);
    summary
}
