//! The step operator: one step of any stage kind as a residual R(x_{n+1}; x_n, t, h, θ) = 0 in
//! the new state, with the vector–Jacobian products a discrete adjoint needs. The Jacobian in
//! the new state's free unknowns is [`NonlinearSystem::evaluate`]'s matrix (exact when the step
//! is asked for it); [`StepOperator::level_vjp`] gives wᵀ∂R/∂· in every other input of the
//! step's equations, [`StepOperator::parameter_vjp`] in a material's parameters.
//!
//! The products are over every dof of a nodal vector (4 per node: u in m, Φ in V), prescribed
//! ones included: the prescribed values of the new state are the drive's (electrode voltages,
//! supports), so an adjoint carries their part to the drive's parameters.

use super::circuit::CircuitStep;
use super::model::Model;
use super::points::PointStates;
use crate::algebra::system::NonlinearSystem;
use crate::element::{CellInput, KelvinVoigtKernel};
use crate::fem::{FIELDS, MAX_QP};
use crate::material::{Mat3, Vec3};

/// wᵀ∂R/∂· of a step residual in the inputs of its equations (each over every dof, 4 per node,
/// or empty when the step does not depend on it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LevelVjp {
    /// In the new state q_{n+1}: its free entries give wᵀJ, its prescribed ones the products
    /// with the drive's values.
    pub q_new: Vec<f64>,
    /// In the previous level's state q_n, velocity v_n and acceleration a_n.
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    /// In the committed internal variables of the material points at the previous level
    /// (laid out as [`PointStates::data`]).
    pub points: Vec<f64>,
    /// In each circuit's state at the start of the step: the fields of a [`CircuitStep`] hold
    /// wᵀ∂R/∂(charge, voltage, source values).
    pub circuits: Vec<CircuitStep>,
    /// In the conservative forces at the previous level that an explicit step takes as given
    /// (∇_u V − f_ext at q_n, N; their own derivatives are those of the load step that gives
    /// them).
    pub forces: Vec<f64>,
}

/// One step of a stage as a nonlinear system in its new state, with the transposed products of
/// its derivatives in everything else it depends on.
pub trait StepOperator: NonlinearSystem {
    /// wᵀ∂R/∂· at the current iterate for `w` over the free equations (the system's scaled
    /// residual): see [`LevelVjp`].
    fn level_vjp(&mut self, w: &[f64]) -> Result<LevelVjp, String>;
    /// wᵀ∂R/∂θ for the parameters of material `material` (in the order of
    /// [`crate::material::Material::parameters`]), at the current iterate: every entry, or
    /// only `entries` (the others 0; each entry costs a pass over the material's cells).
    fn parameter_vjp(
        &mut self,
        w: &[f64],
        material: usize,
        entries: Option<&[usize]>,
    ) -> Result<Vec<f64>, String>;
}

/// The transposed products of the cells' derivatives with a weight `w` over every dof, at a
/// configuration and a velocity: each over every dof, summed over the processes that share the
/// cells.
#[derive(Debug, Clone, PartialEq)]
pub struct CellProducts {
    /// Kᵀw, K = ∂f_int/∂q the consistent tangent of the internal forces at held internal
    /// variables.
    pub stiffness: Vec<f64>,
    /// (∂f_vis/∂q)ᵀw of the Kelvin–Voigt forces at held velocity.
    pub viscous_configuration: Vec<f64>,
    /// (∂f_vis/∂v)ᵀw.
    pub viscous_velocity: Vec<f64>,
    /// (∂f_int/∂ξ)ᵀw in the committed internal variables ξ (this process's, laid out as
    /// [`PointStates::data`]).
    pub points: Vec<f64>,
}

/// [`CellProducts`] of `model` at configuration `q` and velocity `v` (`None`: no viscous forces),
/// with the Kelvin–Voigt `viscosity` of each material (empty: none), the committed `points` and
/// the step `dt` of their update.
pub fn cell_products(
    model: &Model,
    q: &[f64],
    v: Option<&[f64]>,
    viscosity: &[f64],
    points: &PointStates,
    dt: f64,
    w: &[f64],
) -> Result<CellProducts, String> {
    let n = q.len();
    let mut out = CellProducts {
        stiffness: vec![0.0; n],
        viscous_configuration: vec![0.0; n],
        viscous_velocity: vec![0.0; n],
        points: vec![0.0; points.data.len()],
    };
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    let (mut r, mut k) = (vec![0.0; nl], vec![0.0; nl * nl]);
    let (mut wl, mut vl) = (vec![0.0; nl], vec![0.0; nl]);
    let kernel = model.kernel();
    let outcome = model.for_each_cell_where(
        q,
        |c| model.owns(c),
        |c, g, mat, local| {
            let nodes = model.mesh.cell(c);
            let fail = |e: crate::element::PointFailure| {
                (
                    c,
                    format!("cell {c}: {} at quadrature point {}", e.error, e.qp),
                )
            };
            gather(nodes, w, &mut wl);
            let m = model.cell_material[c];
            let hist = points.cell(c, m, dt);
            let input = CellInput {
                geom: g,
                mat,
                hist,
                local,
            };
            kernel
                .residual_tangent(&input, &mut r, Some(&mut k))
                .map_err(fail)?;
            add_transposed(&k, &wl, nodes, &mut out.stiffness);
            let eta = viscosity.get(m).copied().unwrap_or(0.0);
            if let (true, Some(v)) = (eta > 0.0, v) {
                gather(nodes, v, &mut vl);
                let kv = KelvinVoigtKernel { eta };
                k.fill(0.0);
                kv.forces(g, local, &vl, &mut r, Some(&mut k))
                    .map_err(fail)?;
                add_transposed(&k, &wl, nodes, &mut out.viscous_velocity);
                k.fill(0.0);
                kv.configuration_tangent(g, local, &vl, &mut k)
                    .map_err(fail)?;
                add_transposed(&k, &wl, nodes, &mut out.viscous_configuration);
            }
            if hist.size > 0 {
                let range = points.cell_range(c);
                let mut at = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
                let mut weights = [Mat3::zeros(); MAX_QP];
                kernel.point_deformations(&input, &mut at).map_err(fail)?;
                kernel
                    .stress_weights(&input, &wl, &mut weights)
                    .map_err(fail)?;
                for p in 0..g.n_qp {
                    let d = mat
                        .stress_state_vjp(&at[p].0, &at[p].1, hist.at(p), &weights[p])
                        .map_err(|error| fail(crate::element::PointFailure { qp: p, error }))?;
                    let start = range.start + p * hist.size;
                    out.points[start..start + hist.size].copy_from_slice(&d);
                }
            }
            Ok::<(), (usize, String)>(())
        },
    );
    let mut sums = [
        out.stiffness,
        out.viscous_configuration,
        out.viscous_velocity,
    ]
    .concat();
    model.sum_over_processes(&mut sums, outcome.err())?;
    let mut parts = sums.chunks_exact(n).map(<[f64]>::to_vec);
    out.stiffness = parts.next().unwrap_or_default();
    out.viscous_configuration = parts.next().unwrap_or_default();
    out.viscous_velocity = parts.next().unwrap_or_default();
    Ok(out)
}

/// wᵀ∂f_vis/∂η of the Kelvin–Voigt forces of material `material` at configuration `q` and
/// velocity `v` in its viscosity η (the forces are linear in η: wᵀ f_vis at η = 1), with `w`
/// over every dof; summed over the processes that share the cells.
pub fn viscosity_vjp(
    model: &Model,
    q: &[f64],
    v: &[f64],
    material: usize,
    w: &[f64],
) -> Result<f64, String> {
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    let (mut r, mut wl, mut vl) = (vec![0.0; nl], vec![0.0; nl], vec![0.0; nl]);
    let mut sum = [0.0];
    let outcome = model.for_each_cell_where(
        q,
        |c| model.owns(c) && model.cell_material[c] == material,
        |c, g, _, local| {
            let nodes = model.mesh.cell(c);
            gather(nodes, w, &mut wl);
            gather(nodes, v, &mut vl);
            r.fill(0.0);
            KelvinVoigtKernel { eta: 1.0 }
                .forces(g, local, &vl, &mut r, None)
                .map_err(|e| {
                    (
                        c,
                        format!("cell {c}: {} at quadrature point {}", e.error, e.qp),
                    )
                })?;
            sum[0] += wl.iter().zip(&r).map(|(a, b)| a * b).sum::<f64>();
            Ok::<(), (usize, String)>(())
        },
    );
    model.sum_over_processes(&mut sum, outcome.err())?;
    Ok(sum[0])
}

/// The cell's values of a nodal vector `x` (4 per node) into `local`.
fn gather(nodes: &[usize], x: &[f64], local: &mut [f64]) {
    for (a, &node) in nodes.iter().enumerate() {
        local[a * FIELDS..(a + 1) * FIELDS].copy_from_slice(&x[node * FIELDS..(node + 1) * FIELDS]);
    }
}

/// out += kᵀ w of a cell's local matrix `k` (row-major) and local weight `w`, at the cell's dofs.
fn add_transposed(k: &[f64], w: &[f64], nodes: &[usize], out: &mut [f64]) {
    let nl = w.len();
    for j in 0..nl {
        let s: f64 = (0..nl).map(|i| w[i] * k[i * nl + j]).sum();
        out[nodes[j / FIELDS] * FIELDS + j % FIELDS] += s;
    }
}
