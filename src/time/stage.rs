//! The driver of a dynamic stage: steps from t₀ to t₀ + duration with the chosen scheme, halving
//! the step on failure (Newton divergence, J ≤ 0, singular tangent) and growing it back after easy
//! steps, never past the stage end; after each midpoint step the potential is re-projected onto
//! electrostatic equilibrium at the new configuration.

use super::integrator::{Scheme, TimeLevel, TimeStep};
use super::mass::NodalMass;
use crate::problem::dofs::{Dirichlet, Field, FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{FaerLdlt, LinearSolver};
use crate::solve::newton::{newton, NewtonSettings};
use crate::waveform::Waveform;

/// A time integration method of a dynamic stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Implicit midpoint variational integrator.
    Midpoint,
    /// Implicit Newmark.
    Newmark { beta: f64, gamma: f64 },
    /// Explicit trapezoidal variational integrator (Störmer–Verlet), see `trapezoidal.rs`.
    Trapezoidal,
}

impl Method {
    /// Name for messages and files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Midpoint => "midpoint",
            Method::Newmark { .. } => "newmark",
            Method::Trapezoidal => "trapezoidal",
        }
    }
}

/// Settings of a dynamic stage.
#[derive(Debug, Clone)]
pub struct DynamicSettings {
    pub duration: f64,
    /// Nominal (largest) time step (s).
    pub dt: f64,
    pub scheme: Method,
    /// Smallest step as a fraction of the nominal one.
    pub min_fraction: f64,
    /// Newton iterations at or below which the step grows back (doubles).
    pub easy_iterations: usize,
    /// Modified Newton: reuse the factorised iteration matrix across iterations and steps while
    /// the step size is unchanged.
    pub reuse_factorization: bool,
}

/// An accepted step.
#[derive(Debug, Clone)]
pub struct DynamicStepInfo {
    pub dt: f64,
    pub newton_iterations: usize,
    /// Energy dissipated by viscosity during the step (J).
    pub dissipated: f64,
    /// The step size the next step will try (after the growth rule).
    pub next_dt: f64,
    /// Newton iterations of the stage so far, this step included.
    pub total_iterations: usize,
}

/// Where to resume a dynamic stage: the start level given to [`run_dynamic_from`] is an accepted
/// level of an earlier run (not the stage start), `dt` the step size to try next and
/// `iterations` the Newton iterations spent so far. The start-of-stage set-up (Newmark's
/// consistent acceleration, the trapezoidal scheme's first projection) is skipped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicResume {
    /// Time of the stage start (the stage ends at `t_start + duration`).
    pub t_start: f64,
    pub dt: f64,
    pub iterations: usize,
}

/// The stage stopped before its end.
#[derive(Debug, Clone)]
pub struct DynamicFailure {
    /// Time of the last accepted state (the state returned).
    pub t: f64,
    pub reason: String,
    pub newton_iterations: usize,
}

/// Everything a dynamic stage needs besides the model.
pub struct DynamicInputs<'a> {
    pub mass: &'a NodalMass,
    pub viscosity: Vec<f64>,
    pub electrodes: Vec<(Vec<usize>, Waveform)>,
}

/// Runs the stage from `start`; `model.dirichlet` holds the displacement supports (the electrode
/// conditions are added here). Calls `on_step` after every accepted step with the new level, whose
/// potential is in electrostatic equilibrium. Returns the final level, or the failure together
/// with the last accepted level.
pub fn run_dynamic(
    model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    mut on_step: impl FnMut(&TimeLevel, &DynamicStepInfo),
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    run_dynamic_from(
        model,
        inputs,
        start,
        settings,
        newton_settings,
        None,
        |l, i| {
            on_step(l, i);
            false
        },
    )
}

/// [`run_dynamic`], resumable. When `on_step` returns true the reused factorisations (modified
/// Newton, projection) are dropped, so that the next step starts as a resumed run starts: a run
/// resumed from a checkpoint written at that step then continues bit for bit.
pub fn run_dynamic_from(
    model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    resume: Option<DynamicResume>,
    mut on_step: impl FnMut(&TimeLevel, &DynamicStepInfo) -> bool,
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    let mut step_model = model.clone();
    for (nodes, w) in &inputs.electrodes {
        step_model.dirichlet.push(Dirichlet {
            nodes: nodes.clone(),
            field: Field::Phi,
            value: w.value(start.t),
        });
    }
    // electrostatic projection: every displacement held, the potential free except at electrodes
    let mut proj_model = step_model.clone();
    let all: Vec<usize> = (0..model.mesh.n_nodes()).collect();
    proj_model.dirichlet = [Field::Ux, Field::Uy, Field::Uz]
        .into_iter()
        .map(|field| Dirichlet {
            nodes: all.clone(),
            field,
            value: 0.0,
        })
        .chain(
            step_model
                .dirichlet
                .iter()
                .filter(|d| d.field == Field::Phi)
                .cloned(),
        )
        .collect();
    let mut projector = StaticProblem::new(&proj_model, Some(start.q.clone()));
    let mut proj_solver = FaerLdlt::new();
    let mut proj_k = crate::solve::newton::NonlinearSystem::new_matrix(&projector);
    let proj_settings = NewtonSettings {
        check_stability: false,
        reuse_factorization: settings.reuse_factorization,
        ..newton_settings.clone()
    };

    let mut start = start;
    let scheme = match settings.scheme {
        Method::Midpoint => Scheme::Midpoint,
        Method::Newmark { beta, gamma } => Scheme::Newmark { beta, gamma },
        Method::Trapezoidal => {
            return run_trapezoidal(
                &step_model,
                inputs,
                start,
                settings,
                newton_settings,
                (
                    &mut projector,
                    &mut proj_solver,
                    &mut proj_k,
                    &proj_settings,
                ),
                resume,
                on_step,
            )
        }
    };
    if let (Scheme::Newmark { .. }, None) = (scheme, resume) {
        // consistent initial state: Φ in equilibrium at t₀ and M a₀ = f_ext − f_int − f_vis
        project(
            &mut projector,
            &mut proj_solver,
            &mut proj_k,
            &proj_settings,
            &mut start.q,
            inputs,
            start.t,
            model.mesh.n_nodes(),
        )
        .map_err(|e| {
            (
                start.clone(),
                DynamicFailure {
                    t: start.t,
                    reason: e,
                    newton_iterations: 0,
                },
            )
        })?;
        let mut probe = TimeStep::new(
            &step_model,
            inputs.mass,
            inputs.viscosity.clone(),
            Scheme::Midpoint,
            start.clone(),
        );
        let forces = probe.forces_at(&start.q, &start.v).map_err(|e| {
            (
                start.clone(),
                DynamicFailure {
                    t: start.t,
                    reason: e,
                    newton_iterations: 0,
                },
            )
        })?;
        let rhs: Vec<f64> = forces.iter().map(|f| -f).collect();
        start.a = inputs.mass.solve(&rhs, &probe.dofs, 1e-12);
    }
    let mut step = TimeStep::new(
        &step_model,
        inputs.mass,
        inputs.viscosity.clone(),
        scheme,
        start,
    );
    let mut solver = FaerLdlt::new();
    let mut k = crate::solve::newton::NonlinearSystem::new_matrix(&step);
    let t_end = resume.map_or(step.prev.t, |r| r.t_start) + settings.duration;
    let min_dt = settings.dt * settings.min_fraction;
    let mut dt = resume.map_or(settings.dt, |r| r.dt);
    let mut total_iterations = resume.map_or(0, |r| r.iterations);
    let step_settings = NewtonSettings {
        check_stability: false,
        reuse_factorization: settings.reuse_factorization,
        ..newton_settings.clone()
    };
    let mut last_h = f64::NAN;
    while step.prev.t < t_end - 1e-12 * settings.duration {
        if let Some(reason) = crate::solve::interrupt::pending() {
            let t = step.prev.t;
            return Err((
                step.prev.clone(),
                DynamicFailure {
                    t,
                    reason,
                    newton_iterations: total_iterations,
                },
            ));
        }
        let h = dt.min(t_end - step.prev.t);
        let t0 = step.prev.t;
        let voltages: Vec<(&[usize], f64, f64)> = inputs
            .electrodes
            .iter()
            .map(|(n, w)| (n.as_slice(), w.value(t0 + 0.5 * h), w.value(t0 + h)))
            .collect();
        step.begin(h, &voltages);
        if h != last_h {
            // the iteration matrix M/Δt + (Δt/4)K depends on the step size
            solver.invalidate();
            last_h = h;
        }
        let result = newton(
            &mut step,
            &mut solver as &mut dyn LinearSolver,
            &mut k,
            &step_settings,
        );
        let failure = match result {
            Ok(rep) => {
                total_iterations += rep.iterations;
                let dissipated = match step.dissipation_power() {
                    Ok(p) => p * h,
                    Err(e) => {
                        return Err((
                            step.prev.clone(),
                            DynamicFailure {
                                t: t0,
                                reason: e,
                                newton_iterations: total_iterations,
                            },
                        ))
                    }
                };
                let mut level = step.end_level();
                if scheme == Scheme::Midpoint {
                    // Gauss's law at t_{n+1}: solve for the potential with u_{n+1} held
                    let t1 = level.t;
                    if let Err(e) = project(
                        &mut projector,
                        &mut proj_solver,
                        &mut proj_k,
                        &proj_settings,
                        &mut level.q,
                        inputs,
                        t1,
                        model.mesh.n_nodes(),
                    ) {
                        return Err((
                            step.prev.clone(),
                            DynamicFailure {
                                t: t0,
                                reason: e,
                                newton_iterations: total_iterations,
                            },
                        ));
                    }
                }
                if rep.iterations <= settings.easy_iterations {
                    dt = (2.0 * dt).min(settings.dt);
                }
                let info = DynamicStepInfo {
                    dt: h,
                    newton_iterations: rep.iterations,
                    dissipated,
                    next_dt: dt,
                    total_iterations,
                };
                if on_step(&level, &info) {
                    solver.invalidate();
                    proj_solver.invalidate();
                    last_h = f64::NAN;
                }
                step.q = level.q.clone();
                step.prev = level;
                continue;
            }
            Err(e) => e.to_string(),
        };
        // cut back
        step.q = step.prev.q.clone();
        dt = 0.5 * h;
        if dt < min_dt {
            return Err((
                step.prev.clone(),
                DynamicFailure {
                    t: t0,
                    reason: format!("time step fell below {min_dt:e} s at t = {t0:.6e} s; last failure: {failure}"),
                    newton_iterations: total_iterations,
                },
            ));
        }
    }
    Ok((step.prev, total_iterations))
}

/// Puts the potential of `q` into electrostatic equilibrium at fixed displacements, with the
/// electrodes at their voltages at time `t`.
#[allow(clippy::too_many_arguments)]
fn project(
    projector: &mut StaticProblem,
    solver: &mut FaerLdlt,
    k: &mut crate::problem::assembly::CsrMatrix,
    settings: &NewtonSettings,
    q: &mut [f64],
    inputs: &DynamicInputs,
    t: f64,
    n_nodes: usize,
) -> Result<(), String> {
    projector.state.copy_from_slice(q);
    for (nodes, w) in &inputs.electrodes {
        let v = w.value(t);
        for &node in nodes {
            projector.state[node * FIELDS + PHI] = v;
        }
    }
    newton(projector, solver as &mut dyn LinearSolver, k, settings)
        .map_err(|e| format!("electrostatic projection: {e}"))?;
    for node in 0..n_nodes {
        q[node * FIELDS + PHI] = projector.state[node * FIELDS + PHI];
    }
    Ok(())
}

/// The projector of the potential: (problem, solver, tangent, Newton settings).
type Projector<'a, 'm> = (
    &'a mut StaticProblem<'m>,
    &'a mut FaerLdlt,
    &'a mut crate::problem::assembly::CsrMatrix,
    &'a NewtonSettings,
);

/// The explicit trapezoidal (Störmer–Verlet) variational integrator; see `trapezoidal.rs`.
#[allow(clippy::too_many_arguments)]
fn run_trapezoidal(
    step_model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    projector: Projector,
    resume: Option<DynamicResume>,
    mut on_step: impl FnMut(&TimeLevel, &DynamicStepInfo) -> bool,
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    use super::trapezoidal::{dissipation_power, TrapezoidalStep};
    let (proj, proj_solver, proj_k, proj_settings) = projector;
    let n_nodes = step_model.mesh.n_nodes();
    let fail = |level: &TimeLevel, t: f64, reason: String, its: usize| {
        (
            level.clone(),
            DynamicFailure {
                t,
                reason,
                newton_iterations: its,
            },
        )
    };
    let mut level = start;
    if resume.is_none() {
        project(
            proj,
            proj_solver,
            proj_k,
            proj_settings,
            &mut level.q,
            inputs,
            level.t,
            n_nodes,
        )
        .map_err(|e| fail(&level, level.t, e, 0))?;
    }
    let mut forces = TimeStep::new(
        step_model,
        inputs.mass,
        inputs.viscosity.clone(),
        Scheme::Midpoint,
        level.clone(),
    );
    let zero = vec![0.0; level.q.len()];
    let mut f_n = forces
        .forces_at(&level.q, &zero)
        .map_err(|e| fail(&level, level.t, e, 0))?;
    let mut trap = TrapezoidalStep::new(step_model, inputs.mass, inputs.viscosity.clone());
    let free = trap.free_u();
    let mut solver = FaerLdlt::new();
    let mut k = crate::solve::newton::NonlinearSystem::new_matrix(&trap);
    let step_settings = NewtonSettings {
        check_stability: false,
        ..newton_settings.clone()
    };
    let t_end = resume.map_or(level.t, |r| r.t_start) + settings.duration;
    let min_dt = settings.dt * settings.min_fraction;
    let mut dt = resume.map_or(settings.dt, |r| r.dt);
    let mut total = resume.map_or(0, |r| r.iterations);
    while level.t < t_end - 1e-12 * settings.duration {
        if let Some(reason) = crate::solve::interrupt::pending() {
            let t = level.t;
            return Err((
                level.clone(),
                DynamicFailure {
                    t,
                    reason,
                    newton_iterations: total,
                },
            ));
        }
        let h = dt.min(t_end - level.t);
        let t0 = level.t;
        trap.q_n.copy_from_slice(&level.q);
        trap.v_n.copy_from_slice(&level.v);
        trap.f_n.copy_from_slice(&f_n);
        trap.dt = h;
        for d in 0..level.q.len() {
            trap.q[d] = if free[d] {
                level.q[d] + h * level.v[d]
            } else {
                level.q[d]
            };
        }
        solver.invalidate();
        let attempt = newton(
            &mut trap,
            &mut solver as &mut dyn LinearSolver,
            &mut k,
            &step_settings,
        )
        .map_err(|e| e.to_string())
        .and_then(|rep| {
            let vbar: Vec<f64> = trap
                .q
                .iter()
                .zip(&level.q)
                .map(|(a, b)| (a - b) / h)
                .collect();
            let mut q1 = trap.q.clone();
            project(
                proj,
                proj_solver,
                proj_k,
                proj_settings,
                &mut q1,
                inputs,
                t0 + h,
                n_nodes,
            )?;
            let f1 = forces.forces_at(&q1, &vbar)?;
            let mut mv = vec![0.0; vbar.len()];
            inputs.mass.mul(&vbar, &mut mv);
            let p1: Vec<f64> = mv.iter().zip(&f1).map(|(m, f)| m - 0.5 * h * f).collect();
            let v1 = inputs.mass.solve(&p1, &trap.dofs, 1e-12);
            let p0 = dissipation_power(step_model, &inputs.viscosity, &level.q, &vbar)?;
            let p1w = dissipation_power(step_model, &inputs.viscosity, &q1, &vbar)?;
            let f_next = forces.forces_at(&q1, &zero)?;
            if v1.iter().chain(&q1).any(|x| !x.is_finite()) {
                return Err(
                    "non-finite state (explicit step beyond its stability limit?)".to_string(),
                );
            }
            Ok((rep.iterations, q1, v1, 0.5 * h * (p0 + p1w), f_next))
        });
        match attempt {
            Ok((its, q1, v1, dissipated, f_next)) => {
                total += its;
                let a = level.a.clone();
                level = TimeLevel {
                    t: t0 + h,
                    q: q1,
                    v: v1,
                    a,
                };
                f_n = f_next;
                dt = (2.0 * dt).min(settings.dt);
                let refresh = on_step(
                    &level,
                    &DynamicStepInfo {
                        dt: h,
                        newton_iterations: its,
                        dissipated,
                        next_dt: dt,
                        total_iterations: total,
                    },
                );
                if refresh {
                    proj_solver.invalidate();
                }
            }
            Err(reason) => {
                dt = 0.5 * h;
                if dt < min_dt {
                    return Err(fail(
                        &level,
                        t0,
                        format!("time step fell below {min_dt:e} s at t = {t0:.6e} s; last failure: {reason}"),
                        total,
                    ));
                }
            }
        }
    }
    Ok((level, total))
}
