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

use super::objective::Objective;
use super::tape::Tape;
use crate::algebra::system::{LoadedSystem, NonlinearSystem};
use crate::io::build::Parameter;
use crate::job::plan::{Plan, StageKind};
use crate::problem::dofs::{CONSTRAINED, FIELDS, PHI};
use crate::problem::statics::StaticProblem;
use crate::problem::step::StepOperator;
use crate::solve::transposed::TransposedLu;

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
            | StageKind::FrequencyResponse { .. } => {}
            StageKind::Dynamic { .. } | StageKind::Continuation { .. } => {
                return Err(format!(
                    "stage `{}`: the adjoint of {} stages is not built yet; gradients cover \
                     static and quasi-static stages",
                    s.name,
                    if matches!(s.kind, StageKind::Dynamic { .. }) {
                        "dynamic"
                    } else {
                        "continuation"
                    }
                ))
            }
        }
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
            Parameter::Material(_) | Parameter::Voltage { .. } => {}
            _ => {
                return Err(format!(
                    "parameter `{path}`: its derivative is not built yet; gradients cover the \
                     materials' parameters and the electrodes' voltage amplitudes and offsets"
                ))
            }
        }
    }
    Ok(())
}

/// J at the taped run of `plan` and its gradient in `parameters` (named by their key paths), by
/// the adjoint of the taped load steps. The run must be one [`check_supported`] accepts.
pub fn gradient(
    plan: &Plan,
    tape: &Tape,
    objective: &Objective,
    parameters: &[(String, Parameter)],
) -> Result<Gradient, String> {
    check_supported(plan, parameters)?;
    let eval = objective.evaluate(plan, tape)?;
    let mut grad = vec![0.0; parameters.len()];
    // materials whose parameters are asked for, by index in the plan
    let materials: Vec<usize> = {
        let mut m: Vec<usize> = parameters
            .iter()
            .filter_map(|(_, p)| match p {
                Parameter::Material(k) => Some(k.material_index),
                _ => None,
            })
            .collect();
        m.sort_unstable();
        m.dedup();
        m
    };
    let n_dofs = plan.model.mesh.n_nodes() * FIELDS;
    // ∂J/∂(the state a stage ends in), from the stages after it
    let mut carry = vec![0.0; n_dofs];
    for (ti, st) in tape.stages.iter().enumerate().rev() {
        let stage = &plan.stages[st.index];
        let mut problem = StaticProblem::new(&st.model, Some(st.start.clone()));
        problem.set_drive(st.drive.clone());
        problem.duration = st.duration;
        // the electrodes that follow their waveforms in stage time (quasi-static)
        let mut waveform_dof = vec![usize::MAX; n_dofs];
        for (k, (nodes, _)) in st.drive.voltages.iter().enumerate() {
            for &n in nodes {
                waveform_dof[n * FIELDS + PHI] = k;
            }
        }
        let mut from = vec![0.0; n_dofs];
        let mut to = vec![0.0; n_dofs];
        for (k, step) in st.steps.iter().enumerate().rev() {
            let mut g = eval.state[ti][k].clone();
            if g.is_empty() {
                g = vec![0.0; n_dofs];
            }
            if k + 1 == st.steps.len() {
                g.iter_mut().zip(&carry).for_each(|(a, b)| *a += b);
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
            for &m in &materials {
                let vjp = problem.parameter_vjp(&lambda, m)?;
                for (i, (_, p)) in parameters.iter().enumerate() {
                    if let Parameter::Material(key) = p {
                        if key.material_index == m {
                            grad[i] -= vjp[key.entry];
                        }
                    }
                }
            }
            let lv = problem.level_vjp(&lambda)?;
            let eq = problem.dofs.eq.clone();
            for d in 0..n_dofs {
                if eq[d] != CONSTRAINED {
                    continue;
                }
                let a = g[d] - lv.q_new[d];
                if waveform_dof[d] != usize::MAX {
                    if !stage.electrodes_on {
                        continue;
                    }
                    let t = step.load * st.duration;
                    add_waveform(
                        plan,
                        parameters,
                        &mut grad,
                        &st.drive,
                        waveform_dof[d],
                        t,
                        a,
                    );
                } else {
                    to[d] += step.load * a;
                    from[d] += (1.0 - step.load) * a;
                }
            }
        }
        // the targets of the electrodes a static stage holds among its supports: their
        // waveforms at the stage's end
        for (i, (_, p)) in parameters.iter().enumerate() {
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
            grad[i] += dv * held;
        }
        // the supports' start values are the state the stage before ended in
        carry = from;
    }
    Ok(Gradient {
        objective: eval.value,
        gradient: grad,
    })
}

/// Adds `a` · ∂V/∂p at stage time `t` for the waveform `k` of `drive` to the parameters that
/// name its electrode.
fn add_waveform(
    plan: &Plan,
    parameters: &[(String, Parameter)],
    grad: &mut [f64],
    drive: &crate::problem::drive::Drive,
    k: usize,
    t: f64,
    a: f64,
) {
    let (nodes, waveform) = &drive.voltages[k];
    for (i, (_, p)) in parameters.iter().enumerate() {
        if let Parameter::Voltage {
            electrode, offset, ..
        } = p
        {
            let on_it = plan
                .electrodes
                .iter()
                .any(|e| &e.name == electrode && e.nodes == *nodes);
            if on_it {
                grad[i] += a * waveform.derivatives(t)[usize::from(*offset)];
            }
        }
    }
}
