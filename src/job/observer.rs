//! What observers of a run (writers, progress display, checkpoints) receive of it.

use super::plan::Plan;
use super::state::{
    FrequencyResponse, InstabilityRecord, LimitRecord, PathRecord, RunState, RunSummary, StepRecord,
};
use crate::element::CellFields;
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;
use crate::solve::newton::NewtonSettings;
use crate::time::integrator::TimeLevel;
use crate::time::modal::Mode;
use crate::time::stage::{DynamicInputs, DynamicSettings, DynamicStepInfo, Method};

/// What a dynamic stage starts from, for an observer that replays its steps (the adjoint's
/// tape): the model with the stage's supports held, its mass, viscosities, drive and the
/// internal variables of its material points, the integration method, the start level as
/// given to the integrator (stage time), and the integrator's and Newton's settings (with which
/// a replay from a resume point repeats the stage's steps).
pub struct DynamicStart<'a> {
    pub model: &'a Model,
    pub inputs: &'a DynamicInputs<'a>,
    pub method: Method,
    pub start: &'a TimeLevel,
    pub settings: &'a DynamicSettings,
    pub newton: &'a NewtonSettings,
}

/// Receives the progress of a run.
pub trait Observer {
    /// A stage begins.
    fn stage_started(&mut self, _index: usize, _name: &str) {}
    /// A step was accepted; `state` holds u (m) and Φ (V), 4 per node; `fields` the cell fields.
    fn step(&mut self, plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]);
    /// The run ended (converged or not).
    fn finished(&mut self, plan: &Plan, summary: &RunSummary);
    /// The run resumes from a state; `records` are the steps recorded before it (no
    /// [`Observer::step`] is sent for them); `state` and `fields` are those of the last record.
    fn resumed(
        &mut self,
        _plan: &Plan,
        _records: &[StepRecord],
        _state: &[f64],
        _fields: &[CellFields],
    ) {
    }
    /// The cell means of the material points' internal variables at the state of the next
    /// [`Observer::step`] (sent only when a material has internal variables).
    fn point_states(&mut self, _plan: &Plan, _cell_means: &[(String, Vec<f64>)]) {}
    /// A `modes` stage found these modes about `state`.
    fn modes(&mut self, _plan: &Plan, _stage: &str, _state: &[f64], _modes: &[Mode]) {}
    /// A `frequency-response` stage computed this response.
    fn frequency_response(&mut self, _plan: &Plan, _stage: &str, _response: &FrequencyResponse) {}
    /// A continuation stage converged at a point of its path (after its [`Observer::step`]).
    fn path_point(&mut self, _plan: &Plan, _point: &PathRecord) {}
    /// A continuation stage located a limit point of its parameter.
    fn limit_point(&mut self, _plan: &Plan, _limit: &LimitRecord) {}
    /// A static or quasi-static stage found its first state unstable against a circumferential
    /// harmonic (`stability_harmonics`): `state` is that state, `mode` the critical mode.
    fn instability(
        &mut self,
        _plan: &Plan,
        _record: &InstabilityRecord,
        _state: &[f64],
        _mode: &Mode,
    ) {
    }
    /// A static or quasi-static load step of stage `stage` was accepted at load factor `load`
    /// (before its [`Observer::step`]): the problem holds the converged state, the committed
    /// point states and the stage's drive, what the adjoint of the run replays.
    fn load_step(&mut self, _stage: usize, _load: f64, _problem: &StaticProblem<'_>) {}
    /// The pre-stretch phase converged: `model` is the problem it solved (the supports at their
    /// targets, the electrodes at their first voltages), `state` its solution.
    fn prestretched(&mut self, _model: &Model, _state: &[f64]) {}
    /// A load step of phase `phase` of a timed pre-stretch (0: the stretch, 1: the hold) was
    /// accepted at load factor `load`, as [`Observer::load_step`] for a stage.
    fn prestretch_step(&mut self, _phase: usize, _load: f64, _problem: &StaticProblem<'_>) {}
    /// Dynamic stage `stage` starts (before its first [`Observer::time_step`]).
    fn dynamic_started(&mut self, _stage: usize, _start: &DynamicStart<'_>) {}
    /// A time step of dynamic stage `stage` was accepted (before its [`Observer::step`]):
    /// `level` is the new level in stage time, `info` holds the level it started from and its
    /// unknown before the potential's projection.
    fn time_step(&mut self, _stage: usize, _level: &TimeLevel, _info: &DynamicStepInfo<'_>) {}
    /// Whether this observer may ask for run states (the run then keeps its history).
    fn takes_states(&self) -> bool {
        false
    }
    /// Whether it wants the run state after `accepted` accepted steps of the stages; `stopping`:
    /// the run is about to stop on a signal.
    fn wants_state(&self, _accepted: usize, _stopping: bool) -> bool {
        false
    }
    /// The run state, when [`Observer::wants_state`] said so. An error becomes a warning.
    fn run_state(&mut self, _plan: &Plan, _state: &RunState) -> Result<(), String> {
        Ok(())
    }
}

/// Several observers as one: every event goes to each, in order.
pub struct Observers<'a, 'b>(pub &'a mut [&'b mut dyn Observer]);

impl Observer for Observers<'_, '_> {
    fn stage_started(&mut self, index: usize, name: &str) {
        self.0.iter_mut().for_each(|o| o.stage_started(index, name));
    }
    fn load_step(&mut self, stage: usize, load: f64, problem: &StaticProblem<'_>) {
        self.0
            .iter_mut()
            .for_each(|o| o.load_step(stage, load, problem));
    }
    fn prestretched(&mut self, model: &Model, state: &[f64]) {
        self.0.iter_mut().for_each(|o| o.prestretched(model, state));
    }
    fn prestretch_step(&mut self, phase: usize, load: f64, problem: &StaticProblem<'_>) {
        self.0
            .iter_mut()
            .for_each(|o| o.prestretch_step(phase, load, problem));
    }
    fn dynamic_started(&mut self, stage: usize, start: &DynamicStart<'_>) {
        self.0
            .iter_mut()
            .for_each(|o| o.dynamic_started(stage, start));
    }
    fn time_step(&mut self, stage: usize, level: &TimeLevel, info: &DynamicStepInfo<'_>) {
        self.0
            .iter_mut()
            .for_each(|o| o.time_step(stage, level, info));
    }
    fn step(&mut self, plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]) {
        self.0
            .iter_mut()
            .for_each(|o| o.step(plan, record, state, fields));
    }
    fn finished(&mut self, plan: &Plan, summary: &RunSummary) {
        self.0.iter_mut().for_each(|o| o.finished(plan, summary));
    }
    fn resumed(
        &mut self,
        plan: &Plan,
        records: &[StepRecord],
        state: &[f64],
        fields: &[CellFields],
    ) {
        self.0
            .iter_mut()
            .for_each(|o| o.resumed(plan, records, state, fields));
    }
    fn point_states(&mut self, plan: &Plan, cell_means: &[(String, Vec<f64>)]) {
        self.0
            .iter_mut()
            .for_each(|o| o.point_states(plan, cell_means));
    }
    fn modes(&mut self, plan: &Plan, stage: &str, state: &[f64], modes: &[Mode]) {
        self.0
            .iter_mut()
            .for_each(|o| o.modes(plan, stage, state, modes));
    }
    fn frequency_response(&mut self, plan: &Plan, stage: &str, response: &FrequencyResponse) {
        self.0
            .iter_mut()
            .for_each(|o| o.frequency_response(plan, stage, response));
    }
    fn path_point(&mut self, plan: &Plan, point: &PathRecord) {
        self.0.iter_mut().for_each(|o| o.path_point(plan, point));
    }
    fn limit_point(&mut self, plan: &Plan, limit: &LimitRecord) {
        self.0.iter_mut().for_each(|o| o.limit_point(plan, limit));
    }
    fn instability(&mut self, plan: &Plan, record: &InstabilityRecord, state: &[f64], mode: &Mode) {
        self.0
            .iter_mut()
            .for_each(|o| o.instability(plan, record, state, mode));
    }
    fn takes_states(&self) -> bool {
        self.0.iter().any(|o| o.takes_states())
    }
    fn wants_state(&self, accepted: usize, stopping: bool) -> bool {
        self.0.iter().any(|o| o.wants_state(accepted, stopping))
    }
    fn run_state(&mut self, plan: &Plan, state: &RunState) -> Result<(), String> {
        let mut errors = Vec::new();
        for o in self.0.iter_mut() {
            if o.wants_state(state.accepted, false) || o.wants_state(state.accepted, true) {
                if let Err(e) = o.run_state(plan, state) {
                    errors.push(e);
                }
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors.join("; "))
        }
    }
}
