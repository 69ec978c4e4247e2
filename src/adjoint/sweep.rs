//! The backward sweep over a taped run: the adjoint of every accepted load step, last to first,
//! and the gradient of J in the parameters.
//!
//! A static load step n of a stage solves Rₙ(xₙ; θ) = 0 for the free unknowns of xₙ, whose
//! prescribed entries are the drive's at the step's load factor sₙ: a support goes from its
//! value in the stage's start state to its target, gₙ = g₀ + sₙ (g₁ − g₀), a quasi-static
//! stage's electrode follows its waveform, V(sₙ T). An elastic step depends on no earlier step
//! but through the stage's start state (its supports' g₀). With ∂J/∂xₙ = gₙ (from J and from
//! the next stage's start), the adjoint λₙ solves Kₙᵀ λₙ = ∂J/∂yₙ over the free unknowns yₙ,
//! and then
//! - dJ/dθ −= λₙᵀ ∂Rₙ/∂θ (the material parameters),
//! - each prescribed entry d gets aₙ,d = ∂J/∂xₙ,d − λₙᵀ ∂Rₙ/∂xₙ,d, which goes to its target
//!   (·sₙ), to the stage's start state (·(1 − sₙ)), or to its waveform's parameters.

use super::dynamic::{self, Cotangent};
use super::objective::Objective;
use super::sink::{waveform_dofs, Sink};
use super::tape::{Tape, TapedStage};
use crate::algebra::system::{LoadedSystem, NonlinearSystem};
use crate::io::build::Parameter;
use crate::job::plan::{Plan, StageKind};
use crate::problem::dofs::{CONSTRAINED, FIELDS, PHI};
use crate::problem::statics::StaticProblem;
use crate::problem::step::StepOperator;
use crate::solve::transposed::TransposedLu;
use crate::time::stage::Method;

/// J and its gradient.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradient {
    /// J at the run.
    pub objective: f64,
    /// dJ/dp per parameter, in the order given.
    pub gradient: Vec<f64>,
}

/// Whether the adjoint of a run of `plan` with `parameters` is built; an error says what is not.
pub fn check_supported(plan: &Plan, parameters: &[(String, Parameter)]) -> Result<(), String> {
    for s in &plan.stages {
        match s.kind {
            StageKind::Static { .. }
            | StageKind::QuasiStatic { .. }
            | StageKind::Modes { .. }
            | StageKind::FrequencyResponse { .. }
            | StageKind::Dynamic {
                scheme: Method::Implicit(_),
                ..
            } => {}
            StageKind::Dynamic { .. } => {
                return Err(format!(
                    "stage `{}`: the adjoint of the explicit trapezoidal scheme is not built;                      gradients cover the midpoint and Newmark schemes",
                    s.name
                ))
            }
            StageKind::Continuation { .. } => {
                return Err(format!(
                    "stage `{}`: the adjoint of continuation stages is not built; gradients                      cover static, quasi-static and dynamic stages",
                    s.name
                ))
            }
        }
    }
    if !plan.model.circuits.is_empty() {
        return Err("the adjoint of electrodes driven through circuits is not built yet".into());
    }
    if plan.prestretch.is_some() {
        return Err(
            "the adjoint of the pre-stretch is not built yet: gradients cover runs \
                    without `[prestretch]`"
                .into(),
        );
    }
    if let Some(m) = plan.model.materials.iter().find(|m| m.state_size() > 0) {
        return Err(format!(
            "the adjoint of materials with internal variables (Maxwell branches) is not built \
             yet ({} internal variables per point)",
            m.state_size()
        ));
    }
    if plan.model.pressures.iter().any(|p| p.volume.is_some())
        || !plan.pressure_volumes.iter().all(Option::is_none)
    {
        return Err("the adjoint of volume-controlled pressures is not built yet".into());
    }
    if plan.electrodes.iter().any(|e| e.charge.is_some()) {
        return Err("the adjoint of charge-controlled electrodes is not built yet".into());
    }
    for (path, p) in parameters {
        match p {
            Parameter::Material(_)
            | Parameter::Voltage { source: false, .. }
            | Parameter::RigidMass { .. }
            | Parameter::Viscosity { .. } => {}
            _ => {
                return Err(format!(
                    "parameter `{path}`: its derivative is not built yet; gradients cover the \
                     materials' parameters and viscosities, the electrodes' voltage amplitudes \
                     and offsets, and the rigid pads' masses"
                ))
            }
        }
    }
    Ok(())
}

/// J at the taped run of `plan` and its gradient in `parameters` (named by their key paths), by
/// the adjoint of the taped steps. The run must be one [`check_supported`] accepts.
pub fn gradient(
    plan: &Plan,
    tape: &Tape,
    objective: &Objective,
    parameters: &[(String, Parameter)],
) -> Result<Gradient, String> {
    check_supported(plan, parameters)?;
    let eval = objective.evaluate(plan, tape)?;
    let mut sink = Sink::new(plan, parameters);
    let n_dofs = plan.model.mesh.n_nodes() * FIELDS;
    // ∂J/∂(the level a stage ends in), from the stages after it
    let mut carry = Cotangent::zeros(n_dofs);
    for (ti, st) in tape.stages.iter().enumerate().rev() {
        carry = if st.dynamics.is_some() {
            dynamic::sweep(plan, st, &eval.state[ti], carry, &mut sink)?
        } else {
            Cotangent {
                q: static_stage(plan, st, &eval.state[ti], &carry.q, &mut sink)?,
                ..Cotangent::zeros(n_dofs)
            }
        };
    }
    Ok(Gradient {
        objective: eval.value,
        gradient: sink.grad,
    })
}

/// The adjoint of the static or quasi-static stage `st`, its k-th load step's state having the
/// cotangent `state_grads[k]` (empty: none) and its last one `end` besides. Returns the
/// cotangent of the state the stage started from.
fn static_stage(
    plan: &Plan,
    st: &TapedStage,
    state_grads: &[Vec<f64>],
    end: &[f64],
    sink: &mut Sink,
) -> Result<Vec<f64>, String> {
    let stage = &plan.stages[st.index];
    let n_dofs = end.len();
    let mut problem = StaticProblem::new(&st.model, Some(st.start.clone()));
    problem.set_drive(st.drive.clone());
    problem.duration = st.duration;
    // the electrodes that follow their waveforms in stage time (quasi-static)
    let waveform_dof = waveform_dofs(&st.drive, n_dofs);
    let mut from = vec![0.0; n_dofs];
    let mut to = vec![0.0; n_dofs];
    for (k, step) in st.steps.iter().enumerate().rev() {
        let mut g = state_grads[k].clone();
        if g.is_empty() {
            g = vec![0.0; n_dofs];
        }
        if k + 1 == st.steps.len() {
            g.iter_mut().zip(end).for_each(|(a, b)| *a += b);
        }
        problem.set_load(step.load);
        problem.state.copy_from_slice(&step.state);
        let mut r = vec![0.0; problem.n()];
        let mut kmat = problem.new_matrix();
        problem.evaluate(&mut r, Some(&mut kmat))?;
        let dofs = &problem.dofs;
        let mut lambda = vec![0.0; dofs.n_free];
        for (d, &e) in dofs.eq.iter().enumerate() {
            if e != CONSTRAINED {
                lambda[e] += dofs.scale[d % FIELDS] * g[d];
            }
        }
        TransposedLu::factor(&kmat)?.solve_in_place(&mut lambda);
        sink.step_materials(&mut problem, &lambda)?;
        let lv = problem.level_vjp(&lambda)?;
        let eq = problem.dofs.eq.clone();
        for d in 0..n_dofs {
            if eq[d] != CONSTRAINED {
                continue;
            }
            let a = g[d] - lv.q_new[d];
            if waveform_dof[d] != usize::MAX {
                if stage.electrodes_on {
                    sink.voltage(&st.drive, waveform_dof[d], step.load * st.duration, a);
                }
            } else {
                to[d] += step.load * a;
                from[d] += (1.0 - step.load) * a;
            }
        }
    }
    // the targets of the electrodes a static stage holds among its supports: their waveforms
    // at the stage's end
    for (i, (_, p)) in sink.parameters().iter().enumerate() {
        let Parameter::Voltage {
            electrode, offset, ..
        } = p
        else {
            continue;
        };
        let e = plan
            .electrodes
            .iter()
            .find(|e| &e.name == electrode)
            .ok_or_else(|| format!("no electrode `{electrode}`"))?;
        if !e.prescribed(false) || !st.drive.voltages.is_empty() || !stage.electrodes_on {
            continue;
        }
        let dv = stage.waveform(&e.voltage).derivatives(st.duration)[usize::from(*offset)];
        let held: f64 = e.nodes.iter().map(|&n| to[n * FIELDS + PHI]).sum();
        sink.grad[i] += dv * held;
    }
    // the supports' start values are the state the stage before ended in
    Ok(from)
}
