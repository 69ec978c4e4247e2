//! Reference elements: shape functions, Gauss quadrature and the geometry of a cell at its
//! quadrature points; kinematics (F, E₀) at a quadrature point.

use crate::material::{Mat3, Vec3};
use crate::mesh::ElementKind;

/// Largest number of nodes of a supported cell.
pub const MAX_NODES: usize = 8;
/// Largest number of quadrature points of a supported cell.
pub const MAX_QP: usize = 8;

/// Shape functions and quadrature of one element kind, evaluated once.
#[derive(Debug, Clone)]
pub struct ReferenceElement {
    pub kind: ElementKind,
    pub n_nodes: usize,
    pub n_qp: usize,
    /// Quadrature weights in the reference cell.
    pub qp_weights: [f64; MAX_QP],
    /// Shape function values N_a at each quadrature point.
    pub n: [[f64; MAX_NODES]; MAX_QP],
    /// Reference gradients ∂N_a/∂ξ at each quadrature point.
    pub dn: [[[f64; 3]; MAX_NODES]; MAX_QP],
}

/// The geometry of one cell at its quadrature points: gradients of the shape functions with respect
/// to the reference coordinates X, and the integration weights w·det(∂X/∂ξ) (m³).
#[derive(Debug, Clone)]
pub struct CellGeometry {
    pub n_nodes: usize,
    pub n_qp: usize,
    pub grad: [[[f64; 3]; MAX_NODES]; MAX_QP],
    pub weights: [f64; MAX_QP],
}

/// A cell whose Jacobian is not positive at a quadrature point (inverted or degenerate cell).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DegenerateCell {
    pub qp: usize,
    pub det: f64,
}

const HEX_CORNERS: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

impl ReferenceElement {
    /// Hex8 with 2×2×2 Gauss points (exact for the trilinear mass matrix); tet4 with one point.
    pub fn new(kind: ElementKind) -> Self {
        let mut r = ReferenceElement {
            kind,
            n_nodes: kind.nodes_per_cell(),
            n_qp: 0,
            qp_weights: [0.0; MAX_QP],
            n: [[0.0; MAX_NODES]; MAX_QP],
            dn: [[[0.0; 3]; MAX_NODES]; MAX_QP],
        };
        match kind {
            ElementKind::Hex8 => {
                let g = 1.0 / 3f64.sqrt();
                r.n_qp = 8;
                for (q, c) in HEX_CORNERS.iter().enumerate() {
                    let xi = [c[0] * g, c[1] * g, c[2] * g];
                    r.qp_weights[q] = 1.0;
                    for (a, ca) in HEX_CORNERS.iter().enumerate() {
                        let f = [
                            1.0 + ca[0] * xi[0],
                            1.0 + ca[1] * xi[1],
                            1.0 + ca[2] * xi[2],
                        ];
                        r.n[q][a] = 0.125 * f[0] * f[1] * f[2];
                        r.dn[q][a] = [
                            0.125 * ca[0] * f[1] * f[2],
                            0.125 * f[0] * ca[1] * f[2],
                            0.125 * f[0] * f[1] * ca[2],
                        ];
                    }
                }
            }
            ElementKind::Tet4 => {
                r.n_qp = 1;
                r.qp_weights[0] = 1.0 / 6.0;
                r.n[0][..4].copy_from_slice(&[0.25; 4]);
                r.dn[0][0] = [-1.0, -1.0, -1.0];
                r.dn[0][1] = [1.0, 0.0, 0.0];
                r.dn[0][2] = [0.0, 1.0, 0.0];
                r.dn[0][3] = [0.0, 0.0, 1.0];
            }
        }
        r
    }

    /// Gradients and weights of a cell with reference node coordinates `x`.
    pub fn geometry(&self, x: &[[f64; 3]]) -> Result<CellGeometry, DegenerateCell> {
        let mut g = CellGeometry {
            n_nodes: self.n_nodes,
            n_qp: self.n_qp,
            grad: [[[0.0; 3]; MAX_NODES]; MAX_QP],
            weights: [0.0; MAX_QP],
        };
        for q in 0..self.n_qp {
            // jac[i][j] = ∂X_i/∂ξ_j
            let mut jac = Mat3::zeros();
            for a in 0..self.n_nodes {
                for i in 0..3 {
                    for j in 0..3 {
                        jac[(i, j)] += x[a][i] * self.dn[q][a][j];
                    }
                }
            }
            let det = jac.determinant();
            if det.is_nan() || det <= 0.0 || !det.is_finite() {
                return Err(DegenerateCell { qp: q, det });
            }
            let inv = jac.try_inverse().ok_or(DegenerateCell { qp: q, det })?;
            for a in 0..self.n_nodes {
                let d = self.dn[q][a];
                // ∂N/∂X_j = ∂N/∂ξ_k ∂ξ_k/∂X_j
                for j in 0..3 {
                    g.grad[q][a][j] = d[0] * inv[(0, j)] + d[1] * inv[(1, j)] + d[2] * inv[(2, j)];
                }
            }
            g.weights[q] = det * self.qp_weights[q];
        }
        Ok(g)
    }
}

/// Deformation gradient F = I + Σ u_a ⊗ ∇N_a and referential field E₀ = −Σ Φ_a ∇N_a at one
/// quadrature point, from nodal displacements (m) and potentials (V).
pub fn kinematics(grad: &[[f64; 3]], u: &[[f64; 3]], phi: &[f64]) -> (Mat3, Vec3) {
    let mut f = Mat3::identity();
    let mut e0 = Vec3::zeros();
    for a in 0..grad.len() {
        let g = grad[a];
        for i in 0..3 {
            for j in 0..3 {
                f[(i, j)] += u[a][i] * g[j];
            }
            e0[i] -= phi[a] * g[i];
        }
    }
    (f, e0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partition_of_unity_and_linear_completeness() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4] {
            let r = ReferenceElement::new(kind);
            let x: Vec<[f64; 3]> = match kind {
                ElementKind::Hex8 => vec![
                    [0.0, 0.0, 0.0],
                    [1.2, 0.1, 0.0],
                    [1.3, 0.9, 0.1],
                    [-0.1, 1.0, 0.0],
                    [0.1, 0.0, 1.0],
                    [1.0, 0.2, 1.1],
                    [1.1, 1.2, 0.9],
                    [0.0, 1.1, 1.2],
                ],
                ElementKind::Tet4 => vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.1, 0.0],
                    [0.2, 1.1, 0.1],
                    [0.1, 0.2, 0.9],
                ],
            };
            let g = r.geometry(&x).unwrap();
            for q in 0..r.n_qp {
                let s: f64 = r.n[q][..r.n_nodes].iter().sum();
                assert!((s - 1.0).abs() < 1e-14);
                // Σ X_a ⊗ ∇N_a = I on any cell (linear completeness)
                for i in 0..3 {
                    for j in 0..3 {
                        let v: f64 = (0..r.n_nodes).map(|a| x[a][i] * g.grad[q][a][j]).sum();
                        let e = if i == j { 1.0 } else { 0.0 };
                        assert!((v - e).abs() < 1e-13, "{kind:?}");
                    }
                }
            }
            // inverted cell is rejected
            let mut bad = x.clone();
            bad.swap(0, 1);
            assert!(r.geometry(&bad).is_err());
        }
    }
}
