//! The adjoint of a dynamic stage: its accepted midpoint or Newmark steps, last to first.
//!
//! A step n → n+1 of size Δt solves R(y; qₙ, vₙ, aₙ, θ) = 0 for the free unknowns of y (the
//! step's q_{n+1}); its prescribed entries are qₙ's (supports) or the drive's (electrodes:
//! 2V(t_{n+½}) − Φₙ for the midpoint scheme, V(t_{n+1}) for Newmark). The new level follows:
//! - midpoint: v_{n+1} = 2(y − qₙ)/Δt − vₙ on the displacements, and the potential of q_{n+1}
//!   is y's projected onto electrostatic equilibrium at y's displacements with the electrodes
//!   at V(t_{n+1}) (P(Φ; u) = 0, a static problem with every displacement held);
//! - Newmark: q_{n+1} = y, a_{n+1} = (y − qₙ − Δt vₙ)/(βΔt²) − (1/(2β) − 1)aₙ,
//!   v_{n+1} = vₙ + Δt((1 − γ)aₙ + γa_{n+1}).
//!
//! With the cotangents (q̄, v̄, ā) of the new level, the step's adjoint runs these relations
//! backwards: the projection's adjoint μ solves (∂P/∂Φ)ᵀμ = q̄_Φ and gives y's displacements
//! q̄_u − μᵀ∂P/∂u; the velocity relations give ȳ and part of (q̄ₙ, v̄ₙ, āₙ); the step's adjoint
//! λ solves Jᵀλ = ȳ over the free unknowns with the exact step Jacobian J, and
//! (q̄ₙ, v̄ₙ, āₙ) −= λᵀ∂R/∂(qₙ, vₙ, aₙ), dJ/dp −= λᵀ∂R/∂p; the prescribed entries of y carry
//! ȳ − λᵀ∂R/∂y to qₙ or to the drive's voltages.
//!
//! Newmark's first step starts from the consistent acceleration a₀ = −M⁻¹f(q₀', v₀) at the
//! start q₀' projected onto electrostatic equilibrium: its adjoint z = M⁻¹ā₀ gives
//! q̄₀' −= (∂f/∂q)ᵀz, v̄₀ −= (∂f/∂v)ᵀz and dJ/dp −= zᵀ∂f/∂p (−zᵀ(∂M/∂m)a₀ for a pad's mass).

use super::charge::charge_adjoint;
use super::lambda::{AdjointSolver, SolveCounts};
use super::objective::Backward;
use super::sink::{waveform_dofs, Sink};
use super::tape::{TapedDynamics, TapedStage, TapedStep};
use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::{LoadedSystem, NonlinearSystem};
use crate::io::build::Parameter;
use crate::job::plan::Plan;
use crate::problem::dofs::{free_weights, CONSTRAINED, FIELDS, PHI};
use crate::problem::drive::Drive;
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::StaticProblem;
use crate::problem::step::{cell_products, viscosity_vjp, StepOperator};
use crate::time::integrator::{Scheme, TimeLevel, TimeStep};
use crate::time::mass::NodalMass;
use crate::time::stage::{projection_model, step_model, Method};

/// The cotangents ∂J/∂· of a time level's positions, velocities and accelerations (4 values
/// per node each), and of the internal variables of the material points committed with it
/// (laid out as [`PointStates::data`]; empty: zero).
#[derive(Debug, Clone, PartialEq)]
pub struct Cotangent {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub points: Vec<f64>,
}

impl Cotangent {
    pub fn zeros(n: usize) -> Self {
        Cotangent {
            q: vec![0.0; n],
            v: vec![0.0; n],
            a: vec![0.0; n],
            points: Vec::new(),
        }
    }
}

/// The adjoint of a commit of the points `before` to the configuration `x` over `dt`, for the
/// cotangent `w` of the values it committed (empty: zero): the parameters' derivatives go to
/// `sink`; returns x̄ (every dof) and the cotangent of `before`'s values (empty without
/// points).
pub(super) fn commit_adjoint(
    model: &Model,
    before: &PointStates,
    x: &[f64],
    dt: f64,
    w: &[f64],
    sink: &mut Sink,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    if before.is_empty() || w.iter().all(|&v| v == 0.0) {
        return Ok((vec![0.0; x.len()], vec![0.0; before.data.len()]));
    }
    let c = before.commit_vjp(model, x, dt, w)?;
    for (m, theta) in c.theta.iter().enumerate() {
        if !theta.is_empty() {
            sink.materials_product(m, theta, 1.0);
        }
    }
    Ok((c.state, c.points))
}

/// The steps of a dynamic stage for its adjoint.
pub trait Steps {
    /// Step `k` of the stage and the record of the level it started from (`None`: the stage's
    /// first step, which starts from the integrator's initial level); asked for from the last
    /// step to the first.
    fn step(&mut self, k: usize) -> Result<(Option<&TapedStep>, &TapedStep), String>;
}

/// The steps of a stage the tape holds whole.
pub struct Held<'t>(pub &'t TapedStage);

impl Steps for Held<'_> {
    fn step(&mut self, k: usize) -> Result<(Option<&TapedStep>, &TapedStep), String> {
        let steps = &self.0.steps;
        Ok((k.checked_sub(1).map(|j| &steps[j]), &steps[k]))
    }
}

/// What the stage's steps share, read only.
struct Stage<'a, 'm> {
    dynamics: &'a TapedDynamics,
    /// ∂M/∂ρ of each material whose density is asked for (its index, the mass of its cells at
    /// unit density).
    unit_masses: Vec<(usize, NodalMass)>,
    drive: &'a Drive,
    scheme: Scheme,
    step_model: &'m Model,
    waveform: Vec<usize>,
    /// Whether the stage's electrodes follow their waveforms (off: grounded).
    electrodes_on: bool,
}

/// The adjoint solves of the steps and of the projections, each reusing its factors.
#[derive(Default)]
struct Solvers {
    step: AdjointSolver,
    projection: AdjointSolver,
}

/// A step's system and its projection's, moved to the step's point with their Jacobians
/// evaluated: all that a step's adjoint needs before the cotangents of its level are known. The
/// sweep prepares the step before the current one while the current one's solves run, on the
/// threads those leave idle; the two alternate between two of these.
struct Prepared<'m> {
    step: TimeStep<'m>,
    projection: StaticProblem<'m>,
    step_matrix: CsrMatrix,
    /// The projection's Jacobian at the step's new level (the midpoint scheme's steps, and
    /// Newmark's start; `None` until its first evaluation).
    projection_matrix: Option<CsrMatrix>,
}

impl<'m> Prepared<'m> {
    fn new(
        s: &Stage<'m, 'm>,
        projection_model: &'m Model,
        start: &[f64],
        initial: &TimeLevel,
    ) -> Self {
        let mut step = TimeStep::new(
            s.step_model,
            &s.dynamics.mass,
            s.dynamics.viscosity.clone(),
            s.scheme,
            initial.clone(),
        );
        step.exact_jacobian = true;
        step.keep_cell_tangents = true;
        let mut projection = StaticProblem::new(projection_model, Some(start.to_vec()));
        projection.keep_cell_tangents = true;
        projection.set_drive(Drive::held(projection_model));
        projection.set_load(1.0);
        let step_matrix = step.new_matrix();
        Prepared {
            step,
            projection,
            step_matrix,
            projection_matrix: None,
        }
    }

    /// Moves the step to the one from `prev` with the unknown `iterate` over `dt`, from the
    /// points `before` committed, and evaluates its Jacobian; under the midpoint scheme also the
    /// projection's at the new level's positions `q`.
    fn prepare(
        &mut self,
        s: &Stage,
        prev: &TimeLevel,
        iterate: &[f64],
        dt: f64,
        before: &[f64],
        q: &[f64],
    ) -> Result<(), String> {
        let step = &mut self.step;
        step.points = PointStates::from_data(s.step_model, before);
        step.prev.clone_from(prev);
        step.dt = dt;
        step.q.copy_from_slice(iterate);
        // the circuits' start (charges by Gauss's law at qₙ) and sources at t_n, t_{n+½},
        // t_{n+1}
        let times = [prev.t, prev.t + 0.5 * dt, prev.t + dt];
        let sources: Vec<[f64; 3]> = (0..s.step_model.circuits.len())
            .map(|i| times.map(|t| s.drive.circuit_sources_at(t)[i]))
            .collect();
        step.begin_circuits(&sources)?;
        // into the matrix of the step before: no new allocation (whose pages the system maps
        // afresh) per step
        step.jacobian(&mut self.step_matrix)?;
        match s.scheme {
            Scheme::Midpoint => self.prepare_projection(q),
            Scheme::Newmark { .. } => Ok(()),
        }
    }

    /// Moves the projection to the positions `q` and evaluates its Jacobian there.
    fn prepare_projection(&mut self, q: &[f64]) -> Result<(), String> {
        self.projection.state.copy_from_slice(q);
        let projection = &mut self.projection;
        let k = self
            .projection_matrix
            .get_or_insert_with(|| projection.new_matrix());
        projection.jacobian(k)
    }
}

/// A step of the tape and the record of the level it started from (`None`: the stage's
/// initial level), copied out of the tape so that the sweep can ask for the step before it.
struct Fetched {
    prev: Option<TapedStep>,
    taped: TapedStep,
}

impl Fetched {
    fn of(steps: &mut dyn Steps, k: usize) -> Result<Fetched, String> {
        let (prev, taped) = steps.step(k)?;
        Ok(Fetched {
            prev: prev.cloned(),
            taped: taped.clone(),
        })
    }

    /// The step's unknown before the projection of the potential.
    fn iterate(&self) -> &[f64] {
        if self.taped.iterate.is_empty() {
            &self.taped.state
        } else {
            &self.taped.iterate
        }
    }
}

/// The adjoint of the dynamic stage `st`, the `ti`-th of a taped run, whose steps `steps` gives
/// from the last to the first: `objective` reads ∂J/∂q and ∂J/∂v of each step, `end` is the
/// cotangent of its last level from the stages after it. The parameters' derivatives go to
/// `sink`; returns the cotangent of the level the stage started from (as given to the
/// integrator), and the linear solves the stage's adjoint took.
pub fn sweep(
    plan: &Plan,
    st: &TapedStage,
    ti: usize,
    objective: &mut Backward,
    steps: &mut dyn Steps,
    end: Cotangent,
    sink: &mut Sink,
) -> Result<(Cotangent, SolveCounts), String> {
    let dynamics = st
        .dynamics
        .as_ref()
        .ok_or("a static stage given to the dynamic adjoint")?;
    let stage = &plan.stages[st.index];
    let scheme = match dynamics.method {
        Method::Implicit(s) => s,
        Method::Trapezoidal => {
            return Err(format!(
                "stage `{}`: the adjoint of the explicit trapezoidal scheme is not built; use \
                 scheme = \"midpoint\" or \"newmark\"",
                stage.name
            ))
        }
    };
    let step_model = step_model(&st.model, &st.drive, dynamics.given.t);
    let projection_model = projection_model(&step_model);
    let n = st.start.len();
    let initial = dynamics
        .initial
        .as_ref()
        .ok_or_else(|| format!("stage `{}` took no step", stage.name))?;
    let kind = match stage.kind {
        crate::job::plan::StageKind::Dynamic { mass, .. } => mass,
        _ => return Err(format!("stage `{}` is not dynamic", stage.name)),
    };
    let unit_masses = sink
        .densities()
        .into_iter()
        .map(|m| {
            let mut unit = vec![0.0; step_model.materials.len()];
            unit[m] = 1.0;
            (m, NodalMass::new(&step_model, &unit, kind))
        })
        .collect();
    let s = Stage {
        dynamics,
        unit_masses,
        drive: &st.drive,
        scheme,
        waveform: waveform_dofs(&st.drive, n),
        step_model: &step_model,
        electrodes_on: stage.electrodes_on,
    };
    let mut solvers = Solvers::default();
    let mut prepared = [
        Prepared::new(&s, &projection_model, &st.start, initial),
        Prepared::new(&s, &projection_model, &st.start, initial),
    ];
    // the levels' times in stage time, as the integrator reached them
    let dts = st.dts();
    let mut times = Vec::with_capacity(dts.len());
    let mut t = initial.t;
    for dt in &dts {
        t += dt;
        times.push(t);
    }
    let level = |t: f64, k: &TapedStep| TimeLevel {
        t,
        q: k.state.clone(),
        v: k.v.clone(),
        a: k.a.clone(),
    };
    let prev_level = |k: usize, f: &Fetched| match &f.prev {
        None => initial.clone(),
        Some(p) => level(times[k - 1], p),
    };
    let prepare = |p: &mut Prepared, k: usize, f: &Fetched| {
        let before = f.prev.as_ref().map_or(&st.start_points, |p| &p.points);
        p.prepare(
            &s,
            &prev_level(k, f),
            f.iterate(),
            f.taped.dt,
            before,
            &f.taped.state,
        )
    };
    let mut c = end;
    let mut next = match dts.len() {
        0 => None,
        m => {
            let f = Fetched::of(steps, m - 1)?;
            prepare(&mut prepared[(m - 1) % 2], m - 1, &f)?;
            Some(f)
        }
    };
    for k in (0..dts.len()).rev() {
        let current = next.take().expect("fetched with the step after it");
        next = match k {
            0 => None,
            _ => Some(Fetched::of(steps, k - 1)?),
        };
        let [even, odd] = &mut prepared;
        let (this, other) = if k % 2 == 0 { (even, odd) } else { (odd, even) };
        // this step's adjoint beside the Jacobians of the step before it, the next to sweep,
        // which take the threads this one's solves leave idle
        let (adjoint, ahead) = rayon::join(
            || {
                let taped = &current.taped;
                add_reads(plan, objective, ti, k, taped, &mut c, sink)?;
                step_adjoint(
                    &s,
                    &mut solvers,
                    this,
                    &prev_level(k, &current),
                    &level(times[k], taped),
                    current.iterate(),
                    taped.dt,
                    std::mem::replace(&mut c, Cotangent::zeros(0)),
                    sink,
                )
            },
            || match &next {
                Some(f) => prepare(other, k - 1, f),
                None => Ok(()),
            },
        );
        c = adjoint?;
        ahead?;
    }
    let start = match scheme {
        Scheme::Midpoint => c,
        Scheme::Newmark { .. } => {
            let p = &mut prepared[0];
            p.step.points = PointStates::from_data(&step_model, &st.start_points);
            p.prepare_projection(&initial.q)?;
            newmark_start_adjoint(&s, &mut solvers, p, initial, c, sink)?
        }
    };
    let mut solves = solvers.step.counts();
    solves += solvers.projection.counts();
    Ok((start, solves))
}

/// Adds to `c` what J reads at step `k` of the `ti`-th stage, whose record is `taped`: its
/// positions and velocities, and its charges (by Gauss's law at its state and points; their
/// parameters' derivatives go to `sink`).
fn add_reads(
    plan: &Plan,
    objective: &mut Backward,
    ti: usize,
    k: usize,
    taped: &TapedStep,
    c: &mut Cotangent,
    sink: &mut Sink,
) -> Result<(), String> {
    let read = objective.at_step(ti, k, taped)?;
    if !read.state.is_empty() {
        c.q.iter_mut().zip(&read.state).for_each(|(a, b)| *a += b);
    }
    if !read.velocity.is_empty() {
        c.v.iter_mut()
            .zip(&read.velocity)
            .for_each(|(a, b)| *a += b);
    }
    if !read.charges.is_empty() {
        let nodes: Vec<&[usize]> = plan.electrodes.iter().map(|e| e.nodes.as_slice()).collect();
        let points = PointStates::from_data(&plan.model, &taped.points);
        let p = charge_adjoint(
            &plan.model,
            &nodes,
            &taped.state,
            &points,
            &read.charges,
            &mut c.q,
            sink,
        )?;
        if !p.is_empty() {
            c.points.resize(p.len(), 0.0);
            c.points.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
        }
    }
    Ok(())
}

/// The adjoint of one step from `prev` to `level` with the step's unknown `iterate`, whose
/// systems and Jacobians `p` holds prepared ([`Prepared::prepare`]).
#[allow(clippy::too_many_arguments)]
fn step_adjoint(
    s: &Stage,
    solvers: &mut Solvers,
    p: &mut Prepared,
    prev: &TimeLevel,
    level: &TimeLevel,
    iterate: &[f64],
    dt: f64,
    c: Cotangent,
    sink: &mut Sink,
) -> Result<Cotangent, String> {
    let n = c.q.len();
    let mut out = Cotangent::zeros(n);
    let times = [prev.t, prev.t + 0.5 * dt, prev.t + dt];
    let circuits = s.step_model.circuits.len();
    // the cotangents of each circuit's start charge Qₙ, its sources and its resistance
    let mut charge_bar = vec![0.0; circuits];
    let mut source_bar = vec![[0.0; 3]; circuits];
    let mut resistance_bar = vec![0.0; circuits];
    // ȳ: through the projection of the potential (midpoint) or directly (Newmark)
    let mut cy = match s.scheme {
        Scheme::Midpoint => {
            let mut cy = vec![0.0; n];
            let end_bar =
                projection_adjoint(s, &mut solvers.projection, p, &c.q, level.t, &mut cy, sink)?;
            // the end charge the projection held: Q_{n+1} = Qₙ + Δt/R (V_s(t_{n+½}) − V_{n+½})
            // with V_{n+½} = ½(Vₙ + y_V)
            for (i, (ci, st)) in s
                .step_model
                .circuits
                .iter()
                .zip(&p.step.circuits)
                .enumerate()
            {
                let d = ci.nodes[0] * FIELDS + PHI;
                let g = dt / ci.resistance;
                let v_mid = 0.5 * (prev.q[d] + iterate[d]);
                let b = end_bar[i];
                charge_bar[i] += b;
                source_bar[i][1] += b * g;
                cy[d] -= 0.5 * g * b;
                out.q[d] -= 0.5 * g * b;
                resistance_bar[i] -= b * g / ci.resistance * (st.source[1] - v_mid);
            }
            cy
        }
        Scheme::Newmark { .. } => c.q.clone(),
    };
    // the velocity and acceleration of the new level
    for d in 0..n {
        if d % FIELDS == PHI {
            out.v[d] += c.v[d];
            out.a[d] += c.a[d];
            continue;
        }
        match s.scheme {
            Scheme::Midpoint => {
                cy[d] += 2.0 / dt * c.v[d];
                out.q[d] -= 2.0 / dt * c.v[d];
                out.v[d] -= c.v[d];
                out.a[d] += c.a[d];
            }
            Scheme::Newmark { beta, gamma } => {
                let ca = c.a[d] + dt * gamma * c.v[d];
                let k = ca / (beta * dt * dt);
                cy[d] += k;
                out.q[d] -= k;
                out.v[d] += c.v[d] - dt * k;
                out.a[d] += dt * (1.0 - gamma) * c.v[d] - (0.5 / beta - 1.0) * ca;
            }
        }
    }
    // the step's equations
    let step = &mut p.step;
    // the points the step committed, updated at its evaluation point: the midpoint
    // configuration ½(qₙ + y), or y (Newmark)
    let half = s.scheme == Scheme::Midpoint;
    let at: Vec<f64> = if half {
        prev.q
            .iter()
            .zip(iterate)
            .map(|(a, b)| 0.5 * (a + b))
            .collect()
    } else {
        iterate.to_vec()
    };
    let (x_bar, mut points_bar) =
        commit_adjoint(s.step_model, &step.points, &at, dt, &c.points, sink)?;
    let share = if half { 0.5 } else { 1.0 };
    for d in 0..n {
        cy[d] += share * x_bar[d];
        if half {
            out.q[d] += 0.5 * x_bar[d];
        }
    }
    let lambda = solvers
        .step
        .solve_assembled(&p.step_matrix, &step.dofs, &cy)?;
    sink.step_materials(step, &lambda)?;
    for (i, node) in sink_rigid(sink) {
        sink.rigid_mass(i, -step.point_mass_vjp(&lambda, node));
    }
    for (m, unit) in &s.unit_masses {
        sink.density(*m, -step.mass_vjp(&lambda, unit));
    }
    let factor = step.residual_factor();
    let weights = free_weights(&step.dofs, &lambda);
    sink.weights(&weights, factor);
    // the drive's charges at the evaluation point, +f_r·Q on their Gauss equations
    let t_eval = match s.scheme {
        Scheme::Midpoint => prev.t + 0.5 * dt,
        Scheme::Newmark { .. } => prev.t + dt,
    };
    for (k, ch) in s.drive.charges.iter().enumerate() {
        sink.charge(
            s.drive,
            k,
            t_eval,
            1.0,
            -factor * weights[ch.node * FIELDS + PHI],
        );
    }
    for m in sink_viscous(sink) {
        let p = step.viscosity_vjp(&lambda, m)?;
        sink.viscosity(m, -p);
    }
    let lv = step.level_vjp(&lambda)?;
    for d in 0..n {
        out.q[d] -= lv.q[d];
        out.v[d] -= lv.v[d];
        out.a[d] -= lv.a[d];
    }
    points_bar
        .iter_mut()
        .zip(&lv.points)
        .for_each(|(a, b)| *a -= b);
    out.points = points_bar;
    let t_mid = prev.t + 0.5 * dt;
    for (d, &e) in step.dofs.eq.iter().enumerate() {
        let a = cy[d] - lv.q_new[d];
        if e != CONSTRAINED {
            // y = qₙ + Δt vₙ + (the tie's increment): the offsets within a tie (a pad, a
            // charge-controlled electrode) are the previous level's (the sum of `a` over a
            // tie vanishes)
            out.q[d] += a;
            if d % FIELDS != PHI {
                out.v[d] += dt * a;
            }
            continue;
        }
        match (s.waveform[d], s.scheme) {
            (usize::MAX, _) => out.q[d] += a,
            (k, Scheme::Midpoint) => {
                if s.electrodes_on {
                    sink.voltage(s.drive, k, t_mid, 2.0 * a);
                }
                out.q[d] -= a;
            }
            (k, Scheme::Newmark { .. }) => {
                if s.electrodes_on {
                    sink.voltage(s.drive, k, level.t, a);
                }
            }
        }
    }
    // the circuits: the step's charge at its evaluation point in (Qₙ, Vₙ, the sources, R)
    for (i, ci) in s.step_model.circuits.iter().enumerate() {
        let l = &lv.circuits[i];
        charge_bar[i] -= l.charge;
        out.q[ci.nodes[0] * FIELDS + PHI] -= l.voltage;
        for j in 0..3 {
            source_bar[i][j] -= l.source[j];
        }
        resistance_bar[i] -= p.step.resistance_vjp(&lambda, i);
    }
    circuit_charge_adjoint(
        s,
        &p.step.points,
        prev,
        &charge_bar,
        &mut out.q,
        &mut out.points,
        sink,
    )?;
    for i in 0..circuits {
        if s.electrodes_on {
            for (j, &t) in times.iter().enumerate() {
                sink.source(s.drive, i, t, source_bar[i][j]);
            }
        }
        sink.resistance(i, resistance_bar[i]);
    }
    Ok(out)
}

/// The rigid pads whose mass is asked for: (index, the node that carries the mass).
fn sink_rigid(sink: &Sink) -> Vec<(usize, usize)> {
    sink.parameters()
        .iter()
        .filter_map(|(_, p)| match p {
            Parameter::RigidMass { index, .. } => Some(*index),
            _ => None,
        })
        .filter_map(|i| sink.rigid_node(i).map(|node| (i, node)))
        .collect()
}

/// The materials whose viscosity is asked for.
fn sink_viscous(sink: &Sink) -> Vec<usize> {
    let mut m: Vec<usize> = sink
        .parameters()
        .iter()
        .filter_map(|(_, p)| match p {
            Parameter::Viscosity { material_index, .. } => Some(*material_index),
            _ => None,
        })
        .collect();
    m.sort_unstable();
    m.dedup();
    m
}

/// The adjoint of the projection of the potential at stage time `t` that `p` holds, prepared
/// at its result's positions, for the cotangent `g` of that result: adds to `out` the
/// cotangent of the inputs it held (the displacements, and potentials held by supports) and
/// gives the electrodes' voltages at `t` and the materials' parameters theirs. Returns the
/// cotangent of each circuit's charge the projection held on its electrode.
fn projection_adjoint(
    s: &Stage,
    solver: &mut AdjointSolver,
    p: &mut Prepared,
    g: &[f64],
    t: f64,
    out: &mut [f64],
    sink: &mut Sink,
) -> Result<Vec<f64>, String> {
    let problem = &mut p.projection;
    let matrix = p
        .projection_matrix
        .as_ref()
        .expect("the projection prepared with its step");
    let mu = solver.solve_assembled(matrix, &problem.dofs, g)?;
    sink.step_materials(problem, &mu)?;
    // the charges held on charge-controlled electrodes (the weights act on the held
    // displacements, whose entries of μ are zero)
    let dead = problem.drive().dead_loads.at(1.0);
    let weights = free_weights(&problem.dofs, &mu);
    sink.weights(&weights, dead);
    // the stage drive's charges at t, held on their Gauss equations
    for (k, ch) in s.drive.charges.iter().enumerate() {
        sink.charge(s.drive, k, t, 1.0, -weights[ch.node * FIELDS + PHI]);
    }
    // a circuit's charge Q enters its electrode's Gauss equation as +Q
    let charges = s
        .step_model
        .circuits
        .iter()
        .map(|c| -weights[c.nodes[0] * FIELDS + PHI])
        .collect();
    let lv = problem.level_vjp(&mu)?;
    for (d, &e) in problem.dofs.eq.iter().enumerate() {
        let a = g[d] - lv.q_new[d];
        if e != CONSTRAINED {
            // the offsets within a tie are those of the projection's start
            out[d] += a;
            continue;
        }
        match s.waveform[d] {
            usize::MAX => out[d] += a,
            k => {
                if s.electrodes_on {
                    sink.voltage(s.drive, k, t, a);
                }
            }
        }
    }
    Ok(charges)
}

/// The adjoint of the circuits' charges at the start of a step, Q = −Σ ∂Π/∂Φ over each
/// electrode's nodes at `level` with the internal variables `points` (Gauss's law, which the
/// step before enforced), for their cotangents `charge_bar`: adds to `q_bar` and `points_bar`
/// (the cotangent of `points`, empty: none) and gives the materials' parameters theirs.
fn circuit_charge_adjoint(
    s: &Stage,
    points: &PointStates,
    level: &TimeLevel,
    charge_bar: &[f64],
    q_bar: &mut [f64],
    points_bar: &mut [f64],
    sink: &mut Sink,
) -> Result<(), String> {
    let model = s.step_model;
    let nodes: Vec<&[usize]> = model.circuits.iter().map(|c| c.nodes.as_slice()).collect();
    let p = charge_adjoint(model, &nodes, &level.q, points, charge_bar, q_bar, sink)?;
    if !points_bar.is_empty() && !p.is_empty() {
        points_bar.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
    }
    Ok(())
}

/// The adjoint of Newmark's start-up from the given level: the start's potential projected at
/// its time, then the consistent acceleration. `c` is the cotangent of `initial`, the level it
/// gave.
fn newmark_start_adjoint(
    s: &Stage,
    solvers: &mut Solvers,
    prepared: &mut Prepared,
    initial: &TimeLevel,
    c: Cotangent,
    sink: &mut Sink,
) -> Result<Cotangent, String> {
    let n = c.q.len();
    let model = s.step_model;
    let probe = TimeStep::new(
        model,
        &s.dynamics.mass,
        s.dynamics.viscosity.clone(),
        Scheme::Midpoint,
        initial.clone(),
    );
    let z = s.dynamics.mass.solve_on(&c.a, &probe.dofs, 1e-14, None)?;
    let points = &prepared.step.points;
    let p = cell_products(
        model,
        &initial.q,
        Some(&initial.v),
        &s.dynamics.viscosity,
        points,
        0.0,
        &z,
    )?;
    let mut cq = c.q.clone();
    let mut cv = c.v.clone();
    for d in 0..n {
        cq[d] -= p.stiffness[d] + p.viscous_configuration[d];
        cv[d] -= p.viscous_velocity[d];
    }
    for &(node, damping) in &model.point_dampers {
        for i in 0..3 {
            cv[node * FIELDS + i] -= damping * z[node * FIELDS + i];
        }
    }
    for m in sink.materials().to_vec() {
        let entries = sink.entries(m);
        let vjp = crate::problem::statics::parameter_vjp(
            model,
            &initial.q,
            points,
            0.0,
            m,
            Some(&entries),
            &z,
        )?;
        sink.materials_product(m, &vjp, -1.0);
    }
    for m in sink_viscous(sink) {
        let p = viscosity_vjp(model, &initial.q, &initial.v, m, &z)?;
        sink.viscosity(m, -p);
    }
    for (i, node) in sink_rigid(sink) {
        let p: f64 = (0..3)
            .map(|j| z[node * FIELDS + j] * initial.a[node * FIELDS + j])
            .sum();
        sink.rigid_mass(i, -p);
    }
    for (m, unit) in &s.unit_masses {
        let mut ma = vec![0.0; n];
        unit.mul(&initial.a, &mut ma);
        sink.density(*m, -z.iter().zip(&ma).map(|(a, b)| a * b).sum::<f64>());
    }
    sink.weights(&z, 1.0);
    // the start's potential, projected at its time with the charges the given level holds
    let mut out = vec![0.0; n];
    let start_bar = projection_adjoint(
        s,
        &mut solvers.projection,
        prepared,
        &cq,
        initial.t,
        &mut out,
        sink,
    )?;
    let mut points_bar = c.points;
    let given = s.dynamics.given.clone();
    circuit_charge_adjoint(
        s,
        &prepared.step.points,
        &given,
        &start_bar,
        &mut out,
        &mut points_bar,
        sink,
    )?;
    if !points_bar.is_empty() {
        points_bar
            .iter_mut()
            .zip(&p.points)
            .for_each(|(a, b)| *a -= b);
    }
    Ok(Cotangent {
        q: out,
        v: cv,
        a: vec![0.0; n],
        points: points_bar,
    })
}
