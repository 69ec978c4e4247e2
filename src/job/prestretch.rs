//! The pre-stretch phase that runs before the first stage of a plan.

use super::observer::Observer;
use super::plan::Plan;
use super::recorder::Recorder;
use super::statics::{solve_static_from, solve_static_with, StageTime};
use crate::problem::dofs::{constrained_flags, Dirichlet, Field, FIELDS};
use crate::problem::points::PointStates;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;

/// The pre-stretch phase before the first stage: the supports (which hold the pre-stretch targets)
/// are imposed with the electrodes at the first stage's initial voltages, without the dead loads
/// and with the rigid regions free (the pad is attached to the stretched membrane). The solve
/// starts from the homogeneous equibiaxial state of the first material (exact for a uniform
/// membrane: one step, a few iterations); if that fails, the supports are ramped from the start
/// in `steps` load steps. Steps are recorded under the first stage's name at time 0, deflections
/// measured from the current state, and the energy balance starts afresh from the pre-stretched
/// state.
///
/// A **timed** pre-stretch (a `duration` or a `hold`) runs in real time instead: the supports are
/// ramped in `steps` steps over `duration` seconds and then held for `hold` seconds in
/// `hold_steps` steps, materials with internal variables relaxing throughout; its steps are
/// recorded at their times, and the first stage starts at `duration + hold`.
#[allow(clippy::too_many_arguments)]
pub(super) fn prestretch(
    plan: &Plan,
    model: &crate::problem::model::Model,
    state: &[f64],
    points: &PointStates,
    p: super::plan::Prestretch,
    newton: &NewtonSettings,
    rec: &mut Recorder,
    stage: &str,
    observer: &mut dyn Observer,
) -> Result<PrestretchOutcome, String> {
    let pre = prestretch_model(plan, model);
    // on a rank's part, how the ranks divide the pre-stretch's unknowns
    let division = plan.part.as_ref().and_then(|p| p.prestretch.as_ref());
    let prescribed = constrained_flags(model.mesh.n_nodes(), &pre.dirichlet);
    let mut step_no = 0;
    let mut record_error = None;
    // (state, Newton iterations, time, step, energy dissipated so far)
    // (the taped problem of a timed phase's step: its phase, load factor and problem)
    let mut record =
        |rec: &mut Recorder,
         s: &[f64],
         iterations: usize,
         t: f64,
         dt: f64,
         d: f64,
         taped: Option<(usize, f64, &crate::problem::statics::StaticProblem<'_>)>| {
            if let Some((phase, load, problem)) = taped {
                observer.prestretch_step(phase, load, problem);
            }
            step_no += 1;
            // the balance starts from the pre-stretched state (the last of these records)
            rec.restart_balance();
            rec.external_factor = 0.0;
            rec.reference = s.to_vec();
            match rec.record(s, &prescribed, t, stage, step_no, iterations, dt, 0.0, d) {
                Ok((r, f)) => observer.step(plan, &r, s, &f),
                Err(e) => {
                    record_error.get_or_insert(e);
                }
            }
        };
    if p.timed() {
        let mut outcome = PrestretchOutcome {
            state: state.to_vec(),
            steps: 0,
            iterations: 0,
            points: points.clone(),
            time: 0.0,
            dissipated: 0.0,
        };
        for (index, (phase, duration, steps)) in [
            ("stretch", p.duration, p.steps),
            ("hold", p.hold, p.hold_steps),
        ]
        .into_iter()
        .enumerate()
        {
            if phase == "hold" && duration == 0.0 {
                continue;
            }
            let (t0, mut last) = (outcome.time, 0.0);
            let mut dissipated = outcome.dissipated;
            let control = StepControl {
                steps,
                ..plan.step_control.clone()
            };
            let out = solve_static_from(
                &pre,
                &plan.solver,
                outcome.state.clone(),
                StageTime {
                    duration,
                    points: outcome.points.clone(),
                    drive: crate::problem::drive::Drive::ramped(&pre),
                },
                None,
                &control,
                newton,
                division,
                |q, acc| {
                    dissipated += q.dissipated_step;
                    rec.points.clone_from(&q.points);
                    let dt = (acc.load - last) * duration;
                    last = acc.load;
                    record(
                        rec,
                        &q.state,
                        acc.newton.iterations,
                        t0 + acc.load * duration,
                        dt,
                        dissipated,
                        Some((index, acc.load, q)),
                    );
                },
            );
            match out.result {
                Ok(r) => outcome.iterations += r.newton_iterations,
                Err(f) => {
                    return Err(format!(
                        "pre-stretch ({phase}) failed at t = {:.6} s (last converged {:.6} s): {}",
                        t0 + f.attempted * duration,
                        t0 + f.last_converged * duration,
                        f.reason
                    ))
                }
            }
            outcome.state = out.state;
            outcome.points = out.points;
            outcome.time = t0 + duration;
            outcome.dissipated = dissipated;
        }
        if let Some(e) = record_error {
            rec.warnings
                .push(format!("pre-stretch: output evaluation failed: {e}"));
        }
        outcome.steps = step_no;
        return Ok(outcome);
    }
    // the homogeneous guess
    let thickness =
        crate::material::homogeneous::equibiaxial_thickness(model.materials[0].as_ref(), p.stretch);
    let mut guess = state.to_vec();
    for (n, x) in model.mesh.nodes.iter().enumerate() {
        if model.is_axisymmetric() {
            // (r, z) in the slots 0 and 1
            guess[n * FIELDS] = (p.stretch - 1.0) * x[0];
            guess[n * FIELDS + 1] = (thickness - 1.0) * x[1];
        } else {
            guess[n * FIELDS] = (p.stretch - 1.0) * x[0];
            guess[n * FIELDS + 1] = (p.stretch - 1.0) * x[1];
            guess[n * FIELDS + 2] = (thickness - 1.0) * x[2];
        }
    }
    crate::problem::dofs::apply_dirichlet(&mut guess, &pre.dirichlet);
    let one = StepControl {
        steps: 1,
        min_fraction: 1.0,
        ..plan.step_control.clone()
    };
    // a rank's part solves with the plan's solver on its own unknowns
    let static_solve = |initial: Vec<f64>,
                        control: &StepControl,
                        on_step: &mut dyn FnMut(
        &crate::problem::statics::StaticProblem<'_>,
        &crate::solve::stepping::AcceptedStep,
    )| match division {
        None => solve_static_with(
            &pre,
            &plan.solver,
            Some(initial),
            crate::problem::drive::Drive::ramped(&pre),
            control,
            newton,
            on_step,
        ),
        Some(_) => solve_static_from(
            &pre,
            &plan.solver,
            initial,
            // an instantaneous phase from fresh internal variables, as `solve_static` starts
            StageTime {
                duration: 0.0,
                points: PointStates::new(&pre),
                drive: crate::problem::drive::Drive::ramped(&pre),
            },
            None,
            control,
            newton,
            division,
            on_step,
        ),
    };
    let direct = static_solve(guess, &one, &mut |_, _| {});
    let (final_state, iterations) = match direct.result {
        Ok(r) => {
            record(rec, &direct.state, r.newton_iterations, 0.0, 0.0, 0.0, None);
            (direct.state, r.newton_iterations)
        }
        Err(_) => {
            let control = StepControl {
                steps: p.steps,
                ..plan.step_control.clone()
            };
            let ramped = static_solve(state.to_vec(), &control, &mut |q, acc| {
                record(rec, &q.state, acc.newton.iterations, 0.0, 0.0, 0.0, None)
            });
            match ramped.result {
                Ok(r) => (ramped.state, r.newton_iterations),
                Err(f) => {
                    return Err(format!(
                        "pre-stretch failed at load factor {:.6} (last converged {:.6}): {}",
                        f.attempted, f.last_converged, f.reason
                    ))
                }
            }
        }
    };
    if let Some(e) = record_error {
        rec.warnings
            .push(format!("pre-stretch: output evaluation failed: {e}"));
    }
    observer.prestretched(&pre, &final_state);
    Ok(PrestretchOutcome {
        state: final_state,
        steps: step_no,
        iterations,
        points: points.clone(),
        time: 0.0,
        dissipated: 0.0,
    })
}

/// The model the pre-stretch solves: `model` without dead loads and ties, held by the plan's
/// supports and its electrodes at the first stage's initial voltages.
pub(super) fn prestretch_model(
    plan: &Plan,
    model: &crate::problem::model::Model,
) -> crate::problem::model::Model {
    let mut pre = model.clone();
    pre.body_force.clear();
    pre.point_forces.clear();
    pre.tractions.clear();
    pre.ties.clear();
    pre.dirichlet = plan.supports.clone();
    for e in &plan.electrodes {
        pre.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value: if plan.stages[0].electrodes_on {
                e.voltage.value(0.0)
            } else {
                0.0
            },
        });
    }
    pre
}

/// The pre-stretched state and what the phase took.
pub(super) struct PrestretchOutcome {
    pub state: Vec<f64>,
    /// Recorded steps and Newton iterations.
    pub steps: usize,
    pub iterations: usize,
    /// Committed internal variables of the material points at `state`.
    pub points: PointStates,
    /// Real time the phase took (s; 0 for an instantaneous pre-stretch).
    pub time: f64,
    /// Energy the material points dissipated (J).
    pub dissipated: f64,
}
