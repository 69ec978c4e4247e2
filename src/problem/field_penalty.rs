//! A smooth penalty on the true electric field above a limit, the breakdown margin of an
//! objective: P(x) = ½ ∫ max(0, |E| − E_lim)² dV over the reference volume, with the true field
//! E = F⁻ᵀE₀ of each quadrature point (|E|² = E₀·C⁻¹E₀), and its gradient in the state x. The
//! square of the excess is continuously differentiable, so gradient-based drives and fits see it
//! grow from zero as the field passes the limit.
//!
//! With b = C⁻¹E₀ the derivatives of |E|² are ∂|E|²/∂Φ_a = −2 b·∇N_a (from δE₀ = −Σ δΦ_a ∇N_a)
//! and ∂|E|²/∂u_a = −2 (F b)(∇N_a·b) (from δC⁻¹ = −C⁻¹ δC C⁻¹, δF = Σ δu_a ⊗ ∇N_a); in a
//! meridian cell the hoop stretch does not enter, since E₀ has no hoop component and C is
//! block-diagonal.

use crate::fem::axisymmetric::meridian_kinematics;
use crate::fem::kinematics;
use crate::problem::dofs::{FIELDS, PHI};
use crate::problem::model::Model;

/// P at `state` (`FIELDS` values per node) for the limit `limit` (V/m), and ∂P/∂x (same layout)
/// when `gradient` is given (added to it). An inverted cell is an error naming it.
pub fn field_penalty(
    model: &Model,
    state: &[f64],
    limit: f64,
    mut gradient: Option<&mut [f64]>,
) -> Result<f64, String> {
    let mut total = 0.0;
    model.for_each_cell(state, |c, g, _, local| {
        let n = g.n_nodes;
        let mut u = [[0.0; 3]; crate::fem::MAX_NODES];
        let mut phi = [0.0; crate::fem::MAX_NODES];
        for a in 0..n {
            u[a] = [
                local[a * FIELDS],
                local[a * FIELDS + 1],
                local[a * FIELDS + 2],
            ];
            phi[a] = local[a * FIELDS + PHI];
        }
        let cell = model.mesh.cell(c);
        for q in 0..g.n_qp {
            let (f, e0) = if g.axisymmetric {
                u[..n].iter_mut().for_each(|ua| ua[2] = 0.0);
                meridian_kinematics(&g.grad[q][..n], &g.hoop(q)[..n], &u[..n], &phi[..n])
            } else {
                kinematics(&g.grad[q][..n], &u[..n], &phi[..n])
            };
            let c_inv = (f.transpose() * f)
                .try_inverse()
                .ok_or_else(|| format!("field penalty: cell {c} is inverted"))?;
            let b = c_inv * e0;
            let e = e0.dot(&b).max(0.0).sqrt();
            let excess = e - limit;
            if excess <= 0.0 {
                continue;
            }
            let w = g.weights[q];
            total += 0.5 * w * excess * excess;
            let Some(grad) = gradient.as_deref_mut() else {
                continue;
            };
            // ∂P/∂x = w · excess · ∂|E|/∂x, ∂|E| = ∂|E|² / (2|E|)
            let s = w * excess / e;
            let fb = f * b;
            let dims = if g.axisymmetric { 2 } else { 3 };
            for (a, &node) in cell.iter().enumerate() {
                let gb: f64 = (0..3).map(|j| g.grad[q][a][j] * b[j]).sum();
                for i in 0..dims {
                    grad[node * FIELDS + i] -= s * fb[i] * gb;
                }
                grad[node * FIELDS + PHI] -= s * gb;
            }
        }
        Ok::<(), String>(())
    })?;
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElectroNeoHooke;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::meridian::rectangle_mesh;
    use crate::mesh::{ElementKind, MeridianKind};
    use std::sync::Arc;

    /// A deformed, charged state: smooth displacements and a potential whose field runs from
    /// below the limit to well above it across the body.
    fn state_of(model: &Model, seed: f64) -> Vec<f64> {
        let mut x = vec![0.0; model.mesh.n_nodes() * FIELDS];
        for (a, p) in model.mesh.nodes.iter().enumerate() {
            let [px, py, pz] = *p;
            x[a * FIELDS] = 0.1e-3 * (seed * px * 1e3).sin();
            x[a * FIELDS + 1] = -0.05e-3 * (py * 1e3 + seed).cos();
            if !model.is_axisymmetric() {
                x[a * FIELDS + 2] = -0.2 * pz * (1.0 + 0.1 * (px * 1e3).sin());
            }
            let height = if model.is_axisymmetric() { py } else { pz };
            x[a * FIELDS + PHI] = 2e4 * height * 1e3 * (1.0 + 0.3 * (px * 1e3 + seed).sin());
        }
        x
    }

    /// The hand-written gradient equals central differences of P, on 3-D and meridian cells.
    #[test]
    fn gradient_matches_central_differences() {
        let material = Arc::new(ElectroNeoHooke::new(1e5, 1e7, 4.7));
        let models = [
            Model::new(
                box_mesh([2e-3, 2e-3, 1e-3], [2, 2, 2], ElementKind::Hex8),
                material.clone(),
            )
            .unwrap(),
            Model::new(
                rectangle_mesh(0.0, 2e-3, 1e-3, 3, 2, MeridianKind::Quad8).unwrap(),
                material,
            )
            .unwrap(),
        ];
        for model in &models {
            let x = state_of(model, 0.7);
            let limit = 1.5e7;
            let mut g = vec![0.0; x.len()];
            let p = field_penalty(model, &x, limit, Some(&mut g)).unwrap();
            assert!(p > 0.0);
            let mut worst: f64 = 0.0;
            let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for d in 0..x.len() {
                if model.is_axisymmetric() && d % FIELDS == 2 {
                    assert_eq!(g[d], 0.0);
                    continue;
                }
                let h = if d % FIELDS == PHI { 1e-3 } else { 1e-9 };
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[d] += h;
                xm[d] -= h;
                let fd = (field_penalty(model, &xp, limit, None).unwrap()
                    - field_penalty(model, &xm, limit, None).unwrap())
                    / (2.0 * h);
                worst = worst.max((fd - g[d]).abs() / scale);
            }
            assert!(
                worst < 1e-6,
                "axisymmetric {}: {worst:e}",
                model.is_axisymmetric()
            );
            // below the limit everywhere: no penalty and no gradient
            let mut g0 = vec![0.0; x.len()];
            assert_eq!(field_penalty(model, &x, 1e12, Some(&mut g0)).unwrap(), 0.0);
            assert!(g0.iter().all(|&v| v == 0.0));
        }
    }
}
