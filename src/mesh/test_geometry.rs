//! Vector arithmetic and measures the generators' unit tests check meshes with.

use super::Mesh;
use crate::fem::ReferenceElement;

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Area vector (area × normal, by the right-hand rule of the points' order) of a planar triangle
/// (three points) or quadrilateral (the first four).
pub fn area_vector(p: &[[f64; 3]]) -> [f64; 3] {
    let c = if p.len() == 3 {
        cross(sub(p[1], p[0]), sub(p[2], p[0]))
    } else {
        cross(sub(p[2], p[0]), sub(p[3], p[1]))
    };
    c.map(|x| 0.5 * x)
}

/// The volume of a mesh by quadrature; panics on a degenerate cell.
pub fn volume(mesh: &Mesh) -> f64 {
    let el = ReferenceElement::new(mesh.kind);
    let mut coords = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
    let mut v = 0.0;
    for c in 0..mesh.n_cells() {
        mesh.cell_coords_into(c, &mut coords);
        let g = el
            .geometry(&coords)
            .unwrap_or_else(|e| panic!("cell {c} degenerate: {e:?}"));
        v += g.weights[..g.n_qp].iter().sum::<f64>();
    }
    v
}
