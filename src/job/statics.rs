//! Static stages: the load ramp of a model's prescribed values and dead loads, solved by load
//! stepping with Newton.

use super::rank::Division;
use crate::algebra::system::LoadedSystem;
use crate::problem::distributed::Held;
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{SolverSettings, SolverStats};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::{ramp, AcceptedStep, RampFailure, RampReport, StepControl};

/// What a static stage runs in time: its duration (s; a load step Δs lasts Δs·duration for
/// materials with internal variables), the committed point states it starts from, and the
/// electrodes that follow their waveforms in stage time (quasi-static stages).
#[derive(Debug, Clone)]
pub struct StageTime {
    pub duration: f64,
    pub points: PointStates,
    pub drive: crate::problem::drive::Drive,
}

/// Outcome of a static ramp.
#[derive(Debug)]
pub struct StaticOutcome {
    pub state: Vec<f64>,
    /// Committed internal variables of the material points at `state`.
    pub points: PointStates,
    pub result: Result<RampReport, RampFailure>,
    /// The linear solver's work over the stage.
    pub linear: SolverStats,
}

/// Ramps the model's Dirichlet values from `initial` (zero state when `None`), and its dead loads
/// and pressures from nothing, to their targets in `steps` steps.
/// `on_step` sees the problem after every accepted step.
pub fn solve_static(
    model: &Model,
    initial: Option<Vec<f64>>,
    control: &StepControl,
    newton: &NewtonSettings,
    on_step: impl FnMut(&StaticProblem<'_>, &AcceptedStep),
) -> StaticOutcome {
    solve_static_with(
        model,
        &SolverSettings::default(),
        initial,
        crate::problem::drive::Drive::ramped(model),
        control,
        newton,
        on_step,
    )
}

/// [`solve_static`] with the linear solver of `solver` (a plan's `[solver]`) and the loads of
/// `drive`.
pub fn solve_static_with(
    model: &Model,
    solver: &SolverSettings,
    initial: Option<Vec<f64>>,
    drive: crate::problem::drive::Drive,
    control: &StepControl,
    newton: &NewtonSettings,
    mut on_step: impl FnMut(&StaticProblem<'_>, &AcceptedStep),
) -> StaticOutcome {
    let mut problem = StaticProblem::new(model, initial);
    problem.set_drive(drive);
    let mut solver = solver.build_for_load_steps();
    // a serial solver needs the whole tangent on every process
    if !solver.sums_shared_entries() {
        problem.assemble_every_cell();
    }
    let result = ramp(&mut problem, solver.as_mut(), newton, control, |p, s| {
        on_step(p, s)
    });
    StaticOutcome {
        state: problem.state,
        points: problem.points,
        result,
        linear: solver.stats(),
    }
}

/// [`solve_static`] resumable: the ramp's prescribed values start from `stage_start`; with
/// `resume = Some((state, position))` it continues from that converged state and ramp position.
/// `history` says how the stage runs in time ([`StageTime`]).
/// On a rank's part of a divided plan (`part`), Newton runs on the rank's owned unknowns and
/// `on_step` sees the rank's part of the problem.
/// The solver's factorisation after an accepted step is that of the converged state (Newton's
/// stability test), which a resumed ramp factors again at its start: the two agree bit for bit.
#[allow(clippy::too_many_arguments)]
pub fn solve_static_from(
    model: &Model,
    solver: &SolverSettings,
    stage_start: Vec<f64>,
    history: StageTime,
    resume: Option<(Vec<f64>, crate::solve::stepping::RampPosition)>,
    control: &StepControl,
    newton: &NewtonSettings,
    part: Option<&Division>,
    on_step: impl FnMut(&StaticProblem<'_>, &AcceptedStep),
) -> StaticOutcome {
    solve_static_checked(
        model,
        solver,
        stage_start,
        history,
        resume,
        control,
        newton,
        part,
        |_, _, _| Ok(()),
        on_step,
    )
}

/// [`solve_static_from`] with a stability test of the caller's: `check(problem, from, to)`
/// judges each converged state that Newton found stable before it is accepted (an error rejects
/// it and the step is cut back as at a limit point; [`crate::solve::stepping::ramp_from`]).
#[allow(clippy::too_many_arguments)]
pub fn solve_static_checked(
    model: &Model,
    solver: &SolverSettings,
    stage_start: Vec<f64>,
    history: StageTime,
    resume: Option<(Vec<f64>, crate::solve::stepping::RampPosition)>,
    control: &StepControl,
    newton: &NewtonSettings,
    part: Option<&Division>,
    mut check: impl FnMut(&StaticProblem<'_>, f64, f64) -> Result<(), String>,
    mut on_step: impl FnMut(&StaticProblem<'_>, &AcceptedStep),
) -> StaticOutcome {
    let stage_state = stage_start.clone();
    let mut problem = StaticProblem::new(model, Some(stage_start));
    problem.duration = history.duration;
    problem.points = history.points;
    problem.set_drive(history.drive);
    let position = resume.map(|(state, position)| {
        problem.state.copy_from_slice(&state);
        problem.set_load(position.load);
        problem.accept_resumed(position.load);
        position
    });
    let mut solver = solver.build_for_load_steps();
    // the whole problem, or on a rank's part Newton on the rank's owned unknowns, the ranks
    // combining their parts (collective)
    let mut system = match Held::new(problem, part) {
        Ok(s) => s,
        Err(reason) => {
            return StaticOutcome {
                state: stage_state,
                points: PointStates::default(),
                result: Err(RampFailure {
                    last_converged: 0.0,
                    attempted: 0.0,
                    reason,
                    limit_point: false,
                    cause: crate::solve::stepping::FailureCause::NoConvergence,
                    newton_iterations: 0,
                }),
                linear: solver.stats(),
            }
        }
    };
    let result = crate::solve::stepping::ramp_from(
        &mut system,
        solver.as_mut(),
        newton,
        control,
        position,
        |s, from, to| check(s.inner(), from, to),
        |s, acc| {
            on_step(s.inner(), acc);
            false
        },
    );
    let problem = system.into_inner();
    StaticOutcome {
        state: problem.state,
        points: problem.points,
        result,
        linear: solver.stats(),
    }
}
