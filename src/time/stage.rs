//! The driver of a dynamic stage: one adaptive step loop for every time integration scheme. It
//! steps from t₀ to t₀ + duration, halving the step on failure (Newton divergence, J ≤ 0, singular
//! tangent) and growing it back after easy steps, never past the stage end. A scheme is a
//! [`Stepper`]: it attempts one step of a given size from its current level. The midpoint scheme
//! re-projects the potential onto electrostatic equilibrium after each step.

use super::integrator::{FactorPoint, Scheme, TimeLevel, TimeStep};
use super::mass::NodalMass;
use crate::algebra::csr::CsrMatrix;
use crate::algebra::exchange::{Exchange, LocalEquations};
use crate::algebra::system::NonlinearSystem;
use crate::problem::distributed::{agree, Division, Held};
use crate::problem::dofs::{Dirichlet, Field, FIELDS, PHI};
use crate::problem::drive::Drive;
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{LinearSolver, SolverSettings, SolverStats, StepJacobian};
use crate::solve::newton::{newton, NewtonSettings};

/// A time integration method of a dynamic stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Method {
    /// An implicit scheme: the midpoint variational integrator or Newmark.
    Implicit(Scheme),
    /// Explicit trapezoidal variational integrator (Störmer–Verlet), see `trapezoidal.rs`.
    Trapezoidal,
}

impl Method {
    /// Name for messages and files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Implicit(scheme) => scheme.name(),
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
    /// The linear solver.
    pub solver: SolverSettings,
}

/// An accepted step.
#[derive(Debug, Clone)]
pub struct DynamicStepInfo<'a> {
    pub dt: f64,
    pub newton_iterations: usize,
    /// Energy dissipated during the step (J): Kelvin–Voigt viscosity, dashpots and the
    /// materials' internal variables.
    pub dissipated: f64,
    /// The materials' internal variables after the step (`None` for elastic materials).
    pub points: Option<&'a PointStates>,
    /// The step size the next step will try (after the growth rule).
    pub next_dt: f64,
    /// Newton iterations of the stage so far, this step included.
    pub total_iterations: usize,
    /// Where the driver stands, to resume it from this step ([`DynamicResume`]).
    pub last_h: f64,
    pub step_factor: Option<&'a FactorPoint>,
    pub projection_factor: Option<&'a [f64]>,
    /// The linear solvers' work of the stage so far (the steps' and the projections'), failed
    /// attempts included; a resumed stage's includes the work before its checkpoint.
    pub linear: SolverStats,
    /// The level the step started from (after a scheme's start-up at the stage's first step:
    /// Newmark's consistent acceleration).
    pub prev: &'a TimeLevel,
    /// The step's converged unknown q_{n+1} before the midpoint scheme's electrostatic
    /// projection (the new level's q for the other schemes): what a discrete adjoint replays.
    pub iterate: &'a [f64],
}

impl DynamicStepInfo<'_> {
    /// The resume point of the driver after this step, for a stage that started at `t_start`.
    pub fn resume_point(&self, t_start: f64) -> DynamicResume {
        DynamicResume {
            t_start,
            dt: self.next_dt,
            iterations: self.total_iterations,
            last_h: self.last_h,
            step_factor: self.step_factor.cloned(),
            projection_factor: self.projection_factor.map(<[f64]>::to_vec),
            linear: self.linear,
        }
    }
}

/// Where to resume a dynamic stage: the start level given to [`run_dynamic_from`] is an accepted
/// level of an earlier run (not the stage start), `dt` the step size to try next,
/// `iterations` the Newton iterations spent so far, `last_h` the size of the last attempted step,
/// and the points where the reused matrices were factored (they are factored there again, so the
/// resumed run continues bit for bit). The start-of-stage set-up (Newmark's consistent
/// acceleration, the trapezoidal scheme's first projection) is skipped.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DynamicResume {
    /// Time of the stage start (the stage ends at `t_start + duration`).
    pub t_start: f64,
    pub dt: f64,
    pub iterations: usize,
    pub last_h: f64,
    pub step_factor: Option<FactorPoint>,
    pub projection_factor: Option<Vec<f64>>,
    /// The linear solvers' work of the stage so far (absent in older checkpoints: zero).
    #[serde(default)]
    pub linear: SolverStats,
}

/// The stage stopped before its end.
#[derive(Debug, Clone)]
pub struct DynamicFailure {
    /// Time of the last accepted state (the state returned).
    pub t: f64,
    pub reason: String,
    pub newton_iterations: usize,
    /// The linear solvers' work of the stage up to the failure.
    pub linear: SolverStats,
}

/// Everything a dynamic stage needs besides the model.
pub struct DynamicInputs<'a> {
    pub mass: &'a NodalMass,
    pub viscosity: Vec<f64>,
    /// The stage's electrode voltages and circuit sources in stage time.
    pub drive: Drive,
    /// The committed internal variables of the material points at the start level (empty for
    /// elastic materials).
    pub points: PointStates,
    /// On a rank's part of a divided plan: how the ranks divide the unknowns (`None`: the whole
    /// problem is here). The model, the mass, the start level and the points are then the
    /// part's.
    pub part: Option<StageParts<'a>>,
}

/// How the ranks divide the unknowns of a dynamic stage: the implicit step's (displacements
/// and potentials), the electrostatic projection's (the potentials alone) and the explicit
/// scheme's velocity equation's (the displacements alone; `None` where no stage is explicit).
#[derive(Clone, Copy)]
pub struct StageParts<'a> {
    pub step: &'a Division,
    pub projection: &'a Division,
    pub explicit: Option<&'a Division>,
}

/// A division's equations and exchange, for a mass solve over the ranks.
fn equations_and_exchange(d: &Division) -> (&LocalEquations, &dyn Exchange) {
    (d.equations.as_ref(), d.exchange.as_ref())
}

/// `outcome`, agreed over the ranks of a part (every rank fails when one does).
fn agreed<T>(part: Option<StageParts>, outcome: Result<T, String>) -> Result<T, String> {
    match part {
        Some(p) => agree(p.step.exchange.as_ref(), outcome),
        None => outcome,
    }
}

/// Why an attempted step did not give a new level.
enum StepError {
    /// The step may succeed with a smaller size (Newton failed, inadmissible state).
    Retry(String),
    /// The stage cannot go on (a failure after the step converged; its Newton iterations).
    Fatal(String, usize),
}

/// An accepted attempt: the new level, Newton iterations, dissipated energy (J), and the
/// updated internal variables (`None` for elastic materials).
struct Attempt {
    level: TimeLevel,
    /// The step's converged unknown before a projection of the potential.
    iterate: Vec<f64>,
    iterations: usize,
    dissipated: f64,
    points: Option<PointStates>,
}

/// One time integration scheme as the adaptive loop sees it.
trait Stepper {
    /// The last accepted level.
    fn level(&self) -> &TimeLevel;
    /// Tries one step of size `h` from the current level.
    fn attempt(&mut self, h: f64) -> Result<Attempt, StepError>;
    /// Makes the level (and internal variables) of the last successful attempt the current one.
    fn accept(&mut self, level: TimeLevel, points: Option<PointStates>);
    /// Whether the step size may double after an accepted step of `iterations` Newton iterations.
    fn easy(&self, iterations: usize, easy_iterations: usize) -> bool;
    /// Size of the last attempted step and the points of the held factorisations.
    fn position(&self) -> (f64, Option<&FactorPoint>, Option<&[f64]>);
    /// The work of the step's and the projection's linear solvers so far.
    fn linear(&self) -> SolverStats;
}

/// The model of a dynamic stage's steps: `model` (its supports held) with the potential of the
/// drive's electrodes prescribed (their values, here at stage time `t`, are set by each step).
pub fn step_model(model: &Model, drive: &Drive, t: f64) -> Model {
    let mut step_model = model.clone();
    for (nodes, v) in drive.voltages_at(t) {
        step_model.dirichlet.push(Dirichlet {
            nodes: nodes.to_vec(),
            field: Field::Phi,
            value: v,
        });
    }
    step_model
}

/// The model of a dynamic stage's electrostatic projection, from the stage's model with its
/// conditions: every displacement held, the potential prescribed where the stage prescribes it.
pub fn projection_model(step_model: &Model) -> Model {
    Projector::model(step_model)
}

/// The electrostatic projection: every displacement held, the potential solved for with the
/// electrodes at their voltages (Gauss's law at a time level).
struct Projector<'m> {
    problem: Held<StaticProblem<'m>>,
    solver: Box<dyn LinearSolver>,
    k: CsrMatrix,
    settings: NewtonSettings,
}

impl<'m> Projector<'m> {
    /// On a rank's part (`part`: the projection's division) Newton runs on the rank's owned
    /// potentials (collective).
    fn new(
        model: &'m Model,
        start: &[f64],
        settings: &DynamicSettings,
        newton_settings: &NewtonSettings,
        part: Option<&Division>,
    ) -> Result<Self, String> {
        let mut problem = StaticProblem::new(model, Some(start.to_vec()));
        problem.set_drive(Drive::held(model));
        let problem = Held::new(problem, part)?;
        let k = problem.inner().new_matrix();
        Ok(Projector {
            problem,
            solver: settings.solver.build(),
            k,
            settings: NewtonSettings {
                check_stability: false,
                reuse_factorization: settings.reuse_factorization,
                lag_tangent: false,
                ..newton_settings.clone()
            },
        })
    }

    /// The model of the projection: all displacements held, the potential prescribed where
    /// `step_model` prescribes it (its drive holds the dead loads at full value as in the step,
    /// the free charges of charge-controlled electrodes among them).
    fn model(step_model: &Model) -> Model {
        let mut proj_model = step_model.clone();
        let all: Vec<usize> = (0..step_model.mesh.n_nodes()).collect();
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
        proj_model
    }

    /// Factors the projection's matrix at a recorded state (a resumed run).
    fn refactor_at(&mut self, state: &[f64]) -> Result<(), String> {
        self.problem.inner_mut().state.copy_from_slice(state);
        let system = self.problem.system();
        let mut r = vec![0.0; system.n()];
        system.evaluate(&mut r, Some(&mut self.k))?;
        // a shared assembly's solver needs the layout before its first factorisation
        crate::solve::newton::prepare_solver(system, self.solver.as_mut())?;
        self.solver.factor(&self.k).map_err(|e| e.to_string())?;
        system.factored();
        Ok(())
    }

    /// Puts the potential of `q` into electrostatic equilibrium at fixed displacements, with the
    /// electrodes at their voltages at time `t`.
    /// `charges`: the circuits' charges at `t` (node of the potential unknown, C).
    fn project(
        &mut self,
        q: &mut [f64],
        inputs: &DynamicInputs,
        t: f64,
        charges: Vec<(usize, f64)>,
    ) -> Result<(), String> {
        let p = self.problem.inner_mut();
        p.extra_charges = charges;
        // and the drive's free charges at t (a dynamic stage holds them at their waveforms)
        p.extra_charges.extend(inputs.drive.charges_at(t, 1.0));
        p.state.copy_from_slice(q);
        inputs.drive.apply_voltages(&mut p.state, t);
        newton(
            self.problem.system(),
            self.solver.as_mut(),
            &mut self.k,
            &self.settings,
        )
        .map_err(|e| format!("electrostatic projection: {e}"))?;
        let p = self.problem.inner();
        for node in 0..q.len() / FIELDS {
            q[node * FIELDS + PHI] = p.state[node * FIELDS + PHI];
        }
        Ok(())
    }

    fn factor_point(&self) -> Option<&[f64]> {
        if self.solver.is_factored() {
            self.problem.inner().factored_at.as_deref()
        } else {
            None
        }
    }
}

/// Midpoint and Newmark: Newton on the step equation of [`TimeStep`].
struct ImplicitStepper<'a, 'm> {
    step: Held<TimeStep<'m>>,
    solver: Box<dyn LinearSolver>,
    k: CsrMatrix,
    settings: NewtonSettings,
    projector: Projector<'m>,
    inputs: &'a DynamicInputs<'a>,
    scheme: Scheme,
    last_h: f64,
}

impl Stepper for ImplicitStepper<'_, '_> {
    fn level(&self) -> &TimeLevel {
        &self.step.inner().prev
    }

    fn attempt(&mut self, h: f64) -> Result<Attempt, StepError> {
        let t0 = self.step.inner().prev.t;
        let drive = &self.inputs.drive;
        let voltages: Vec<(&[usize], f64, f64)> = drive
            .voltages_at(t0 + 0.5 * h)
            .zip(drive.voltages_at(t0 + h))
            .map(|((nodes, mid), (_, end))| (nodes, mid, end))
            .collect();
        self.step.inner_mut().begin(h, &voltages);
        // the drive's charges at the step's evaluation point
        let t_eval = match self.scheme {
            Scheme::Midpoint => t0 + 0.5 * h,
            Scheme::Newmark { .. } => t0 + h,
        };
        self.step.inner_mut().charges = drive.charges_at(t_eval, 1.0);
        let at = |t: f64| drive.circuit_sources_at(t);
        let (start, mid, end) = (at(t0), at(t0 + 0.5 * h), at(t0 + h));
        let sources: Vec<[f64; 3]> = (0..start.len())
            .map(|i| [start[i], mid[i], end[i]])
            .collect();
        if let Err(e) = self.step.inner_mut().begin_circuits(&sources) {
            return Err(StepError::Fatal(e, 0));
        }
        if h != self.last_h {
            // the iteration matrix M/Δt + (Δt/4)K depends on the step size
            self.solver.invalidate();
            self.last_h = h;
        }
        let rep = match newton(
            self.step.system(),
            self.solver.as_mut(),
            &mut self.k,
            &self.settings,
        ) {
            Ok(rep) => rep,
            Err(e) => {
                let step = self.step.inner_mut();
                step.q = step.prev.q.clone();
                return Err(StepError::Retry(e.to_string()));
            }
        };
        // on a rank's part: its own cells' and dashpots' power (the records sum the ranks')
        let power = self.step.inner_mut().dissipation_power();
        let dissipated = match self.step.agree(power) {
            Ok(p) => p * h,
            Err(e) => return Err(StepError::Fatal(e, rep.iterations)),
        };
        // the internal variables follow the update whose stresses the step used; a failure here
        // (an inadmissible evaluation point) is a step to retry smaller
        let (points, dissipated) = if self.step.inner().points.is_empty() {
            (None, dissipated)
        } else {
            let updated = self.step.inner_mut().updated_points();
            match self.step.agree(updated) {
                Ok((p, d)) => (Some(p), dissipated + d),
                Err(e) => {
                    let step = self.step.inner_mut();
                    step.q = step.prev.q.clone();
                    return Err(StepError::Retry(e));
                }
            }
        };
        let mut level = self.step.inner().end_level();
        let iterate = level.q.clone();
        if self.scheme == Scheme::Midpoint {
            // Gauss's law at t_{n+1}: solve for the potential with u_{n+1} held
            let t1 = level.t;
            let charges = self.step.inner_mut().end_charges();
            self.projector
                .project(&mut level.q, self.inputs, t1, charges)
                .map_err(|e| StepError::Fatal(e, rep.iterations))?;
        }
        Ok(Attempt {
            level,
            iterate,
            iterations: rep.iterations,
            dissipated,
            points,
        })
    }

    fn accept(&mut self, level: TimeLevel, points: Option<PointStates>) {
        let step = self.step.inner_mut();
        step.q = level.q.clone();
        step.prev = level;
        if let Some(p) = points {
            step.points = p;
        }
    }

    fn easy(&self, iterations: usize, easy_iterations: usize) -> bool {
        iterations <= easy_iterations
    }

    fn position(&self) -> (f64, Option<&FactorPoint>, Option<&[f64]>) {
        let step = if self.solver.is_factored() {
            self.step.inner().factor_point.as_ref()
        } else {
            None
        };
        (self.last_h, step, self.projector.factor_point())
    }

    fn linear(&self) -> SolverStats {
        self.solver.stats() + self.projector.solver.stats()
    }
}

/// The explicit trapezoidal (Störmer–Verlet) scheme; see `trapezoidal.rs`.
struct TrapezoidalStepper<'a, 'm> {
    level: TimeLevel,
    trap: Held<super::trapezoidal::TrapezoidalStep<'m>>,
    forces: TimeStep<'m>,
    /// Conservative forces at the current level.
    f_n: Vec<f64>,
    free: Vec<bool>,
    solver: Box<dyn LinearSolver>,
    k: CsrMatrix,
    settings: NewtonSettings,
    projector: Projector<'m>,
    inputs: &'a DynamicInputs<'a>,
    model: &'m Model,
    last_h: f64,
    /// The forces at the level of the last successful attempt.
    f_next: Vec<f64>,
}

impl Stepper for TrapezoidalStepper<'_, '_> {
    fn level(&self) -> &TimeLevel {
        &self.level
    }

    fn attempt(&mut self, h: f64) -> Result<Attempt, StepError> {
        use super::trapezoidal::dissipation_power;
        let level = &self.level;
        let t0 = level.t;
        let step = self.trap.inner_mut();
        step.q_n.copy_from_slice(&level.q);
        step.v_n.copy_from_slice(&level.v);
        step.f_n.copy_from_slice(&self.f_n);
        step.dt = h;
        for d in 0..level.q.len() {
            step.q[d] = if self.free[d] {
                level.q[d] + h * level.v[d]
            } else {
                level.q[d]
            };
        }
        self.last_h = h;
        self.solver.invalidate();
        let (projector, forces, inputs, model) = (
            &mut self.projector,
            &mut self.forces,
            self.inputs,
            self.model,
        );
        // on a rank's part the forces, the mass and the power are the rank's shares: the local
        // failures are agreed over the ranks before the next collective call
        let part = inputs.part;
        let trap = &mut self.trap;
        let attempt = newton(
            trap.system(),
            self.solver.as_mut(),
            &mut self.k,
            &self.settings,
        )
        .map_err(|e| e.to_string())
        .and_then(|rep| {
            let trap = trap.inner();
            let vbar: Vec<f64> = trap
                .q
                .iter()
                .zip(&level.q)
                .map(|(a, b)| (a - b) / h)
                .collect();
            let iterate = trap.q.clone();
            let mut q1 = iterate.clone();
            projector.project(&mut q1, inputs, t0 + h, Vec::new())?;
            let f1 = agreed(part, forces.forces_at(&q1, &vbar))?;
            let mut mv = vec![0.0; vbar.len()];
            inputs.mass.mul(&vbar, &mut mv);
            let p1: Vec<f64> = mv.iter().zip(&f1).map(|(m, f)| m - 0.5 * h * f).collect();
            let explicit = part.and_then(|p| p.explicit).map(equations_and_exchange);
            let v1 = inputs.mass.solve_on(&p1, &trap.dofs, 1e-12, explicit)?;
            let rest = (|| {
                let p0 = dissipation_power(model, &inputs.viscosity, &level.q, &vbar)?;
                let p1w = dissipation_power(model, &inputs.viscosity, &q1, &vbar)?;
                let zero = vec![0.0; q1.len()];
                let f_next = forces.forces_at(&q1, &zero)?;
                if v1.iter().chain(&q1).any(|x| !x.is_finite()) {
                    return Err(
                        "non-finite state (explicit step beyond its stability limit?)".to_string(),
                    );
                }
                Ok((0.5 * h * (p0 + p1w), f_next))
            })();
            let (dissipated, f_next) = agreed(part, rest)?;
            Ok((rep.iterations, iterate, q1, v1, dissipated, f_next))
        });
        match attempt {
            Ok((iterations, iterate, q, v, dissipated, f_next)) => {
                self.f_next = f_next;
                Ok(Attempt {
                    level: TimeLevel {
                        t: t0 + h,
                        q,
                        v,
                        a: level.a.clone(),
                    },
                    iterate,
                    iterations,
                    dissipated,
                    points: None,
                })
            }
            Err(reason) => Err(StepError::Retry(reason)),
        }
    }

    fn accept(&mut self, level: TimeLevel, _points: Option<PointStates>) {
        self.level = level;
        std::mem::swap(&mut self.f_n, &mut self.f_next);
    }

    fn easy(&self, _iterations: usize, _easy_iterations: usize) -> bool {
        true
    }

    fn position(&self) -> (f64, Option<&FactorPoint>, Option<&[f64]>) {
        (self.last_h, None, self.projector.factor_point())
    }

    fn linear(&self) -> SolverStats {
        self.solver.stats() + self.projector.solver.stats()
    }
}

/// How much longer than the step size a stage's last step may be. The summed time can fall short
/// of the stage end by round-off, up to about N²·10⁻¹⁶ of a step after N steps (2·10⁻⁷ after
/// 10⁵ steps of 0.5/501 s), and a step of that sliver would be dominated by M/Δt, numerically
/// singular.
const LAST_STEP_STRETCH: f64 = 1e-3;

/// The size of the next step with `remaining` time left in the stage: `dt` or what is left,
/// whichever is shorter; but the whole rest when a step of `dt` would leave a sliver, more than
/// the stage's `end_tolerance` (which ends it) and at most [`LAST_STEP_STRETCH`] of `dt`.
fn next_step(dt: f64, remaining: f64, end_tolerance: f64) -> f64 {
    let left = remaining - dt;
    if left > end_tolerance && left <= LAST_STEP_STRETCH * dt {
        remaining
    } else {
        dt.min(remaining)
    }
}

/// The adaptive step loop shared by every scheme: `on_step` sees every accepted level.
// one result per stage: the size of its failure (the last level and what stopped it) costs nothing
#[allow(clippy::result_large_err)]
fn step_loop(
    stepper: &mut dyn Stepper,
    settings: &DynamicSettings,
    t_end: f64,
    mut dt: f64,
    // the Newton iterations and linear work of the stage before this run (a resumed one)
    (mut total, base): (usize, SolverStats),
    mut on_step: impl FnMut(&TimeLevel, &DynamicStepInfo) -> bool,
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    let min_dt = settings.dt * settings.min_fraction;
    // the stage is over within this much of its end
    let end_tolerance = 1e-12 * settings.duration;
    while stepper.level().t < t_end - end_tolerance {
        let t0 = stepper.level().t;
        if let Some(reason) = crate::solve::interrupt::pending() {
            return Err((
                stepper.level().clone(),
                DynamicFailure {
                    t: t0,
                    reason,
                    newton_iterations: total,
                    linear: base + stepper.linear(),
                },
            ));
        }
        let h = next_step(dt, t_end - t0, end_tolerance);
        match stepper.attempt(h) {
            Ok(a) => {
                total += a.iterations;
                if stepper.easy(a.iterations, settings.easy_iterations) {
                    dt = (2.0 * dt).min(settings.dt);
                }
                let (last_h, step_factor, projection_factor) = stepper.position();
                let info = DynamicStepInfo {
                    dt: h,
                    newton_iterations: a.iterations,
                    dissipated: a.dissipated,
                    points: a.points.as_ref(),
                    next_dt: dt,
                    total_iterations: total,
                    last_h,
                    step_factor,
                    projection_factor,
                    linear: base + stepper.linear(),
                    prev: stepper.level(),
                    iterate: &a.iterate,
                };
                let go_on = on_step(&a.level, &info);
                stepper.accept(a.level, a.points);
                if !go_on {
                    break;
                }
            }
            Err(StepError::Fatal(reason, iterations)) => {
                return Err((
                    stepper.level().clone(),
                    DynamicFailure {
                        t: t0,
                        reason,
                        newton_iterations: total + iterations,
                        linear: base + stepper.linear(),
                    },
                ));
            }
            Err(StepError::Retry(failure)) => {
                dt = 0.5 * h;
                if dt < min_dt {
                    return Err((
                        stepper.level().clone(),
                        DynamicFailure {
                            t: t0,
                            reason: format!(
                                "time step fell below {min_dt:e} s at t = {t0:.6e} s; last failure: {failure}"
                            ),
                            newton_iterations: total,
                            linear: base + stepper.linear(),
                        },
                    ));
                }
            }
        }
    }
    Ok((stepper.level().clone(), total))
}

/// Runs the stage from `start`; `model.dirichlet` holds the displacement supports (the electrode
/// conditions are added here). Calls `on_step` after every accepted step with the new level, whose
/// potential is in electrostatic equilibrium. Returns the final level, or the failure together
/// with the last accepted level.
// one result per stage: the size of its failure (the last level and what stopped it) costs nothing
#[allow(clippy::result_large_err)]
pub fn run_dynamic(
    model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    on_step: impl FnMut(&TimeLevel, &DynamicStepInfo),
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    run_dynamic_from(
        model,
        inputs,
        start,
        settings,
        newton_settings,
        None,
        on_step,
    )
}

/// [`run_dynamic`], resumable from a [`DynamicResume`] recorded by an earlier run
/// ([`DynamicStepInfo::resume_point`]).
// one result per stage: the size of its failure (the last level and what stopped it) costs nothing
#[allow(clippy::result_large_err)]
pub fn run_dynamic_from(
    model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    resume: Option<DynamicResume>,
    mut on_step: impl FnMut(&TimeLevel, &DynamicStepInfo),
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    run_dynamic_while(
        model,
        inputs,
        start,
        settings,
        newton_settings,
        resume,
        |level, info| {
            on_step(level, info);
            true
        },
    )
}

/// [`run_dynamic_from`] that stops after the first step for which `on_step` returns false (the
/// level it returns is that step's): the adjoint's replay of part of a stage.
// one result per stage: the size of its failure (the last level and what stopped it) costs nothing
#[allow(clippy::result_large_err)]
pub fn run_dynamic_while(
    model: &Model,
    inputs: &DynamicInputs,
    start: TimeLevel,
    settings: &DynamicSettings,
    newton_settings: &NewtonSettings,
    resume: Option<DynamicResume>,
    on_step: impl FnMut(&TimeLevel, &DynamicStepInfo) -> bool,
) -> Result<(TimeLevel, usize), (TimeLevel, DynamicFailure)> {
    if settings.scheme == Method::Trapezoidal && !inputs.points.is_empty() {
        return Err((
            start.clone(),
            DynamicFailure {
                t: start.t,
                reason: "the explicit trapezoidal scheme does not evolve materials with internal \
                         variables (Maxwell branches); use scheme = \"midpoint\" or \"newmark\""
                    .to_string(),
                newton_iterations: 0,
                linear: SolverStats::default(),
            },
        ));
    }
    let fail = |level: &TimeLevel, reason: String| {
        (
            level.clone(),
            DynamicFailure {
                t: level.t,
                reason,
                newton_iterations: 0,
                linear: SolverStats::default(),
            },
        )
    };
    let part = inputs.part;
    let step_model = step_model(model, &inputs.drive, start.t);
    let proj_model = Projector::model(&step_model);
    let mut projector = Projector::new(
        &proj_model,
        &start.q,
        settings,
        newton_settings,
        part.map(|p| p.projection),
    )
    .map_err(|e| fail(&start, e))?;
    if let Some(q) = resume.as_ref().and_then(|r| r.projection_factor.as_ref()) {
        projector
            .refactor_at(q)
            .map_err(|e| fail(&start, format!("re-factoring at the checkpoint: {e}")))?;
    }
    let t_end = resume.as_ref().map_or(start.t, |r| r.t_start) + settings.duration;
    let dt = resume.as_ref().map_or(settings.dt, |r| r.dt);
    let total = resume.as_ref().map_or(0, |r| r.iterations);
    let base = resume.as_ref().map_or(SolverStats::default(), |r| r.linear);
    let last_h = resume.as_ref().map_or(f64::NAN, |r| r.last_h);
    let mut start = start;
    let scheme = match settings.scheme {
        Method::Implicit(scheme) => scheme,
        Method::Trapezoidal => {
            if resume.is_none() {
                let t = start.t;
                // circuits are refused with this scheme
                projector
                    .project(&mut start.q, inputs, t, Vec::new())
                    .map_err(|e| fail(&start, e))?;
            }
            let mut forces = TimeStep::new(
                &step_model,
                inputs.mass,
                inputs.viscosity.clone(),
                Scheme::Midpoint,
                start.clone(),
            );
            let zero = vec![0.0; start.q.len()];
            let f_n =
                agreed(part, forces.forces_at(&start.q, &zero)).map_err(|e| fail(&start, e))?;
            let trap = super::trapezoidal::TrapezoidalStep::new(
                &step_model,
                inputs.mass,
                inputs.viscosity.clone(),
            );
            let free = trap.free_u();
            let k = trap.new_matrix();
            let explicit = match part {
                None => None,
                Some(p) => Some(p.explicit.ok_or_else(|| {
                    fail(
                        &start,
                        "the rank's part has no division of the explicit scheme's unknowns"
                            .to_string(),
                    )
                })?),
            };
            let trap = Held::new(trap, explicit).map_err(|e| fail(&start, e))?;
            let mut stepper = TrapezoidalStepper {
                level: start,
                trap,
                forces,
                f_next: vec![0.0; f_n.len()],
                f_n,
                free,
                solver: settings.solver.build(),
                k,
                settings: NewtonSettings {
                    check_stability: false,
                    lag_tangent: false,
                    ..newton_settings.clone()
                },
                projector,
                inputs,
                model: &step_model,
                last_h,
            };
            return step_loop(&mut stepper, settings, t_end, dt, (total, base), on_step);
        }
    };
    if let (Scheme::Newmark { .. }, None) = (scheme, &resume) {
        // consistent initial state: Φ in equilibrium at t₀ and M a₀ = f_ext − f_int − f_vis
        let t = start.t;
        // the circuits keep the charges the start state holds
        let charges = {
            let mut probe = TimeStep::new(
                &step_model,
                inputs.mass,
                inputs.viscosity.clone(),
                Scheme::Newmark {
                    beta: 0.25,
                    gamma: 0.5,
                },
                start.clone(),
            );
            probe.points = inputs.points.clone();
            probe
                .begin_circuits(&vec![[0.0; 3]; step_model.circuits.len()])
                .map_err(|e| fail(&start, e))?;
            step_model
                .circuits
                .iter()
                .zip(&probe.circuits)
                .map(|(c, st)| (c.nodes[0], st.charge))
                .collect()
        };
        projector
            .project(&mut start.q, inputs, t, charges)
            .map_err(|e| fail(&start, e))?;
        let mut probe = TimeStep::new(
            &step_model,
            inputs.mass,
            inputs.viscosity.clone(),
            Scheme::Midpoint,
            start.clone(),
        );
        probe.points = inputs.points.clone();
        // on a rank's part: its share of the forces and of the mass, solved over the ranks
        let forces =
            agreed(part, probe.forces_at(&start.q, &start.v)).map_err(|e| fail(&start, e))?;
        let rhs: Vec<f64> = forces.iter().map(|f| -f).collect();
        start.a = inputs
            .mass
            .solve_on(
                &rhs,
                &probe.dofs,
                1e-12,
                part.map(|p| equations_and_exchange(p.step)),
            )
            .map_err(|e| fail(&start, e))?;
    }
    let mut step = TimeStep::new(
        &step_model,
        inputs.mass,
        inputs.viscosity.clone(),
        scheme,
        start.clone(),
    );
    step.points = inputs.points.clone();
    // the exact Jacobian: a new tangent at every iteration, solved by FGMRES with a held factor
    // of its symmetric part (on a rank's part the symmetric matrix, whose solver sums the parts)
    let exact = match (settings.solver.jacobian, part) {
        (StepJacobian::Exact, None) => settings.solver.build_unsymmetric(),
        _ => None,
    };
    let step_exact = exact.is_some();
    step.exact_jacobian = step_exact;
    let reuse_factorization = settings.reuse_factorization && exact.is_none();
    let step = Held::new(step, part.map(|p| p.step)).map_err(|e| fail(&start, e))?;
    let k = step.inner().new_matrix();
    let mut stepper = ImplicitStepper {
        step,
        solver: exact.unwrap_or_else(|| settings.solver.build()),
        k,
        settings: NewtonSettings {
            check_stability: false,
            reuse_factorization,
            lazy_tangent: step_exact,
            lag_tangent: false,
            ..newton_settings.clone()
        },
        projector,
        inputs,
        scheme,
        last_h,
    };
    if let Some(point) = resume.as_ref().and_then(|r| r.step_factor.as_ref()) {
        let s = &mut stepper;
        let saved = s.step.inner_mut().enter_factor_point(point);
        // the circuits' terms of the matrix, which depend on Δt and R only
        let sources = vec![[0.0; 3]; step_model.circuits.len()];
        let circuits = s.step.inner_mut().begin_circuits(&sources);
        let system = s.step.system();
        let mut r = vec![0.0; system.n()];
        // a shared assembly's solver needs the layout before its first factorisation
        let result = circuits
            .and_then(|()| crate::solve::newton::prepare_solver(system, s.solver.as_mut()))
            .and_then(|()| system.evaluate(&mut r, Some(&mut s.k)))
            .and_then(|()| s.solver.factor(&s.k).map(|_| ()).map_err(|e| e.to_string()));
        let step = s.step.inner_mut();
        step.leave_factor_point(saved);
        result.map_err(|e| fail(&step.prev, format!("re-factoring at the checkpoint: {e}")))?;
    }
    step_loop(&mut stepper, settings, t_end, dt, (total, base), on_step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scheme that only advances the time, and fails any step far shorter than the nominal
    /// one (as a step of a round-off sliver does, its iteration matrix singular).
    struct Clock {
        level: TimeLevel,
        steps: Vec<f64>,
        nominal: f64,
        last: f64,
    }

    impl Stepper for Clock {
        fn level(&self) -> &TimeLevel {
            &self.level
        }
        fn attempt(&mut self, h: f64) -> Result<Attempt, StepError> {
            if h < 1e-6 * self.nominal {
                return Err(StepError::Retry("singular tangent".into()));
            }
            self.last = h;
            let mut level = self.level.clone();
            level.t += h;
            Ok(Attempt {
                level,
                iterate: Vec::new(),
                iterations: 1,
                dissipated: 0.0,
                points: None,
            })
        }
        fn accept(&mut self, level: TimeLevel, _points: Option<PointStates>) {
            self.steps.push(self.last);
            self.level = level;
        }
        fn easy(&self, _iterations: usize, _easy_iterations: usize) -> bool {
            true
        }
        fn position(&self) -> (f64, Option<&FactorPoint>, Option<&[f64]>) {
            (self.nominal, None, None)
        }
        fn linear(&self) -> SolverStats {
            SolverStats::default()
        }
    }

    /// 10⁵ steps of 0.5/501 s sum to 2·10⁻¹⁰ s short of 10⁵ times the step (the stage's
    /// duration): the last step takes that sliver along, and the stage ends after 10⁵ steps,
    /// at its end. 2000 steps of 0.2 ms fall short of 0.4 s by 10⁻¹⁴ s, within the stage's end
    /// tolerance: every step is 0.2 ms, as before. A stage whose duration is not a multiple of
    /// the step still ends with the short step it needs.
    #[test]
    fn a_stage_ends_without_a_step_of_the_time_round_off() {
        let run = |dt: f64, duration: f64| {
            let settings = DynamicSettings {
                duration,
                dt,
                scheme: Method::Implicit(Scheme::Midpoint),
                min_fraction: 1.0 / 1024.0,
                easy_iterations: 4,
                reuse_factorization: true,
                solver: SolverSettings::default(),
            };
            let mut clock = Clock {
                level: TimeLevel {
                    t: 0.0,
                    q: Vec::new(),
                    v: Vec::new(),
                    a: Vec::new(),
                },
                steps: Vec::new(),
                nominal: dt,
                last: 0.0,
            };
            let (end, _) = step_loop(
                &mut clock,
                &settings,
                duration,
                dt,
                (0, SolverStats::default()),
                |_, _| true,
            )
            .unwrap_or_else(|(_, f)| panic!("{}", f.reason));
            (end.t, clock.steps)
        };
        let dt = 0.5 / 501.0;
        let (n, duration) = (100_000, 100_000.0 * dt);
        let mut sum = 0.0;
        for _ in 0..n {
            sum += dt;
        }
        assert!(duration - sum > 1e-12 * duration, "{}", duration - sum);
        let (t, steps) = run(dt, duration);
        assert_eq!(steps.len(), n);
        assert_eq!(t, duration);
        assert!(steps[..n - 1].iter().all(|&h| h == dt));
        assert!(steps[n - 1] > dt && steps[n - 1] < dt * (1.0 + 1e-6));
        let (t, steps) = run(2e-4, 0.4);
        assert_eq!(steps.len(), 2000);
        assert!(steps.iter().all(|&h| h == 2e-4));
        assert!(t < 0.4 && t > 0.4 - 1e-12 * 0.4, "{t}");
        let (t, steps) = run(1e-3, 0.0105);
        assert_eq!(steps.len(), 11);
        assert!((t - 0.0105).abs() < 1e-15);
        assert!((steps[10] - 5e-4).abs() < 1e-15, "{}", steps[10]);
    }
}
