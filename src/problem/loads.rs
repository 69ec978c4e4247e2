//! Surface loads: dead nominal tractions t₀ (N/m² of reference area, a constant vector) on faces.
//!
//! The consistent nodal forces are f_a = ∫ N_a t₀ dA over the reference face; the residual gets
//! −f_a (a dead load has no tangent). Quadrilateral faces (hex8) are bilinear patches integrated
//! with 2×2 Gauss points: exact on plane faces (there the area element |∂X/∂ξ × ∂X/∂η| is bilinear,
//! so N_a dA is biquadratic), an approximation on warped ones; triangular faces (tet4) are flat and
//! ∫N_a dA = A/3 exactly. Six-node triangles (tet10) are quadratic patches integrated with the
//! 6-point rule of degree 4 (Dunavant): exact on flat straight-sided faces (∫N_a dA = 0 at a corner,
//! A/3 at a mid-edge node), an approximation on curved ones.

use crate::mesh::{FaceRef, Mesh};
use crate::problem::dofs::FIELDS;
use crate::problem::model::Model;

/// A dead nominal traction on a list of faces (N/m² of reference area).
#[derive(Debug, Clone, PartialEq)]
pub struct Traction {
    pub faces: Vec<FaceRef>,
    pub value: [f64; 3],
}

/// ∫ N_a dA (m²) of each node of a face, in the order of [`crate::mesh::ElementKind::faces`].
/// Returns the local node list of the face and the weights (only the first `list.len()` are used).
pub fn face_node_areas(mesh: &Mesh, face: FaceRef) -> (&'static [usize], [f64; 6]) {
    let local = mesh.kind.faces()[face.face];
    let cell = mesh.cell(face.cell);
    let p: Vec<[f64; 3]> = local.iter().map(|&l| mesh.nodes[cell[l]]).collect();
    (local, face_point_areas(&p))
}

/// ∫ N_a dA (m²) of each node of a face with node positions `p` (3, 4 or 6 nodes, in the order
/// of [`crate::mesh::ElementKind::faces`]); their sum is the face's area.
pub fn face_point_areas(p: &[[f64; 3]]) -> [f64; 6] {
    let mut out = [0.0; 6];
    match p.len() {
        6 => {
            // Dunavant's degree-4 rule: (weight, a) for the orbits (a, a, 1 − 2a)
            const ORBITS: [(f64, f64); 2] = [
                (0.223_381_589_678_011, 0.445_948_490_915_965),
                (0.109_951_743_655_322, 0.091_576_213_509_771),
            ];
            for (w, a) in ORBITS {
                for k in 0..3 {
                    let mut l = [a; 3];
                    l[k] = 1.0 - 2.0 * a;
                    // L = (1 − s − t, s, t); derivatives with respect to s and t
                    let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
                    let mut n = [0.0; 6];
                    let mut dn = [[0.0; 2]; 6];
                    for i in 0..3 {
                        n[i] = l[i] * (2.0 * l[i] - 1.0);
                        dn[i] = dl[i].map(|d| (4.0 * l[i] - 1.0) * d);
                        let j = (i + 1) % 3;
                        n[3 + i] = 4.0 * l[i] * l[j];
                        for c in 0..2 {
                            dn[3 + i][c] = 4.0 * (dl[i][c] * l[j] + l[i] * dl[j][c]);
                        }
                    }
                    let mut ds = [0.0; 3];
                    let mut dt = [0.0; 3];
                    for a in 0..6 {
                        for i in 0..3 {
                            ds[i] += dn[a][0] * p[a][i];
                            dt[i] += dn[a][1] * p[a][i];
                        }
                    }
                    let da = 0.5 * w * norm(cross(ds, dt));
                    for a in 0..6 {
                        out[a] += n[a] * da;
                    }
                }
            }
        }
        3 => {
            let a = sub(p[1], p[0]);
            let b = sub(p[2], p[0]);
            let area = 0.5 * norm(cross(a, b));
            out[..3].iter_mut().for_each(|v| *v = area / 3.0);
        }
        4 => {
            // bilinear quad on [−1, 1]², corners (−1,−1), (1,−1), (1,1), (−1,1)
            const C: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
            let gp = 1.0 / 3f64.sqrt();
            for &xi in &[-gp, gp] {
                for &eta in &[-gp, gp] {
                    let mut dxi = [0.0; 3];
                    let mut deta = [0.0; 3];
                    let mut n = [0.0; 4];
                    for a in 0..4 {
                        n[a] = 0.25 * (1.0 + C[a][0] * xi) * (1.0 + C[a][1] * eta);
                        let dn_dxi = 0.25 * C[a][0] * (1.0 + C[a][1] * eta);
                        let dn_deta = 0.25 * (1.0 + C[a][0] * xi) * C[a][1];
                        for i in 0..3 {
                            dxi[i] += dn_dxi * p[a][i];
                            deta[i] += dn_deta * p[a][i];
                        }
                    }
                    let da = norm(cross(dxi, deta));
                    for a in 0..4 {
                        out[a] += n[a] * da;
                    }
                }
            }
        }
        k => unreachable!("faces have 3, 4 or 6 nodes, not {k}"),
    }
    out
}

/// Calls `f(node, force)` with the consistent force ∫ N_a t₀ dA (N) of every node of every loaded
/// face, at the full traction value (a node shared by several faces is visited once per face).
pub fn for_each_nodal_force(
    mesh: &Mesh,
    tractions: &[Traction],
    mut f: impl FnMut(usize, [f64; 3]),
) {
    for t in tractions {
        for &face in &t.faces {
            let (local, w) = face_node_areas(mesh, face);
            let cell = mesh.cell(face.cell);
            for (a, &l) in local.iter().enumerate() {
                f(cell[l], t.value.map(|v| v * w[a]));
            }
        }
    }
}

/// External nodal forces of the tractions times `factor` (N), `FIELDS` entries per node (zero in
/// the potential entries).
pub fn traction_forces(mesh: &Mesh, tractions: &[Traction], factor: f64) -> Vec<f64> {
    let mut out = vec![0.0; mesh.n_nodes() * FIELDS];
    for_each_nodal_force(mesh, tractions, |node, force| {
        for i in 0..3 {
            out[node * FIELDS + i] += factor * force[i];
        }
    });
    out
}

/// Consistent nodal forces (N, `FIELDS` per node, zero potential entries) of all the dead loads of
/// a model at full value: tractions ∫N t₀ dA, body forces ∫N b₀ dV (with the element's own
/// quadrature, exact for constant b₀ on affine cells) and point forces.
pub fn dead_load_forces(model: &Model) -> Vec<f64> {
    let mut out = traction_forces(&model.mesh, &model.tractions, 1.0);
    for &(node, q) in &model.point_charges {
        out[node * FIELDS + crate::problem::dofs::PHI] -= q;
    }
    for (o, g) in out.iter_mut().zip(weight_forces(model)) {
        *o += g;
    }
    out
}

/// Consistent nodal forces (N, `FIELDS` per node) of the body and point forces of a model at
/// full value: the loads with a potential energy −f·u (gravity on the body and attached masses).
pub fn weight_forces(model: &Model) -> Vec<f64> {
    let mesh = &model.mesh;
    let mut out = vec![0.0; mesh.n_nodes() * FIELDS];
    if model.body_force.iter().any(|b| *b != [0.0; 3]) {
        let npc = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; npc];
        for c in 0..mesh.n_cells() {
            let Some(b) = model.body_force.get(model.cell_material[c]) else {
                continue;
            };
            mesh.cell_coords_into(c, &mut x);
            // a degenerate cell is reported by the solver; it carries no load here
            let Ok(g) = model.reference.geometry(&x) else {
                continue;
            };
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                let w: f64 = (0..g.n_qp)
                    .map(|q| g.weights[q] * model.reference.n[q][a])
                    .sum();
                for i in 0..3 {
                    out[node * FIELDS + i] += w * b[i];
                }
            }
        }
    }
    for &(node, f) in &model.point_forces {
        for i in 0..3 {
            out[node * FIELDS + i] += f[i];
        }
    }
    out
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{generate::box_mesh, ElementKind};

    /// The total force is t₀ × reference area, on a box and on a sheared, tapered box whose x1 face
    /// is a non-planar (warped) quadrilateral; the first moment ∫X dA is reproduced as well.
    #[test]
    fn total_force_and_moment() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10] {
            let mesh = box_mesh([2.0, 3.0, 0.5], [2, 3, 2], kind);
            let t = Traction {
                faces: mesh.face_sets["x1"].clone(),
                value: [1.0, -2.0, 3.0],
            };
            let f = traction_forces(&mesh, std::slice::from_ref(&t), 2.0);
            let area = 3.0 * 0.5;
            for i in 0..3 {
                let s: f64 = (0..mesh.n_nodes()).map(|n| f[n * FIELDS + i]).sum();
                assert!((s - 2.0 * t.value[i] * area).abs() < 1e-12, "{kind:?}");
            }
            // first moment about the y axis: ∫ Y dA = area · 1.5
            let m: f64 = (0..mesh.n_nodes())
                .map(|n| f[n * FIELDS] * mesh.nodes[n][1])
                .sum();
            assert!((m - 2.0 * area * 1.5).abs() < 1e-12);
        }
        // warped face: 2×2 Gauss points against a fine midpoint rule on the bilinear patch
        let mut mesh = box_mesh([1.0, 1.0, 1.0], [1, 1, 1], ElementKind::Hex8);
        let corner = mesh.cell(0)[6]; // (1,1,1), moved out of the x1 plane
        mesh.nodes[corner][0] += 0.3;
        let (_, w) = face_node_areas(&mesh, mesh.face_sets["x1"][0]);
        let local = ElementKind::Hex8.faces()[mesh.face_sets["x1"][0].face];
        let p: Vec<[f64; 3]> = local.iter().map(|&l| mesh.nodes[mesh.cell(0)[l]]).collect();
        let m = 400;
        let mut area = 0.0;
        for i in 0..m {
            for j in 0..m {
                let (u, v) = ((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
                let du = (0..3)
                    .map(|k| (1.0 - v) * (p[1][k] - p[0][k]) + v * (p[2][k] - p[3][k]))
                    .collect::<Vec<_>>();
                let dv = (0..3)
                    .map(|k| (1.0 - u) * (p[3][k] - p[0][k]) + u * (p[2][k] - p[1][k]))
                    .collect::<Vec<_>>();
                let c = cross([du[0], du[1], du[2]], [dv[0], dv[1], dv[2]]);
                area += norm(c) / (m * m) as f64;
            }
        }
        let s: f64 = w.iter().sum();
        assert!((s - area).abs() < 1e-3 * area, "{s} vs {area}");
    }
}
