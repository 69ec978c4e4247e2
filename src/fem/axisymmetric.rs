//! Meridian elements of the axisymmetric model: cells on the (R, Z) half-plane R ≥ 0, each
//! standing for the ring it sweeps about the Z axis.
//!
//! Kinematics (Zienkiewicz & Taylor, The Finite Element Method, vol. 1, axisymmetric stress
//! analysis): with the displacement (u_r, u_z)(R, Z) and the potential Φ(R, Z),
//! F = [[∂r/∂R, ∂r/∂Z, 0], [∂z/∂R, ∂z/∂Z, 0], [0, 0, 1 + u_r/R]] and E₀ = (−∂Φ/∂R, −∂Φ/∂Z, 0),
//! in the basis (e_R, e_Z, e_Θ); the volume element is 2πR dR dZ, so cell integrals are values of
//! the whole ring. The hoop stretch is interpolated as 1 + Σ u_{r,a} N_a/R at the quadrature
//! points, which are interior, so R > 0 there whenever the cell has R ≥ 0 at its nodes and a
//! positive Jacobian.
//!
//! Nodal layout: the node-major four unknowns of the 3-D model are kept, slot 0 = u_r, slot 1 =
//! u_z, slot 2 unused (held at zero by a Dirichlet condition; the meridian kernel neither reads
//! it nor gives it a residual) and slot 3 = Φ.

use super::{CellGeometry, MAX_NODES, MAX_QP};
use crate::material::{Mat3, Vec3};

pub use crate::mesh::MeridianKind;

/// Quadrature points and weights of a meridian kind in its reference cell: 2 × 2 Gauss points
/// (quad4), 3 × 3 (quad8, quad9), the centroid (tri3), the 3-point interior rule of degree 2
/// (tri6).
pub fn meridian_quadrature(kind: MeridianKind) -> Vec<([f64; 2], f64)> {
    let gauss = |pts: &[(f64, f64)]| {
        let mut out = Vec::new();
        for &(y, wy) in pts {
            for &(x, wx) in pts {
                out.push(([x, y], wx * wy));
            }
        }
        out
    };
    match kind {
        MeridianKind::Quad4 => {
            let g = 1.0 / 3f64.sqrt();
            gauss(&[(-g, 1.0), (g, 1.0)])
        }
        MeridianKind::Quad8 | MeridianKind::Quad9 => {
            let g = (0.6f64).sqrt();
            gauss(&[(-g, 5.0 / 9.0), (0.0, 8.0 / 9.0), (g, 5.0 / 9.0)])
        }
        MeridianKind::Tri3 => vec![([1.0 / 3.0, 1.0 / 3.0], 0.5)],
        MeridianKind::Tri6 => vec![
            ([1.0 / 6.0, 1.0 / 6.0], 1.0 / 6.0),
            ([2.0 / 3.0, 1.0 / 6.0], 1.0 / 6.0),
            ([1.0 / 6.0, 2.0 / 3.0], 1.0 / 6.0),
        ],
    }
}

/// Shape functions N_a(ξ) and their reference gradients of a meridian kind.
pub fn meridian_shape_functions(kind: MeridianKind, xi: [f64; 2]) -> (Vec<f64>, Vec<[f64; 2]>) {
    let (x, y) = (xi[0], xi[1]);
    match kind {
        MeridianKind::Quad4 => {
            let c = &kind.reference_nodes();
            let n = c
                .iter()
                .map(|a| 0.25 * (1.0 + a[0] * x) * (1.0 + a[1] * y))
                .collect();
            let dn = c
                .iter()
                .map(|a| {
                    [
                        0.25 * a[0] * (1.0 + a[1] * y),
                        0.25 * (1.0 + a[0] * x) * a[1],
                    ]
                })
                .collect();
            (n, dn)
        }
        MeridianKind::Quad8 => {
            let c = kind.reference_nodes();
            let mut n = Vec::with_capacity(8);
            let mut dn = Vec::with_capacity(8);
            for a in &c {
                let (xa, ya) = (a[0], a[1]);
                if xa != 0.0 && ya != 0.0 {
                    let (p, q, s) = (1.0 + xa * x, 1.0 + ya * y, xa * x + ya * y - 1.0);
                    n.push(0.25 * p * q * s);
                    dn.push([
                        0.25 * (xa * q * s + p * q * xa),
                        0.25 * (p * ya * s + p * q * ya),
                    ]);
                } else if xa == 0.0 {
                    n.push(0.5 * (1.0 - x * x) * (1.0 + ya * y));
                    dn.push([-x * (1.0 + ya * y), 0.5 * (1.0 - x * x) * ya]);
                } else {
                    n.push(0.5 * (1.0 + xa * x) * (1.0 - y * y));
                    dn.push([0.5 * xa * (1.0 - y * y), -(1.0 + xa * x) * y]);
                }
            }
            (n, dn)
        }
        MeridianKind::Quad9 => {
            // 1-D quadratic Lagrange polynomials at −1, 0, 1
            let l = |t: f64, a: f64| -> (f64, f64) {
                if a < 0.0 {
                    (0.5 * t * (t - 1.0), t - 0.5)
                } else if a > 0.0 {
                    (0.5 * t * (t + 1.0), t + 0.5)
                } else {
                    (1.0 - t * t, -2.0 * t)
                }
            };
            let c = kind.reference_nodes();
            let mut n = Vec::with_capacity(9);
            let mut dn = Vec::with_capacity(9);
            for a in &c {
                let (lx, dlx) = l(x, a[0]);
                let (ly, dly) = l(y, a[1]);
                n.push(lx * ly);
                dn.push([dlx * ly, lx * dly]);
            }
            (n, dn)
        }
        MeridianKind::Tri3 | MeridianKind::Tri6 => {
            let l = [1.0 - x - y, x, y];
            let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
            if kind == MeridianKind::Tri3 {
                return (l.to_vec(), dl.to_vec());
            }
            let mut n = Vec::with_capacity(6);
            let mut dn = Vec::with_capacity(6);
            for a in 0..3 {
                n.push(l[a] * (2.0 * l[a] - 1.0));
                dn.push(dl[a].map(|d| (4.0 * l[a] - 1.0) * d));
            }
            for [i, j] in [[0, 1], [1, 2], [2, 0]] {
                n.push(4.0 * l[i] * l[j]);
                dn.push([0, 1].map(|k| 4.0 * (dl[i][k] * l[j] + l[i] * dl[j][k])));
            }
            (n, dn)
        }
    }
}

/// Why a meridian cell has no geometry.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MeridianCellError {
    /// A node left of the axis (R < 0), or a cell crossing it.
    #[error("node {node} of the cell has R = {r} m < 0 (a meridian cell must lie in R ≥ 0)")]
    NegativeRadius { node: usize, r: f64 },
    /// The Jacobian is not positive at a quadrature point, or the point lies on the axis.
    #[error(
        "the cell is inverted or degenerate at quadrature point {qp} (det = {det}, R = {r} m)"
    )]
    Degenerate { qp: usize, det: f64, r: f64 },
}

/// The geometry of a meridian cell with nodes `x` = (R, Z) (m): gradients (∂N/∂R, ∂N/∂Z, 0),
/// ring weights 2πR·w·det J (m³) and the hoop row N_a/R (1/m).
pub fn meridian_geometry(
    kind: MeridianKind,
    x: &[[f64; 2]],
) -> Result<CellGeometry, MeridianCellError> {
    let n = kind.nodes_per_cell();
    for (a, xa) in x[..n].iter().enumerate() {
        if xa[0].is_nan() || xa[0] < 0.0 {
            return Err(MeridianCellError::NegativeRadius { node: a, r: xa[0] });
        }
    }
    let rule = meridian_quadrature(kind);
    let mut g = CellGeometry {
        n_nodes: n,
        n_qp: rule.len(),
        grad: [[[0.0; 3]; MAX_NODES]; MAX_QP],
        weights: [0.0; MAX_QP],
        hoop: None,
        axisymmetric: true,
    };
    let mut hoop = Box::new([[0.0; MAX_NODES]; MAX_QP]);
    for (q, (xi, wq)) in rule.iter().enumerate() {
        let (nv, dn) = meridian_shape_functions(kind, *xi);
        let mut jac = [[0.0; 2]; 2];
        let mut r = 0.0;
        for a in 0..n {
            r += nv[a] * x[a][0];
            for i in 0..2 {
                for j in 0..2 {
                    jac[i][j] += x[a][i] * dn[a][j];
                }
            }
        }
        let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        if det.is_nan() || det <= 0.0 || !det.is_finite() || r.is_nan() || r <= 0.0 {
            return Err(MeridianCellError::Degenerate { qp: q, det, r });
        }
        // inverse of ∂X/∂ξ: ∂ξ_k/∂X_j
        let inv = [
            [jac[1][1] / det, -jac[0][1] / det],
            [-jac[1][0] / det, jac[0][0] / det],
        ];
        for a in 0..n {
            for j in 0..2 {
                g.grad[q][a][j] = dn[a][0] * inv[0][j] + dn[a][1] * inv[1][j];
            }
            hoop[q][a] = nv[a] / r;
        }
        g.weights[q] = 2.0 * std::f64::consts::PI * r * det * wq;
    }
    g.hoop = Some(hoop);
    Ok(g)
}

/// F and E₀ at one quadrature point of a meridian cell (module docs), from the gradients, the
/// hoop row, nodal (u_r, u_z, ·) (m; the third entry is not read) and potentials (V).
pub fn meridian_kinematics(
    grad: &[[f64; 3]],
    hoop: &[f64],
    u: &[[f64; 3]],
    phi: &[f64],
) -> (Mat3, Vec3) {
    let mut f = Mat3::identity();
    let mut e0 = Vec3::zeros();
    for a in 0..grad.len() {
        let g = grad[a];
        for i in 0..2 {
            for j in 0..2 {
                f[(i, j)] += u[a][i] * g[j];
            }
            e0[i] -= phi[a] * g[i];
        }
        f[(2, 2)] += u[a][0] * hoop[a];
    }
    (f, e0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// N_a(node b) = δ_ab, Σ N_a = 1, and the gradients match central differences.
    #[test]
    fn shape_functions_interpolate_and_differentiate() {
        for kind in MeridianKind::ALL {
            let nodes = kind.reference_nodes();
            for (b, xb) in nodes.iter().enumerate() {
                let (n, _) = meridian_shape_functions(kind, *xb);
                for (a, na) in n.iter().enumerate() {
                    let e = if a == b { 1.0 } else { 0.0 };
                    assert!((na - e).abs() < 1e-15, "{kind:?}: N_{a}(node {b}) = {na}");
                }
            }
            let h = 1e-6;
            for xi in [[0.1, 0.2], [0.3, -0.4], [0.25, 0.25]] {
                let (n, dn) = meridian_shape_functions(kind, xi);
                assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-14);
                for k in 0..2 {
                    let (mut p, mut m) = (xi, xi);
                    p[k] += h;
                    m[k] -= h;
                    let (np, _) = meridian_shape_functions(kind, p);
                    let (nm, _) = meridian_shape_functions(kind, m);
                    for a in 0..n.len() {
                        let fd = (np[a] - nm[a]) / (2.0 * h);
                        // central difference of a quadratic: exact up to rounding (~1e-10)
                        assert!((fd - dn[a][k]).abs() < 1e-8, "{kind:?} dN_{a}/dξ_{k}");
                    }
                }
            }
        }
    }

    /// Σ weights = volume of the ring, π(R₂² − R₁²)·H, exactly (the integrand 2πR is linear).
    #[test]
    fn weights_give_the_ring_volume_and_bad_cells_are_rejected() {
        for kind in MeridianKind::ALL {
            let (r1, r2, h) = (0.0, 2.0, 0.5);
            let x: Vec<[f64; 2]> = kind
                .reference_nodes()
                .iter()
                .map(|p| match kind {
                    MeridianKind::Tri3 | MeridianKind::Tri6 => [r1 + (r2 - r1) * p[0], h * p[1]],
                    _ => [r1 + (r2 - r1) * 0.5 * (p[0] + 1.0), h * 0.5 * (p[1] + 1.0)],
                })
                .collect();
            let g = meridian_geometry(kind, &x).unwrap();
            let v: f64 = g.weights[..g.n_qp].iter().sum();
            let exact = match kind {
                // the triangle (0,0), (2,0), (0,h): ∫ 2πR dA = 2π·h·r2²/6
                MeridianKind::Tri3 | MeridianKind::Tri6 => {
                    2.0 * std::f64::consts::PI * h * r2 * r2 / 6.0
                }
                _ => std::f64::consts::PI * (r2 * r2 - r1 * r1) * h,
            };
            assert!(
                (v - exact).abs() < 1e-13 * exact,
                "{kind:?}: {v} vs {exact}"
            );
            let mut left = x.clone();
            for p in left.iter_mut() {
                p[0] -= 1.0;
            }
            assert!(matches!(
                meridian_geometry(kind, &left),
                Err(MeridianCellError::NegativeRadius { .. })
            ));
            let mut flipped = x.clone();
            for p in flipped.iter_mut() {
                p[1] = -p[1];
            }
            assert!(matches!(
                meridian_geometry(kind, &flipped),
                Err(MeridianCellError::Degenerate { .. })
            ));
        }
    }
}
