//! The record of a forward run that its adjoint replays: for every static or quasi-static stage
//! the run went through, its model (supports and electrodes as the stage holds them), its drive
//! and duration, and the converged state of each accepted load step with its load factor.

use crate::element::CellFields;
use crate::job::observer::Observer;
use crate::job::plan::Plan;
use crate::job::state::{RunSummary, StepRecord};
use crate::problem::drive::Drive;
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;

/// One accepted load step.
#[derive(Debug, Clone)]
pub struct TapedStep {
    /// Load factor s ∈ (0, 1] of the stage.
    pub load: f64,
    /// Time in the run's clock (s): the stage's start + s · duration.
    pub time: f64,
    /// The converged state, 4 values per node.
    pub state: Vec<f64>,
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
    pub steps: Vec<TapedStep>,
}

/// The taped run: an [`Observer`] that keeps the accepted load steps.
#[derive(Debug, Clone)]
pub struct Tape {
    pub stages: Vec<TapedStage>,
    /// Start time of each stage of the plan in the run's clock (s).
    starts: Vec<f64>,
}

impl Tape {
    /// An empty tape for a run of `plan`.
    pub fn new(plan: &Plan) -> Tape {
        let mut t = 0.0;
        let starts = plan
            .stages
            .iter()
            .map(|s| {
                let start = t;
                t += s.duration;
                start
            })
            .collect();
        Tape {
            stages: Vec::new(),
            starts,
        }
    }

    /// The bytes the tape's states take.
    pub fn state_bytes(&self) -> usize {
        self.stages
            .iter()
            .map(|s| (s.start.len() + s.steps.iter().map(|k| k.state.len()).sum::<usize>()) * 8)
            .sum()
    }
}

impl Observer for Tape {
    fn load_step(&mut self, stage: usize, load: f64, problem: &StaticProblem<'_>) {
        if self.stages.last().is_none_or(|s| s.index != stage) {
            self.stages.push(TapedStage {
                index: stage,
                model: problem.model.clone(),
                drive: problem.drive().clone(),
                duration: problem.duration,
                start: problem.start().to_vec(),
                steps: Vec::new(),
            });
        }
        let st = self.stages.last_mut().expect("a stage was just pushed");
        st.steps.push(TapedStep {
            load,
            time: self.starts[stage] + load * st.duration,
            state: problem.state.clone(),
        });
    }

    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[CellFields]) {}

    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}
