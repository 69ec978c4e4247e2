//! The trapezoidal discrete Lagrangian (docs/theory.md): L_d = (Δt/2)[L(q_n, v̄) + L(q_{n+1}, v̄)],
//! v̄ = (q_{n+1} − q_n)/Δt, with the reduced potential V(u, Φ*(u)) and Kelvin–Voigt forces
//! f_d⁻ = (Δt/2) f_vis(q_n, v̄), f_d⁺ = (Δt/2) f_vis(q_{n+1}, v̄). In position–momentum form:
//!   M v̄ = p_n − (Δt/2)[f(q_n) + f_vis-term at q_n],      p_{n+1} = M v̄ − (Δt/2) f(q_{n+1}, v̄),
//! with f = ∇_u V − f_ext + r_vis: the Störmer–Verlet (velocity Verlet) scheme, explicit in the
//! positions (only the mass and the viscous damping at q_n enter the step's matrix) and therefore
//! stable only for Δt < 2/ω_max. Gauss's law holds at every end point (the potential is solved at
//! q_{n+1} with the voltages at t_{n+1}). Symplectic and momentum preserving for η = 0.

use super::mass::NodalMass;
use crate::algebra::csr::CsrMatrix;
use crate::element::{KelvinVoigtKernel, MAX_LOCAL};
use crate::problem::assembly::Assembler;
use crate::problem::dofs::free_weights;
use crate::problem::dofs::{Dirichlet, DofMap, Field, CONSTRAINED, FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::{discretize, layout_of};
use crate::problem::step::{cell_products, LevelVjp, StepOperator};
use crate::solve::newton::NonlinearSystem;

/// The velocity equation of one trapezoidal step; the unknown is u_{n+1} (the potential is held).
pub struct TrapezoidalStep<'m> {
    model: Model,
    pub(crate) dofs: DofMap,
    assembler: Assembler,
    mass: &'m NodalMass,
    viscosity: Vec<f64>,
    /// q_n, v_n and the conservative forces ∇_u V − f_ext at q_n (4 per node).
    pub q_n: Vec<f64>,
    pub v_n: Vec<f64>,
    pub f_n: Vec<f64>,
    /// The iterate q_{n+1}.
    pub q: Vec<f64>,
    pub dt: f64,
    floor: f64,
    mass_positions: Vec<(usize, usize)>,
    cell_energy: Vec<f64>,
}

/// The model of a trapezoidal step's velocity equation, from the stage's model with its
/// conditions: its displacement supports, every potential held.
pub fn velocity_model(model: &Model) -> Model {
    let mut m = model.clone();
    m.dirichlet.retain(|d| d.field != Field::Phi);
    m.dirichlet.push(Dirichlet {
        nodes: (0..m.mesh.n_nodes()).collect(),
        field: Field::Phi,
        value: 0.0,
    });
    m
}

impl<'m> TrapezoidalStep<'m> {
    /// `model.dirichlet` holds the displacement supports; every potential dof is held here.
    pub fn new(model: &Model, mass: &'m NodalMass, viscosity: Vec<f64>) -> Self {
        let m = velocity_model(model);
        let (dofs, assembler, floor) = discretize(&m);
        let n = m.mesh.n_nodes() * FIELDS;
        TrapezoidalStep {
            model: m,
            dofs,
            assembler,
            mass,
            viscosity,
            q_n: vec![0.0; n],
            v_n: vec![0.0; n],
            f_n: vec![0.0; n],
            q: vec![0.0; n],
            dt: 0.0,
            floor,
            mass_positions: Vec::new(),
            cell_energy: Vec::new(),
        }
    }

    /// Flags of the free displacement dofs.
    pub fn free_u(&self) -> Vec<bool> {
        self.dofs
            .eq
            .iter()
            .enumerate()
            .map(|(d, &e)| e != CONSTRAINED && d % FIELDS != PHI)
            .collect()
    }

    fn velocity(&self) -> Vec<f64> {
        self.q
            .iter()
            .zip(&self.q_n)
            .map(|(a, b)| (a - b) / self.dt)
            .collect()
    }
}

/// Viscous dissipation power ∫ Jη d:d dV (W) at configuration `q` and velocity `v`. When
/// processes share the cells, each evaluates its own and the power is summed over them.
pub fn dissipation_power(
    model: &Model,
    viscosity: &[f64],
    q: &[f64],
    v: &[f64],
) -> Result<f64, String> {
    let (power, failure) = own_cells_power(model, viscosity, q, v);
    let mut total = [power];
    model.sum_over_processes(&mut total, failure)?;
    Ok(total[0])
}

/// The Kelvin–Voigt power of this process's own cells (all cells without a share), not summed
/// over the processes, and the cell that failed with its message, if one did.
pub(crate) fn own_cells_power(
    model: &Model,
    viscosity: &[f64],
    q: &[f64],
    v: &[f64],
) -> (f64, Option<(usize, String)>) {
    let mut total = 0.0;
    let mut r = vec![0.0; MAX_LOCAL];
    let mut vel = vec![0.0; MAX_LOCAL];
    let keep = |c: usize| viscosity[model.cell_material[c]] > 0.0 && model.owns(c);
    let outcome = model.for_each_cell_where(q, keep, |c, g, _, local| {
        let eta = viscosity[model.cell_material[c]];
        for (a, &node) in model.mesh.cell(c).iter().enumerate() {
            vel[a * FIELDS..(a + 1) * FIELDS]
                .copy_from_slice(&v[node * FIELDS..(node + 1) * FIELDS]);
        }
        total += KelvinVoigtKernel { eta }
            .forces(g, local, &vel[..local.len()], &mut r, None)
            .map_err(|e| (c, format!("cell {c}: {}", e.error)))?;
        Ok(())
    });
    (total, outcome.err())
}

/// The velocity equation R = M(v̄ − v_n) + (Δt/2)[f_n + r_vis(q_n, v̄)], v̄ = (q_{n+1} − q_n)/Δt:
/// its inputs are q_{n+1}, q_n (through v̄ and the viscous forces' configuration), v_n and the
/// forces f_n; no material parameter enters it but through f_n.
impl StepOperator for TrapezoidalStep<'_> {
    fn level_vjp(&mut self, w: &[f64]) -> Result<LevelVjp, String> {
        let (dt, vbar) = (self.dt, self.velocity());
        let weights = free_weights(&self.dofs, w);
        let p = cell_products(
            &self.model,
            &self.q_n,
            Some(&vbar),
            &self.viscosity,
            &PointStates::default(),
            dt,
            &weights,
        )?;
        let mut mw = vec![0.0; weights.len()];
        self.mass.mul(&weights, &mut mw);
        let viscous = |d: usize| 0.5 * p.viscous_velocity[d];
        Ok(LevelVjp {
            q_new: (0..mw.len()).map(|d| mw[d] / dt + viscous(d)).collect(),
            q: (0..mw.len())
                .map(|d| -mw[d] / dt - viscous(d) + 0.5 * dt * p.viscous_configuration[d])
                .collect(),
            v: mw.iter().map(|x| -x).collect(),
            forces: weights.iter().map(|x| 0.5 * dt * x).collect(),
            ..LevelVjp::default()
        })
    }

    fn parameter_vjp(
        &mut self,
        _w: &[f64],
        material: usize,
        _entries: Option<&[usize]>,
    ) -> Result<Vec<f64>, String> {
        let theta = self
            .model
            .materials
            .get(material)
            .and_then(|m| m.parameters());
        Ok(vec![0.0; theta.map_or(0, |t| t.values.len())])
    }
}

impl NonlinearSystem for TrapezoidalStep<'_> {
    fn n(&self) -> usize {
        self.dofs.n_free
    }

    fn evaluate(&mut self, r: &mut [f64], mut k: Option<&mut CsrMatrix>) -> Result<(), String> {
        let dt = self.dt;
        let vbar = self.velocity();
        let model = &self.model;
        let npc = model.mesh.kind.nodes_per_cell();
        let viscosity = &self.viscosity;
        // viscous forces at q_n with the step velocity: (Δt/2) r_vis, tangent ½ ∂r_vis/∂v
        let kernel = |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
            let nl = npc * FIELDS;
            rl[..nl].iter_mut().for_each(|v| *v = 0.0);
            let mut kl = kl;
            if let Some(kl) = kl.as_deref_mut() {
                kl[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
            }
            let eta = viscosity[model.cell_material[c]];
            if eta > 0.0 {
                let g = &*model.geometry(c);
                let mut vel = [0.0; MAX_LOCAL];
                for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                    vel[a * FIELDS..(a + 1) * FIELDS]
                        .copy_from_slice(&vbar[node * FIELDS..(node + 1) * FIELDS]);
                }
                KelvinVoigtKernel { eta }
                    .forces(g, local, &vel[..nl], rl, kl.as_deref_mut())
                    .map_err(|e| format!("{} at quadrature point {}", e.error, e.qp))?;
                rl[..nl].iter_mut().for_each(|v| *v *= 0.5 * dt);
                if let Some(kl) = kl {
                    kl[..nl * nl].iter_mut().for_each(|v| *v *= 0.5);
                }
            }
            Ok::<f64, String>(0.0)
        };
        let cells = self.assembler.assemble(
            &model.mesh,
            &self.dofs,
            &self.q_n,
            kernel,
            r,
            k.as_deref_mut(),
            &mut self.cell_energy,
        );
        self.assembler.combine(r, cells)?;
        // the terms below are no cell terms: in the residual everywhere, in the tangent once
        let k = self.assembler.global_terms(k);
        let dv: Vec<f64> = vbar.iter().zip(&self.v_n).map(|(a, b)| a - b).collect();
        let mut mdv = vec![0.0; dv.len()];
        self.mass.mul(&dv, &mut mdv);
        for (d, &e) in self.dofs.eq.iter().enumerate() {
            if e != CONSTRAINED {
                r[e] += mdv[d] + 0.5 * dt * self.f_n[d];
            }
        }
        if let Some(mut k) = k {
            if self.mass_positions.is_empty() {
                self.mass_positions = self.mass.positions_in(&self.dofs, |i, j| k.position(i, j));
            }
            let values = k.values_mut();
            for &(pos, p) in &self.mass_positions {
                values[pos] += self.mass.values[p] / dt;
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
        0
    }

    fn residual_floor(&self) -> f64 {
        self.floor * self.residual_factor()
    }

    fn residual_factor(&self) -> f64 {
        0.5 * self.dt
    }

    fn groups(&self) -> Vec<u8> {
        vec![0; self.dofs.n_free]
    }

    fn shares_cells(&self) -> bool {
        self.assembler.is_shared()
    }

    fn layout(&self) -> Option<crate::algebra::system::DofLayout> {
        Some(layout_of(&self.model, &self.dofs, &self.assembler))
    }
}
