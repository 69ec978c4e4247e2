//! An eighth of a thick spherical shell (x, y, z ≥ 0) in hex8 cells: a balloon or a dome.
//!
//! The octant of the sphere is the radial projection of the three faces of the unit cube's corner
//! (x = 1, y = 1 and z = 1, each with its other two coordinates in [0, 1]). Each face carries an
//! n × n grid, equi-angular (tan-spaced) so that the cells on the sphere are of similar size, and
//! the grid is extruded radially in `layers` layers from the inner to the outer radius. Nodes on
//! the edges shared by two faces are merged.
//!
//! Sets: node and face sets `inner` and `outer` (the two spherical surfaces) and `x0`, `y0`, `z0`
//! (the symmetry planes), and the cell set `all`.

use super::{ElementKind, FaceRef, Mesh};
use std::collections::HashMap;

/// The octant shell of inner radius `r_in` and outer radius `r_out` (m), `n` cells along each
/// edge of the three cube faces and `layers` cells through the thickness.
pub fn sphere_octant(r_in: f64, r_out: f64, n: usize, layers: usize) -> Mesh {
    let n = n.max(1);
    let layers = layers.max(1);
    // grid coordinate in [0, 1], tan-spaced (equal angles seen from the centre)
    let g = |i: usize| (std::f64::consts::FRAC_PI_4 * i as f64 / n as f64).tan();
    // the three faces: (i, j) ↦ point on the cube face
    let faces: [&dyn Fn(f64, f64) -> [f64; 3]; 3] =
        [&|a, b| [a, b, 1.0], &|a, b| [1.0, a, b], &|a, b| {
            [b, 1.0, a]
        }];
    let mut nodes: Vec<[f64; 3]> = Vec::new();
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    let mut node = |p: [f64; 3]| -> usize {
        let key = p.map(|v| (v * 1e12).round() as i64);
        *index.entry(key).or_insert_with(|| {
            nodes.push(p);
            nodes.len() - 1
        })
    };
    let radius = |k: usize| r_in + (r_out - r_in) * k as f64 / layers as f64;
    let point = |c: [f64; 3], r: f64| {
        let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        c.map(|v| r * v / len)
    };
    let mut connectivity = Vec::new();
    for face in faces {
        for j in 0..n {
            for i in 0..n {
                let quad = [
                    face(g(i), g(j)),
                    face(g(i + 1), g(j)),
                    face(g(i + 1), g(j + 1)),
                    face(g(i), g(j + 1)),
                ];
                for k in 0..layers {
                    let mut h = [0usize; 8];
                    for (a, c) in quad.iter().enumerate() {
                        h[a] = node(point(*c, radius(k)));
                        h[a + 4] = node(point(*c, radius(k + 1)));
                    }
                    connectivity.push(h);
                }
            }
        }
    }
    // positive orientation: (x1 − x0) × (x3 − x0) points outwards, towards x4
    for h in connectivity.iter_mut() {
        let x = |a: usize| nodes[h[a]];
        let d = |a: usize, b: usize| [x(b)[0] - x(a)[0], x(b)[1] - x(a)[1], x(b)[2] - x(a)[2]];
        let (e1, e3, e4) = (d(0, 1), d(0, 3), d(0, 4));
        let cross = [
            e1[1] * e3[2] - e1[2] * e3[1],
            e1[2] * e3[0] - e1[0] * e3[2],
            e1[0] * e3[1] - e1[1] * e3[0],
        ];
        if cross[0] * e4[0] + cross[1] * e4[1] + cross[2] * e4[2] < 0.0 {
            h.swap(1, 3);
            h.swap(5, 7);
        }
    }
    let mut mesh = Mesh::new(
        ElementKind::Hex8,
        nodes,
        connectivity.iter().flatten().copied().collect(),
    );
    let tol = 1e-9 * r_out;
    let on = |p: [f64; 3], name: &str| -> bool {
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        match name {
            "inner" => (r - r_in).abs() <= tol,
            "outer" => (r - r_out).abs() <= tol,
            "x0" => p[0].abs() <= tol,
            "y0" => p[1].abs() <= tol,
            _ => p[2].abs() <= tol,
        }
    };
    for name in ["inner", "outer", "x0", "y0", "z0"] {
        let set: Vec<usize> = (0..mesh.n_nodes())
            .filter(|&a| on(mesh.nodes[a], name))
            .collect();
        mesh.node_sets.insert(name.into(), set);
        let mut faces = Vec::new();
        for c in 0..mesh.n_cells() {
            let cell = mesh.cell(c);
            for (f, local) in ElementKind::Hex8.faces().iter().enumerate() {
                if local.iter().all(|&l| on(mesh.nodes[cell[l]], name)) {
                    faces.push(FaceRef { cell: c, face: f });
                }
            }
        }
        mesh.face_sets.insert(name.into(), faces);
    }
    mesh.cell_sets
        .insert("all".into(), (0..mesh.n_cells()).collect());
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ReferenceElement;

    /// Cell and node counts, the sets, positive volumes summing to the octant's volume (to the
    /// faceting error, second order in the cell size), and every node at its radius.
    #[test]
    fn octant_counts_sets_and_volume() {
        let (a, b) = (1.0, 1.2);
        let exact = std::f64::consts::PI / 6.0 * (b * b * b - a * a * a);
        let mut errors = Vec::new();
        for n in [4, 8] {
            let m = sphere_octant(a, b, n, 2);
            assert_eq!(m.n_cells(), 3 * n * n * 2);
            // 3n² + 3n + 1 points per surface
            assert_eq!(m.n_nodes(), 3 * (3 * n * n + 3 * n + 1));
            assert_eq!(m.node_sets["inner"].len(), 3 * n * n + 3 * n + 1);
            assert_eq!(m.face_sets["inner"].len(), 3 * n * n);
            assert_eq!(m.face_sets["outer"].len(), 3 * n * n);
            for s in ["x0", "y0", "z0"] {
                assert_eq!(m.face_sets[s].len(), 2 * n * 2, "{s}");
            }
            let el = ReferenceElement::new(m.kind);
            let mut v = 0.0;
            let mut x = vec![[0.0; 3]; 8];
            for c in 0..m.n_cells() {
                m.cell_coords_into(c, &mut x);
                // rejects inverted cells
                let g = el.geometry(&x).expect("a valid cell");
                v += g.weights.iter().sum::<f64>();
            }
            errors.push((v - exact).abs() / exact);
            for &i in &m.node_sets["outer"] {
                let p = m.nodes[i];
                assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - b).abs() < 1e-12);
            }
        }
        assert!(
            errors[0] < 2e-2 && errors[1] < errors[0] / 3.5,
            "{errors:?}"
        );
    }
}
