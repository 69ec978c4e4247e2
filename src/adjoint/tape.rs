//! The record of a forward run that its adjoint replays: for every static, quasi-static or
//! dynamic stage the run went through, its model (supports and electrodes as the stage holds
//! them), its drive and duration, and the converged state of each accepted step: a load step
//! with its load factor, or a time step with its size, velocities, accelerations and the
//! step's unknown before the potential's projection, and the internal variables of the material
//! points each step committed.
//!
//! Under a memory budget ([`Tape::with_budget`]) a dynamic stage also keeps checkpoints of the
//! forward run (a level, its points and where the driver stood) every `spacing` steps. While
//! every state fits the budget the stage holds them all, as without a budget, with each step's
//! resume point (the factor points shared between the steps that reuse them). Beyond it the
//! stage keeps every `spacing`-th level as a checkpoint, the least spacing (a power of two)
//! whose checkpoints take a quarter of what the budget leaves beside the stages before, its
//! steps' sizes and its last step; when the checkpoints outgrow their quarter, every other one
//! is dropped and the spacing doubles, so that they stay evenly spread over a stage whose step
//! count is not known in advance. The adjoint recomputes the steps from the checkpoints
//! ([`super::replay`]).

use crate::element::CellFields;
use crate::job::observer::{DynamicStart, Observer};
use crate::job::plan::Plan;
use crate::job::state::{RunSummary, StepRecord};
use crate::problem::drive::Drive;
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::SolverStats;
use crate::solve::newton::NewtonSettings;
use crate::time::integrator::FactorPoint;
use crate::time::integrator::TimeLevel;
use crate::time::mass::NodalMass;
use crate::time::stage::{DynamicResume, DynamicSettings, DynamicStepInfo, Method};
use std::sync::Arc;

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

impl TapedStep {
    /// The bytes of its vectors.
    pub fn bytes(&self) -> usize {
        (self.state.len() + self.v.len() + self.a.len() + self.iterate.len() + self.points.len())
            * 8
    }

    /// The record of a dynamic stage's accepted step to `level` (stage time) whose run clock
    /// started at `clock` (s).
    pub fn time_step(clock: f64, level: &TimeLevel, info: &DynamicStepInfo<'_>) -> TapedStep {
        TapedStep {
            load: 1.0,
            time: clock + level.t,
            state: level.q.clone(),
            dt: info.dt,
            v: level.v.clone(),
            a: level.a.clone(),
            iterate: if info.iterate == level.q.as_slice() {
                Vec::new()
            } else {
                info.iterate.to_vec()
            },
            points: info.points.map(|p| p.data.clone()).unwrap_or_default(),
        }
    }
}

/// Where the integrator stood after a step: a [`DynamicResume`] whose factor points are shared
/// with the other steps that reuse the same factorisations.
#[derive(Debug, Clone)]
pub struct Resume {
    /// The level's stage time (s).
    pub t: f64,
    pub dt: f64,
    pub iterations: usize,
    pub last_h: f64,
    pub linear: SolverStats,
    pub step_factor: Option<Arc<FactorPoint>>,
    pub projection_factor: Option<Arc<Vec<f64>>>,
}

impl Resume {
    /// The resume point after the step `info` that reached the level at stage time `t` (its
    /// factor points held on their own).
    pub fn after(t: f64, info: &DynamicStepInfo<'_>) -> Resume {
        let r = info.resume_point(0.0);
        Resume {
            t,
            dt: r.dt,
            iterations: r.iterations,
            last_h: r.last_h,
            linear: r.linear,
            step_factor: r.step_factor.map(Arc::new),
            projection_factor: r.projection_factor.map(Arc::new),
        }
    }

    /// The resume point to give the integrator.
    pub fn point(&self) -> DynamicResume {
        DynamicResume {
            t_start: 0.0,
            dt: self.dt,
            iterations: self.iterations,
            last_h: self.last_h,
            step_factor: self.step_factor.as_deref().cloned(),
            projection_factor: self.projection_factor.as_deref().cloned(),
            linear: self.linear,
        }
    }

    /// The bytes of its factor points.
    pub fn vector_bytes(&self) -> usize {
        self.step_factor.as_deref().map_or(0, factor_bytes)
            + self.projection_factor.as_ref().map_or(0, |p| p.len() * 8)
    }
}

/// The bytes of a factor point's vectors.
fn factor_bytes(f: &FactorPoint) -> usize {
    (f.q_prev.len() + f.v_prev.len() + f.a_prev.len() + f.q.len() + f.points.len()) * 8
}

/// A level a dynamic stage is replayed from: the level after `step` accepted steps (stage time
/// `t`) as the record of that step (its iterate left out), and where the driver stood then
/// (`None`: the stage's start, `record` its given level and start points).
#[derive(Debug, Clone)]
pub struct Checkpoint {
    pub step: usize,
    pub t: f64,
    pub record: TapedStep,
    pub resume: Option<Resume>,
}

impl Checkpoint {
    /// The bytes of its vectors, the factor points included.
    pub fn bytes(&self) -> usize {
        self.record.bytes() + self.resume.as_ref().map_or(0, Resume::vector_bytes)
    }

    /// The checkpoint after the step to `level` (stage time), the stage's `step`-th, with
    /// factor points of its own.
    pub fn after(
        step: usize,
        record: &TapedStep,
        level: &TimeLevel,
        info: &DynamicStepInfo<'_>,
    ) -> Self {
        Checkpoint {
            step,
            t: level.t,
            record: TapedStep {
                iterate: Vec::new(),
                ..record.clone()
            },
            resume: Some(Resume::after(level.t, info)),
        }
    }
}

/// A dynamic stage taped under a memory budget: what its replay needs.
#[derive(Debug, Clone)]
pub struct Replay {
    pub settings: DynamicSettings,
    pub newton: NewtonSettings,
    /// The run's clock at the stage's start (s).
    pub clock: f64,
    /// The points the integrator started from.
    pub start_points: PointStates,
    /// Each accepted step's size (s).
    pub dts: Vec<f64>,
    /// Every `spacing`-th level, from the stage's start (only the start while `whole`).
    pub checkpoints: Vec<Checkpoint>,
    pub spacing: usize,
    /// The bytes its checkpoints may take: a quarter of what the budget leaves beside the
    /// stages before it.
    pub room: usize,
    /// Whether the stage's `steps` still hold every step (else only the last), and then the
    /// resume points of every `spacing`-th level (the level and its resume point).
    pub whole: bool,
    pub resumes: Vec<(usize, Resume)>,
    /// The factor points the resume points share (each counted once).
    factors: Vec<Arc<FactorPoint>>,
    projections: Vec<Arc<Vec<f64>>>,
}

impl Replay {
    /// The bytes of its checkpoints' records, resume points, shared factor points and steps'
    /// sizes.
    pub fn bytes(&self) -> usize {
        self.checkpoints
            .iter()
            .map(|c| c.record.bytes())
            .sum::<usize>()
            + self.factors.iter().map(|f| factor_bytes(f)).sum::<usize>()
            + self.projections.iter().map(|p| p.len() * 8).sum::<usize>()
            + (self.checkpoints.len() + self.resumes.len()) * std::mem::size_of::<Resume>()
            + self.dts.len() * 8
    }

    /// The resume point after the step `info` to stage time `t`, sharing the factor points of
    /// the step before when they are the same.
    fn resume(&mut self, t: f64, info: &DynamicStepInfo<'_>) -> Resume {
        let step_factor = info.step_factor.map(|f| match self.factors.last() {
            Some(last) if **last == *f => last.clone(),
            _ => {
                let a = Arc::new(f.clone());
                self.factors.push(a.clone());
                a
            }
        });
        let projection_factor = info
            .projection_factor
            .map(|p| match self.projections.last() {
                Some(last) if last.as_slice() == p => last.clone(),
                _ => {
                    let a = Arc::new(p.to_vec());
                    self.projections.push(a.clone());
                    a
                }
            });
        let r = info.resume_point(0.0);
        Resume {
            t,
            dt: r.dt,
            iterations: r.iterations,
            last_h: r.last_h,
            linear: r.linear,
            step_factor,
            projection_factor,
        }
    }

    /// Drops the shared factor points no resume point holds any more.
    fn prune(&mut self) {
        self.factors.retain(|f| Arc::strong_count(f) > 1);
        self.projections.retain(|p| Arc::strong_count(p) > 1);
    }

    /// Keeps every `spacing`-th level of `steps` (every step of the stage so far) as
    /// checkpoints with their resume points, moving their records, the least spacing (a power
    /// of two, no less than that of the resume points) whose checkpoints take at most `room`
    /// bytes; only the last step stays in `steps`.
    fn checkpoint_steps(&mut self, steps: &mut Vec<TapedStep>) {
        let m = steps.len();
        let per = steps.first().map_or(0, |k| k.bytes() - k.iterate.len() * 8);
        let mut spacing = self.spacing;
        while m / spacing > 1 && (m / spacing) * per > self.room {
            spacing *= 2;
        }
        self.spacing = spacing;
        let last = steps.pop();
        let mut resumes: std::collections::BTreeMap<usize, Resume> =
            std::mem::take(&mut self.resumes).into_iter().collect();
        for (i, mut step) in steps.drain(..).enumerate() {
            if (i + 1) % spacing == 0 {
                if let Some(resume) = resumes.remove(&(i + 1)) {
                    step.iterate = Vec::new();
                    self.checkpoints.push(Checkpoint {
                        step: i + 1,
                        t: resume.t,
                        record: step,
                        resume: Some(resume),
                    });
                }
            }
        }
        if let Some(last) = last {
            if let Some(resume) = resumes.remove(&m).filter(|_| m.is_multiple_of(spacing)) {
                self.checkpoints.push(Checkpoint {
                    step: m,
                    t: resume.t,
                    record: TapedStep {
                        iterate: Vec::new(),
                        ..last.clone()
                    },
                    resume: Some(resume),
                });
            }
            steps.push(last);
        }
        drop(resumes);
        self.prune();
        self.thin();
    }

    /// Drops every other resume point of a whole stage (their spacing doubles) while their
    /// factor points take more than `room` bytes and more than one is left.
    fn thin_resumes(&mut self) {
        while self.resumes.len() > 1
            && self.factors.iter().map(|f| factor_bytes(f)).sum::<usize>()
                + self.projections.iter().map(|p| p.len() * 8).sum::<usize>()
                > self.room
        {
            self.spacing *= 2;
            let spacing = self.spacing;
            self.resumes.retain(|(j, _)| j % spacing == 0);
            self.prune();
        }
    }

    /// Drops every other checkpoint (the spacing doubles) while they take more than `room`
    /// bytes (with their factor points) and more than two are left.
    fn thin(&mut self) {
        while self.checkpoints.len() > 2 && self.bytes() > self.room {
            self.spacing *= 2;
            let spacing = self.spacing;
            self.checkpoints.retain(|c| c.step % spacing == 0);
            self.prune();
        }
    }
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
    /// A dynamic stage's checkpoints under a memory budget (`None`: without a budget).
    pub replay: Option<Replay>,
}

impl TapedStage {
    /// Its accepted steps.
    pub fn count(&self) -> usize {
        self.replay
            .as_ref()
            .map_or(self.steps.len(), |r| r.dts.len())
    }

    /// Its last accepted step.
    pub fn last_step(&self) -> &TapedStep {
        self.steps.last().expect("a taped stage has a step")
    }

    /// Whether its steps are recomputed from checkpoints (only the last is held).
    pub fn is_checkpointed(&self) -> bool {
        self.replay.as_ref().is_some_and(|r| !r.whole)
    }

    /// The sizes of its steps (s; zero for load steps).
    pub fn dts(&self) -> Vec<f64> {
        match &self.replay {
            Some(r) => r.dts.clone(),
            None => self.steps.iter().map(|k| k.dt).collect(),
        }
    }

    /// The bytes it holds: its start, its steps, its checkpoints and steps' sizes.
    pub fn bytes(&self) -> usize {
        let steps: usize = self.steps.iter().map(TapedStep::bytes).sum();
        let replay = self.replay.as_ref().map_or(0, Replay::bytes);
        (self.start.len() + self.start_points.len()) * 8 + steps + replay
    }
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
    /// The memory budget of the dynamic stages' states (bytes; `None`: hold every state).
    budget: Option<usize>,
    /// The bytes held now and the most held so far.
    held: usize,
    peak: usize,
    /// The largest dynamic step record and checkpoint taped (bytes).
    largest: (usize, usize),
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
            budget: None,
            held: 0,
            peak: 0,
            largest: (0, 0),
        }
    }

    /// An empty tape for a run of `plan` whose dynamic stages keep checkpoints and hold their
    /// states only while all of them fit `budget` bytes.
    pub fn with_budget(plan: &Plan, budget: usize) -> Tape {
        Tape {
            budget: Some(budget),
            ..Tape::new(plan)
        }
    }

    /// The memory budget (bytes), if any.
    pub fn budget(&self) -> Option<usize> {
        self.budget
    }

    /// The bytes the tape holds: states, checkpoints and steps' sizes.
    pub fn held_bytes(&self) -> usize {
        self.held
    }

    /// The most bytes the tape held during the run.
    pub fn peak_bytes(&self) -> usize {
        self.peak
    }

    /// The bytes of the largest record of a dynamic step and of the largest checkpoint. The
    /// held bytes exceed the budget by at most twice the larger (the record and checkpoint of
    /// the step that crosses it, or the two steps a recomputation holds at least), while the
    /// static stages' steps and the dynamic stages' checkpoints fit the budget.
    pub fn unit_bytes(&self) -> (usize, usize) {
        let checkpoints = self
            .stages
            .iter()
            .filter_map(|s| s.replay.as_ref())
            .flat_map(|r| r.checkpoints.iter().map(Checkpoint::bytes))
            .max()
            .unwrap_or(0);
        (self.largest.0, self.largest.1.max(checkpoints))
    }

    fn grow(&mut self, bytes: usize) {
        self.held += bytes;
        self.peak = self.peak.max(self.held);
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
) -> usize {
    let mut added = 0;
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
            replay: None,
        });
        added += stages.last().map_or(0, TapedStage::bytes);
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
    added + st.steps.last().map_or(0, TapedStep::bytes)
}

impl Observer for Tape {
    fn load_step(&mut self, stage: usize, load: f64, problem: &StaticProblem<'_>) {
        let start = self.starts[stage];
        let added = tape_load_step(
            &mut self.stages,
            &mut self.points,
            stage,
            start,
            load,
            problem,
        );
        self.grow(added);
    }

    fn prestretch_step(&mut self, phase: usize, load: f64, problem: &StaticProblem<'_>) {
        // the phases' clock: the hold starts where the stretch ended
        let start = self
            .prestretch_phases
            .first()
            .filter(|_| phase > 0)
            .map_or(0.0, |s| s.duration);
        let added = tape_load_step(
            &mut self.prestretch_phases,
            &mut self.points,
            phase,
            start,
            load,
            problem,
        );
        self.grow(added);
    }

    fn prestretched(&mut self, model: &Model, state: &[f64]) {
        self.prestretch = Some((model.clone(), state.to_vec()));
    }

    fn dynamic_started(&mut self, stage: usize, start: &DynamicStart<'_>) {
        let inputs = start.inputs;
        self.points.clone_from(&inputs.points.data);
        let replay = self.budget.map(|budget| Replay {
            settings: start.settings.clone(),
            newton: start.newton.clone(),
            clock: self.starts[stage],
            start_points: inputs.points.clone(),
            dts: Vec::new(),
            checkpoints: vec![Checkpoint {
                step: 0,
                t: start.start.t,
                record: TapedStep {
                    load: 1.0,
                    time: self.starts[stage] + start.start.t,
                    state: start.start.q.clone(),
                    dt: 0.0,
                    v: start.start.v.clone(),
                    a: start.start.a.clone(),
                    iterate: Vec::new(),
                    points: inputs.points.data.clone(),
                },
                resume: None,
            }],
            spacing: 1,
            room: budget.saturating_sub(self.held) / 4,
            whole: true,
            resumes: Vec::new(),
            factors: Vec::new(),
            projections: Vec::new(),
        });
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
            replay,
        });
        let added = self.stages.last().map_or(0, TapedStage::bytes);
        self.grow(added);
    }

    fn time_step(&mut self, stage: usize, level: &TimeLevel, info: &DynamicStepInfo<'_>) {
        let start = self.starts[stage];
        let budget = self.budget;
        let Some(st) = self.stages.last_mut().filter(|s| s.index == stage) else {
            return;
        };
        if let Some(d) = st.dynamics.as_mut() {
            if d.initial.is_none() {
                d.initial = Some(info.prev.clone());
            }
        }
        st.duration = level.t;
        let record = TapedStep::time_step(start, level, info);
        self.largest.0 = self.largest.0.max(record.bytes());
        if info.points.is_some() {
            self.points.clone_from(&record.points);
        }
        let (Some(r), Some(budget)) = (st.replay.as_mut(), budget) else {
            let added = record.bytes();
            st.steps.push(record);
            self.grow(added);
            return;
        };
        // the bytes held before the step, with the step's record and shared factor points
        let before = r.bytes();
        let held = self.held - before;
        r.dts.push(info.dt);
        let resume = r.resume(level.t, info);
        if r.whole {
            let k = r.dts.len();
            if k % r.spacing == 0 {
                r.resumes.push((k, resume));
                r.thin_resumes();
            } else {
                drop(resume);
                r.prune();
            }
            let added = record.bytes();
            st.steps.push(record);
            if self.held + added + r.bytes() - before > budget {
                // beyond the budget: the steps are recomputed from checkpoints
                self.peak = self.peak.max(held + added + r.bytes());
                r.whole = false;
                let freed: usize = st.steps.iter().map(TapedStep::bytes).sum();
                r.checkpoint_steps(&mut st.steps);
                let kept: usize = st.steps.iter().map(TapedStep::bytes).sum();
                self.held = held - (freed - added) + kept + r.bytes();
            } else {
                self.held = held + added + r.bytes();
            }
        } else {
            let k = r.dts.len();
            if k % r.spacing == 0 {
                let c = Checkpoint {
                    step: k,
                    t: level.t,
                    record: TapedStep {
                        iterate: Vec::new(),
                        ..record.clone()
                    },
                    resume: Some(resume),
                };
                self.largest.1 = self.largest.1.max(c.bytes());
                r.checkpoints.push(c);
            }
            // the new record and checkpoint exist before the dropped ones are freed
            self.peak = self.peak.max(held + record.bytes() + r.bytes());
            r.prune();
            r.thin();
            let old: usize = st.steps.iter().map(TapedStep::bytes).sum();
            self.held = held - old + record.bytes() + r.bytes();
            st.steps.clear();
            st.steps.push(record);
        }
        self.peak = self.peak.max(self.held);
    }

    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[CellFields]) {}

    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}
