//! The job: runs the stages of a plan one after the other and reports every accepted step to an
//! observer (writers, progress display). It never reports a state that did not converge.

use super::prestretch::prestretch;
use super::recorder::Recorder;
use super::statics::solve_static_from;
use crate::element::CellFields;
use super::plan::{Plan, StageKind};
use crate::io::checkpoint::{Checkpoint, StagePosition};
use crate::problem::dofs::{constrained_flags, Dirichlet, Field, FIELDS};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::RampPosition;
use crate::solve::stepping::StepControl;
use crate::time::integrator::TimeLevel;
use crate::time::mass::NodalMass;
use crate::time::stage::{run_dynamic_from, DynamicInputs, DynamicResume, DynamicSettings};
use std::path::PathBuf;
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
    /// The run resumes from a checkpoint; `records` are the steps recorded before it (no
    /// [`Observer::step`] is sent for them).
    fn resumed(&mut self, _plan: &Plan, _records: &[StepRecord]) {}
}

/// Where a run reads its scenario from; stored in its checkpoints so that `--resume` rebuilds
/// the same plan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioSource {
    pub text: String,
    /// The name the scenario was read under (its path, or `<embedded NAME>`).
    pub file: String,
    /// Its directory (relative mesh files are read from there).
    pub base_dir: Option<String>,
    pub overrides: Vec<String>,
}

/// Periodic checkpoints of a run.
#[derive(Debug, Clone)]
pub struct CheckpointOptions {
    /// The output directory (checkpoints go to its `checkpoint/`).
    pub dir: PathBuf,
    /// Write one every this many accepted steps (≥ 1); also when the run stops on a signal.
    pub every: usize,
    pub source: ScenarioSource,
}

/// Options of [`run_with`].
#[derive(Debug, Default)]
pub struct RunOptions {
    pub checkpoint: Option<CheckpointOptions>,
    /// Continue from this checkpoint (already checked against the plan).
    pub resume: Option<Checkpoint>,
}

/// What a checkpoint needs besides the recorder and the stage position.
struct CheckpointContext<'a> {
    options: &'a CheckpointOptions,
    fingerprint: u64,
    stage: usize,
    stage_time: f64,
    first_step: usize,
    prestretch_iterations: usize,
    dead_load_start: f64,
    stages: &'a [StageSummary],
    warnings: &'a [String],
    wall_before: f64,
    start: Instant,
}

impl CheckpointContext<'_> {
    /// Builds and writes a checkpoint; a write failure becomes a warning of the recorder.
    #[allow(clippy::too_many_arguments)]
    fn write(
        &self,
        rec: &mut Recorder,
        accepted: usize,
        step_no: usize,
        position: StagePosition,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dissipated: f64,
    ) {
        let ck = Checkpoint {
            deasim_version: env!("CARGO_PKG_VERSION").to_string(),
            scenario_text: self.options.source.text.clone(),
            scenario_file: self.options.source.file.clone(),
            base_dir: self.options.source.base_dir.clone(),
            overrides: self.options.source.overrides.clone(),
            fingerprint: self.fingerprint,
            threads: rayon::current_num_threads() as u64,
            every: self.options.every as u64,
            accepted: accepted as u64,
            stage: self.stage as u64,
            stage_time: self.stage_time,
            step_no: step_no as u64,
            first_step: self.first_step as u64,
            prestretch_iterations: self.prestretch_iterations as u64,
            position,
            q: q.to_vec(),
            v: v.to_vec(),
            a: a.to_vec(),
            dissipated,
            dead_load_start: self.dead_load_start,
            recorder: rec.state(),
            stages: self.stages.to_vec(),
            warnings: self.warnings.to_vec(),
            records: rec.history.clone(),
            wall_s: self.wall_before + self.start.elapsed().as_secs_f64(),
        };
        if let Err(e) = ck.write(&self.options.dir) {
            rec.warnings.push(format!("checkpoint not written: {e}"));
        }
    }
}

/// Runs every stage of the plan. `newton` applies to every stage.
pub fn run(plan: &Plan, newton: &NewtonSettings, observer: &mut dyn Observer) -> RunSummary {
    run_with(plan, newton, observer, RunOptions::default())
}

/// [`run`] with checkpoints and/or from a checkpoint.
///
/// Checkpoints are written after every `every`-th accepted step of the stages (pre-stretch
/// steps are not counted) and when a stop is requested. At each periodic checkpoint the
/// drivers drop their reused factorisations (modified Newton) and re-factorise as at a start,
/// so a run resumed from it repeats the decisions of the run that goes on: the two agree bit
/// for bit on the same thread count. A resume from a stop checkpoint agrees to the Newton
/// tolerance only (the uninterrupted run had no refresh there).
pub fn run_with(
    plan: &Plan,
    newton: &NewtonSettings,
    observer: &mut dyn Observer,
    options: RunOptions,
) -> RunSummary {
    let start = Instant::now();
    let RunOptions {
        checkpoint: ck_options,
        mut resume,
    } = options;
    let fingerprint = crate::io::checkpoint::fingerprint(plan);
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
    let mut rec = Recorder::new(plan, ck_options.is_some());
    crate::solve::interrupt::clear_local();
    let mut time = 0.0;
    let mut dissipated = 0.0;
    let mut accepted = 0usize;
    let mut wall_before = 0.0;
    let mut first_stage = 0;
    if let Some(ck) = &resume {
        state.clone_from(&ck.q);
        velocity.clone_from(&ck.v);
        acceleration.clone_from(&ck.a);
        rec.restore(&ck.recorder, &ck.records);
        summary.stages = ck.stages.clone();
        summary.warnings = ck.warnings.clone();
        time = ck.stage_time;
        dissipated = ck.dissipated;
        accepted = ck.accepted as usize;
        wall_before = ck.wall_s;
        first_stage = ck.stage as usize;
        model.dead_load_start = ck.dead_load_start;
        observer.resumed(plan, &ck.records);
    }
    for (si, stage) in plan.stages.iter().enumerate().skip(first_stage) {
        let resume_here = resume.take();
        observer.stage_started(si, &stage.name);
        let stage_start = Instant::now();
        let t_end = time + stage.duration;
        // waveforms run on stage time (0 at the start of the stage), as Abaqus' step time;
        // a stage with its electrodes off holds them at 0 V
        let voltage_of = |w: &crate::waveform::Waveform, t_stage: f64| {
            if stage.electrodes_on {
                w.value(t_stage)
            } else {
                0.0
            }
        };
        // steps already recorded under this stage's name (the pre-stretch, for the first stage)
        let mut first_step = 0;
        let mut prestretch_iterations = 0;
        model.dirichlet = plan.supports.clone();
        for e in &plan.electrodes {
            model.dirichlet.push(Dirichlet {
                nodes: e.nodes.clone(),
                field: Field::Phi,
                value: voltage_of(&e.voltage, stage.duration),
            });
        }
        let prescribed = constrained_flags(n_nodes, &model.dirichlet);
        if let Some(ck) = &resume_here {
            first_step = ck.first_step as usize;
            prestretch_iterations = ck.prestretch_iterations as usize;
        } else if si == 0 {
            match rec.record(&state, &prescribed, time, &stage.name, 0, 0, 0.0, 0.0, 0.0) {
                Ok((r, f)) => observer.step(plan, &r, &state, &f),
                Err(e) => {
                    summary.converged = false;
                    summary.error = Some(format!("initial state: {e}"));
                    break;
                }
            }
            if let Some(p) = plan.prestretch {
                match prestretch(
                    plan,
                    &model,
                    &state,
                    p,
                    newton,
                    &mut rec,
                    &stage.name,
                    observer,
                ) {
                    Ok((s, n, its)) => {
                        state = s;
                        first_step = n;
                        prestretch_iterations = its;
                        rec.reference = state.clone();
                    }
                    Err(e) => {
                        summary.converged = false;
                        summary.error = Some(e);
                        summary.stages.push(StageSummary {
                            name: stage.name.clone(),
                            kind: "static".into(),
                            steps: 0,
                            newton_iterations: 0,
                            wall_s: stage_start.elapsed().as_secs_f64(),
                            converged: false,
                        });
                        break;
                    }
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
        // what a checkpoint of this stage records besides the solver's position
        let context = ck_options.as_ref().map(|o| CheckpointContext {
            options: o,
            fingerprint,
            stage: si,
            stage_time: time,
            first_step,
            prestretch_iterations,
            dead_load_start: model.dead_load_start,
            stages: &summary.stages,
            warnings: &summary.warnings,
            wall_before,
            start,
        });
        let failure: Option<String> = match stage.kind {
            StageKind::Static { steps } => {
                stage_summary.kind = "static".into();
                velocity.iter_mut().for_each(|v| *v = 0.0);
                acceleration.iter_mut().for_each(|v| *v = 0.0);
                let (stage_start_state, resume_at, mut step_no, mut last_load) = match resume_here {
                    Some(Checkpoint {
                        position:
                            StagePosition::Static {
                                ramp,
                                stage_start,
                                last_load,
                            },
                        step_no,
                        ..
                    }) => (
                        stage_start,
                        Some((state.clone(), ramp)),
                        step_no as usize,
                        last_load,
                    ),
                    _ => (state.clone(), None, first_step, 0.0),
                };
                let start_voltages: Vec<f64> = plan
                    .electrodes
                    .iter()
                    .map(|e| stage_start_state[e.nodes[0] * FIELDS + 3])
                    .collect();
                let targets: Vec<f64> = plan
                    .electrodes
                    .iter()
                    .map(|e| voltage_of(&e.voltage, stage.duration))
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
                let nominal = 1.0 / steps.max(1) as f64;
                let mut last_position = resume_at.as_ref().map_or(
                    RampPosition {
                        load: 0.0,
                        increment: nominal,
                        next_nominal: 1,
                        accepted_steps: 0,
                        cutbacks: 0,
                        newton_iterations: 0,
                    },
                    |r| r.1,
                );
                let outcome = solve_static_from(
                    &model,
                    stage_start_state.clone(),
                    resume_at,
                    &control,
                    newton,
                    |p, acc| {
                        step_no += 1;
                        let t = time + acc.load * stage.duration;
                        let dt = (acc.load - last_load) * stage.duration;
                        last_load = acc.load;
                        rec.sudden_loads = false;
                        rec.external_factor =
                            model.dead_load_start + acc.load * (1.0 - model.dead_load_start);
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
                        accepted += 1;
                        last_position = acc.position;
                        let Some(ctx) = &context else { return false };
                        if !accepted.is_multiple_of(ctx.options.every) {
                            return false;
                        }
                        ctx.write(
                            &mut rec,
                            accepted,
                            step_no,
                            StagePosition::Static {
                                ramp: acc.position,
                                stage_start: stage_start_state.clone(),
                                last_load,
                            },
                            &p.state,
                            &velocity,
                            &acceleration,
                            dissipated,
                        );
                        true
                    },
                );
                if let Some(ctx) = &context {
                    if crate::solve::interrupt::requested() && outcome.result.is_err() {
                        ctx.write(
                            &mut rec,
                            accepted,
                            step_no,
                            StagePosition::Static {
                                ramp: last_position,
                                stage_start: stage_start_state.clone(),
                                last_load,
                            },
                            &outcome.state,
                            &velocity,
                            &acceleration,
                            dissipated,
                        );
                    }
                }
                state = outcome.state;
                stage_summary.steps = step_no;
                match outcome.result {
                    Ok(r) => {
                        stage_summary.newton_iterations =
                            r.newton_iterations + prestretch_iterations;
                        // the tractions are now fully applied; later static stages keep them
                        model.dead_load_start = 1.0;
                        None
                    }
                    Err(f) => {
                        stage_summary.newton_iterations =
                            f.newton_iterations + prestretch_iterations;
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
                let mut mass = NodalMass::new(&model, &plan.densities, mass_kind);
                for r in &plan.rigid {
                    if r.mass > 0.0 {
                        mass.add_point_mass(r.nodes[0], r.mass);
                    }
                }
                model.dirichlet = plan.supports.clone();
                let inputs = DynamicInputs {
                    mass: &mass,
                    viscosity: plan.viscosities.clone(),
                    electrodes: plan
                        .electrodes
                        .iter()
                        .map(|e| {
                            let w = if stage.electrodes_on {
                                e.voltage.clone()
                            } else {
                                crate::waveform::Waveform::constant(0.0)
                            };
                            (e.nodes.clone(), w)
                        })
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
                // the integrator runs on stage time; records get the global time
                let (t0, dyn_resume, mut step_no) = match resume_here {
                    Some(Checkpoint {
                        position: StagePosition::Dynamic { t, dt, iterations },
                        step_no,
                        ..
                    }) => (
                        t,
                        Some(DynamicResume {
                            t_start: 0.0,
                            dt,
                            iterations: iterations as usize,
                        }),
                        step_no as usize,
                    ),
                    _ => (0.0, None, first_step),
                };
                let start_level = TimeLevel {
                    t: t0,
                    q: state.clone(),
                    v: velocity.clone(),
                    a: acceleration.clone(),
                };
                let mut last_position = (
                    t0,
                    dyn_resume.map_or(dt, |r| r.dt),
                    dyn_resume.map_or(0, |r| r.iterations),
                );
                let mut mv = vec![0.0; state.len()];
                let outcome = run_dynamic_from(
                    &model,
                    &inputs,
                    start_level,
                    &settings,
                    newton,
                    dyn_resume,
                    |level, info| {
                        step_no += 1;
                        dissipated += info.dissipated;
                        mass.mul(&level.v, &mut mv);
                        let kinetic =
                            0.5 * level.v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
                        rec.external_factor = 1.0;
                        rec.sudden_loads = true;
                        match rec.record(
                            &level.q,
                            &prescribed,
                            time + level.t,
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
                        accepted += 1;
                        last_position = (level.t, info.next_dt, info.total_iterations);
                        let Some(ctx) = &context else { return false };
                        if !accepted.is_multiple_of(ctx.options.every) {
                            return false;
                        }
                        ctx.write(
                            &mut rec,
                            accepted,
                            step_no,
                            StagePosition::Dynamic {
                                t: level.t,
                                dt: info.next_dt,
                                iterations: info.total_iterations as u64,
                            },
                            &level.q,
                            &level.v,
                            &level.a,
                            dissipated,
                        );
                        true
                    },
                );
                if let (Some(ctx), Err((level, _))) = (&context, &outcome) {
                    if crate::solve::interrupt::requested() {
                        ctx.write(
                            &mut rec,
                            accepted,
                            step_no,
                            StagePosition::Dynamic {
                                t: last_position.0,
                                dt: last_position.1,
                                iterations: last_position.2 as u64,
                            },
                            &level.q,
                            &level.v,
                            &level.a,
                            dissipated,
                        );
                    }
                }
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
                                stage.name,
                                time + f.t,
                                f.reason
                            )),
                        )
                    }
                };
                state = level.q;
                model.dead_load_start = 1.0;
                velocity = level.v;
                acceleration = level.a;
                failure
            }
        };
        stage_summary.wall_s = stage_start.elapsed().as_secs_f64();
        summary.warnings.append(&mut rec.warnings);
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
    summary.warnings.append(&mut rec.warnings);
    summary.wall_s = wall_before + start.elapsed().as_secs_f64();
    summary.interrupted = crate::solve::interrupt::requested() && !summary.converged;
    observer.finished(plan, &summary);
    summary
}
