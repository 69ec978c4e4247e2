//! Reference elements: shape functions, Gauss quadrature and the geometry of a cell at its
//! quadrature points; kinematics (F, E₀) at a quadrature point. `axisymmetric`: the meridian
//! elements and the axisymmetric kinematics.

pub mod axisymmetric;

use crate::material::{Mat3, Vec3};
use crate::mesh::ElementKind;

/// Unknowns per node, interleaved node-major: ux, uy, uz (m) and Φ (V).
pub const FIELDS: usize = 4;
/// Index of the potential among a node's unknowns.
pub const PHI: usize = 3;

/// Largest number of nodes of a supported cell.
pub const MAX_NODES: usize = 10;
/// Largest number of quadrature points of a supported cell.
pub const MAX_QP: usize = 9;

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
///
/// A meridian (axisymmetric) cell stores ∇₀N_a = (∂N_a/∂R, ∂N_a/∂Z, 0), the weights
/// 2πR·w·det(∂(R, Z)/∂ξ) of the whole ring, and the hoop row N_a/R in `hoop`; a 3-D cell has
/// none (see [`axisymmetric`]): a quarter of a cell's size, which the 3-D cells of a large mesh
/// would otherwise each carry as zeros.
#[derive(Debug, Clone)]
pub struct CellGeometry {
    pub n_nodes: usize,
    pub n_qp: usize,
    pub grad: [[[f64; 3]; MAX_NODES]; MAX_QP],
    pub weights: [f64; MAX_QP],
    /// N_a/R at each quadrature point of a meridian cell (1/m); `None` for a 3-D cell.
    pub hoop: Option<Box<[[f64; MAX_NODES]; MAX_QP]>>,
    /// Whether the cell is a meridian cell of an axisymmetric model.
    pub axisymmetric: bool,
}

impl CellGeometry {
    /// The hoop row N_a/R (1/m) at quadrature point `q` of a meridian cell; zeros for a 3-D cell.
    #[inline]
    pub fn hoop(&self, q: usize) -> &[f64; MAX_NODES] {
        static NONE: [f64; MAX_NODES] = [0.0; MAX_NODES];
        self.hoop.as_deref().map_or(&NONE, |h| &h[q])
    }
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
    /// Hex8 with 2×2×2 Gauss points (exact for the trilinear mass matrix); tet4 with one point;
    /// tet10 with the 4-point rule of degree 2 (Hammer–Stroud).
    ///
    /// Tet10: degree 2 integrates the linear-elastic stiffness (∇N_a·∇N_b, degree 2) of a
    /// straight-sided cell exactly and, with 4 points × 6 strain components = 24 = 30 − 6 rigid
    /// modes and 4 × 3 field components ≥ 9 potential modes, leaves no spurious zero-energy mode;
    /// its weights are positive, which the nonlinear terms need (the 5- and 11-point rules of higher
    /// degree have a negative weight, so a convex energy could give an indefinite cell tangent).
    /// It is the rule of the common commercial codes' quadratic tetrahedra. The homogeneous state
    /// is exact with any rule.
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
            ElementKind::Meridian(m) => {
                let rule = axisymmetric::meridian_quadrature(m);
                r.n_qp = rule.len();
                for (q, (xi, w)) in rule.into_iter().enumerate() {
                    let (n, dn) = axisymmetric::meridian_shape_functions(m, xi);
                    r.qp_weights[q] = w;
                    r.n[q][..n.len()].copy_from_slice(&n);
                    for (a, d) in dn.iter().enumerate() {
                        r.dn[q][a] = [d[0], d[1], 0.0];
                    }
                }
            }
            ElementKind::Hex8 => {
                let g = 1.0 / 3f64.sqrt();
                r.n_qp = 8;
                for (q, c) in HEX_CORNERS.iter().enumerate() {
                    r.qp_weights[q] = 1.0;
                    let (n, dn) = shape_functions(kind, [c[0] * g, c[1] * g, c[2] * g]);
                    r.n[q] = n;
                    r.dn[q] = dn;
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
            ElementKind::Tet10 => {
                let a = (5.0 + 3.0 * 5f64.sqrt()) / 20.0;
                let b = (5.0 - 5f64.sqrt()) / 20.0;
                r.n_qp = 4;
                for q in 0..4 {
                    let mut xi = [b; 3];
                    if q > 0 {
                        xi[q - 1] = a;
                    }
                    r.qp_weights[q] = 1.0 / 24.0;
                    let (n, dn) = shape_functions(kind, xi);
                    r.n[q] = n;
                    r.dn[q] = dn;
                }
            }
        }
        r
    }

    /// Gradients and weights of a cell with reference node coordinates `x` (a meridian cell:
    /// (R, Z, ·), see [`axisymmetric::meridian_geometry`]).
    pub fn geometry(&self, x: &[[f64; 3]]) -> Result<CellGeometry, DegenerateCell> {
        if let ElementKind::Meridian(m) = self.kind {
            let rz: Vec<[f64; 2]> = x.iter().map(|p| [p[0], p[1]]).collect();
            return axisymmetric::meridian_geometry(m, &rz).map_err(|e| match e {
                axisymmetric::MeridianCellError::NegativeRadius { r, .. } => {
                    DegenerateCell { qp: 0, det: r }
                }
                axisymmetric::MeridianCellError::Degenerate { qp, det, .. } => {
                    DegenerateCell { qp, det }
                }
            });
        }
        let mut g = CellGeometry {
            n_nodes: self.n_nodes,
            n_qp: self.n_qp,
            grad: [[[0.0; 3]; MAX_NODES]; MAX_QP],
            weights: [0.0; MAX_QP],
            hoop: None,
            axisymmetric: false,
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

pub use crate::mesh::TET10_EDGES;

/// Shape functions N_a(ξ) and their reference gradients ∂N_a/∂ξ at a point ξ of the reference
/// cell (entries beyond `nodes_per_cell` are 0). Tet10: with the barycentric coordinates
/// L = (1 − ξ₁ − ξ₂ − ξ₃, ξ₁, ξ₂, ξ₃), N = L_a(2L_a − 1) at a corner and 4L_iL_j at the node of edge
/// i–j.
pub fn shape_functions(
    kind: ElementKind,
    xi: [f64; 3],
) -> ([f64; MAX_NODES], [[f64; 3]; MAX_NODES]) {
    let mut n = [0.0; MAX_NODES];
    let mut dn = [[0.0; 3]; MAX_NODES];
    match kind {
        ElementKind::Hex8 => {
            for (a, ca) in HEX_CORNERS.iter().enumerate() {
                let f = [
                    1.0 + ca[0] * xi[0],
                    1.0 + ca[1] * xi[1],
                    1.0 + ca[2] * xi[2],
                ];
                n[a] = 0.125 * f[0] * f[1] * f[2];
                dn[a] = [
                    0.125 * ca[0] * f[1] * f[2],
                    0.125 * f[0] * ca[1] * f[2],
                    0.125 * f[0] * f[1] * ca[2],
                ];
            }
        }
        ElementKind::Tet4 | ElementKind::Tet10 => {
            let l = [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]];
            let dl = [
                [-1.0, -1.0, -1.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ];
            if kind == ElementKind::Tet4 {
                n[..4].copy_from_slice(&l);
                dn[..4].copy_from_slice(&dl);
            } else {
                for a in 0..4 {
                    n[a] = l[a] * (2.0 * l[a] - 1.0);
                    dn[a] = dl[a].map(|d| (4.0 * l[a] - 1.0) * d);
                }
                for (e, [i, j]) in TET10_EDGES.iter().enumerate() {
                    n[4 + e] = 4.0 * l[*i] * l[*j];
                    for k in 0..3 {
                        dn[4 + e][k] = 4.0 * (dl[*i][k] * l[*j] + l[*i] * dl[*j][k]);
                    }
                }
            }
        }
        ElementKind::Meridian(m) => {
            let (v, d) = axisymmetric::meridian_shape_functions(m, [xi[0], xi[1]]);
            n[..v.len()].copy_from_slice(&v);
            for (a, g) in d.iter().enumerate() {
                dn[a] = [g[0], g[1], 0.0];
            }
        }
    }
    (n, dn)
}

/// A quadrature rule on the reference tetrahedron with positive weights, exact for polynomials of
/// degree ≤ 5 (4 × 4 × 4 Gauss–Legendre points of the collapsed cube, Stroud's conical product):
/// for integrals the element rule does not integrate exactly, such as the tet10 mass matrix
/// (degree 4). Returns (ξ, weight) pairs; the weights sum to 1/6.
pub fn tet_rule_degree5() -> Vec<([f64; 3], f64)> {
    // Gauss–Legendre on [0, 1]
    let s = (6.0f64 / 5.0).sqrt();
    let x = [
        (3.0 / 7.0 - 2.0 / 7.0 * s).sqrt(),
        (3.0 / 7.0 + 2.0 / 7.0 * s).sqrt(),
    ];
    let w = [(18.0 + 30f64.sqrt()) / 36.0, (18.0 - 30f64.sqrt()) / 36.0];
    let pts: Vec<(f64, f64)> = [(-x[1], w[1]), (-x[0], w[0]), (x[0], w[0]), (x[1], w[1])]
        .iter()
        .map(|&(p, q)| (0.5 * (p + 1.0), 0.5 * q))
        .collect();
    let mut out = Vec::with_capacity(64);
    for &(u, wu) in &pts {
        for &(v, wv) in &pts {
            for &(t, wt) in &pts {
                // (u, v, t) ∈ [0,1]³ ↦ ξ = (u, v(1−u), t(1−u)(1−v)), Jacobian (1−u)²(1−v)
                let xi = [u, v * (1.0 - u), t * (1.0 - u) * (1.0 - v)];
                out.push((xi, wu * wv * wt * (1.0 - u).powi(2) * (1.0 - v)));
            }
        }
    }
    out
}

/// Deformation gradient F = I + Σ u_a ⊗ ∇N_a and referential field E₀ = −Σ Φ_a ∇N_a at one
/// quadrature point, from nodal displacements (m) and potentials (V).
/// (Inlined: the element loops call it at every point, and callers that need F only drop E₀.)
#[inline]
pub fn kinematics(grad: &[[f64; 3]], u: &[[f64; 3]], phi: &[f64]) -> (Mat3, Vec3) {
    let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut e0 = [0.0; 3];
    for ((g, ua), pa) in grad.iter().zip(u).zip(phi) {
        for i in 0..3 {
            for j in 0..3 {
                f[i][j] += ua[i] * g[j];
            }
            e0[i] -= pa * g[i];
        }
    }
    (
        Mat3::new(
            f[0][0], f[0][1], f[0][2], f[1][0], f[1][1], f[1][2], f[2][0], f[2][1], f[2][2],
        ),
        Vec3::new(e0[0], e0[1], e0[2]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3-D cell holds no hoop row: its geometry is the gradients, the weights and a few
    /// words (2264 bytes; 2976 when every cell carried the meridian cells' hoop row).
    #[test]
    fn a_3d_cell_holds_no_hoop_row() {
        // the reference cube [-1, 1]³ as the cell
        let g = ReferenceElement::new(ElementKind::Hex8)
            .geometry(&HEX_CORNERS)
            .unwrap();
        assert!(g.hoop.is_none() && !g.axisymmetric);
        assert!((0..g.n_qp).all(|q| g.hoop(q).iter().all(|&v| v == 0.0)));
        let words = std::mem::size_of::<[[[f64; 3]; MAX_NODES]; MAX_QP]>()
            + std::mem::size_of::<[f64; MAX_QP]>();
        assert!(
            std::mem::size_of::<CellGeometry>() <= words + 32,
            "{} bytes",
            std::mem::size_of::<CellGeometry>()
        );
    }

    #[test]
    fn partition_of_unity_and_linear_completeness() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10] {
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
                ElementKind::Tet10 => curved_tet10(),
                ElementKind::Meridian(_) => unreachable!("3-D kinds only"),
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
            if kind == ElementKind::Tet10 {
                // keep the mid-edge nodes on their edges: 1–2 ↔ 0–2, 1–3 ↔ 0–3
                bad.swap(5, 6);
                bad.swap(7, 8);
            }
            assert!(r.geometry(&bad).is_err());
        }
    }

    /// A tet10 with its mid-edge nodes moved off the straight edges (a curved cell).
    fn curved_tet10() -> Vec<[f64; 3]> {
        let c = [
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.0],
            [0.2, 1.1, 0.1],
            [0.1, 0.2, 0.9],
        ];
        let mut x = c.to_vec();
        for (e, [i, j]) in TET10_EDGES.iter().enumerate() {
            let shift = 0.03 * (e as f64 - 2.5);
            x.push([0, 1, 2].map(|k| 0.5 * (c[*i][k] + c[*j][k]) + shift * (k as f64 - 1.0)));
        }
        x
    }

    /// Tet10 shape functions: N_a(node b) = δ_ab, and the gradients match central differences.
    #[test]
    fn tet10_shape_functions_interpolate_and_differentiate() {
        let mut nodes = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        for [i, j] in TET10_EDGES {
            nodes.push([0, 1, 2].map(|k| 0.5 * (nodes[i][k] + nodes[j][k])));
        }
        for (b, xb) in nodes.iter().enumerate() {
            let (n, _) = shape_functions(ElementKind::Tet10, *xb);
            for (a, na) in n[..10].iter().enumerate() {
                let e = if a == b { 1.0 } else { 0.0 };
                assert!((na - e).abs() < 1e-15, "N_{a}(node {b}) = {na}");
            }
        }
        let h = 1e-6;
        for xi in [[0.1, 0.2, 0.3], [0.6, 0.1, 0.05], [0.25, 0.25, 0.25]] {
            let (_, dn) = shape_functions(ElementKind::Tet10, xi);
            for k in 0..3 {
                let (mut p, mut m) = (xi, xi);
                p[k] += h;
                m[k] -= h;
                let (np, _) = shape_functions(ElementKind::Tet10, p);
                let (nm, _) = shape_functions(ElementKind::Tet10, m);
                for a in 0..10 {
                    let fd = (np[a] - nm[a]) / (2.0 * h);
                    assert!(
                        (fd - dn[a][k]).abs() < 1e-9,
                        "dN_{a}/dξ_{k}: {fd} vs {}",
                        dn[a][k]
                    );
                }
            }
        }
    }

    /// ∫ ξ^a η^b ζ^c over the reference tetrahedron is a! b! c! / (a + b + c + 3)!: the tet10 rule
    /// is exact to degree 2 (not 3), the mass rule to degree 5.
    #[test]
    fn tetrahedron_rules_are_exact_to_their_degree() {
        let fact = |n: u32| (1..=n).map(f64::from).product::<f64>();
        let exact =
            |p: [u32; 3]| fact(p[0]) * fact(p[1]) * fact(p[2]) / fact(p[0] + p[1] + p[2] + 3);
        let r = ReferenceElement::new(ElementKind::Tet10);
        let mut qp: Vec<([f64; 3], f64)> = Vec::new();
        for q in 0..r.n_qp {
            // the points are recovered from the tet10 shape functions: ξ_a = Σ_b N_b ξ_a(node b)
            let l: [f64; 3] = [1, 2, 3].map(|a| {
                let mut v = r.n[q][a];
                for (e, [i, j]) in TET10_EDGES.iter().enumerate() {
                    if *i == a || *j == a {
                        v += 0.5 * r.n[q][4 + e];
                    }
                }
                v
            });
            qp.push((l, r.qp_weights[q]));
        }
        let rule5 = tet_rule_degree5();
        for d in 0..=6u32 {
            for a in 0..=d {
                for b in 0..=d - a {
                    let p = [a, b, d - a - b];
                    let integrate = |rule: &[([f64; 3], f64)]| {
                        rule.iter()
                            .map(|(x, w)| {
                                w * x[0].powi(p[0] as i32)
                                    * x[1].powi(p[1] as i32)
                                    * x[2].powi(p[2] as i32)
                            })
                            .sum::<f64>()
                    };
                    let e = exact(p);
                    let err4 = (integrate(&qp) - e).abs() / e;
                    let err5 = (integrate(&rule5) - e).abs() / e;
                    assert_eq!(err4 < 1e-13, d <= 2, "4-point rule, {p:?}: {err4:e}");
                    assert_eq!(err5 < 1e-13, d <= 5, "degree-5 rule, {p:?}: {err5:e}");
                }
            }
        }
    }
}
