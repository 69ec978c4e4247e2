//! One time step of the coupled problem, as a nonlinear system for Newton.
//!
//! **Midpoint variational integrator** (Marsden & West 2001; docs/theory.md): the discrete Lagrangian
//! L_d = Δt·L(q_{n+½}, (q_{n+1} − q_n)/Δt) with Kelvin–Voigt forces through the discrete
//! Lagrange–d'Alembert principle gives, in position–velocity form (p = M v),
//!   R_u = M(v̄ − v_n) + (Δt/2)[∇_u V(q_{n+½}) − f_vis(q_{n+½}, v̄) − f_ext] = 0,   v̄ = (q_{n+1} − q_n)/Δt,
//!   R_Φ = (Δt/2) ∇_Φ V(q_{n+½}) = 0   (Gauss's law at the midpoint; electrodes at V(t_{n+½})),
//!   v_{n+1} = 2v̄ − v_n.
//! The tangent M/Δt + (Δt/4)K_T + ½∂f_vis/∂v is symmetric. After each step the potential is
//! re-projected onto electrostatic equilibrium at q_{n+1} (see `stage.rs`), so that end-point
//! energies and charges are those of the reduced Lagrangian V(u, Φ*(u)).
//!
//! **Newmark** (β, γ; the conventional reference): Gauss's law and the electrodes at t_{n+1},
//!   R = βΔt²[M a_{n+1} + ∇V(q_{n+1}) + f_vis(q_{n+1}, v_{n+1}) − f_ext],
//! tangent M + βΔt² K_T + γΔt ∂f_vis/∂v.
//!
//! **The exact step Jacobian** ([`TimeStep::exact_jacobian`]) adds the configuration derivative
//! of the Kelvin–Voigt forces at fixed velocity, f_r (∂q_eval/∂q_{n+1}) ∂f_vis/∂q: (Δt/4)∂f_vis/∂q
//! for the midpoint, βΔt² ∂f_vis/∂q for Newmark. Every other term of the residual (inertia, the
//! material's consistent tangent with its internal variables, dashpots, circuits, ties of rigid
//! pads and charge-controlled electrodes through the dof map) is already in the iteration matrix.
//! The Jacobian is unsymmetric.

use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::DofLayout;
use crate::element::{CellInput, KelvinVoigtKernel, ViscousTangent, MAX_LOCAL};
use crate::problem::assembly::Assembler;
use crate::problem::circuit::CircuitStep;
use crate::problem::dofs::{free_weights, DofMap, CONSTRAINED, FIELDS, PHI};
use crate::problem::kept_tangents::{KeptTangents, Rows};
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::{discretize, layout_of};
use crate::problem::step::{
    cell_products, points_products, viscous_velocity_products, LevelVjp, StepOperator,
};
use crate::solve::newton::NonlinearSystem;
use crate::time::mass::NodalMass;
use crate::time::trapezoidal::own_cells_power;

/// An implicit time integration scheme.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Scheme {
    /// Midpoint variational integrator (symplectic, momentum preserving).
    Midpoint,
    /// Newmark with parameters β, γ (β = 1/4, γ = 1/2: the trapezoidal rule).
    Newmark { beta: f64, gamma: f64 },
}

impl Scheme {
    /// Name for messages and files.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Midpoint => "midpoint",
            Scheme::Newmark { .. } => "newmark",
        }
    }

    /// Where a step takes the electrodes' drive, weighted as its force acts over the step:
    /// (fraction of the step, weight) pairs. The midpoint rule's at t_{n+½}; Newmark's velocity
    /// update weighs the accelerations at t_n and t_{n+1} by 1 − γ and γ.
    pub fn drive_weights(self) -> Vec<(f64, f64)> {
        match self {
            Scheme::Midpoint => vec![(0.5, 1.0)],
            Scheme::Newmark { gamma, .. } => vec![(0.0, 1.0 - gamma), (1.0, gamma)],
        }
    }
}

/// The state at a time level: positions q (u in m, Φ in V, 4 per node), velocities and
/// accelerations of the displacements (4 per node, potential entries unused).
#[derive(Debug, Clone, PartialEq)]
pub struct TimeLevel {
    pub t: f64,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
}

/// The point at which a stage driver's reused iteration matrix was assembled and factored
/// (modified Newton): a resumed run re-factors there, so that it makes the same decisions, bit for
/// bit, as the run that went on.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FactorPoint {
    /// The time level the step started from: t, q, v, a.
    pub t: f64,
    pub q_prev: Vec<f64>,
    pub v_prev: Vec<f64>,
    pub a_prev: Vec<f64>,
    /// The Newton iterate at which the matrix was evaluated.
    pub q: Vec<f64>,
    /// The step size of the matrix.
    pub dt: f64,
    /// The committed internal variables of the material points the matrix was evaluated with
    /// (empty for elastic materials).
    pub points: Vec<f64>,
}

/// One step from `prev` to `prev.t + dt`, the unknown being q_{n+1}.
pub struct TimeStep<'m> {
    model: &'m Model,
    pub dofs: DofMap,
    assembler: Assembler,
    mass: &'m NodalMass,
    /// Kelvin–Voigt viscosity of each material (Pa·s).
    viscosity: Vec<f64>,
    /// Nodal forces of the model's dead loads at full value (N, `FIELDS` per node; empty without).
    dead_load: Vec<f64>,
    scheme: Scheme,
    pub prev: TimeLevel,
    /// The iterate q_{n+1}.
    pub q: Vec<f64>,
    pub dt: f64,
    floor: f64,
    /// (tangent position, mass value index) of every free u–u mass coupling, to add M to the
    /// tangent without searching.
    mass_map: Vec<(usize, usize)>,
    mass_map_built: bool,
    work_q: Vec<f64>,
    work_v: Vec<f64>,
    work_m: Vec<f64>,
    /// Each cell's viscous dissipation power at the last evaluation (W).
    cell_energy: Vec<f64>,
    /// The Kelvin–Voigt power of the last evaluation and where it was evaluated (iterate,
    /// start level, step size): the converged step's dissipation is that of Newton's last
    /// residual, which need not be evaluated again.
    power_cache: Option<(Vec<f64>, Vec<f64>, f64, f64)>,
    /// Where the matrix the solver holds was factored (see [`FactorPoint`]); `None` when the
    /// driver dropped the factorisation.
    pub factor_point: Option<FactorPoint>,
    /// Committed internal variables of the material points at `prev` (empty for elastic
    /// materials). The step's stresses come from the update over Δt to the evaluation point.
    pub points: PointStates,
    /// The model's circuits over this step (set by [`TimeStep::begin_circuits`]).
    pub circuits: Vec<CircuitStep>,
    /// The free charges the drive gives over this step, at its evaluation point (node of an
    /// electrode's potential unknown, C of the meshed part; set by the stage driver).
    pub charges: Vec<(usize, f64)>,
    /// The matrix of [`NonlinearSystem::evaluate`]: the exact (unsymmetric) Jacobian of the step
    /// residual when true, else the symmetric iteration matrix without the configuration
    /// derivative of the Kelvin–Voigt forces.
    pub exact_jacobian: bool,
    /// Keep each cell's tangents of the last evaluation with a matrix, for
    /// [`StepOperator::level_vjp`] at the same point (an adjoint's step: its transposed
    /// products then cost no second pass of cell tangents). Elastic materials on a whole model
    /// only; otherwise the products take their own pass.
    pub keep_cell_tangents: bool,
    /// Set while [`NonlinearSystem::jacobian`] evaluates: the exact Jacobian's cells skip the
    /// Kelvin–Voigt forces, which enter only the residual (then incomplete, and not returned).
    jacobian_only: bool,
    /// Per cell: ∂f_int/∂q + ∂f_vis/∂q and, with a viscosity, ∂f_vis/∂v, at the evaluation
    /// point (stamp: configuration, velocity, Δt).
    kept: KeptTangents,
}

impl<'m> TimeStep<'m> {
    /// Sets up the step operator for a model whose Dirichlet conditions hold the constrained dofs.
    pub fn new(
        model: &'m Model,
        mass: &'m NodalMass,
        viscosity: Vec<f64>,
        scheme: Scheme,
        start: TimeLevel,
    ) -> Self {
        let (dofs, assembler, floor) = discretize(model);
        let n = start.q.len();
        TimeStep {
            model,
            dofs,
            assembler,
            mass,
            viscosity,
            dead_load: if model.has_dead_loads() {
                model.dead_load_forces()
            } else {
                Vec::new()
            },
            scheme,
            q: start.q.clone(),
            prev: start,
            dt: 0.0,
            floor,
            mass_map: Vec::new(),
            mass_map_built: false,
            work_q: vec![0.0; n],
            work_v: vec![0.0; n],
            work_m: vec![0.0; n],
            cell_energy: Vec::new(),
            power_cache: None,
            factor_point: None,
            points: PointStates::default(),
            circuits: Vec::new(),
            charges: Vec::new(),
            exact_jacobian: false,
            keep_cell_tangents: false,
            jacobian_only: false,
            kept: KeptTangents::default(),
        }
    }

    /// The material points' internal variables updated over the converged step at its
    /// evaluation point (the midpoint configuration, or the end point for Newmark) — the same
    /// update whose stresses entered the step's residual — and the energy they dissipated (J).
    /// `self.points` is left as it was: the driver commits the result when it accepts the step.
    pub fn updated_points(&mut self) -> Result<(PointStates, f64), String> {
        if self.points.is_empty() {
            return Ok((PointStates::default(), 0.0));
        }
        self.evaluation_point();
        let mut points = self.points.clone();
        let dissipated = points.commit(self.model, &self.work_q, self.dt)?;
        Ok((points, dissipated))
    }

    /// wᵀ∂R/∂m of the step residual in the point mass of a node (a rigid pad's, kg): the
    /// inertia term's M·m has m at the node's displacements.
    pub fn point_mass_vjp(&self, w: &[f64], node: usize) -> f64 {
        let weights = free_weights(&self.dofs, w);
        (0..3)
            .map(|i| node * FIELDS + i)
            .map(|d| weights[d] * self.inertia_term(d))
            .sum()
    }

    /// wᵀ(∂R/∂M)·`mass` of the step residual along a mass matrix (the derivative of the mass
    /// in a density, kg per kg/m³): the inertia term's M·m with `mass` for M.
    pub fn mass_vjp(&self, w: &[f64], mass: &NodalMass) -> f64 {
        let weights = free_weights(&self.dofs, w);
        let m: Vec<f64> = (0..self.q.len()).map(|d| self.inertia_term(d)).collect();
        let mut y = vec![0.0; m.len()];
        mass.mul(&m, &mut y);
        weights.iter().zip(&y).map(|(a, b)| a * b).sum()
    }

    /// wᵀ∂R/∂η of the step residual in the Kelvin–Voigt viscosity of material `material`
    /// (Pa·s): the viscous forces enter with the factor of the internal forces at the
    /// evaluation point and velocity.
    pub fn viscosity_vjp(&mut self, w: &[f64], material: usize) -> Result<f64, String> {
        self.evaluation_point();
        let weights = free_weights(&self.dofs, w);
        let p = crate::problem::step::viscosity_vjp(
            self.model,
            &self.work_q,
            &self.work_v,
            material,
            &weights,
        )?;
        Ok(self.residual_factor() * p)
    }

    /// wᵀ∂R/∂R_c of the step residual in the series resistance of circuit `circuit` (Ω, the
    /// model's): the charge at the evaluation point is Q_n + g·(drop), g = Δt/(2R_c), so
    /// ∂Q/∂R_c = −(Q − Q_n)/R_c.
    pub fn resistance_vjp(&mut self, w: &[f64], circuit: usize) -> f64 {
        self.evaluation_point();
        let c = &self.model.circuits[circuit];
        let d = c.nodes[0] * FIELDS + PHI;
        let e = self.dofs.eq[d];
        if e == CONSTRAINED {
            return 0.0;
        }
        let st = &self.circuits[circuit];
        let midpoint = self.scheme == Scheme::Midpoint;
        let (q, _) = st.charge_at(midpoint, self.dt, c.resistance, self.work_q[d]);
        self.dofs.scale[PHI] * w[e] * self.residual_factor() * (-(q - st.charge) / c.resistance)
    }

    /// The evaluation point as a stamp of [`KeptTangents`]: configuration, velocity, Δt and the
    /// committed internal variables.
    fn evaluation_stamp(&self) -> Vec<f64> {
        let mut stamp = Vec::with_capacity(2 * self.work_q.len() + 1 + self.points.data.len());
        stamp.extend_from_slice(&self.work_q);
        stamp.extend_from_slice(&self.work_v);
        stamp.push(self.dt);
        stamp.extend_from_slice(&self.points.data);
        stamp
    }

    /// The round-off of the inertia term M·m (the residual's units): each of m's differences of
    /// displacements carries about ε times its terms, so M·m is known no closer than
    /// ε·‖M·|terms of m|‖. With short steps this exceeds the internal forces' round-off (midpoint:
    /// |q|/Δt grows as Δt falls while Δt/2·f shrinks), and Newton could not reach a floor below it.
    fn inertia_floor(&self) -> f64 {
        let dt = self.dt;
        let terms: Vec<f64> = (0..self.q.len())
            .map(|d| {
                if d % FIELDS == PHI {
                    return 0.0;
                }
                let (q, q0, v0) = (self.q[d].abs(), self.prev.q[d].abs(), self.prev.v[d].abs());
                match self.scheme {
                    Scheme::Midpoint => (q + q0) / dt + v0,
                    Scheme::Newmark { beta, .. } => {
                        q + q0
                            + dt * v0
                            + (beta * dt * dt * (0.5 / beta - 1.0) * self.prev.a[d]).abs()
                    }
                }
            })
            .collect();
        let mut mt = vec![0.0; terms.len()];
        self.mass.mul(&terms, &mut mt);
        let mut eq = vec![0.0; self.dofs.n_free];
        for (d, &e) in self.dofs.eq.iter().enumerate() {
            if e != CONSTRAINED {
                eq[e] += mt[d];
            }
        }
        f64::EPSILON * eq.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// The inertia term m of dof `d` (R gets M·m): midpoint v̄ − v_n, Newmark βΔt² a_{n+1}; 0 for
    /// a potential.
    fn inertia_term(&self, d: usize) -> f64 {
        if d % FIELDS == PHI {
            return 0.0;
        }
        let dt = self.dt;
        match self.scheme {
            Scheme::Midpoint => (self.q[d] - self.prev.q[d]) / dt - self.prev.v[d],
            Scheme::Newmark { beta, .. } => {
                self.q[d]
                    - self.prev.q[d]
                    - dt * self.prev.v[d]
                    - beta * dt * dt * (0.5 / beta - 1.0) * self.prev.a[d]
            }
        }
    }

    /// Prepares the step to `prev.t + dt`: prescribed potentials `phi_d(t)` on the electrode nodes
    /// (midpoint: set so that the midpoint potential equals the voltage at t_{n+½}), and the
    /// predictor q_{n+1} = q_n + Δt v_n.
    pub fn begin(&mut self, dt: f64, electrodes: &[(&[usize], f64, f64)]) {
        self.dt = dt;
        let n_nodes = self.q.len() / FIELDS;
        for node in 0..n_nodes {
            for i in 0..3 {
                let d = node * FIELDS + i;
                self.q[d] = if self.dofs.eq[d] == CONSTRAINED {
                    self.prev.q[d]
                } else {
                    self.prev.q[d] + dt * self.prev.v[d]
                };
            }
            self.q[node * FIELDS + PHI] = self.prev.q[node * FIELDS + PHI];
        }
        // electrodes: (nodes, voltage at t_{n+½}, voltage at t_{n+1})
        for (nodes, v_mid, v_end) in electrodes {
            for &node in nodes.iter() {
                let d = node * FIELDS + PHI;
                self.q[d] = match self.scheme {
                    Scheme::Midpoint => 2.0 * v_mid - self.prev.q[d],
                    Scheme::Newmark { .. } => *v_end,
                };
            }
        }
    }

    /// The circuits' state at the start of the step to `prev.t + dt` with their sources at
    /// t_n, t_{n+½} and t_{n+1}: each electrode's charge from Gauss's law at the start level,
    /// Q_n = −Σ ∂Π/∂Φ over its nodes (which the previous step enforced).
    pub fn begin_circuits(&mut self, sources: &[[f64; 3]]) -> Result<(), String> {
        self.circuits.clear();
        if self.model.circuits.is_empty() {
            return Ok(());
        }
        let zero = vec![0.0; self.prev.q.len()];
        let prev = self.prev.q.clone();
        let forces = self.forces_at(&prev, &zero)?;
        for (c, source) in self.model.circuits.iter().zip(sources) {
            let charge = -c
                .nodes
                .iter()
                .map(|&n| forces[n * FIELDS + PHI])
                .sum::<f64>();
            self.circuits.push(CircuitStep {
                charge,
                voltage: prev[c.nodes[0] * FIELDS + PHI],
                source: *source,
            });
        }
        Ok(())
    }

    /// The circuits' charges at t_{n+1} of the converged step, with the node of each electrode's
    /// potential unknown.
    pub fn end_charges(&mut self) -> Vec<(usize, f64)> {
        self.evaluation_point();
        let midpoint = self.scheme == Scheme::Midpoint;
        self.model
            .circuits
            .iter()
            .zip(&self.circuits)
            .map(|(c, st)| {
                let v = self.work_q[c.nodes[0] * FIELDS + PHI];
                (
                    c.nodes[0],
                    st.end_charge(midpoint, self.dt, c.resistance, v),
                )
            })
            .collect()
    }

    /// The time level reached by the converged iterate (potential not yet re-projected).
    pub fn end_level(&self) -> TimeLevel {
        let dt = self.dt;
        let mut v = self.prev.v.clone();
        let mut a = self.prev.a.clone();
        for d in 0..self.q.len() {
            if d % FIELDS == PHI {
                continue;
            }
            match self.scheme {
                Scheme::Midpoint => {
                    let vbar = (self.q[d] - self.prev.q[d]) / dt;
                    v[d] = 2.0 * vbar - self.prev.v[d];
                }
                Scheme::Newmark { beta, gamma } => {
                    let an = (self.q[d] - self.prev.q[d] - dt * self.prev.v[d]) / (beta * dt * dt)
                        - (0.5 / beta - 1.0) * self.prev.a[d];
                    v[d] = self.prev.v[d] + dt * ((1.0 - gamma) * self.prev.a[d] + gamma * an);
                    a[d] = an;
                }
            }
        }
        TimeLevel {
            t: self.prev.t + dt,
            q: self.q.clone(),
            v,
            a,
        }
    }

    /// The configuration where forces are evaluated and the velocity of the viscous forces.
    fn evaluation_point(&mut self) {
        let dt = self.dt;
        for d in 0..self.q.len() {
            match self.scheme {
                Scheme::Midpoint => {
                    self.work_q[d] = 0.5 * (self.prev.q[d] + self.q[d]);
                    self.work_v[d] = (self.q[d] - self.prev.q[d]) / dt;
                }
                Scheme::Newmark { beta, gamma } => {
                    self.work_q[d] = self.q[d];
                    let an = (self.q[d] - self.prev.q[d] - dt * self.prev.v[d]) / (beta * dt * dt)
                        - (0.5 / beta - 1.0) * self.prev.a[d];
                    self.work_v[d] =
                        self.prev.v[d] + dt * ((1.0 - gamma) * self.prev.a[d] + gamma * an);
                }
            }
        }
    }

    /// Dissipation power ∫ Jη d:d dV + Σ c|v|² (W) at the evaluation point of the current iterate.
    /// When processes share the cells, each adds its own cells' power and the sum is over the
    /// processes.
    pub fn dissipation_power(&mut self) -> Result<f64, String> {
        self.evaluation_point();
        let model = self.model;
        // this process's cells' power: the assembly's, when it evaluated the same point
        let cached = match &self.power_cache {
            Some((q, q_prev, dt, power))
                if *dt == self.dt && *q == self.q && *q_prev == self.prev.q =>
            {
                Some(*power)
            }
            _ => None,
        };
        let (qv, vv) = (&self.work_q, &self.work_v);
        let (power, failure) = match cached {
            Some(p) => (p, None),
            None => own_cells_power(model, &self.viscosity, qv, vv),
        };
        let mut cells = [power];
        model.sum_over_processes(&mut cells, failure)?;
        Ok(cells[0] + damper_power(model, vv))
    }

    /// Internal, viscous and dead-load forces f_int + f_vis − f_ext at configuration `q` and
    /// velocity `v` (N, 4 per node; potential entries are ∂Π/∂Φ), all dofs, with the committed
    /// internal variables (no relaxation). Dead loads at full value. When processes share the
    /// cells, each evaluates its own and the cell forces are summed over the processes.
    pub fn forces_at(&mut self, q: &[f64], v: &[f64]) -> Result<Vec<f64>, String> {
        let model = self.model;
        let mut out = vec![0.0; q.len()];
        let mut r = vec![0.0; MAX_LOCAL];
        let mut rv = vec![0.0; MAX_LOCAL];
        let mut vel = vec![0.0; MAX_LOCAL];
        let points = &self.points;
        let outcome = model.for_each_cell_where(
            q,
            |c| model.owns(c),
            |c, g, mat, local| {
                let nl = local.len();
                model
                    .kernel()
                    .residual_tangent(
                        &CellInput {
                            geom: g,
                            mat,
                            hist: points.cell(c, model.cell_material[c], 0.0),
                            local,
                        },
                        &mut r,
                        None,
                    )
                    .map_err(|e| (c, format!("cell {c}: {}", e.error)))?;
                let m = model.cell_material[c];
                let eta = self.viscosity[m];
                rv[..nl].iter_mut().for_each(|x| *x = 0.0);
                if eta > 0.0 {
                    for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                        vel[a * FIELDS..(a + 1) * FIELDS]
                            .copy_from_slice(&v[node * FIELDS..(node + 1) * FIELDS]);
                    }
                    KelvinVoigtKernel { eta }
                        .forces(g, local, &vel[..nl], &mut rv, None)
                        .map_err(|e| (c, format!("cell {c}: {}", e.error)))?;
                }
                for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                    for f in 0..FIELDS {
                        out[node * FIELDS + f] += r[a * FIELDS + f] + rv[a * FIELDS + f];
                    }
                }
                Ok::<(), (usize, String)>(())
            },
        );
        model.sum_over_processes(&mut out, outcome.err())?;
        for (o, f) in out.iter_mut().zip(&self.dead_load) {
            *o -= f;
        }
        for &(node, c) in &model.point_dampers {
            for i in 0..3 {
                out[node * FIELDS + i] += c * v[node * FIELDS + i];
            }
        }
        Ok(out)
    }

    /// Puts the step at a recorded factor point (a resumed run re-factors its matrix there,
    /// through whatever system holds the step); returns what [`TimeStep::leave_factor_point`]
    /// puts back.
    pub fn enter_factor_point(&mut self, point: &FactorPoint) -> FactorPoint {
        // a checkpoint of shared cells holds every cell's variables: this process's part
        let own = self.points.own_part(self.model, &point.points);
        let points = match own {
            Some(own) if own.len() == self.points.data.len() => own,
            _ => self.points.data.clone(),
        };
        let prev = std::mem::replace(
            &mut self.prev,
            TimeLevel {
                t: point.t,
                q: point.q_prev.clone(),
                v: point.v_prev.clone(),
                a: point.a_prev.clone(),
            },
        );
        FactorPoint {
            t: prev.t,
            q_prev: prev.q,
            v_prev: prev.v,
            a_prev: prev.a,
            q: std::mem::replace(&mut self.q, point.q.clone()),
            dt: std::mem::replace(&mut self.dt, point.dt),
            points: std::mem::replace(&mut self.points.data, points),
        }
    }

    /// Returns from [`TimeStep::enter_factor_point`] to the step as it was, the matrix the
    /// solver now holds being that of the factor point.
    pub fn leave_factor_point(&mut self, saved: FactorPoint) {
        let at = FactorPoint {
            t: self.prev.t,
            q_prev: std::mem::take(&mut self.prev.q),
            v_prev: std::mem::take(&mut self.prev.v),
            a_prev: std::mem::take(&mut self.prev.a),
            q: std::mem::replace(&mut self.q, saved.q),
            dt: std::mem::replace(&mut self.dt, saved.dt),
            points: std::mem::replace(&mut self.points.data, saved.points),
        };
        self.prev = TimeLevel {
            t: saved.t,
            q: saved.q_prev,
            v: saved.v_prev,
            a: saved.a_prev,
        };
        self.factor_point = Some(at);
    }
}

impl StepOperator for TimeStep<'_> {
    /// The step's equations see the previous level through the evaluation point (q_eval,
    /// v_eval), the inertia term and the circuits' charges; each input's product is a
    /// combination of the cells' transposed products at the evaluation point with the
    /// coefficients of the scheme (∂q_eval/∂x, ∂v_eval/∂x, ∂m/∂x for the inertia term M·m).
    fn level_vjp(&mut self, w: &[f64]) -> Result<LevelVjp, String> {
        self.evaluation_point();
        let (dt, model) = (self.dt, self.model);
        let weights = free_weights(&self.dofs, w);
        let n = weights.len();
        let f_r = self.residual_factor();
        // the cells' step Jacobians J_c = K + ∂f_vis/∂q + c_v ∂f_vis/∂v (c_v = f_v/f_k, as
        // the evaluation formed them), and the velocity derivative apart: the products
        // through J_c from the tangents the last evaluation kept at this point, or a pass of
        // their own; through ∂f_vis/∂v (symmetric) the forces at velocities w
        let c_v = match self.scheme {
            Scheme::Midpoint => 2.0 / dt,
            Scheme::Newmark { beta, gamma } => gamma / (beta * dt),
        };
        let kept = self
            .kept
            .products(model, &self.evaluation_stamp(), &weights);
        let (mut through_j, mut through_v, points_bar) = match kept {
            Some(j) => {
                let points = points_products(model, &self.work_q, &self.points, dt, &weights)?;
                let v = viscous_velocity_products(model, &self.work_q, &self.viscosity, &weights)?;
                (j, v, points)
            }
            None => {
                let p = cell_products(
                    model,
                    &self.work_q,
                    Some(&self.work_v),
                    &self.viscosity,
                    &self.points,
                    dt,
                    &weights,
                )?;
                let j = (0..n)
                    .map(|d| {
                        p.stiffness[d] + p.viscous_configuration[d] + c_v * p.viscous_velocity[d]
                    })
                    .collect();
                (j, p.viscous_velocity, p.points)
            }
        };
        through_j.iter_mut().for_each(|x| *x *= f_r);
        through_v.iter_mut().for_each(|x| *x *= f_r);
        // the dashpots, on the evaluation velocity alone
        let mut dampers = vec![0.0; n];
        for &(node, c) in &model.point_dampers {
            for i in 0..3 {
                dampers[node * FIELDS + i] += f_r * c * weights[node * FIELDS + i];
            }
        }
        let midpoint = self.scheme == Scheme::Midpoint;
        let mut circuits = Vec::with_capacity(model.circuits.len());
        for (c, st) in model.circuits.iter().zip(&self.circuits) {
            let d = c.nodes[0] * FIELDS + PHI;
            let wq = f_r * weights[d];
            let (_, dq) = st.charge_at(midpoint, dt, c.resistance, self.work_q[d]);
            through_j[d] += wq * dq;
            // the charge's derivatives in the circuit's start and its source: g = −dq
            circuits.push(if midpoint {
                CircuitStep {
                    charge: wq,
                    voltage: 0.0,
                    source: [0.0, -wq * dq, 0.0],
                }
            } else {
                CircuitStep {
                    charge: wq,
                    voltage: wq * dq,
                    source: [-wq * dq, 0.0, -wq * dq],
                }
            });
        }
        // the inertia term M·m over the displacements
        let mut inertia = weights.clone();
        inertia
            .iter_mut()
            .skip(PHI)
            .step_by(FIELDS)
            .for_each(|x| *x = 0.0);
        let mut mw = vec![0.0; n];
        self.mass.mul(&inertia, &mut mw);
        // (∂q_eval/∂x, ∂v_eval/∂x, ∂m/∂x) for x = q_{n+1}, q_n, v_n, a_n
        let (new, q, v, a) = match self.scheme {
            Scheme::Midpoint => (
                (0.5, 1.0 / dt, 1.0 / dt),
                (0.5, -1.0 / dt, -1.0 / dt),
                (0.0, 0.0, -1.0),
                (0.0, 0.0, 0.0),
            ),
            Scheme::Newmark { beta, gamma } => (
                (1.0, gamma / (beta * dt), 1.0),
                (0.0, -gamma / (beta * dt), -1.0),
                (0.0, 1.0 - gamma / beta, -dt),
                (
                    0.0,
                    dt * (1.0 - 0.5 * gamma / beta),
                    -dt * dt * (0.5 - beta),
                ),
            ),
        };
        // cq·(J − c_v ∂f_vis/∂v)ᵀw + cv·(∂f_vis/∂v w + dashpots) + cm·Mw
        let combine = |(cq, cv, cm): (f64, f64, f64)| -> Vec<f64> {
            (0..n)
                .map(|d| {
                    cq * through_j[d]
                        + (cv - cq * c_v) * through_v[d]
                        + cv * dampers[d]
                        + cm * mw[d]
                })
                .collect()
        };
        Ok(LevelVjp {
            q_new: combine(new),
            q: combine(q),
            v: combine(v),
            a: combine(a),
            points: points_bar.iter().map(|x| f_r * x).collect(),
            circuits,
            forces: Vec::new(),
        })
    }

    /// wᵀ ∂R/∂θ of the step residual (scaled, over the free unknowns, at the current q_{n+1}) for
    /// the parameters of material `material` ([`crate::material::Material::parameters`]): the
    /// internal forces enter R with the factor of the scheme (½Δt midpoint, βΔt² Newmark) at the
    /// evaluation point, and nothing else in R depends on a material parameter. The scaling of
    /// the unknowns (from the moduli) is held: a numerical choice, not part of the equations.
    fn parameter_vjp(
        &mut self,
        w: &[f64],
        material: usize,
        entries: Option<&[usize]>,
    ) -> Result<Vec<f64>, String> {
        self.evaluation_point();
        let f_r = match self.scheme {
            Scheme::Midpoint => 0.5 * self.dt,
            Scheme::Newmark { beta, .. } => beta * self.dt * self.dt,
        };
        let full: Vec<f64> = free_weights(&self.dofs, w)
            .into_iter()
            .map(|x| f_r * x)
            .collect();
        crate::problem::statics::parameter_vjp(
            self.model,
            &self.work_q,
            &self.points,
            self.dt,
            material,
            entries,
            &full,
        )
    }
}

impl NonlinearSystem for TimeStep<'_> {
    fn n(&self) -> usize {
        self.dofs.n_free
    }

    /// The matrix without the Kelvin–Voigt forces of the residual where it is the exact
    /// Jacobian: their pass over the cells is about 8 % of the Jacobian's.
    fn jacobian(&mut self, k: &mut CsrMatrix) -> Result<(), String> {
        let mut r = vec![0.0; self.n()];
        self.jacobian_only = true;
        let out = self.evaluate(&mut r, Some(k));
        self.jacobian_only = false;
        out
    }

    fn evaluate(&mut self, r: &mut [f64], mut k: Option<&mut CsrMatrix>) -> Result<(), String> {
        self.evaluation_point();
        let dt = self.dt;
        // factors of the internal forces, their stiffness, and the viscous velocity derivative
        let (f_r, f_k, f_v) = match self.scheme {
            Scheme::Midpoint => (0.5 * dt, 0.25 * dt, 0.5),
            Scheme::Newmark { beta, gamma } => (beta * dt * dt, beta * dt * dt, gamma * dt),
        };
        let model = self.model;
        let npc = model.mesh.kind.nodes_per_cell();
        let (viscosity, vel_all, points) = (&self.viscosity, &self.work_v, &self.points);
        let exact = self.exact_jacobian;
        let forces = !(self.jacobian_only && exact && k.is_some());
        let slots = self.kept.begin(
            model,
            self.keep_cell_tangents && exact && k.is_some(),
            Rows::All,
        );
        let keep = slots.is_some();
        // each cell's dissipation power goes into `cell_energy` (the step needs no cell energies)
        let kernel = |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
            let g = &*model.geometry(c);
            let mat = model.cell_material[c];
            let nl = npc * FIELDS;
            let eta = viscosity[mat];
            let mut vel = [0.0; MAX_LOCAL];
            if eta > 0.0 {
                for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                    vel[a * FIELDS..(a + 1) * FIELDS]
                        .copy_from_slice(&vel_all[node * FIELDS..(node + 1) * FIELDS]);
                }
            }
            let input = CellInput {
                geom: g,
                mat: model.materials[mat].as_ref(),
                hist: points.cell(c, mat, dt),
                local,
            };
            let fail = |e: crate::element::PointFailure| {
                format!("{} at quadrature point {}", e.error, e.qp)
            };
            let Some(kl) = kl else {
                let viscous = (eta > 0.0).then_some((KelvinVoigtKernel { eta }, &vel[..nl]));
                let (_, power) = model
                    .kernel()
                    .dynamic_residual(&input, viscous, f_r, rl)
                    .map_err(fail)?;
                return Ok::<f64, String>(power);
            };
            let kv_kernel = KelvinVoigtKernel { eta };
            if exact && eta > 0.0 {
                // the step Jacobian's cell matrix J_c = K + ∂f_vis/∂q + (f_v/f_k) ∂f_vis/∂v,
                // scaled by f_k (∂f_vis/∂q at fixed velocity, through the evaluation point:
                // f_r ∂q_eval/∂q = f_k): from the kernel's point blocks where it forms them,
                // else from the two viscous matrices
                let viscous = ViscousTangent {
                    eta,
                    vel: &vel[..nl],
                    cv: f_v / f_k,
                };
                let mut rv = [0.0; MAX_LOCAL];
                let power = match model
                    .kernel()
                    .residual_viscous_tangent(&input, &viscous, rl, kl)
                {
                    Some(fused) => {
                        fused.map_err(fail)?;
                        if forces {
                            kv_kernel
                                .forces(g, local, &vel[..nl], &mut rv, None)
                                .map_err(fail)?
                        } else {
                            0.0
                        }
                    }
                    None => {
                        model
                            .kernel()
                            .residual_tangent(&input, rl, Some(&mut *kl))
                            .map_err(fail)?;
                        let (mut kv, mut kq) = (vec![0.0; nl * nl], vec![0.0; nl * nl]);
                        let power = kv_kernel
                            .forces(g, local, &vel[..nl], &mut rv, Some(&mut kv))
                            .map_err(fail)?;
                        kv_kernel
                            .configuration_tangent(g, local, &vel[..nl], &mut kq)
                            .map_err(fail)?;
                        for i in 0..nl * nl {
                            kl[i] += kq[i] + viscous.cv * kv[i];
                        }
                        power
                    }
                };
                // this cell's slot, filled only here (each cell is evaluated once per assembly)
                if let Some(s) = slots {
                    KeptTangents::keep(s, c, kl, nl, Rows::All);
                }
                for i in 0..nl {
                    rl[i] = f_r * rl[i] + f_r * rv[i];
                }
                kl[..nl * nl].iter_mut().for_each(|v| *v *= f_k);
                return Ok(power);
            }
            model
                .kernel()
                .residual_tangent(&input, rl, Some(&mut *kl))
                .map_err(fail)?;
            if let Some(s) = slots {
                KeptTangents::keep(s, c, kl, nl, Rows::All);
            }
            rl[..nl].iter_mut().for_each(|v| *v *= f_r);
            kl[..nl * nl].iter_mut().for_each(|v| *v *= f_k);
            let mut power = 0.0;
            if eta > 0.0 {
                // the iteration matrix: the velocity derivative only (symmetric)
                let mut rv = [0.0; MAX_LOCAL];
                let mut kv = vec![0.0; nl * nl];
                power = kv_kernel
                    .forces(g, local, &vel[..nl], &mut rv, Some(&mut kv))
                    .map_err(fail)?;
                for i in 0..nl {
                    rl[i] += f_r * rv[i];
                }
                for i in 0..nl * nl {
                    kl[i] += f_v * kv[i];
                }
            }
            Ok::<f64, String>(power)
        };
        let (q_eval, dofs) = (&self.work_q, &self.dofs);
        let cells = self.assembler.assemble(
            &model.mesh,
            dofs,
            q_eval,
            kernel,
            r,
            k.as_deref_mut(),
            &mut self.cell_energy,
        );
        self.assembler.combine(r, cells)?;
        if keep {
            let stamp = self.evaluation_stamp();
            self.kept.filled_at(stamp);
        }
        // the power of this process's cells summed in cell order, as `dissipation_power` does
        if forces {
            let power = self.cell_energy.iter().fold(0.0, |t, p| t + p);
            let mut cache = self.power_cache.take().unwrap_or_default();
            cache.0.clone_from(&self.q);
            cache.1.clone_from(&self.prev.q);
            (cache.2, cache.3) = (dt, power);
            self.power_cache = Some(cache);
        }
        // the terms below are no cell terms: in the residual everywhere, in the tangent once
        let mut k = self.assembler.global_terms(k);
        // dead loads at full value, with the factor of the internal forces: −f_r·f_ext
        let (eq, scale) = (&self.dofs.eq, self.dofs.scale);
        for (d, &f) in self.dead_load.iter().enumerate() {
            let e = eq[d];
            if e != CONSTRAINED && f != 0.0 {
                r[e] -= scale[d % FIELDS] * f_r * f;
            }
        }
        // circuits: the charge at the evaluation point on the electrode's Gauss equation
        let midpoint = self.scheme == Scheme::Midpoint;
        for (c, st) in model.circuits.iter().zip(&self.circuits) {
            let d = c.nodes[0] * FIELDS + PHI;
            let e = eq[d];
            if e == CONSTRAINED {
                continue;
            }
            let (q, dq) = st.charge_at(midpoint, dt, c.resistance, self.work_q[d]);
            r[e] += scale[PHI] * f_r * q;
            if let Some(k) = k.as_mut() {
                // ∂V_eval/∂V_{n+1}: ½ at the midpoint, 1 at the end point
                let dv = if midpoint { 0.5 } else { 1.0 };
                k.add(e, e, scale[PHI] * scale[PHI] * f_r * dq * dv);
            }
        }
        // the drive's free charges, +Q on their electrodes' Gauss equations
        for &(node, q) in &self.charges {
            let e = eq[node * FIELDS + PHI];
            if e != CONSTRAINED {
                r[e] += scale[PHI] * f_r * q;
            }
        }
        // dashpots c·v at the evaluation velocity, like the viscous forces
        for &(node, c) in &model.point_dampers {
            for i in 0..3 {
                let d = node * FIELDS + i;
                let e = eq[d];
                if e == CONSTRAINED {
                    continue;
                }
                r[e] += scale[i] * f_r * c * self.work_v[d];
                if let Some(k) = k.as_mut() {
                    k.add(e, e, scale[i] * scale[i] * f_v * c);
                }
            }
        }
        // inertia: midpoint M(v̄ − v_n); Newmark βΔt² M a_{n+1}
        for d in 0..self.q.len() {
            self.work_m[d] = self.inertia_term(d);
        }
        let mut mv = vec![0.0; self.q.len()];
        self.mass.mul(&self.work_m, &mut mv);
        for (d, &e) in self.dofs.eq.iter().enumerate() {
            if e != CONSTRAINED && d % FIELDS != PHI {
                r[e] += mv[d];
            }
        }
        if let Some(mut k) = k {
            if !self.mass_map_built {
                self.mass_map = self.mass.positions_in(&self.dofs, |i, j| k.position(i, j));
                self.mass_map_built = true;
            }
            let factor = match self.scheme {
                Scheme::Midpoint => 1.0 / dt,
                Scheme::Newmark { .. } => 1.0,
            };
            let values = k.values_mut();
            for &(pos, p) in &self.mass_map {
                values[pos] += factor * self.mass.values[p];
            }
        }
        Ok(())
    }

    fn increment(&mut self, dx: &[f64], alpha: f64) {
        self.dofs.add_scaled(&mut self.q, dx, alpha);
    }

    fn snapshot(&self) -> Vec<f64> {
        self.q.clone()
    }

    fn restore(&mut self, s: &[f64]) {
        self.q.copy_from_slice(s);
    }

    fn new_matrix(&self) -> CsrMatrix {
        self.assembler.new_matrix()
    }

    fn expected_negative_pivots(&self) -> usize {
        self.dofs.n_free_phi
    }

    fn residual_floor(&self) -> f64 {
        self.floor * self.residual_factor() + self.inertia_floor()
    }

    fn residual_factor(&self) -> f64 {
        // the residual carries the factor of the internal forces
        let f = match self.scheme {
            Scheme::Midpoint => 0.5 * self.dt,
            Scheme::Newmark { beta, .. } => beta * self.dt * self.dt,
        };
        f.max(1e-300)
    }

    fn groups(&self) -> Vec<u8> {
        self.dofs.groups()
    }

    fn shares_cells(&self) -> bool {
        self.assembler.is_shared()
    }

    fn layout(&self) -> Option<DofLayout> {
        Some(layout_of(self.model, &self.dofs, &self.assembler))
    }

    fn factored(&mut self) {
        self.factor_point = Some(FactorPoint {
            t: self.prev.t,
            q_prev: self.prev.q.clone(),
            v_prev: self.prev.v.clone(),
            a_prev: self.prev.a.clone(),
            q: self.q.clone(),
            dt: self.dt,
            points: self.points.data.clone(),
        });
    }
}

/// Power Σ c|v|² (W) of the model's dashpots at velocity `v` (4 values per node).
pub fn damper_power(model: &Model, v: &[f64]) -> f64 {
    model
        .point_dampers
        .iter()
        .map(|&(node, c)| c * (0..3).map(|i| v[node * FIELDS + i].powi(2)).sum::<f64>())
        .sum()
}
