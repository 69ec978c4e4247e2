//! Load stepping with automatic cut-back and regrowth.
//!
//! A load factor s runs from 0 to 1 in `steps` nominal steps. A step whose Newton solve fails, or
//! whose converged state is unstable (more negative pivots than potential unknowns: a limit point was
//! passed), is undone and retried with half the increment; after an easy step the increment grows
//! back, never past the next nominal point. When the increment falls below `min_fraction` of a
//! nominal step the ramp stops and reports the last converged load factor: under load (voltage)
//! control this is how a limit point such as electromechanical pull-in shows itself.

use super::linear::LinearSolver;
use super::newton::{newton, NewtonError, NewtonReport, NewtonSettings};
use crate::algebra::csr::CsrMatrix;

pub use crate::algebra::system::LoadedSystem;

/// Step control.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepControl {
    /// Nominal number of steps.
    pub steps: usize,
    /// Smallest increment, as a fraction of a nominal step.
    pub min_fraction: f64,
    /// Iterations at or below which the increment grows back (doubles).
    pub easy_iterations: usize,
}

impl Default for StepControl {
    fn default() -> Self {
        StepControl {
            steps: 10,
            min_fraction: 1.0 / 4096.0,
            easy_iterations: 6,
        }
    }
}

/// An accepted (sub)step.
#[derive(Debug, Clone)]
pub struct AcceptedStep {
    /// Load factor reached.
    pub load: f64,
    /// True when `load` is one of the nominal points k/steps.
    pub nominal: bool,
    pub newton: NewtonReport,
    /// Where the ramp stands after this step (to resume it from here).
    pub position: RampPosition,
}

/// The ramp's position between two steps: enough to continue it with [`ramp_from`].
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RampPosition {
    /// Load factor of the converged state.
    pub load: f64,
    /// The next increment to try.
    pub increment: f64,
    /// Index of the next nominal point k/steps.
    pub next_nominal: usize,
    pub accepted_steps: usize,
    pub cutbacks: usize,
    pub newton_iterations: usize,
    /// A step failed since the last nominal load: solves are to the solver's own tolerance.
    #[serde(default)]
    pub retrying: bool,
}

/// The ramp stopped before reaching s = 1.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("no converged stable state beyond load factor {last_converged} (tried {attempted}; last failure: {reason})")]
pub struct RampFailure {
    /// Last load factor with a converged, stable state (the system is left there).
    pub last_converged: f64,
    /// The smallest failed load factor above it.
    pub attempted: f64,
    /// The last failure.
    pub reason: String,
    /// True when failures persisted down to the minimum increment, or the converged states
    /// became unstable: a limit point of the load path.
    pub limit_point: bool,
    /// What the last failed attempt ran into.
    pub cause: FailureCause,
    /// Total Newton iterations spent, failed attempts included.
    pub newton_iterations: usize,
}

/// What stopped the last attempt of a failed ramp: tells a limit point (an unstable state, or
/// Newton failing as the increments shrink) from a singular tangent (e.g. a body free to move), a
/// non-finite residual and a material pushed out of its domain (e.g. a locked Gent network).
#[derive(Debug, Clone, PartialEq)]
pub enum FailureCause {
    /// Newton converged to a state whose tangent has too many negative pivots.
    Unstable,
    /// Newton did not converge (or diverged with a finite residual).
    NoConvergence,
    /// The tangent was singular.
    Singular,
    /// The residual or the update was not finite (NaN, ∞).
    NonFinite,
    /// A material could not be evaluated (the message names why).
    Material(String),
    /// The linear solver failed other than by a singular matrix (the message names how).
    LinearSolver(String),
    /// Stopped by a signal, or anything else.
    Other,
}

/// Whether a failure's message is a cell's non-positive volume ratio (an inverted element).
fn names_inverted_cell(message: &str) -> bool {
    message.contains("volume ratio")
}

impl FailureCause {
    /// A singular matrix (a zero pivot) or a non-finite value, by the failure's message.
    fn numerical(message: &str) -> Option<Self> {
        if message.contains("singular") || message.contains("pivot") {
            Some(FailureCause::Singular)
        } else if message.contains("NaN") || message.contains("non-finite") {
            Some(FailureCause::NonFinite)
        } else {
            None
        }
    }

    /// The cause of a Newton failure.
    pub fn of(e: &NewtonError) -> Self {
        match e {
            NewtonError::Singular { .. } => FailureCause::Singular,
            NewtonError::Diverged { residual, .. }
            | NewtonError::MaxIterations { residual, .. }
                if !residual.is_finite() =>
            {
                FailureCause::NonFinite
            }
            // held back by a material outside its domain (e.g. a Gent network at its lock)
            NewtonError::MaxIterations {
                blocked: Some(m), ..
            } if !names_inverted_cell(m) => FailureCause::Material(m.clone()),
            NewtonError::Diverged { .. } | NewtonError::MaxIterations { .. } => {
                FailureCause::NoConvergence
            }
            // a solver library's zero pivot is a singular tangent, as faer's is
            NewtonError::LinearSolve { message, .. } => Self::numerical(message)
                .unwrap_or_else(|| FailureCause::LinearSolver(message.clone())),
            NewtonError::Evaluation { message, .. } => {
                if let Some(cause) = Self::numerical(message) {
                    cause
                } else if names_inverted_cell(message) {
                    // an inverted element: the step went too far, as near a limit point
                    FailureCause::NoConvergence
                } else {
                    FailureCause::Material(message.clone())
                }
            }
        }
    }
}

/// Summary of a completed ramp.
#[derive(Debug, Clone, Default)]
pub struct RampReport {
    pub accepted_steps: usize,
    pub cutbacks: usize,
    pub newton_iterations: usize,
}

/// Ramps the load from 0 to 1. `on_step` is called after every accepted (sub)step.
pub fn ramp<S: LoadedSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    settings: &NewtonSettings,
    control: &StepControl,
    mut on_step: impl FnMut(&mut S, &AcceptedStep),
) -> Result<RampReport, RampFailure> {
    ramp_from(
        system,
        solver,
        settings,
        control,
        None,
        |_, _, _| Ok(()),
        |s, a| {
            on_step(s, a);
            false
        },
    )
}

/// [`ramp`] from a position (`None`: the start, s = 0; else the system must hold the converged
/// state at `start.load` with the prescribed values set). When `on_step` returns true the tangent
/// is re-evaluated and re-factorised at the accepted state, exactly as at the start of a ramp: a
/// ramp resumed from that step then makes the same decisions, bit for bit, as one that goes on.
/// `check(system, from, to)` judges a converged state of the step from load factor `from` to
/// `to` that Newton found stable before it is accepted: an error rejects it as unstable (a
/// stability test of the caller's, e.g. against non-axisymmetric perturbations), and the step is
/// cut back as at a limit point.
#[allow(clippy::too_many_arguments)]
pub fn ramp_from<S: LoadedSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    settings: &NewtonSettings,
    control: &StepControl,
    start: Option<RampPosition>,
    mut check: impl FnMut(&S, f64, f64) -> Result<(), String>,
    mut on_step: impl FnMut(&mut S, &AcceptedStep) -> bool,
) -> Result<RampReport, RampFailure> {
    let nominal = 1.0 / control.steps.max(1) as f64;
    let min_inc = nominal * control.min_fraction;
    let mut k: CsrMatrix = system.new_matrix();
    let start = start.unwrap_or(RampPosition {
        load: 0.0,
        increment: nominal,
        next_nominal: 1,
        accepted_steps: 0,
        cutbacks: 0,
        newton_iterations: 0,
        retrying: false,
    });
    let mut report = RampReport {
        accepted_steps: start.accepted_steps,
        cutbacks: start.cutbacks,
        newton_iterations: start.newton_iterations,
    };
    let mut s = start.load;
    let mut inc = start.increment;
    let mut next_nominal = start.next_nominal;
    let mut last_reason = String::new();
    // the last failure that met an inverted cell: which attempt ends the bisection there is
    // round-off, and the reason of a ramp that stops short of inversion names it
    let mut inverted: Option<String> = None;
    let mut last_cause;
    // the solver holds a factorisation of the tangent at (or next to) the current state
    let mut predictor_work = vec![0.0; system.n()];
    // after a failure, until the next nominal load is reached: every linear solve to the
    // solver's own tolerance. Next to a limit point a loose first solve can put Newton where it
    // only creeps, and the ramp would stop short of the limit (by 0.5 V of 33.7 kV on the film)
    let exact = NewtonSettings {
        inexact: false,
        ..settings.clone()
    };
    let mut retrying = start.retrying;
    // the solver learns the layout of the unknowns before its first factorisation (an iterative
    // solver would otherwise fall back to a direct one for it); a shared assembly's tangent is
    // whole only to a solver that knows its entries
    let prepared = super::newton::prepare_solver(system, solver).is_ok();
    let mut have_factor = prepared
        && system.evaluate(&mut predictor_work, Some(&mut k)).is_ok()
        && solver.factor(&k).is_ok();
    while next_nominal <= control.steps.max(1) {
        if let Some(reason) = super::interrupt::pending() {
            return Err(RampFailure {
                last_converged: s,
                attempted: s,
                reason,
                limit_point: false,
                cause: FailureCause::Other,
                newton_iterations: report.newton_iterations,
            });
        }
        let target_nominal = next_nominal as f64 * nominal;
        let target = (s + inc).min(target_nominal);
        let hits_nominal = (target - target_nominal).abs() <= 1e-12;
        let target = if hits_nominal { target_nominal } else { target };
        let saved = system.snapshot();
        if have_factor {
            predict(system, solver, s, target, &mut predictor_work);
        } else {
            system.set_load(target);
        }
        let outcome = newton(
            system,
            solver,
            &mut k,
            if retrying { &exact } else { settings },
        );
        let mut rejected = None;
        let accepted = match &outcome {
            Ok(rep) if rep.stable => match check(system, s, target) {
                Ok(()) => Some(system.accept()),
                Err(reason) => {
                    rejected = Some(reason);
                    None
                }
            },
            _ => None,
        };
        let failure = match (outcome, accepted) {
            (Ok(rep), Some(Ok(history))) => {
                have_factor = rep.iterations > 0 || rep.inertia.is_some();
                report.newton_iterations += rep.iterations;
                report.accepted_steps += 1;
                let easy = rep.iterations <= control.easy_iterations;
                s = target;
                if hits_nominal {
                    next_nominal += 1;
                    retrying = false;
                    inverted = None;
                }
                if easy {
                    inc = (inc * 2.0).min(nominal);
                }
                let step = AcceptedStep {
                    load: s,
                    nominal: hits_nominal,
                    newton: rep,
                    position: RampPosition {
                        load: s,
                        increment: inc,
                        next_nominal,
                        accepted_steps: report.accepted_steps,
                        cutbacks: report.cutbacks,
                        newton_iterations: report.newton_iterations,
                        retrying,
                    },
                };
                // a committed history changes the tangent: the predictor's factorisation is that
                // of the committed state (as a resumed ramp's first one)
                if on_step(system, &step) || history {
                    have_factor = system.evaluate(&mut predictor_work, Some(&mut k)).is_ok()
                        && solver.factor(&k).is_ok();
                }
                continue;
            }
            (Ok(rep), Some(Err(e))) => {
                report.newton_iterations += rep.iterations;
                last_cause = FailureCause::Material(e.clone());
                format!("the accepted state could not be committed: {e}")
            }
            (Ok(rep), None) => {
                report.newton_iterations += rep.iterations;
                last_cause = FailureCause::Unstable;
                if let Some(reason) = rejected {
                    reason
                } else {
                    format!(
                        "converged state is unstable (tangent has {} negative pivots, {} expected)",
                        rep.inertia.map(|i| i.negative).unwrap_or(0),
                        system.expected_negative_pivots()
                    )
                }
            }
            (Err(e), _) => {
                report.newton_iterations += match &e {
                    NewtonError::MaxIterations { iterations, .. } => *iterations,
                    NewtonError::Diverged { iteration, .. }
                    | NewtonError::Singular { iteration }
                    | NewtonError::Evaluation { iteration, .. }
                    | NewtonError::LinearSolve { iteration, .. } => *iteration,
                };
                last_cause = FailureCause::of(&e);
                e.to_string()
            }
        };
        // undo and cut back; the factorisation in the solver belongs to a rejected state
        have_factor = false;
        retrying = true;
        system.restore(&saved);
        system.set_load(s);
        report.cutbacks += 1;
        if names_inverted_cell(&failure) {
            inverted = Some(failure.clone());
        }
        last_reason = failure;
        inc = (target - s) * 0.5;
        if inc < min_inc {
            // a limit point: states that turn unstable, or Newton failing ever closer to a
            // converged state; not a singular, non-finite or material failure
            let limit_point = matches!(
                last_cause,
                FailureCause::Unstable | FailureCause::NoConvergence
            );
            return Err(RampFailure {
                last_converged: s,
                attempted: target,
                reason: match inverted {
                    Some(m) if !names_inverted_cell(&last_reason) => {
                        format!("{last_reason}; an attempt before it: {m}")
                    }
                    _ => last_reason,
                },
                limit_point,
                cause: last_cause,
                newton_iterations: report.newton_iterations,
            });
        }
    }
    let _ = last_reason;
    Ok(report)
}

/// Tangent predictor: moves the free unknowns along the solution path to first order,
/// Δx_f = −K⁻¹ K_fd Δx_d, with the factorised tangent of the converged state at load `from`.
/// K_fd Δx_d is the directional derivative of the residual along the change of the prescribed
/// values, taken by a one-sided difference (the residual vanishes at the converged state). The
/// solve is asked for the difference's accuracy only ([`LinearSolver::set_forcing`]).
fn predict<S: LoadedSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    from: f64,
    to: f64,
    work: &mut [f64],
) {
    const H: f64 = 1e-4;
    let start = system.snapshot();
    system.set_load(from + H * (to - from));
    let ok = system.evaluate(work, None).is_ok();
    system.restore(&start);
    system.set_load(to);
    if !ok {
        return;
    }
    let mut r0 = vec![0.0; work.len()];
    let base_ok = {
        let s2 = system.snapshot();
        system.restore(&start);
        let r = system.evaluate(&mut r0, None).is_ok();
        system.restore(&s2);
        r
    };
    if !base_ok {
        return;
    }
    for (w, b) in work.iter_mut().zip(&r0) {
        *w = -(*w - b) / H;
    }
    // the difference quotient is accurate to about H: an iterative solver need not go further
    solver.set_forcing(Some(H));
    let solved = solver.solve_in_place(work).is_ok();
    solver.set_forcing(None);
    // every process's part of the prediction, so that all take the same path
    let mut not_finite = [work.iter().filter(|v| !v.is_finite()).count() as f64];
    let finite = system.sum_over_processes(&mut not_finite).is_ok() && not_finite[0] == 0.0;
    if solved && finite {
        let before = system.snapshot();
        system.increment(work, 1.0);
        if system.evaluate(&mut r0, None).is_err() {
            // the predicted state is not admissible (e.g. J <= 0): start from the plain one
            system.restore(&before);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each Newton failure maps to its cause: a singular tangent or a solver's zero pivot, a
    /// non-finite residual, a material outside its domain (directly, or as what held full steps
    /// back), plain non-convergence (inverted elements included: a step too long near a limit
    /// point), and any other failure of the linear solver.
    #[test]
    fn newton_failures_are_classified() {
        let eval = |m: &str| NewtonError::Evaluation {
            iteration: 1,
            message: m.into(),
        };
        let max = |residual: f64, blocked: Option<&str>| NewtonError::MaxIterations {
            iterations: 25,
            residual,
            first: 1.0,
            blocked: blocked.map(String::from),
        };
        assert_eq!(
            FailureCause::of(&NewtonError::Singular { iteration: 0 }),
            FailureCause::Singular
        );
        assert_eq!(
            FailureCause::of(&eval("singular matrix (zero pivot at 3)")),
            FailureCause::Singular
        );
        assert_eq!(
            FailureCause::of(&max(f64::NAN, None)),
            FailureCause::NonFinite
        );
        assert_eq!(
            FailureCause::of(&NewtonError::Diverged {
                iteration: 2,
                residual: f64::INFINITY
            }),
            FailureCause::NonFinite
        );
        let gent = "cell 3: Gent model locked: Ī₁ − 3 = 0.51 ≥ J_m = 0.5 at quadrature point 1";
        assert_eq!(
            FailureCause::of(&eval(gent)),
            FailureCause::Material(gent.into())
        );
        assert_eq!(
            FailureCause::of(&max(1e-3, Some(gent))),
            FailureCause::Material(gent.into())
        );
        assert_eq!(
            FailureCause::of(&max(
                1e-3,
                Some("cell 0: non-positive volume ratio J = -1e-2")
            )),
            FailureCause::NoConvergence
        );
        assert_eq!(
            FailureCause::of(&max(1e-3, None)),
            FailureCause::NoConvergence
        );
        assert_eq!(
            FailureCause::of(&eval("cell 0: non-positive volume ratio J = -1e-2")),
            FailureCause::NoConvergence
        );
        // the linear solver's failures: a zero pivot is a singular tangent, the rest its own
        let linear = |m: &str| NewtonError::LinearSolve {
            iteration: 1,
            message: m.into(),
        };
        assert_eq!(
            FailureCause::of(&linear("PETSc error 71: Zero pivot in LU factorization")),
            FailureCause::Singular
        );
        let krylov = "PETSc solve did not converge (KSP cg, PC gamg): DIVERGED_ITS after 3";
        assert_eq!(
            FailureCause::of(&linear(krylov)),
            FailureCause::LinearSolver(krylov.into())
        );
    }
}
