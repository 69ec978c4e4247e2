//! The record of a forward run that its adjoint replays: for every static, quasi-static or
//! dynamic stage the run went through, its model (supports and electrodes as the stage holds
//! them), its drive and duration, and the converged state of each accepted step: a load step
//! with its load factor, or a time step with its size, velocities, accelerations and the
//! step's unknown before the potential's projection, and the internal variables of the material
//! points each step committed.

use crate::element::CellFields;
use crate::job::observer::{DynamicStart, Observer};
use crate::job::plan::Plan;
use crate::job::state::{RunSummary, StepRecord};
use crate::problem::drive::Drive;
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::time::integrator::TimeLevel;
use crate::time::mass::NodalMass;
use crate::time::stage::{DynamicStepInfo, Method};

/// One accepted load step.
#[derive(Debug, Clone)]
pub struct TapedStep {
    /// Load factor s ∈ (0, 1] of the stage.
    pub load: f64,
    /// Time in the run's clock (s): the stage's start + s · duration.
    pub time: f64,
    /// The converged state, 4 values per node.
    pub state: Vec<f64>,
    /// A time step's: its size (s), the new level's velocities and accelerations, and the
    /// step's unknown before the midpoint scheme's projection of the potential (empty when it
    /// is `state`). Empty for a load step.
    pub dt: f64,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub iterate: Vec<f64>,
    /// The material points' internal variables the step committed (laid out as
    /// [`PointStates::data`]; empty for elastic materials).
    pub points: Vec<f64>,
}

/// What a dynamic stage's steps need besides the model and drive.
#[derive(Debug, Clone)]
pub struct TapedDynamics {
    pub mass: NodalMass,
    /// Kelvin–Voigt viscosity of each material (Pa·s).
    pub viscosity: Vec<f64>,
    pub method: Method,
    /// The start level as given to the integrator (stage time).
    pub given: TimeLevel,
    /// The level its first step started from (after Newmark's consistent acceleration).
    pub initial: Option<TimeLevel>,
}

/// One static or quasi-static stage of the run.
#[derive(Debug, Clone)]
pub struct TapedStage {
    /// The stage's index in the plan.
    pub index: usize,
    pub model: Model,
    pub drive: Drive,
    /// The stage's duration (s).
    pub duration: f64,
    /// The state the stage started from.
    pub start: Vec<f64>,
    /// The internal variables it started from (laid out as [`PointStates::data`]; empty for
    /// elastic materials).
    pub start_points: Vec<f64>,
    pub steps: Vec<TapedStep>,
    /// A dynamic stage's integrator (`None`: a static or quasi-static stage).
    pub dynamics: Option<TapedDynamics>,
}

/// The taped run: an [`Observer`] that keeps the accepted load steps.
#[derive(Debug, Clone)]
pub struct Tape {
    pub stages: Vec<TapedStage>,
    /// The pre-stretch phase's problem and solution (the reference of deflections), if any.
    pub prestretch: Option<(Model, Vec<f64>)>,
    /// A timed pre-stretch's phases (the stretch, then the hold) as static stages of load
    /// steps in real time; the last state of the last is the reference of deflections.
    pub prestretch_phases: Vec<TapedStage>,
    /// Start time of each stage of the plan in the run's clock (s).
    starts: Vec<f64>,
    /// The internal variables the last accepted step committed (empty: none yet, the virgin
    /// state).
    points: Vec<f64>,
}

impl Tape {
    /// An empty tape for a run of `plan`.
    pub fn new(plan: &Plan) -> Tape {
        let starts = (0..plan.stages.len())
            .map(|i| plan.stage_start(i))
            .collect();
        Tape {
            stages: Vec::new(),
            prestretch: None,
            prestretch_phases: Vec::new(),
            starts,
            points: Vec::new(),
        }
    }

    /// The state deflections are measured from: the pre-stretched one (or zero, the undeformed
    /// state, without a pre-stretch), of `n` values.
    pub fn reference_state(&self, n: usize) -> Vec<f64> {
        if let Some((_, s)) = &self.prestretch {
            return s.clone();
        }
        self.prestretch_phases
            .last()
            .and_then(|p| p.steps.last())
            .map_or_else(|| vec![0.0; n], |k| k.state.clone())
    }

    /// The bytes the tape's states take.
    pub fn state_bytes(&self) -> usize {
        self.stages
            .iter()
            .chain(&self.prestretch_phases)
            .map(|s| {
                let steps: usize = s
                    .steps
                    .iter()
                    .map(|k| {
                        k.state.len() + k.v.len() + k.a.len() + k.iterate.len() + k.points.len()
                    })
                    .sum();
                (s.start.len() + s.start_points.len() + steps) * 8
            })
            .sum()
    }
}

/// Appends the accepted load step at load factor `load` of `problem` to the stage `index` of
/// `stages` (a new stage at its first step), its clock starting at `start` (s); `points` holds
/// the values the last accepted step committed.
fn tape_load_step(
    stages: &mut Vec<TapedStage>,
    points: &mut Vec<f64>,
    index: usize,
    start: f64,
    load: f64,
    problem: &StaticProblem<'_>,
) {
    if stages.last().is_none_or(|s| s.index != index) {
        // the first step's points were committed from the last step's before (the virgin
        // state at the first)
        let start_points = if points.is_empty() && !problem.points.is_empty() {
            PointStates::new(problem.model).data
        } else {
            points.clone()
        };
        stages.push(TapedStage {
            index,
            model: problem.model.clone(),
            drive: problem.drive().clone(),
            duration: problem.duration,
            start: problem.start().to_vec(),
            start_points,
            steps: Vec::new(),
            dynamics: None,
        });
    }
    points.clone_from(&problem.points.data);
    let st = stages.last_mut().expect("a stage was just pushed");
    st.steps.push(TapedStep {
        load,
        time: start + load * st.duration,
        state: problem.state.clone(),
        dt: 0.0,
        v: Vec::new(),
        a: Vec::new(),
        iterate: Vec::new(),
        points: problem.points.data.clone(),
    });
}

impl Observer for Tape {
    fn load_step(&mut self, stage: usize, load: f64, problem: &StaticProblem<'_>) {
        let start = self.starts[stage];
        tape_load_step(
            &mut self.stages,
            &mut self.points,
            stage,
            start,
            load,
            problem,
        );
    }

    fn prestretch_step(&mut self, phase: usize, load: f64, problem: &StaticProblem<'_>) {
        // the phases' clock: the hold starts where the stretch ended
        let start = self
            .prestretch_phases
            .first()
            .filter(|_| phase > 0)
            .map_or(0.0, |s| s.duration);
        tape_load_step(
            &mut self.prestretch_phases,
            &mut self.points,
            phase,
            start,
            load,
            problem,
        );
    }

    fn prestretched(&mut self, model: &Model, state: &[f64]) {
        self.prestretch = Some((model.clone(), state.to_vec()));
    }

    fn dynamic_started(&mut self, stage: usize, start: &DynamicStart<'_>) {
        let inputs = start.inputs;
        self.points.clone_from(&inputs.points.data);
        self.stages.push(TapedStage {
            index: stage,
            model: start.model.clone(),
            drive: inputs.drive.clone(),
            duration: 0.0,
            start: start.start.q.clone(),
            start_points: inputs.points.data.clone(),
            steps: Vec::new(),
            dynamics: Some(TapedDynamics {
                mass: inputs.mass.clone(),
                viscosity: inputs.viscosity.clone(),
                method: start.method,
                given: start.start.clone(),
                initial: None,
            }),
        });
    }

    fn time_step(&mut self, stage: usize, level: &TimeLevel, info: &DynamicStepInfo<'_>) {
        let start = self.starts[stage];
        let Some(st) = self.stages.last_mut().filter(|s| s.index == stage) else {
            return;
        };
        if let Some(d) = st.dynamics.as_mut() {
            if d.initial.is_none() {
                d.initial = Some(info.prev.clone());
            }
        }
        st.duration = level.t;
        let points = info.points.map(|p| p.data.clone()).unwrap_or_default();
        st.steps.push(TapedStep {
            load: 1.0,
            time: start + level.t,
            state: level.q.clone(),
            dt: info.dt,
            v: level.v.clone(),
            a: level.a.clone(),
            iterate: if info.iterate == level.q.as_slice() {
                Vec::new()
            } else {
                info.iterate.to_vec()
            },
            points: points.clone(),
        });
        if info.points.is_some() {
            self.points = points;
        }
    }

    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[CellFields]) {}

    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}
