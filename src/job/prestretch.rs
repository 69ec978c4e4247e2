//! The pre-stretch phase that runs before the first stage of a plan.

use super::plan::Plan;
use super::recorder::Recorder;
use super::run::Observer;
use super::statics::solve_static;
use crate::problem::dofs::{constrained_flags, Dirichlet, Field, FIELDS};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;

/// The pre-stretch phase before the first stage: the supports (which hold the pre-stretch targets)
/// are imposed with the electrodes at the first stage's initial voltages, without the dead loads
/// and with the rigid regions free (the pad is attached to the stretched membrane). The solve
/// starts from the homogeneous equibiaxial state of the first material (exact for a uniform
/// membrane: one step, a few iterations); if that fails, the supports are ramped from the start
/// in `steps` load steps. Steps are recorded under the first stage's name at time 0, deflections
/// measured from the current state, and the energy balance starts afresh from the pre-stretched
/// state. Returns the state, the number of recorded steps and the Newton iterations.
#[allow(clippy::too_many_arguments)]
pub(super) fn prestretch(
    plan: &Plan,
    model: &crate::problem::model::Model,
    state: &[f64],
    p: super::plan::Prestretch,
    newton: &NewtonSettings,
    rec: &mut Recorder,
    stage: &str,
    observer: &mut dyn Observer,
) -> Result<(Vec<f64>, usize, usize), String> {
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
    let prescribed = constrained_flags(model.mesh.n_nodes(), &pre.dirichlet);
    let mut step_no = 0;
    let mut record_error = None;
    let mut record = |rec: &mut Recorder, s: &[f64], iterations: usize| {
        step_no += 1;
        // the balance starts from the pre-stretched state (the last of these records)
        rec.restart_balance();
        rec.external_factor = 0.0;
        rec.reference = s.to_vec();
        match rec.record(
            s,
            &prescribed,
            0.0,
            stage,
            step_no,
            iterations,
            0.0,
            0.0,
            0.0,
        ) {
            Ok((r, f)) => observer.step(plan, &r, s, &f),
            Err(e) => {
                record_error.get_or_insert(e);
            }
        }
    };
    // the homogeneous guess
    let thickness = crate::material::homogeneous::solve(
        model.materials[0].as_ref(),
        crate::material::homogeneous::Mode::Equibiaxial,
        p.stretch,
    )
    .map(|h| h.lateral)
    .unwrap_or(1.0 / (p.stretch * p.stretch));
    let mut guess = state.to_vec();
    for (n, x) in model.mesh.nodes.iter().enumerate() {
        guess[n * FIELDS] = (p.stretch - 1.0) * x[0];
        guess[n * FIELDS + 1] = (p.stretch - 1.0) * x[1];
        guess[n * FIELDS + 2] = (thickness - 1.0) * x[2];
    }
    crate::problem::dofs::apply_dirichlet(&mut guess, &pre.dirichlet);
    let one = StepControl {
        steps: 1,
        min_fraction: 1.0,
        ..Default::default()
    };
    let direct = solve_static(&pre, Some(guess), &one, newton, |_, _| {});
    let (final_state, iterations) = match direct.result {
        Ok(r) => {
            record(rec, &direct.state, r.newton_iterations);
            (direct.state, r.newton_iterations)
        }
        Err(_) => {
            let control = StepControl {
                steps: p.steps,
                ..Default::default()
            };
            let ramped = solve_static(&pre, Some(state.to_vec()), &control, newton, |q, acc| {
                record(rec, &q.state, acc.newton.iterations)
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
    Ok((final_state, step_no, iterations))
}
