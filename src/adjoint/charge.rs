//! The charge on an electrode by Gauss's law, Q = −Σₐ ∂Π/∂Φₐ over its nodes (the free charge
//! its source supplies, as the run records it), and the adjoint of Q: the transposed products
//! with the tangent at the state and the materials' parameter derivatives of those forces.
//! The objective reads charge probes with it, and the time steps take a circuit's start charge
//! from it.

use super::sink::Sink;
use crate::problem::dofs::{FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::statics::{nodal_reactions_with, parameter_vjp};
use crate::problem::step::cell_products;

/// Q of each electrode (its nodes in `nodes`) at `state` with the committed `points`, for the
/// model as it is meshed (before a symmetry factor).
pub fn charges(
    model: &Model,
    nodes: &[&[usize]],
    state: &[f64],
    points: &PointStates,
) -> Result<Vec<f64>, String> {
    let f = nodal_reactions_with(model, state, points, 0.0)?;
    Ok(nodes
        .iter()
        .map(|ns| -ns.iter().map(|&n| f[n * FIELDS + PHI]).sum::<f64>())
        .collect())
}

/// For the cotangents `bar` of the charges Q of the electrodes `nodes` at `state` with the
/// committed `points`: adds (∂Q/∂x)ᵀ·bar to `q_bar` (every dof), gives the materials'
/// parameters their share through `sink`, and returns (∂Q/∂ξ)ᵀ·bar in the points' internal
/// variables ξ (empty without points).
pub fn charge_adjoint(
    model: &Model,
    nodes: &[&[usize]],
    state: &[f64],
    points: &PointStates,
    bar: &[f64],
    q_bar: &mut [f64],
    sink: &mut Sink,
) -> Result<Vec<f64>, String> {
    if bar.iter().all(|&b| b == 0.0) {
        return Ok(Vec::new());
    }
    let mut w = vec![0.0; q_bar.len()];
    for (ns, &b) in nodes.iter().zip(bar) {
        for &n in ns.iter() {
            w[n * FIELDS + PHI] -= b;
        }
    }
    let p = cell_products(model, state, None, &[], points, 0.0, &w)?;
    q_bar
        .iter_mut()
        .zip(&p.stiffness)
        .for_each(|(a, b)| *a += b);
    for m in sink.materials().to_vec() {
        let entries = sink.entries(m);
        let vjp = parameter_vjp(model, state, points, 0.0, m, Some(&entries), &w)?;
        sink.materials_product(m, &vjp, 1.0);
    }
    Ok(p.points)
}
