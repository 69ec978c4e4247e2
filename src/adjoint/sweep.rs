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

use super::charge::charge_adjoint;
use super::dynamic::{self, Cotangent};
use super::dynamic::{Held, Steps};
use super::lambda::{AdjointSolver, SolveCounts};
use super::objective::{Backward, Finished, Objective};
use super::replay::Recompute;
use super::sink::{waveform_dofs, ControlGradient, Sink};
use super::tape::{Tape, TapedStage, TapedStep};
use crate::algebra::system::LoadedSystem;
use crate::io::build::Parameter;
use crate::job::plan::{Plan, StageKind};
use crate::problem::dofs::{free_weights, CONSTRAINED, FIELDS, PHI};
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::problem::step::StepOperator;
use crate::time::stage::Method;

/// J and its gradient.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradient {
    /// J at the run.
    pub objective: f64,
    /// dJ/dp per parameter, in the order given.
    pub gradient: Vec<f64>,
    /// dJ/dV at the knots of each control, stage by stage.
    pub controls: Vec<ControlGradient>,
    /// The steps recomputed from checkpoints (0 when the tape held every state), and the most
    /// bytes the tape and the recomputation held at once.
    pub recomputed_steps: usize,
    pub peak_bytes: usize,
    /// The factorisations and GMRES iterations of the adjoint's linear solves.
    pub solves: SolveCounts,
}

/// Whether the adjoint of a run of `plan` is built (every differentiable parameter is); an
/// error says what is not.
pub fn check_supported(plan: &Plan) -> Result<(), String> {
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
                    "stage `{}`: the adjoint of the explicit trapezoidal scheme is not built; \
                     gradients cover the midpoint and Newmark schemes",
                    s.name
                ))
            }
            StageKind::Continuation { .. } => {
                return Err(format!(
                    "stage `{}`: the adjoint of continuation stages is not built; gradients \
                     cover static, quasi-static and dynamic stages",
                    s.name
                ))
            }
        }
    }
    if let Some(e) = plan.electrodes.iter().find(|e| e.controller.is_some()) {
        return Err(format!(
            "electrode `{}` has a controller: its feedback drive depends on the state, and the \
             adjoint of a feedback loop is not built; remove `electrodes.{}.controller` (e.g. \
             give the voltage the loop produced as a `table` waveform)",
            e.name, e.name
        ));
    }
    if plan.model.pressures.iter().any(|p| p.volume.is_some())
        || !plan.pressure_volumes.iter().all(Option::is_none)
    {
        return Err("the adjoint of volume-controlled pressures is not built yet".into());
    }
    Ok(())
}

/// J at the taped run of `plan` and its gradient in `parameters` (named by their key paths), by
/// the adjoint of the taped steps. `supports[i]` holds the derivatives of the values of
/// `plan.supports` in parameter i (empty: they do not depend on it), which a pre-stretch's
/// targets do. The run must be one [`check_supported`] accepts.
pub fn gradient(
    plan: &Plan,
    tape: &Tape,
    objective: &Objective,
    parameters: &[(String, Parameter)],
    supports: &[Vec<f64>],
) -> Result<Gradient, String> {
    check_supported(plan)?;
    let mut reader = Backward::new(objective, plan, tape)?;
    let mut recomputed_steps = 0;
    let mut peak_bytes = tape.peak_bytes();
    let mut sink = Sink::new(plan, parameters);
    let n_dofs = plan.model.mesh.n_nodes() * FIELDS;
    // each dof's support (the last that prescribes it, as they are applied in order)
    let mut support_of = vec![usize::MAX; n_dofs];
    for (j, d) in plan.supports.iter().enumerate() {
        for &n in &d.nodes {
            support_of[n * FIELDS + d.field.index()] = j;
        }
    }
    // ∂J/∂(the supports' values)
    let mut support_cotangent = vec![0.0; plan.supports.len()];
    // ∂J/∂(the level a stage ends in), from the stages after it
    let mut carry = Cotangent::zeros(n_dofs);
    let mut solves = SolveCounts::default();
    for (ti, st) in tape.stages.iter().enumerate().rev() {
        sink.stage = st.index;
        carry = if st.dynamics.is_none() {
            let mut state_grads = vec![Vec::new(); st.steps.len()];
            for (k, step) in st.steps.iter().enumerate().rev() {
                let read = reader.at_step(ti, k, step)?;
                state_grads[k] = read.state;
                if !read.charges.is_empty() {
                    static_charges(plan, step, &read.charges, &mut state_grads[k], &mut sink)?;
                }
            }
            let start = static_stage(plan, st, &state_grads, &carry, &mut sink)?;
            solves += start.solves;
            for (d, &j) in support_of.iter().enumerate() {
                if j != usize::MAX {
                    support_cotangent[j] += start.to[d];
                }
            }
            Cotangent {
                q: start.from,
                points: start.points,
                ..Cotangent::zeros(n_dofs)
            }
        } else if st.is_checkpointed() {
            let budget = tape.budget().unwrap_or(usize::MAX);
            let mut steps = Recompute::new(st, budget, tape.held_bytes())?;
            let (c, s) = dynamic::sweep(plan, st, ti, &mut reader, &mut steps, carry, &mut sink)?;
            recomputed_steps += steps.recomputed;
            peak_bytes = peak_bytes.max(steps.peak);
            solves += s;
            c
        } else {
            let (c, s) =
                dynamic::sweep(plan, st, ti, &mut reader, &mut Held(st), carry, &mut sink)?;
            solves += s;
            c
        };
    }
    let eval = reader.finish()?;
    if !tape.prestretch_phases.is_empty() {
        // a timed pre-stretch: its phases' load steps in real time, the last state the
        // deflections' reference; each phase ramps the supports from where the one before
        // ended (the undeformed state and virgin points before the first: constants)
        let mut c = carry;
        c.q.iter_mut()
            .zip(&eval.reference)
            .for_each(|(a, b)| *a += b);
        let on = plan.stages.first().is_some_and(|s| s.electrodes_on);
        for phase in tape.prestretch_phases.iter().rev() {
            let start = load_steps(phase, true, false, &[], &c, &mut sink)?;
            solves += start.solves;
            for (d, &a) in start.to.iter().enumerate() {
                if a != 0.0 {
                    prestretch_target(
                        plan,
                        on,
                        d,
                        a,
                        &support_of,
                        &mut support_cotangent,
                        &mut sink,
                    );
                }
            }
            c = Cotangent {
                q: start.from,
                points: start.points,
                ..Cotangent::zeros(n_dofs)
            };
        }
    } else if let Some((model, state)) = &tape.prestretch {
        // the first stage starts from the pre-stretched state, the deflections' reference
        let mut c = carry.q;
        c.iter_mut().zip(&eval.reference).for_each(|(a, b)| *a += b);
        solves += prestretch(
            plan,
            model,
            state,
            &c,
            &support_of,
            &mut support_cotangent,
            &mut sink,
        )?;
    }
    // the terms that read the controls' knots directly
    for (c, g) in sink.controls.iter_mut().zip(&eval.controls) {
        c.gradient.iter_mut().zip(g).for_each(|(a, b)| *a += b);
    }
    for (i, dg) in supports.iter().enumerate() {
        sink.grad[i] += dg
            .iter()
            .zip(&support_cotangent)
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    Ok(Gradient {
        objective: eval.value,
        gradient: sink.grad,
        controls: sink.controls,
        recomputed_steps,
        peak_bytes,
        solves,
    })
}

/// J at the taped run of `plan` with its terms' readings, read step by step from the last to the
/// first as the gradient's sweep reads them; a dynamic stage kept as checkpoints (a run beyond
/// its memory budget) is recomputed from them within the budget. Returns them and the steps
/// recomputed.
pub fn read_objective(
    plan: &Plan,
    tape: &Tape,
    objective: &Objective,
) -> Result<(Finished, usize), String> {
    let mut reader = Backward::new(objective, plan, tape)?;
    let mut recomputed = 0;
    for (ti, st) in tape.stages.iter().enumerate().rev() {
        if st.is_checkpointed() {
            let budget = tape.budget().unwrap_or(usize::MAX);
            let mut steps = Recompute::new(st, budget, tape.held_bytes())?;
            for k in (0..st.count()).rev() {
                let (_, step) = steps.step(k)?;
                reader.at_step(ti, k, step)?;
            }
            recomputed += steps.recomputed;
        } else {
            for (k, step) in st.steps.iter().enumerate().rev() {
                reader.at_step(ti, k, step)?;
            }
        }
    }
    Ok((reader.finish()?, recomputed))
}

/// The adjoint of the pre-stretch phase, whose solution `state` of the problem `model` has the
/// cotangent `c`: its supports' targets get theirs (`support_of`: each dof's support), the
/// electrodes held at their first voltages theirs, and the materials' parameters theirs.
/// Returns the linear solves it took.
fn prestretch(
    plan: &Plan,
    model: &crate::problem::model::Model,
    state: &[f64],
    c: &[f64],
    support_of: &[usize],
    support_cotangent: &mut [f64],
    sink: &mut Sink,
) -> Result<SolveCounts, String> {
    let mut problem = StaticProblem::new(model, Some(state.to_vec()));
    problem.keep_cell_tangents = true;
    problem.set_drive(crate::problem::drive::Drive::held(model));
    problem.set_load(1.0);
    problem.state.copy_from_slice(state);
    let mut solver = AdjointSolver::default();
    let lambda = solver.solve(&mut problem, c)?;
    sink.step_materials(&mut problem, &lambda)?;
    let lv = problem.level_vjp(&lambda)?;
    let on = plan.stages.first().is_some_and(|s| s.electrodes_on);
    for (d, &e) in problem.dofs.eq.iter().enumerate() {
        if e == CONSTRAINED {
            let a = c[d] - lv.q_new[d];
            prestretch_target(plan, on, d, a, support_of, support_cotangent, sink);
        }
    }
    Ok(solver.counts())
}

/// Hands the cotangent `a` of the pre-stretch's prescribed value of dof `d` to what prescribes
/// it: a support of the plan (`support_of`: each dof's), or an electrode held at its first
/// voltage (when the first stage has its electrodes on, `on`).
fn prestretch_target(
    plan: &Plan,
    on: bool,
    d: usize,
    a: f64,
    support_of: &[usize],
    support_cotangent: &mut [f64],
    sink: &mut Sink,
) {
    if support_of[d] != usize::MAX {
        support_cotangent[support_of[d]] += a;
    } else if on && d % FIELDS == PHI {
        let node = d / FIELDS;
        for (i, (_, p)) in sink.parameters().iter().enumerate() {
            if let Parameter::Voltage {
                electrode, scalar, ..
            } = p
            {
                let held = plan
                    .electrodes
                    .iter()
                    .find(|el| &el.name == electrode && el.nodes.contains(&node));
                if let Some(el) = held {
                    sink.grad[i] += a * el.voltage.derivative(0.0, *scalar);
                }
            }
        }
    }
}

/// The adjoint of the static or quasi-static stage `st`, its k-th load step's state having the
/// cotangent `state_grads[k]` (empty: none) and its last one (state and committed points) `end`
/// besides. Returns the cotangents of the state the stage started from, of its prescribed
/// targets, and of the points it started from.
///
/// With internal variables, load step n also commits ξₙ = U(xₙ, ξₙ₋₁, θ, Δtₙ) (Δtₙ from the
/// load factors and the stage's duration); ξₙ enters the next step's residual and its commit.
/// With ξ̄ₙ the cotangent of ξₙ, the step's adjoint adds (∂U/∂xₙ)ᵀξ̄ₙ to xₙ's cotangent before
/// it solves for λₙ, and carries ξ̄ₙ₋₁ = (∂U/∂ξₙ₋₁)ᵀξ̄ₙ − (∂Rₙ/∂ξₙ₋₁)ᵀλₙ back;
/// dJ/dθ += (∂U/∂θ)ᵀξ̄ₙ.
/// The adjoint of the charges J reads at load step `step` (cotangents `bar`): their products
/// with the tangent join the step's state cotangent `g` (every dof; empty: zero), their
/// parameter derivatives go to `sink`. The dielectric energy does not depend on the material
/// points' internal variables; a model whose charges did would be refused here.
fn static_charges(
    plan: &Plan,
    step: &TapedStep,
    bar: &[f64],
    g: &mut Vec<f64>,
    sink: &mut Sink,
) -> Result<(), String> {
    let nodes: Vec<&[usize]> = plan.electrodes.iter().map(|e| e.nodes.as_slice()).collect();
    let points = PointStates::from_data(&plan.model, &step.points);
    g.resize(step.state.len(), 0.0);
    let p = charge_adjoint(&plan.model, &nodes, &step.state, &points, bar, g, sink)?;
    if p.iter().any(|&v| v != 0.0) {
        return Err(
            "an objective reads a charge that depends on the material points' internal \
             variables in a static stage: not differentiated yet"
                .into(),
        );
    }
    Ok(())
}

fn static_stage(
    plan: &Plan,
    st: &TapedStage,
    state_grads: &[Vec<f64>],
    end: &Cotangent,
    sink: &mut Sink,
) -> Result<StageStart, String> {
    let stage = &plan.stages[st.index];
    let out = load_steps(st, false, stage.electrodes_on, state_grads, end, sink)?;
    // the targets of the electrodes a static stage holds among its supports: their waveforms
    // at the stage's end
    for (i, (_, p)) in sink.parameters().iter().enumerate() {
        let Parameter::Voltage {
            electrode, scalar, ..
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
        let dv = stage.waveform(&e.voltage).derivative(st.duration, *scalar);
        let held: f64 = e.nodes.iter().map(|&n| out.to[n * FIELDS + PHI]).sum();
        sink.grad[i] += dv * held;
    }
    Ok(out)
}

/// The cotangents a run of load steps hands back to what it started from: the start state
/// (`from`), the targets its drive ramps the supports to (`to`), and the points' values at its
/// start (empty without internal variables); and the linear solves its adjoint took.
struct StageStart {
    from: Vec<f64>,
    to: Vec<f64>,
    points: Vec<f64>,
    solves: SolveCounts,
}

/// The adjoint of the taped load steps of `st` (a stage, or a phase of a timed pre-stretch
/// when `prestretch`), as [`static_stage`] describes; the voltages of electrodes that follow
/// waveforms go to the sink when `electrodes_on`.
fn load_steps(
    st: &TapedStage,
    prestretch: bool,
    electrodes_on: bool,
    state_grads: &[Vec<f64>],
    end: &Cotangent,
    sink: &mut Sink,
) -> Result<StageStart, String> {
    let n_dofs = end.q.len();
    let mut problem = StaticProblem::new(&st.model, Some(st.start.clone()));
    problem.keep_cell_tangents = true;
    problem.set_drive(st.drive.clone());
    problem.duration = st.duration;
    // ∂J/∂ξ of the points the step being swept committed
    let mut points_bar = end.points.clone();
    let mut solver = AdjointSolver::default();
    // the electrodes that follow their waveforms in stage time (quasi-static)
    let waveform_dof = waveform_dofs(&st.drive, n_dofs);
    let mut from = vec![0.0; n_dofs];
    let mut to = vec![0.0; n_dofs];
    // the prescribed dofs that the drive's supports move (the others keep their start value:
    // a tie held as a whole, a rigid pad's radial slot on the axis)
    let mut ramped = vec![false; n_dofs];
    for &(d, _) in &st.drive.supports {
        ramped[d] = true;
    }
    for (k, step) in st.steps.iter().enumerate().rev() {
        let mut g = state_grads.get(k).cloned().unwrap_or_default();
        if g.is_empty() {
            g = vec![0.0; n_dofs];
        }
        if k + 1 == st.steps.len() {
            g.iter_mut().zip(&end.q).for_each(|(a, b)| *a += b);
        }
        // the step from the previous one's load factor and committed points
        let (before, prev_load) = match k {
            0 => (&st.start_points, 0.0),
            _ => (&st.steps[k - 1].points, st.steps[k - 1].load),
        };
        problem.points = PointStates::from_data(&st.model, before);
        problem.accept_resumed(prev_load);
        problem.set_load(step.load);
        problem.state.copy_from_slice(&step.state);
        let dt = (step.load - prev_load) * st.duration;
        let (x_bar, mut before_bar) = super::dynamic::commit_adjoint(
            &st.model,
            &problem.points,
            &step.state,
            dt,
            &points_bar,
            sink,
        )?;
        g.iter_mut().zip(&x_bar).for_each(|(a, b)| *a += b);
        let lambda = solver.solve(&mut problem, &g)?;
        sink.step_materials(&mut problem, &lambda)?;
        if !prestretch {
            // (the pre-stretch hangs no weight: its model has no dead loads)
            let dead = problem.drive().dead_loads.at(step.load);
            let weights = free_weights(&problem.dofs, &lambda);
            sink.weights(&weights, dead);
            // the pressures' values: −λᵀ ∂r/∂p
            for (i, (_, p)) in sink.parameters().iter().enumerate() {
                if let Parameter::Pressure { index, .. } = p {
                    let forces = problem.pressure_forces(*index);
                    sink.grad[i] -= forces.iter().zip(&weights).map(|(f, w)| f * w).sum::<f64>();
                }
            }
            // the drive's charges, +Q on their Gauss equations
            let t = step.load * st.duration;
            for (k, c) in st.drive.charges.iter().enumerate() {
                sink.charge(&st.drive, k, t, step.load, -weights[c.node * FIELDS + PHI]);
            }
        }
        let lv = problem.level_vjp(&lambda)?;
        before_bar
            .iter_mut()
            .zip(&lv.points)
            .for_each(|(a, b)| *a -= b);
        points_bar = before_bar;
        let eq = problem.dofs.eq.clone();
        for d in 0..n_dofs {
            let a = g[d] - lv.q_new[d];
            if eq[d] != CONSTRAINED {
                // a tied dof moves with its tie from its start value: the offsets within a
                // tie are the start's (the sum of `a` over a tie vanishes)
                from[d] += a;
                continue;
            }
            if waveform_dof[d] != usize::MAX {
                if electrodes_on {
                    sink.voltage(&st.drive, waveform_dof[d], step.load * st.duration, a);
                }
            } else if ramped[d] {
                to[d] += step.load * a;
                from[d] += (1.0 - step.load) * a;
            } else {
                from[d] += a;
            }
        }
    }
    // the supports' start values are the state the stage before ended in
    Ok(StageStart {
        from,
        to,
        points: points_bar,
        solves: solver.counts(),
    })
}
