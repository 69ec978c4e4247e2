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

/// A dead nominal traction on a list of faces (N/m² of reference area).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
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
    if mesh.kind.meridian().is_some() {
        return (local, crate::problem::faces::ring_node_areas(&p));
    }
    (local, face_point_areas(&p))
}

/// ∫ N_a dA (m²) of each node of a face with node positions `p` (3, 4 or 6 nodes, in the order
/// of [`crate::mesh::ElementKind::faces`]); their sum is the face's area.
pub fn face_point_areas(p: &[[f64; 3]]) -> [f64; 6] {
    crate::problem::faces::node_areas(p)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{generate::box_mesh, ElementKind};
    use crate::problem::faces::{cross, norm};

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
