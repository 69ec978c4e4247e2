//! The run: a short loop over the stages of a plan on one [`RunState`]. Every accepted step is
//! recorded and sent to the observers (writers, progress display, checkpoints); a state that did
//! not converge is never sent. An observer that asks for it receives the whole run state
//! (checkpoints); taking it changes nothing in the run, so a run with checkpoints gives the same
//! numbers, bit for bit, as one without, and a run resumed from a state continues exactly as the
//! run that went on.

use super::linear::{frequency_response_at, modes_of_harmonics};
use super::observer::{DynamicStart, Observer, Observers};
use super::plan::{Plan, Stage, StageKind};
use super::prestretch::prestretch;
use super::recorder::Recorder;
use super::stability::{HarmonicCheck, Onset, HARMONIC_REASON};
pub use super::state::{
    Energies, InstabilityRecord, LimitRecord, PathRecord, RecorderState, RunState, RunSummary,
    StagePosition, StageSummary, StepRecord,
};
use super::statics::{solve_static_checked, StageTime};
use crate::algebra::system::NonlinearSystem;
use crate::problem::distributed::Held;
use crate::problem::dofs::{constrained_flags, Dirichlet, Field, FIELDS};
use crate::problem::drive::{Drive, DrivenCharge, HeldVoltages, Ramp};
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::{RampPosition, StepControl};
use crate::time::integrator::TimeLevel;
use crate::time::mass::NodalMass;
use crate::time::modal::ModeSettings;
use crate::time::stage::{
    run_dynamic_from, DynamicInputs, DynamicResume, DynamicSettings, StageParts,
};
use crate::waveform::Waveform;
use std::time::Instant;

/// Runs every stage of the plan, with the plan's Newton settings and step control.
pub fn run(plan: &Plan, observer: &mut dyn Observer) -> RunSummary {
    run_with(plan, &mut [observer], None)
}

/// [`run`] with several observers, from the start or from a run state (already checked against
/// the plan).
pub fn run_with(
    plan: &Plan,
    observers: &mut [&mut dyn Observer],
    start: Option<RunState>,
) -> RunSummary {
    let mut observers = Observers(observers);
    let mut model = plan.model.clone();
    let resuming = start.is_some();
    let mut job = Job::new(plan, &plan.newton, &mut observers, start);
    let mut resume = None;
    if resuming {
        resume = Some((job.state.position.clone(), job.state.step_no));
    }
    for si in job.state.stage..plan.stages.len() {
        if !job.stage(si, &mut model, resume.take()) {
            break;
        }
    }
    job.finish()
}

/// A run in progress.
struct Job<'p, 'o> {
    plan: &'p Plan,
    newton: &'p NewtonSettings,
    observer: &'o mut dyn Observer,
    rec: Recorder<'p>,
    summary: RunSummary,
    /// The evolving state of the run: nodal values, velocities, stage position, dissipated
    /// energy, pressure fractions (the point states live in `points`, the records in `rec`; a
    /// checkpoint completes a copy of it with them).
    state: RunState,
    started: Instant,
    /// The first failure to evaluate a record in the current stage.
    record_error: Option<String>,
    /// Committed internal variables of the material points: their only live copy.
    points: PointStates,
    /// The controllers acting in the current stage ([`Plan::controller_loops`]) and the
    /// voltages they hold in its drive.
    loops: Vec<ControllerLoop>,
    held: HeldVoltages,
}

impl<'p, 'o> Job<'p, 'o> {
    fn new(
        plan: &'p Plan,
        newton: &'p NewtonSettings,
        observer: &'o mut dyn Observer,
        start: Option<RunState>,
    ) -> Self {
        let n = plan.model.mesh.n_nodes() * FIELDS;
        let whole = plan.whole_nodes() * FIELDS;
        let resumed = start.is_some();
        let mut state = start.unwrap_or_else(|| RunState {
            accepted: 0,
            stage: 0,
            stage_time: 0.0,
            step_no: 0,
            first_step: 0,
            prestretch_iterations: 0,
            // not read: a run from the start begins its first stage afresh
            position: StagePosition::Static {
                ramp: RampPosition::default(),
                stage_start: Vec::new(),
                last_load: 0.0,
            },
            q: vec![0.0; n],
            v: vec![0.0; n],
            a: vec![0.0; n],
            points: Vec::new(),
            dissipated: 0.0,
            dead_load_start: 0.0,
            pressure_start: Vec::new(),
            recorder: RecorderState::default(),
            stages: Vec::new(),
            warnings: Vec::new(),
            records: Vec::new(),
            wall_s: 0.0,
            controllers: Vec::new(),
        });
        let controllers: Vec<_> = plan
            .electrodes
            .iter()
            .filter_map(|e| e.controller.as_ref())
            .collect();
        if state.controllers.len() != controllers.len() {
            state.controllers = controllers.iter().map(|c| c.start()).collect();
        }
        let pressures = plan.model.pressures.len();
        if state.pressure_start.len() != pressures {
            // an older checkpoint: the fractions the stage before left
            state.pressure_start = if state.stage > 0 {
                plan.pressure_targets(state.stage - 1)
            } else {
                vec![0.0; pressures]
            };
        }
        let mut points = PointStates::new(&plan.model);
        if let Some(p) = PointStates::with_data(&plan.model, std::mem::take(&mut state.points)) {
            points = p;
        }
        let mut job = Job {
            plan,
            newton,
            rec: Recorder::new(plan, observer.takes_states()),
            observer,
            summary: RunSummary {
                converged: true,
                error: None,
                stages: std::mem::take(&mut state.stages),
                wall_s: 0.0,
                dofs: whole,
                warnings: plan.warnings.clone(),
                interrupted: false,
            },
            started: Instant::now(),
            record_error: None,
            points,
            state,
            loops: Vec::new(),
            held: HeldVoltages::default(),
        };
        crate::solve::interrupt::clear_local();
        if !plan.solver.gives_inertia() {
            job.summary.warnings.push(format!(
                "stability not checked: the linear solver ({}) gives no inertia, so limit points \
                 show only as Newton failures",
                plan.solver.kind.name()
            ));
        }
        if resumed {
            let s = &mut job.state;
            job.rec.restore(&s.recorder, &s.records);
            job.summary.warnings = std::mem::take(&mut s.warnings);
            let records = std::mem::take(&mut s.records);
            // the fields of the last recorded state, for writers that complete a stage's files
            // (of this process's cells when processes share them, as a step's record gives them)
            let fields = crate::problem::statics::record_with(&plan.model, &s.q, &job.points)
                .map(|r| r.fields)
                .unwrap_or_default();
            job.observer.resumed(plan, &records, &s.q, &fields);
        }
        job
    }

    /// The run state at an accepted step of the current stage (collective when processes share
    /// the cells: the point states are merged from their owners).
    fn state(
        &self,
        model: &Model,
        stage: usize,
        step_no: usize,
        position: StagePosition,
        q: &[f64],
    ) -> Result<RunState, String> {
        let mut position = position;
        if let StagePosition::Dynamic { driver, .. } = &mut position {
            if let Some(f) = driver.step_factor.as_mut() {
                f.points = self.points.merge(model, &f.points)?;
            }
        }
        Ok(RunState {
            stage,
            step_no,
            position,
            q: q.to_vec(),
            points: self.points.merged(model)?,
            dead_load_start: self.state.dead_load_start,
            recorder: self.rec.state(),
            stages: self.summary.stages.clone(),
            warnings: self.summary.warnings.clone(),
            records: self.rec.history.clone(),
            wall_s: self.state.wall_s + self.started.elapsed().as_secs_f64(),
            ..self.state.clone()
        })
    }

    /// Sends the run state to the observers that want it now.
    fn offer_state(
        &mut self,
        stopping: bool,
        state: impl FnOnce(&Self) -> Result<RunState, String>,
    ) {
        if self.observer.wants_state(self.state.accepted, stopping) {
            let written = state(self).and_then(|s| self.observer.run_state(self.plan, &s));
            if let Err(e) = written {
                self.rec
                    .warnings
                    .push(format!("checkpoint not written: {e}"));
            }
        }
    }

    /// Records an accepted state and sends it to the observers.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        q: &[f64],
        prescribed: &[bool],
        time: f64,
        stage: &str,
        step: usize,
        iterations: usize,
        dt: f64,
        kinetic: f64,
    ) -> Option<StepRecord> {
        if !self.points.is_empty() {
            match self.points.cell_means(&self.plan.model) {
                Ok(means) => self.observer.point_states(self.plan, &means),
                Err(e) => self
                    .rec
                    .warnings
                    .push(format!("internal variables not written: {e}")),
            }
        }
        match self.rec.record(
            q,
            prescribed,
            time,
            stage,
            step,
            iterations,
            dt,
            kinetic,
            self.state.dissipated,
        ) {
            Ok((r, f)) => {
                self.observer.step(self.plan, &r, q, &f);
                Some(r)
            }
            Err(e) => {
                self.record_error.get_or_insert(e);
                None
            }
        }
    }

    /// Runs stage `si` (from `position` when resuming inside it); false when the run stops.
    fn stage(
        &mut self,
        si: usize,
        model: &mut Model,
        position: Option<(StagePosition, usize)>,
    ) -> bool {
        let plan = self.plan;
        let stage = &plan.stages[si];
        self.observer.stage_started(si, &stage.name);
        let stage_start = Instant::now();
        let prescribed = plan.stage_conditions(model, stage);
        // a volume-controlled pressure acting in the stage is an unknown of it
        let targets = plan.pressure_targets(si);
        for (i, p) in model.pressures.iter_mut().enumerate() {
            p.volume = plan.pressure_volumes[i].filter(|_| targets[i] != 0.0);
        }
        let drive = plan.drive(si, self.state.dead_load_start, &self.state.pressure_start);
        if position.is_none() {
            self.state.first_step = 0;
            self.state.prestretch_iterations = 0;
            if si == 0 && !self.initial_phase(model, stage, &prescribed, stage_start) {
                return false;
            }
        }
        self.record_error = None;
        let start_failure = self.start_controllers(si, &drive, position.is_some());
        let mut summary = StageSummary {
            name: stage.name.clone(),
            kind: String::new(),
            steps: 0,
            newton_iterations: 0,
            wall_s: 0.0,
            converged: true,
            modes_hz: Vec::new(),
            modes_harmonic: Vec::new(),
            instability: None,
            linear: Default::default(),
        };
        let failure = match stage.kind {
            _ if start_failure.is_some() => start_failure,
            StageKind::Static { steps } | StageKind::QuasiStatic { steps } => {
                self.static_stage(si, model, drive, steps, &prescribed, position, &mut summary)
            }
            StageKind::Dynamic { .. } => {
                self.dynamic_stage(si, model, drive, &prescribed, position, &mut summary)
            }
            StageKind::Modes { .. } | StageKind::FrequencyResponse { .. } => {
                self.linearised_stage(stage, &mut summary)
            }
            StageKind::Continuation { .. } => {
                self.continuation_stage(si, model, drive, &prescribed, &mut summary)
            }
        };
        summary.wall_s = stage_start.elapsed().as_secs_f64();
        self.summary.warnings.append(&mut self.rec.warnings);
        if let Some(e) = self.record_error.take() {
            self.summary.warnings.push(format!(
                "stage `{}`: output evaluation failed: {e}",
                stage.name
            ));
        }
        if let Some(f) = failure {
            summary.converged = false;
            self.summary.converged = false;
            self.summary.error = Some(f);
        }
        self.summary.stages.push(summary);
        if !self.summary.converged {
            return false;
        }
        // where the stage left the pressures: at the last record (a continuation's path may end
        // short of its load 1, a volume-controlled pressure where its volume needed it)
        if self.rec.pressure_now.len() == model.pressures.len() {
            self.state.pressure_start.clone_from(&self.rec.pressure_now);
        }
        self.state.stage_time += stage.duration;
        true
    }

    /// Sets up the controllers acting in stage `si` on its `drive`: resumed inside the stage,
    /// they hold the outputs of their state; else their clocks restart and they take their first
    /// sample of the stage's start state. Returns the failure, if any.
    fn start_controllers(&mut self, si: usize, drive: &Drive, resumed: bool) -> Option<String> {
        let plan = self.plan;
        self.loops = plan.controller_loops(&plan.stages[si]);
        self.held = drive.held.clone();
        if self.loops.is_empty() {
            return None;
        }
        if resumed {
            for l in &self.loops {
                self.held
                    .set(l.drive, self.state.controllers[l.state].output);
            }
            return None;
        }
        for l in &self.loops {
            let c = plan.electrodes[l.electrode].controller.as_ref();
            if let Some(c) = c {
                c.restart_clock(&mut self.state.controllers[l.state]);
            }
        }
        match self.rec.probes_at(&self.state.q) {
            Ok(probes) => {
                self.control(0.0, Some(&probes));
                None
            }
            Err(e) => Some(format!(
                "stage `{}`: the controllers' first sample: {e}",
                plan.stages[si].name
            )),
        }
    }

    /// The controllers due at stage time `t` sample the probe values `probes` (`None`: the
    /// record failed, the outputs stay held) and hold their outputs for the steps that follow.
    fn control(&mut self, t: f64, probes: Option<&[f64]>) {
        let plan = self.plan;
        for l in &self.loops {
            let Some(c) = plan.electrodes[l.electrode].controller.as_ref() else {
                continue;
            };
            let state = &mut self.state.controllers[l.state];
            if let Some(p) = probes {
                if c.due(state, t) {
                    c.sample(state, t, p);
                }
            }
            self.held.set(l.drive, state.output);
        }
    }

    /// A small-signal stage about the current state: modes or a frequency response, sent to
    /// the observers. The state and the time do not change. Returns the failure, if any.
    fn linearised_stage(&mut self, stage: &Stage, summary: &mut StageSummary) -> Option<String> {
        let plan = self.plan;
        match &stage.kind {
            StageKind::Modes {
                count,
                shift_hz,
                harmonics,
            } => {
                summary.kind = "modes".into();
                let settings = ModeSettings {
                    count: *count,
                    shift_hz: *shift_hz,
                    ..Default::default()
                };
                match modes_of_harmonics(plan, &self.state.q, &settings, harmonics) {
                    Ok(found) => {
                        summary.modes_hz = found.iter().map(|m| m.frequency).collect();
                        summary.modes_harmonic = found.iter().map(|m| m.harmonic).collect();
                        self.observer
                            .modes(plan, &stage.name, &self.state.q, &found);
                        None
                    }
                    Err(e) => Some(format!("stage `{}`: modes: {e}", stage.name)),
                }
            }
            StageKind::FrequencyResponse {
                electrode,
                frequencies,
                method,
            } => {
                summary.kind = "frequency-response".into();
                match frequency_response_at(
                    plan,
                    &self.state.q,
                    &self.rec.reference,
                    *electrode,
                    frequencies,
                    *method,
                ) {
                    Ok(r) => {
                        if let Some(w) = &r.warning {
                            self.summary
                                .warnings
                                .push(format!("stage `{}`: {w}", stage.name));
                        }
                        self.observer.frequency_response(plan, &stage.name, &r);
                        None
                    }
                    Err(e) => Some(format!("stage `{}`: frequency response: {e}", stage.name)),
                }
            }
            _ => None,
        }
    }

    /// The initial record and the pre-stretch phase before the first stage; false on failure.
    fn initial_phase(
        &mut self,
        model: &Model,
        stage: &Stage,
        prescribed: &[bool],
        started: Instant,
    ) -> bool {
        let plan = self.plan;
        match self.rec.record(
            &self.state.q,
            prescribed,
            self.state.stage_time,
            &stage.name,
            0,
            0,
            0.0,
            0.0,
            0.0,
        ) {
            Ok((r, f)) => self.observer.step(plan, &r, &self.state.q, &f),
            Err(e) => {
                self.summary.converged = false;
                self.summary.error = Some(format!("initial state: {e}"));
                return false;
            }
        }
        let Some(p) = plan.prestretch else {
            return true;
        };
        match prestretch(
            plan,
            model,
            &self.state.q,
            &self.points,
            p,
            self.newton,
            &mut self.rec,
            &stage.name,
            &mut *self.observer,
        ) {
            Ok(o) => {
                self.state.q = o.state;
                self.state.first_step = o.steps;
                self.state.prestretch_iterations = o.iterations;
                self.rec.reference = self.state.q.clone();
                self.rec.points.clone_from(&o.points);
                self.points = o.points;
                self.state.dissipated += o.dissipated;
                self.state.stage_time += o.time;
                true
            }
            Err(e) => {
                self.summary.converged = false;
                self.summary.error = Some(e);
                self.summary.stages.push(StageSummary {
                    name: stage.name.clone(),
                    kind: "static".into(),
                    steps: 0,
                    newton_iterations: 0,
                    wall_s: started.elapsed().as_secs_f64(),
                    converged: false,
                    modes_hz: Vec::new(),
                    modes_harmonic: Vec::new(),
                    instability: None,
                    linear: Default::default(),
                });
                false
            }
        }
    }

    /// A static stage: the load ramp to the stage's targets. Returns the failure, if any.
    #[allow(clippy::too_many_arguments)]
    fn static_stage(
        &mut self,
        si: usize,
        model: &mut Model,
        mut drive: Drive,
        steps: usize,
        prescribed: &[bool],
        position: Option<(StagePosition, usize)>,
        summary: &mut StageSummary,
    ) -> Option<String> {
        let plan = self.plan;
        let stage = &plan.stages[si];
        let quasi_static = matches!(stage.kind, StageKind::QuasiStatic { .. });
        summary.kind = if quasi_static {
            "quasi-static"
        } else {
            "static"
        }
        .into();
        self.state.v.iter_mut().for_each(|v| *v = 0.0);
        self.state.a.iter_mut().for_each(|v| *v = 0.0);
        let (stage_start, resume_at, mut step_no, mut last_load) = match position {
            Some((
                StagePosition::Static {
                    ramp,
                    stage_start,
                    last_load,
                },
                step_no,
            )) => (
                stage_start,
                Some((self.state.q.clone(), ramp)),
                step_no,
                last_load,
            ),
            _ => (self.state.q.clone(), None, self.state.first_step, 0.0),
        };
        // a resumed volume-controlled pressure continues from its level at the last record
        if resume_at.is_some() {
            for ((p, r), &level) in model
                .pressures
                .iter()
                .zip(drive.pressures.iter_mut())
                .zip(&self.rec.prev_pressure)
            {
                if p.volume.is_some() {
                    *r = Ramp::held_at(level);
                }
            }
        }
        let start_voltages: Vec<f64> = match plan.electrode_voltages(&stage_start) {
            Ok(v) => plan
                .electrodes
                .iter()
                .zip(v)
                .filter(|(e, _)| e.charge.is_none())
                .map(|(_, v)| v)
                .collect(),
            Err(e) => return Some(format!("stage `{}`: {e}", stage.name)),
        };
        let targets: Vec<f64> = plan
            .electrodes
            .iter()
            .filter(|e| e.charge.is_none())
            .map(|e| stage.electrode_waveform(e).value(stage.duration))
            .collect();
        let voltage_at = |s: f64| -> f64 {
            let pick = |m: f64, v: f64| if v.abs() > m.abs() { v } else { m };
            if quasi_static {
                drive
                    .voltages_at(s * stage.duration)
                    .map(|(_, v)| v)
                    .fold(0.0, pick)
            } else {
                start_voltages
                    .iter()
                    .zip(&targets)
                    .map(|(a, b)| a + s * (b - a))
                    .fold(0.0, pick)
            }
        };
        let control = StepControl {
            steps,
            ..self.plan.step_control.clone()
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
                retrying: false,
            },
            |r| r.1,
        );
        let time = self.state.stage_time;
        let model_ref: &Model = model;
        let mut check = match harmonic_check(plan, stage, nominal * control.min_fraction) {
            Ok(c) => c,
            Err(e) => return Some(e),
        };
        let outcome = solve_static_checked(
            model_ref,
            &plan.solver,
            stage_start.clone(),
            StageTime {
                duration: stage.duration,
                points: self.points.clone(),
                drive: drive.clone(),
            },
            resume_at,
            &control,
            self.newton,
            plan.part.as_ref().map(|p| &p.stages),
            |p, from, to| match check.as_mut() {
                Some(c) => c.check(model_ref, &p.state, from, to),
                None => Ok(()),
            },
            |p, acc| {
                step_no += 1;
                self.observer.load_step(si, acc.load, p);
                self.state.dissipated += p.dissipated_step;
                self.points.clone_from(&p.points);
                self.rec.points.clone_from(&p.points);
                let t = time + acc.load * stage.duration;
                let dt = (acc.load - last_load) * stage.duration;
                last_load = acc.load;
                self.rec.sudden_loads = false;
                self.rec.circuit_current = false;
                self.rec.external_factor = p.load();
                self.rec.pressure_now = p.pressure_fractions();
                self.rec.charges_now = p.drive().charges_at(acc.load * stage.duration, acc.load);
                let record = self.record(
                    &p.state,
                    prescribed,
                    t,
                    &stage.name,
                    step_no,
                    acc.newton.iterations,
                    dt,
                    0.0,
                );
                self.control(t - time, record.as_ref().map(|r| r.probes.as_slice()));
                self.state.accepted += 1;
                last_position = acc.position;
                self.offer_state(false, |job| {
                    job.state(
                        model_ref,
                        si,
                        step_no,
                        StagePosition::Static {
                            ramp: acc.position,
                            stage_start: stage_start.clone(),
                            last_load,
                        },
                        &p.state,
                    )
                });
            },
        );
        if crate::solve::interrupt::requested() && outcome.result.is_err() {
            self.offer_state(true, |job| {
                job.state(
                    model_ref,
                    si,
                    step_no,
                    StagePosition::Static {
                        ramp: last_position,
                        stage_start: stage_start.clone(),
                        last_load,
                    },
                    &outcome.state,
                )
            });
        }
        self.state.q = outcome.state;
        self.points = outcome.points;
        summary.steps = step_no;
        summary.linear = outcome.linear;
        // a stage that tests harmonics reports a loss in harmonic 0 (its ramp's own test) alike
        let axisymmetric = match (&check, &outcome.result) {
            (Some(c), Err(f))
                if f.limit_point && f.cause == crate::solve::stepping::FailureCause::Unstable =>
            {
                c.axisymmetric_onset(model_ref, &self.state.q, f.last_converged, f.attempted)
                    .unwrap_or_else(|e| {
                        self.summary.warnings.push(format!(
                            "stage `{}`: the loss of stability in harmonic 0: {e}",
                            stage.name
                        ));
                        None
                    })
            }
            _ => None,
        };
        let onset = check
            .and_then(|c| c.onset)
            .or(axisymmetric)
            .map(|o| self.report_onset(stage, time, &o, summary));
        match outcome.result {
            Ok(r) => {
                summary.newton_iterations = r.newton_iterations + self.state.prestretch_iterations;
                // the tractions are now fully applied; later static stages keep them
                self.state.dead_load_start = 1.0;
                None
            }
            Err(f) => {
                summary.newton_iterations = f.newton_iterations + self.state.prestretch_iterations;
                // a limit point with a voltage on (ramped, or held while the material creeps)
                let electric = start_voltages
                    .iter()
                    .zip(&targets)
                    .any(|(a, b)| a != b || *b != 0.0)
                    || quasi_static;
                let charged = plan.electrodes.iter().any(|e| {
                    e.charge
                        .as_ref()
                        .is_some_and(|w| *w != Waveform::constant(0.0))
                });
                use crate::solve::stepping::FailureCause;
                let interrupted = f.cause == FailureCause::Other;
                // the evidence beyond the failed step: a material at its locking limit in the
                // last converged state, or input whose scales leave nothing physical to solve
                let locked = (!interrupted)
                    .then(|| crate::problem::statics::nearest_locking(model_ref, &self.state.q))
                    .flatten()
                    .filter(|l| l.0 >= LOCKED_FRACTION);
                let implausible = (!interrupted)
                    .then(|| implausible_scales(plan, voltage_at(f.attempted)))
                    .flatten();
                let harmonic = onset.as_ref().filter(|o| {
                    o.stopped && (o.harmonic == 0 || f.reason.starts_with(HARMONIC_REASON))
                });
                let what = match &f.cause {
                    _ if harmonic.is_some_and(|o| o.harmonic == 0) => {
                        "loss of stability against circumferential harmonic n = 0 (axisymmetric: \
                         pull-in, or buckling in the meridian plane)"
                            .to_string()
                    }
                    _ if harmonic.is_some() => format!(
                        "loss of stability against circumferential harmonic n = {} (wrinkling \
                         or buckling out of the meridian plane)",
                        harmonic.map_or(0, |o| o.harmonic)
                    ),
                    _ if locked.is_some() => {
                        let (x, m, key) = locked.unwrap_or_default();
                        let name = &plan.material_names[m];
                        format!(
                            "material limit: material `{name}` reached {:.1} % of its locking \
                             limit (key `materials.{name}.{key}`; the network stiffens without \
                             bound there, so the ramp cannot go on)",
                            100.0 * x
                        )
                    }
                    _ if implausible.is_some() => format!(
                        "ill-conditioned or non-physical input ({})",
                        implausible.clone().unwrap_or_default()
                    ),
                    FailureCause::Singular if f.last_converged == 0.0 => {
                        "singular tangent at the start of the stage: the body is not fully \
                         supported (a rigid-body motion is free; add constraints)"
                            .to_string()
                    }
                    FailureCause::Singular => "singular tangent".to_string(),
                    FailureCause::NonFinite => {
                        "non-finite (NaN or infinite) residual or update".to_string()
                    }
                    FailureCause::Material(m) => format!("material limit ({m})"),
                    FailureCause::LinearSolver(m) => format!("linear solver failure ({m})"),
                    _ if f.limit_point && electric => {
                        "electromechanical instability (pull-in)".to_string()
                    }
                    _ if f.limit_point && charged => {
                        "electromechanical instability under charge control".to_string()
                    }
                    _ if f.limit_point => "limit point (loss of stability)".to_string(),
                    _ if crate::solve::interrupt::is_request(&f.reason) => {
                        format!("{} (the last accepted step is in the outputs)", f.reason)
                    }
                    _ => "solve failed".to_string(),
                };
                // what the stage controls, at the last converged and the attempted load factor:
                // the prescribed voltages (unless all are zero beside charged electrodes) and each
                // charged electrode's charge, with the potential it took (an unknown)
                let mut controls = Vec::new();
                if electric || !charged {
                    controls.push(format!(
                        "last converged voltage {} V, failed at {} V",
                        volts(voltage_at(f.last_converged)),
                        volts(voltage_at(f.attempted))
                    ));
                }
                // an electrode's charge (whole device) at load factor s
                let charge_at = |e: &super::plan::Electrode, q: &Waveform, s: f64| {
                    if e.charge_in_drive {
                        let node = e.nodes[0];
                        drive
                            .charges_at(s * stage.duration, s)
                            .iter()
                            .find(|c| c.0 == node)
                            .map_or(f64::NAN, |c| c.1 * plan.symmetry_factor)
                    } else {
                        q.value(0.0) * drive.dead_loads.at(s)
                    }
                };
                let voltages = plan
                    .electrode_voltages(&self.state.q)
                    .unwrap_or_else(|_| vec![f64::NAN; plan.electrodes.len()]);
                for (e, voltage) in plan.electrodes.iter().zip(voltages) {
                    if let Some(q) = &e.charge {
                        controls.push(format!(
                            "last converged charge of `{}` {:.6e} C at {} V, failed at {:.6e} C",
                            e.name,
                            charge_at(e, q, f.last_converged),
                            volts(voltage),
                            charge_at(e, q, f.attempted)
                        ));
                    }
                }
                Some(format!(
                    "{what} in stage `{}` at t = {:.6} s: no stable equilibrium beyond load factor {:.6} \
                     (tried {:.6}); {}; last failure: {}",
                    stage.name,
                    self.state.stage_time + f.last_converged * stage.duration,
                    f.last_converged,
                    f.attempted,
                    controls.join("; "),
                    f.reason
                ))
            }
        }
    }

    /// Sends the first loss of stability against a harmonic of stage `stage` (which started at
    /// run time `time`) to the observers and the stage's summary.
    fn report_onset(
        &mut self,
        stage: &Stage,
        time: f64,
        o: &Onset,
        summary: &mut StageSummary,
    ) -> InstabilityRecord {
        let plan = self.plan;
        let voltages = plan
            .electrode_voltages(&o.state)
            .map(|v| {
                plan.electrodes
                    .iter()
                    .zip(v)
                    .filter(|(e, _)| e.prescribed(false))
                    .map(|(e, v)| (e.name.clone(), v))
                    .collect()
            })
            .unwrap_or_default();
        let record = InstabilityRecord {
            stage: stage.name.clone(),
            harmonic: o.harmonic,
            stable_load_factor: o.stable_load,
            load_factor: o.load,
            time: time + o.load * stage.duration,
            voltages,
            unstable: o.unstable.clone(),
            axial_share: axial_share(&o.mode.shape),
            stopped: o.harmonic == 0 || stage.stability.is_some_and(|s| s.stop),
        };
        self.observer.instability(plan, &record, &o.state, &o.mode);
        summary.instability = Some(record.clone());
        record
    }

    /// A continuation stage: the equilibrium path of the stage's loads by arc length, through
    /// limit points, to its target. Every point is recorded as a step (its pseudo-time is
    /// load factor × duration, so it runs back where the load does) and sent as a path point
    /// with its stability; located limit points go to the observers. Returns the failure, if any.
    fn continuation_stage(
        &mut self,
        si: usize,
        model: &mut Model,
        drive: Drive,
        prescribed: &[bool],
        summary: &mut StageSummary,
    ) -> Option<String> {
        use crate::job::plan::{PathParameter, PathTarget};
        use crate::solve::continuation::{
            continuation, ContinuationSettings, Next, PathEnd, PathEvent,
        };
        let plan = self.plan;
        let stage = &plan.stages[si];
        let StageKind::Continuation {
            steps,
            ref parameter,
            ref target,
            max_points,
        } = stage.kind
        else {
            unreachable!("a continuation stage")
        };
        summary.kind = "continuation".into();
        self.state.v.iter_mut().for_each(|v| *v = 0.0);
        self.state.a.iter_mut().for_each(|v| *v = 0.0);
        let stage_start = self.state.q.clone();
        let t0 = drive.dead_loads.from;
        let (column, unit) = parameter.column(plan);
        // the parameter at the stage's start and end (load factor 0 and 1)
        let (p0, p1) = match parameter {
            PathParameter::Voltage { electrode } => {
                let e = &plan.electrodes[*electrode];
                // on a rank's part the electrode's nodes may lie on other ranks
                let start = match plan.electrode_voltages(&stage_start) {
                    Ok(v) => v[*electrode],
                    Err(e) => return Some(format!("stage `{}`: {e}", stage.name)),
                };
                (start, stage.electrode_waveform(e).value(stage.duration))
            }
            PathParameter::Charge { electrode } => {
                let q = plan.electrodes[*electrode]
                    .charge
                    .as_ref()
                    .and_then(Waveform::constant_value)
                    .unwrap_or(0.0);
                (q * t0, q)
            }
            PathParameter::Pressure { index } => {
                let (p, r) = (&model.pressures[*index], drive.pressures[*index]);
                (p.value * r.from, p.value * r.to)
            }
            PathParameter::Force => (t0, 1.0),
        };
        if p0 == p1 {
            return Some(format!(
                "stage `{}`: the parameter `{column}` is {} {unit} at the start and at the end \
                 of the stage: a continuation follows a load that its stage changes",
                stage.name,
                crate::units::Short(p0)
            ));
        }
        let parameter_at = |s: f64| p0 + s * (p1 - p0);
        let probe_target = match target {
            PathTarget::Probe { name, value } => plan
                .probes
                .iter()
                .position(|(n, _)| n == name)
                .map(|i| (i, *value)),
            _ => None,
        };
        let settings = ContinuationSettings {
            increment: 1.0 / steps.max(1) as f64,
            max_points,
            target_load: match target {
                PathTarget::Load(l) => Some(*l),
                _ => None,
            },
            ..Default::default()
        };
        let time = self.state.stage_time;
        let model_ref: &Model = model;
        let mut problem = StaticProblem::new(model_ref, Some(stage_start));
        problem.set_drive(drive);
        problem.duration = stage.duration;
        problem.points = self.points.clone();
        // the whole problem, or on a rank's part the rank's owned unknowns
        let mut held = match Held::new(problem, plan.part.as_ref().map(|p| &p.stages)) {
            Ok(h) => h,
            Err(e) => return Some(format!("stage `{}`: {e}", stage.name)),
        };
        let mut solver = plan.solver.build();
        let mut step_no = self.state.first_step;
        let mut last_load = 0.0;
        let mut previous_probe: Option<f64> = None;
        let mut reached = false;
        let mut limit_error = None;
        // each point of the path is tested as it comes (no bisection: the onset lies between
        // two points)
        let mut check = match harmonic_check(plan, stage, f64::INFINITY) {
            Ok(c) => c,
            Err(e) => return Some(e),
        };
        let mut check_error = None;
        let mut stopped_unstable = false;
        let result = continuation(
            &mut held,
            solver.as_mut(),
            self.newton,
            &settings,
            0.0,
            |held, event| match event {
                PathEvent::Point(pt) => {
                    // the whole problem's count (the rank's part's system would give its own)
                    let expected = held.expected_negative_pivots();
                    let p = held.inner();
                    step_no += 1;
                    self.rec.sudden_loads = false;
                    self.rec.circuit_current = false;
                    self.rec.external_factor = p.drive().dead_loads.at(pt.load);
                    self.rec.pressure_now =
                        p.drive().pressures.iter().map(|r| r.at(pt.load)).collect();
                    self.rec.charges_now = p.drive().charges_at(pt.load * stage.duration, pt.load);
                    let dt = (pt.load - last_load) * stage.duration;
                    let previous_load = last_load;
                    last_load = pt.load;
                    let record = self.record(
                        &p.state,
                        prescribed,
                        time + pt.load * stage.duration,
                        &stage.name,
                        step_no,
                        pt.iterations,
                        dt,
                        0.0,
                    );
                    self.state.accepted += 1;
                    let probes = record.map(|r| r.probes).unwrap_or_default();
                    self.observer.path_point(
                        plan,
                        &PathRecord {
                            stage: stage.name.clone(),
                            point: pt.index,
                            load_factor: pt.load,
                            parameter: parameter_at(pt.load),
                            arc_length: pt.arc,
                            negative_pivots: pt.inertia.map(|i| (i.negative, expected)),
                            stable: pt.stable,
                            probes: probes.clone(),
                        },
                    );
                    if let Some(c) = check.as_mut().filter(|c| c.onset.is_none()) {
                        let verdict = c.check(model_ref, &p.state, previous_load, pt.load);
                        if c.onset.is_some() {
                            if c.stops() {
                                stopped_unstable = true;
                                return Next::Stop;
                            }
                        } else if let Err(e) = verdict {
                            check_error = Some(e);
                        }
                    }
                    if let (Some((i, target)), Some(&x)) =
                        (probe_target, probe_target.and_then(|(i, _)| probes.get(i)))
                    {
                        let _ = i;
                        let crossed = previous_probe
                            .is_some_and(|prev| (prev - target) * (x - target) <= 0.0);
                        previous_probe = Some(x);
                        if crossed || x == target {
                            reached = true;
                            return Next::Stop;
                        }
                    }
                    Next::Continue
                }
                PathEvent::Limit(l) => {
                    match self.rec.probes_at(&held.inner().state) {
                        Ok(probes) => self.observer.limit_point(
                            plan,
                            &LimitRecord {
                                stage: stage.name.clone(),
                                maximum: l.maximum,
                                load_factor: l.load,
                                parameter: parameter_at(l.load),
                                probes,
                            },
                        ),
                        Err(e) => limit_error = Some(e),
                    }
                    Next::Continue
                }
            },
        );
        if let Some(e) = limit_error {
            self.summary.warnings.push(format!(
                "stage `{}`: the probes at a limit point could not be evaluated: {e}",
                stage.name
            ));
        }
        if let Some(e) = check_error {
            self.summary.warnings.push(format!(
                "stage `{}`: the test against harmonics failed: {e}",
                stage.name
            ));
        }
        if let Some(o) = check.and_then(|c| c.onset) {
            let record = self.report_onset(stage, time, &o, summary);
            if stopped_unstable {
                let problem = held.into_inner();
                self.state.q = problem.state;
                self.points = problem.points;
                summary.steps = step_no;
                return Some(format!(
                    "loss of stability against circumferential harmonic n = {} in stage `{}` \
                     between load factors {:.6} and {:.6} ({column} = {} {unit}); the run stops \
                     at the first unstable point of the path",
                    record.harmonic,
                    stage.name,
                    record.stable_load_factor,
                    record.load_factor,
                    crate::units::Short(parameter_at(record.load_factor))
                ));
            }
        }
        let problem = held.into_inner();
        self.state.q = problem.state;
        self.points = problem.points;
        summary.steps = step_no;
        match result {
            Ok(report) => {
                summary.newton_iterations = report.iterations + self.state.prestretch_iterations;
                // later stages start from the dead loads where the path ended
                self.state.dead_load_start = t0 + last_load * (1.0 - t0);
                let missed = match (target, &report.end) {
                    (PathTarget::Points, _) | (PathTarget::Load(_), PathEnd::TargetLoad) => false,
                    (PathTarget::Probe { .. }, _) => !reached,
                    _ => true,
                };
                missed.then(|| {
                    format!(
                        "continuation in stage `{}`: the target was not reached in {} points \
                         (last point: load factor {:.6}, {column} = {} {unit}); raise \
                         `max_points` or check the target",
                        stage.name,
                        report.points,
                        last_load,
                        crate::units::Short(parameter_at(last_load))
                    )
                })
            }
            Err(f) => {
                summary.newton_iterations = f.iterations + self.state.prestretch_iterations;
                Some(format!(
                    "continuation in stage `{}` stopped after {} points at load factor {:.6} \
                     ({column} = {} {unit}): {}",
                    stage.name,
                    f.points,
                    f.last_load,
                    crate::units::Short(parameter_at(f.last_load)),
                    f.reason
                ))
            }
        }
    }

    /// A dynamic stage: time integration over the stage's duration. Returns the failure, if any.
    fn dynamic_stage(
        &mut self,
        si: usize,
        model: &mut Model,
        drive: Drive,
        prescribed: &[bool],
        position: Option<(StagePosition, usize)>,
        summary: &mut StageSummary,
    ) -> Option<String> {
        let plan = self.plan;
        let stage = &plan.stages[si];
        let StageKind::Dynamic {
            dt,
            scheme,
            mass: mass_kind,
        } = stage.kind
        else {
            unreachable!("a dynamic stage");
        };
        summary.kind = "dynamic".into();
        let mut mass = NodalMass::new(model, &plan.densities, mass_kind);
        for r in &plan.rigid {
            if r.mass > 0.0 {
                mass.add_point_mass(r.nodes[0], r.mass);
            }
        }
        model.dirichlet = plan.supports.clone();
        // on a rank's part: the step's and the projection's division of the unknowns
        let part = match &plan.part {
            None => None,
            Some(p) => match &p.projection {
                Some(projection) => Some(StageParts {
                    step: &p.stages,
                    projection,
                    explicit: p.explicit.as_ref(),
                }),
                None => {
                    return Some(format!(
                        "dynamic stage `{}`: the rank's part has no division of the \
                         projection's unknowns",
                        stage.name
                    ))
                }
            },
        };
        let inputs = DynamicInputs {
            mass: &mass,
            viscosity: plan.viscosities.clone(),
            drive,
            points: self.points.clone(),
            part,
        };
        let settings = DynamicSettings {
            duration: stage.duration,
            dt,
            scheme,
            min_fraction: 1.0 / 1024.0,
            easy_iterations: 6,
            reuse_factorization: true,
            solver: plan.solver.clone(),
        };
        // the integrator runs on stage time; records get the global time
        let (t0, resume, mut step_no) = match position {
            Some((StagePosition::Dynamic { t, driver }, step_no)) => (t, Some(driver), step_no),
            _ => (0.0, None, self.state.first_step),
        };
        let start_level = TimeLevel {
            t: t0,
            q: self.state.q.clone(),
            v: self.state.v.clone(),
            a: self.state.a.clone(),
        };
        let mut last = resume.clone().unwrap_or(DynamicResume {
            t_start: 0.0,
            dt,
            iterations: 0,
            last_h: f64::NAN,
            step_factor: None,
            projection_factor: None,
            linear: Default::default(),
        });
        let mut mv = vec![0.0; self.state.q.len()];
        let time = self.state.stage_time;
        let model_ref: &Model = model;
        self.observer.dynamic_started(
            si,
            &DynamicStart {
                model: model_ref,
                inputs: &inputs,
                method: scheme,
                start: &start_level,
                settings: &settings,
                newton: self.newton,
            },
        );
        // the stage's linear work up to its last accepted step
        let mut linear = Default::default();
        let outcome = run_dynamic_from(
            model_ref,
            &inputs,
            start_level,
            &settings,
            self.newton,
            resume,
            |level, info| {
                self.observer.time_step(si, level, info);
                step_no += 1;
                linear = info.linear;
                self.state.dissipated += info.dissipated;
                if let Some(p) = info.points {
                    self.points.clone_from(p);
                    self.rec.points.clone_from(p);
                }
                // on a rank's part, its cells' and owned masses' share (the records sum them)
                mass.mul(&level.v, &mut mv);
                let kinetic = 0.5 * level.v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
                self.rec.external_factor = 1.0;
                self.rec.pressure_now = vec![0.0; plan.model.pressures.len()];
                self.rec.charges_now = inputs.drive.charges_at(level.t, 1.0);
                self.rec.sudden_loads = true;
                self.rec.circuit_current = true;
                let record = self.record(
                    &level.q,
                    prescribed,
                    time + level.t,
                    &stage.name,
                    step_no,
                    info.newton_iterations,
                    info.dt,
                    kinetic,
                );
                self.control(level.t, record.as_ref().map(|r| r.probes.as_slice()));
                self.state.accepted += 1;
                last = info.resume_point(0.0);
                if self.observer.wants_state(self.state.accepted, false) {
                    let r = last.clone();
                    self.state.v.clone_from(&level.v);
                    self.state.a.clone_from(&level.a);
                    self.offer_state(false, |job| {
                        job.state(
                            model_ref,
                            si,
                            step_no,
                            StagePosition::Dynamic {
                                t: level.t,
                                driver: r,
                            },
                            &level.q,
                        )
                    });
                }
            },
        );
        summary.steps = step_no;
        let (level, failure) = match outcome {
            Ok((level, its)) => {
                summary.newton_iterations = its;
                summary.linear = linear;
                (level, None)
            }
            Err((level, f)) => {
                summary.newton_iterations = f.newton_iterations;
                summary.linear = f.linear;
                if crate::solve::interrupt::requested() {
                    self.state.v.clone_from(&level.v);
                    self.state.a.clone_from(&level.a);
                    let r = last.clone();
                    self.offer_state(true, |job| {
                        job.state(
                            model_ref,
                            si,
                            step_no,
                            StagePosition::Dynamic {
                                t: level.t,
                                driver: r,
                            },
                            &level.q,
                        )
                    });
                }
                (
                    level,
                    Some(format!(
                        "dynamic stage `{}` stopped at t = {:.6e} s: {}",
                        stage.name,
                        self.state.stage_time + f.t,
                        f.reason
                    )),
                )
            }
        };
        self.state.q = level.q;
        self.state.dead_load_start = 1.0;
        self.state.v = level.v;
        self.state.a = level.a;
        failure
    }

    /// Ends the run: the summary, sent to the observers.
    fn finish(mut self) -> RunSummary {
        self.summary.warnings.append(&mut self.rec.warnings);
        self.summary.wall_s = self.state.wall_s + self.started.elapsed().as_secs_f64();
        self.summary.interrupted = crate::solve::interrupt::requested() && !self.summary.converged;
        self.observer.finished(self.plan, &self.summary);
        self.summary
    }
}

impl Plan {
    /// The drive of stage `si`, its loads starting where the stages before left them (the dead
    /// loads at the fraction `dead_loads_from` of their value, each pressure at its fraction in
    /// `pressures_from`):
    /// - the prescribed electrodes' waveforms and the circuits' sources, at 0 V when the stage has
    ///   its electrodes off; quasi-static stages follow them in stage time, dynamic steps take
    ///   them at their time levels; a static stage holds its electrodes among its supports
    ///   instead, ramped to their values at its end ([`Plan::stage_conditions`]);
    /// - a static, quasi-static or continuation stage ramps the dead loads on to full and each
    ///   pressure to on (1) or off (0) as the stage says; a volume-controlled pressure acting in
    ///   the stage starts from its fraction, which is then an unknown;
    /// - a dynamic stage holds the dead loads at full value.
    pub fn drive(&self, si: usize, dead_loads_from: f64, pressures_from: &[f64]) -> Drive {
        let stage = &self.stages[si];
        let (dynamic, ramped_voltages) = match stage.kind {
            StageKind::Dynamic { .. } => (true, true),
            StageKind::QuasiStatic { .. } => (false, true),
            _ => (false, false),
        };
        let targets = self.pressure_targets(si);
        let mut drive = Drive {
            voltages: if ramped_voltages {
                self.voltage_waveforms(stage, dynamic)
            } else {
                Vec::new()
            },
            circuits: self
                .electrodes
                .iter()
                .filter(|e| e.resistance.is_some())
                .map(|e| stage.electrode_waveform(e))
                .collect(),
            dead_loads: Ramp {
                from: dead_loads_from,
                to: 1.0,
            },
            pressures: (0..targets.len())
                .map(|i| {
                    let from = pressures_from[i];
                    if self.pressure_volumes[i].is_some() && targets[i] != 0.0 {
                        Ramp::held_at(from)
                    } else {
                        Ramp {
                            from,
                            to: targets[i],
                        }
                    }
                })
                .collect(),
            supports: Vec::new(),
            held: Default::default(),
            charges: self.driven_charges(stage, dead_loads_from),
        };
        if dynamic {
            drive.dead_loads = Ramp::HELD;
        }
        drive
    }

    /// The charges of `stage`'s drive (meshed part): each electrode whose charge follows the
    /// drive, at its control's table or its waveform in stage time; a static or continuation
    /// stage ramps it from the fraction `dead_loads_from` of its value at the stage's end, as
    /// its dead loads.
    fn driven_charges(&self, stage: &Stage, dead_loads_from: f64) -> Vec<DrivenCharge> {
        let in_time = matches!(
            stage.kind,
            StageKind::Dynamic { .. } | StageKind::QuasiStatic { .. }
        );
        self.electrodes
            .iter()
            .filter(|e| e.charge_in_drive)
            .filter_map(|e| {
                let charge = stage
                    .electrode_charge(e)?
                    .scaled(1.0 / self.symmetry_factor);
                Some(if in_time {
                    DrivenCharge {
                        node: e.nodes[0],
                        charge,
                        ramp: Ramp::HELD,
                        at: None,
                    }
                } else {
                    DrivenCharge {
                        node: e.nodes[0],
                        charge,
                        ramp: Ramp {
                            from: dead_loads_from,
                            to: 1.0,
                        },
                        at: Some(stage.duration),
                    }
                })
            })
            .collect()
    }

    /// The controllers acting in `stage` (a dynamic or quasi-static stage with its electrodes
    /// on), in electrode order.
    pub fn controller_loops(&self, stage: &Stage) -> Vec<ControllerLoop> {
        let active = stage.electrodes_on
            && matches!(
                stage.kind,
                StageKind::Dynamic { .. } | StageKind::QuasiStatic { .. }
            );
        if !active {
            return Vec::new();
        }
        let dynamic = matches!(stage.kind, StageKind::Dynamic { .. });
        let mut loops = Vec::new();
        let mut state = 0;
        for (electrode, e) in self.electrodes.iter().enumerate() {
            if e.controller.is_none() {
                continue;
            }
            let drive = self.electrodes[..electrode]
                .iter()
                .filter(|e| e.prescribed(dynamic))
                .count();
            loops.push(ControllerLoop {
                state,
                electrode,
                drive,
            });
            state += 1;
        }
        loops
    }

    /// The prescribed electrodes' nodes and the waveforms they follow in `stage` (0 V when the
    /// stage has its electrodes off); `dynamic`: the circuits' electrodes are free.
    fn voltage_waveforms(&self, stage: &Stage, dynamic: bool) -> Vec<(Vec<usize>, Waveform)> {
        self.electrodes
            .iter()
            .filter(|e| e.prescribed(dynamic))
            .map(|e| (e.nodes.clone(), stage.electrode_waveform(e)))
            .collect()
    }

    /// The prescribed values of a stage's end: supports and electrodes at their drive's voltages
    /// at the stage's end. In dynamic stages a circuit's electrode is free, but its potential
    /// counts as prescribed in the flags: the circuit does work −Q·ΔV on the body, like a voltage
    /// electrode.
    pub fn stage_conditions(&self, model: &mut Model, stage: &Stage) -> Vec<bool> {
        model.dirichlet = self.supports.clone();
        let dynamic = matches!(stage.kind, StageKind::Dynamic { .. });
        for (nodes, waveform) in self.voltage_waveforms(stage, dynamic) {
            model.dirichlet.push(Dirichlet {
                nodes,
                field: Field::Phi,
                value: waveform.value(stage.duration),
            });
        }
        let mut flags = constrained_flags(model.mesh.n_nodes(), &model.dirichlet);
        for e in self.electrodes.iter().filter(|e| e.resistance.is_some()) {
            for &n in &e.nodes {
                flags[n * FIELDS + 3] = true;
            }
        }
        flags
    }
}

/// A controller acting in a stage: its index in [`RunState::controllers`], its electrode (plan
/// index) and the electrode's entry in the stage drive's voltages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControllerLoop {
    pub state: usize,
    pub electrode: usize,
    pub drive: usize,
}

/// A material point at this fraction of its locking limit (or beyond) in the last converged state
/// makes a failed ramp a material limit, not a loss of stability.
const LOCKED_FRACTION: f64 = 0.8;

/// An electrical stress εE² above this multiple of a material's shear modulus is no elastomer
/// under a field: a film pulls in near εE² ≈ μ/2 (Zhao & Suo, APL 91 (2007) 061921).
const FIELD_STRESS_RATIO: f64 = 1e3;

/// The test of `stage`'s states against harmonics, if it asks for one, for a ramp whose
/// smallest step is `min_increment` (infinite: every state tested as it comes); it needs the
/// whole model in this process.
fn harmonic_check(
    plan: &Plan,
    stage: &Stage,
    min_increment: f64,
) -> Result<Option<HarmonicCheck>, String> {
    let Some(settings) = stage.stability else {
        return Ok(None);
    };
    if plan.part.is_some() {
        return Err(format!(
            "stage `{}`: `stability_harmonics` needs the whole model in one process",
            stage.name
        ));
    }
    Ok(Some(HarmonicCheck::new(
        settings,
        min_increment,
        &plan.densities,
    )))
}

/// Σ u_z² / Σ |u|² of a shape (`FIELDS` values per node; slot 2 is u_θ of a harmonic mode).
fn axial_share(shape: &[f64]) -> f64 {
    let (mut z, mut all) = (0.0, 0.0);
    for node in shape.chunks(FIELDS) {
        z += node[1] * node[1];
        all += node[0] * node[0] + node[1] * node[1] + node[2] * node[2];
    }
    if all > 0.0 {
        z / all
    } else {
        0.0
    }
}

/// `x` rounded to three significant digits, shortly: `2.4e24`, `0.49`.
fn few(x: f64) -> String {
    let rounded: f64 = format!("{x:.2e}").parse().unwrap_or(x);
    crate::units::Short(rounded).to_string()
}

/// A voltage in a message: two decimals, or four significant digits beyond 10⁷ V.
fn volts(v: f64) -> String {
    if v.abs() < 1e7 || !v.is_finite() {
        format!("{v:.2}")
    } else {
        format!("{v:.4e}")
    }
}

/// What makes the input's scales ill-conditioned or non-physical at `voltage` (V), naming the
/// quantity: an electrical stress εE² (E = the voltage over the mesh's thinnest extent) far above
/// a material's shear modulus μ, a modulus too small for any solid, or a mesh thinner than a
/// nanometre (no continuum film; its energies fall to the solver's round-off). `None` when the
/// scales are those of a device.
fn implausible_scales(plan: &Plan, voltage: f64) -> Option<String> {
    use crate::units::Short;
    let (lo, hi) = plan.model.mesh.extents();
    let thin = (0..3)
        .map(|c| hi[c] - lo[c])
        .filter(|&d| d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let mut found = Vec::new();
    if thin < 1e-9 {
        found.push(format!(
            "the mesh is {} m thick at its thinnest, below a nanometre",
            Short(thin)
        ));
    }
    let field = voltage.abs() / thin;
    for (name, m) in plan.material_names.iter().zip(&plan.model.materials) {
        let (mu, eps) = (m.shear_modulus(), m.permittivity());
        let stress = eps * field * field;
        if mu.is_nan() || mu < 1e-6 {
            found.push(format!(
                "material `{name}`: its shear modulus μ = {} Pa is below any solid's",
                Short(mu)
            ));
        }
        if field > 0.0 && (!stress.is_finite() || stress > FIELD_STRESS_RATIO * mu) {
            found.push(format!(
                "material `{name}`: the electrical stress εE² ≈ {} Pa (ε = {} F/m, E ≈ {} V/m) \
                 is {} times its shear modulus μ = {} Pa, where a film pulls in near εE² ≈ μ/2",
                few(stress),
                few(eps),
                few(field),
                few(stress / mu),
                few(mu)
            ));
        }
    }
    (!found.is_empty()).then(|| found.join("; "))
}
