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
use super::kept_tangents::transposed_product;
use super::model::Model;
use super::points::PointStates;
use crate::algebra::system::NonlinearSystem;
use crate::element::{CellInput, KelvinVoigtKernel, MAX_LOCAL};
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
    let kernel = model.kernel();
    // one cell's products (kᵀw at its dofs for the three matrices, and its points'), each
    // computed alone so that the cells may run on the pool
    let eval = |c: usize| -> Result<CellProduct, (usize, String)> {
        let nodes = model.mesh.cell(c);
        let fail = |e: crate::element::PointFailure| {
            (
                c,
                format!("cell {c}: {} at quadrature point {}", e.error, e.qp),
            )
        };
        let (mut local, mut wl) = ([0.0; MAX_LOCAL], [0.0; MAX_LOCAL]);
        gather(nodes, q, &mut local[..nl]);
        gather(nodes, w, &mut wl[..nl]);
        let (local, wl) = (&local[..nl], &wl[..nl]);
        let m = model.cell_material[c];
        let mat = model.materials[m].as_ref();
        let g = &*model.geometry(c);
        let hist = points.cell(c, m, dt);
        let input = CellInput {
            geom: g,
            mat,
            hist,
            local,
        };
        let mut r = [0.0; MAX_LOCAL];
        let mut k = vec![0.0; nl * nl];
        let mut cell = CellProduct {
            stiffness: [0.0; MAX_LOCAL],
            viscous_configuration: [0.0; MAX_LOCAL],
            viscous_velocity: [0.0; MAX_LOCAL],
            points: Vec::new(),
        };
        kernel
            .residual_tangent(&input, &mut r[..nl], Some(&mut k))
            .map_err(fail)?;
        transposed_product(&k, wl, &mut cell.stiffness[..nl]);
        let eta = viscosity.get(m).copied().unwrap_or(0.0);
        if let (true, Some(v)) = (eta > 0.0, v) {
            let mut vl = [0.0; MAX_LOCAL];
            gather(nodes, v, &mut vl[..nl]);
            let kv = KelvinVoigtKernel { eta };
            k.fill(0.0);
            kv.forces(g, local, &vl[..nl], &mut r[..nl], Some(&mut k))
                .map_err(fail)?;
            transposed_product(&k, wl, &mut cell.viscous_velocity[..nl]);
            k.fill(0.0);
            kv.configuration_tangent(g, local, &vl[..nl], &mut k)
                .map_err(fail)?;
            transposed_product(&k, wl, &mut cell.viscous_configuration[..nl]);
        }
        cell_points_product(kernel, &input, wl, &mut cell.points).map_err(fail)?;
        Ok(cell)
    };
    // the cells' products added in cell order on either path (the same sums, bit for bit)
    let mut failure = None;
    let mut add = |c: usize, cell: Result<CellProduct, (usize, String)>| match cell {
        Ok(cell) => {
            let nodes = model.mesh.cell(c);
            scatter(nodes, &cell.stiffness[..nl], &mut out.stiffness);
            scatter(
                nodes,
                &cell.viscous_configuration[..nl],
                &mut out.viscous_configuration,
            );
            scatter(
                nodes,
                &cell.viscous_velocity[..nl],
                &mut out.viscous_velocity,
            );
            if !cell.points.is_empty() {
                let range = points.cell_range(c);
                out.points[range].copy_from_slice(&cell.points);
            }
            true
        }
        Err(e) => {
            failure = Some(e);
            false
        }
    };
    let cells: Vec<usize> = (0..model.mesh.n_cells())
        .filter(|&c| model.owns(c))
        .collect();
    for (&c, cell) in cells
        .iter()
        .zip(crate::problem::assembly::map_cells(&cells, eval))
    {
        if !add(c, cell) {
            break;
        }
    }
    let mut sums = [
        out.stiffness,
        out.viscous_configuration,
        out.viscous_velocity,
    ]
    .concat();
    model.sum_over_processes(&mut sums, failure)?;
    let mut parts = sums.chunks_exact(n).map(<[f64]>::to_vec);
    out.stiffness = parts.next().unwrap_or_default();
    out.viscous_configuration = parts.next().unwrap_or_default();
    out.viscous_velocity = parts.next().unwrap_or_default();
    Ok(out)
}

/// A cell's part of (∂f_int/∂ξ)ᵀw in its points' committed internal variables ξ (nothing
/// without them), appended to `out` point by point, for the local weight `wl`.
fn cell_points_product(
    kernel: &dyn crate::element::CellKernel,
    input: &CellInput,
    wl: &[f64],
    out: &mut Vec<f64>,
) -> Result<(), crate::element::PointFailure> {
    let (g, mat, hist) = (input.geom, input.mat, input.hist);
    if hist.size == 0 {
        return Ok(());
    }
    let mut at = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
    let mut weights = [Mat3::zeros(); MAX_QP];
    kernel.point_deformations(input, &mut at)?;
    kernel.stress_weights(input, wl, &mut weights)?;
    for p in 0..g.n_qp {
        let d = mat
            .stress_state_vjp(&at[p].0, &at[p].1, hist.at(p), &weights[p])
            .map_err(|error| crate::element::PointFailure { qp: p, error })?;
        out.extend_from_slice(&d);
    }
    Ok(())
}

/// (∂f_int/∂ξ)ᵀw in the committed internal variables ξ of `points` (laid out as
/// [`PointStates::data`]) at configuration `q`, with the step `dt` of their update: the points'
/// part of [`cell_products`] alone, for an adjoint whose stiffness products come from the
/// cell tangents its evaluation kept (a pass of kinematics and point products, no tangent).
pub fn points_products(
    model: &Model,
    q: &[f64],
    points: &PointStates,
    dt: f64,
    w: &[f64],
) -> Result<Vec<f64>, String> {
    let mut out = vec![0.0; points.data.len()];
    if points.is_empty() {
        return Ok(out);
    }
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    let kernel = model.kernel();
    let eval = |c: usize| -> Result<Vec<f64>, String> {
        let nodes = model.mesh.cell(c);
        let (mut local, mut wl) = ([0.0; MAX_LOCAL], [0.0; MAX_LOCAL]);
        gather(nodes, q, &mut local[..nl]);
        gather(nodes, w, &mut wl[..nl]);
        let m = model.cell_material[c];
        let input = CellInput {
            geom: &model.geometry(c),
            mat: model.materials[m].as_ref(),
            hist: points.cell(c, m, dt),
            local: &local[..nl],
        };
        let mut cell = Vec::new();
        cell_points_product(kernel, &input, &wl[..nl], &mut cell)
            .map_err(|e| format!("cell {c}: {} at quadrature point {}", e.error, e.qp))?;
        Ok(cell)
    };
    let cells: Vec<usize> = (0..model.mesh.n_cells())
        .filter(|&c| model.owns(c) && !points.cell_range(c).is_empty())
        .collect();
    for (&c, cell) in cells
        .iter()
        .zip(crate::problem::assembly::map_cells(&cells, eval))
    {
        out[points.cell_range(c)].copy_from_slice(&cell?);
    }
    Ok(out)
}

/// (∂f_vis/∂v)ᵀw of the Kelvin–Voigt forces at configuration `q`, with the `viscosity` of each
/// material (empty or 0: none) and `w` over every dof: the forces are linear in the nodal
/// velocities and their derivative symmetric, so it is the forces at velocities `w`. For an
/// adjoint whose other products come from the cell tangents its evaluation kept (a pass of
/// kinematics, no tangent); the cells on the pool, summed in cell order.
pub fn viscous_velocity_products(
    model: &Model,
    q: &[f64],
    viscosity: &[f64],
    w: &[f64],
) -> Result<Vec<f64>, String> {
    let mut out = vec![0.0; q.len()];
    let eta = |c: usize| {
        viscosity
            .get(model.cell_material[c])
            .copied()
            .unwrap_or(0.0)
    };
    let cells: Vec<usize> = (0..model.mesh.n_cells())
        .filter(|&c| model.owns(c) && eta(c) > 0.0)
        .collect();
    if cells.is_empty() {
        return Ok(out);
    }
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    let eval = |c: usize| -> Result<[f64; MAX_LOCAL], String> {
        let nodes = model.mesh.cell(c);
        let (mut local, mut wl, mut r) = ([0.0; MAX_LOCAL], [0.0; MAX_LOCAL], [0.0; MAX_LOCAL]);
        gather(nodes, q, &mut local[..nl]);
        gather(nodes, w, &mut wl[..nl]);
        KelvinVoigtKernel { eta: eta(c) }
            .forces(
                &model.geometry(c),
                &local[..nl],
                &wl[..nl],
                &mut r[..nl],
                None,
            )
            .map_err(|e| format!("cell {c}: {} at quadrature point {}", e.error, e.qp))?;
        Ok(r)
    };
    for (&c, cell) in cells
        .iter()
        .zip(crate::problem::assembly::map_cells(&cells, eval))
    {
        scatter(model.mesh.cell(c), &cell?[..nl], &mut out);
    }
    Ok(out)
}

/// One cell's part of [`CellProducts`]: the products at its local dofs, and its points'.
struct CellProduct {
    stiffness: [f64; MAX_LOCAL],
    viscous_configuration: [f64; MAX_LOCAL],
    viscous_velocity: [f64; MAX_LOCAL],
    points: Vec<f64>,
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

/// out += a cell's local vector `local` at the cell's dofs.
fn scatter(nodes: &[usize], local: &[f64], out: &mut [f64]) {
    for (j, &v) in local.iter().enumerate() {
        out[nodes[j / FIELDS] * FIELDS + j % FIELDS] += v;
    }
}
