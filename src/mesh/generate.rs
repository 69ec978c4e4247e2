//! Mesh generators.

use super::{ElementKind, FaceRef, Mesh};
use std::collections::BTreeMap;

/// The six tetrahedra of the Kuhn subdivision of a hexahedron (VTK node order), all sharing the
/// diagonal 0–6. Translated copies of a hexahedron give a conforming tetrahedral mesh.
pub(super) const HEX_TO_TETS: [[usize; 4]; 6] = [
    [0, 1, 2, 6],
    [0, 2, 3, 6],
    [0, 3, 7, 6],
    [0, 7, 4, 6],
    [0, 4, 5, 6],
    [0, 5, 1, 6],
];

/// The corners (VTK order) of hexahedron (i, j, k) of a structured grid whose node (i, j, k) is
/// `node_id(i, j, k)`.
pub(super) fn hex_corners(
    node_id: impl Fn(usize, usize, usize) -> usize,
    i: usize,
    j: usize,
    k: usize,
) -> [usize; 8] {
    [
        node_id(i, j, k),
        node_id(i + 1, j, k),
        node_id(i + 1, j + 1, k),
        node_id(i, j + 1, k),
        node_id(i, j, k + 1),
        node_id(i + 1, j, k + 1),
        node_id(i + 1, j + 1, k + 1),
        node_id(i, j + 1, k + 1),
    ]
}

/// A block `[0, size[0]] × [0, size[1]] × [0, size[2]]` (m) with `divisions` cells per direction,
/// hexahedra or tetrahedra (each hexahedron split into six; tet10 with straight edges).
///
/// Sets: node sets and face sets `x0 x1 y0 y1 z0 z1` (the faces at the low/high end of each axis),
/// node sets of the same names, and the cell set `all`.
///
/// A meridian kind gives the rectangle R ∈ [0, size[0]], Z ∈ [0, size[1]] with
/// `divisions[0] × divisions[1]` cells (see [`super::meridian::structured`]; its sets are
/// `inner`/`axis`, `outer`, `bottom`, `top`).
pub fn box_mesh(size: [f64; 3], divisions: [usize; 3], kind: ElementKind) -> Mesh {
    if let ElementKind::Meridian(m) = kind {
        let rs = super::meridian::uniform(0.0, size[0], divisions[0].max(1));
        let zs = super::meridian::uniform(0.0, size[1], divisions[1].max(1));
        return super::meridian::structured(&rs, &zs, m)
            .unwrap_or_else(|e| panic!("box_mesh: invalid rectangle: {e}"));
    }
    if kind == ElementKind::Tet10 {
        return super::quadratic::to_tet10(&box_mesh(size, divisions, ElementKind::Tet4));
    }
    let [nx, ny, nz] = divisions;
    let node_id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
    let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push([
                    size[0] * i as f64 / nx as f64,
                    size[1] * j as f64 / ny as f64,
                    size[2] * k as f64 / nz as f64,
                ]);
            }
        }
    }
    let mut connectivity = Vec::new();
    let mut face_sets: BTreeMap<String, Vec<FaceRef>> = BTreeMap::new();
    for name in ["x0", "x1", "y0", "y1", "z0", "z1"] {
        face_sets.insert(name.to_string(), Vec::new());
    }
    let mut cell = 0usize;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let h = hex_corners(node_id, i, j, k);
                match kind {
                    ElementKind::Hex8 => {
                        connectivity.extend_from_slice(&h);
                        let hex_faces = [
                            (k == 0, "z0", 0),
                            (k + 1 == nz, "z1", 1),
                            (j == 0, "y0", 2),
                            (i + 1 == nx, "x1", 3),
                            (j + 1 == ny, "y1", 4),
                            (i == 0, "x0", 5),
                        ];
                        for (on, name, face) in hex_faces {
                            if on {
                                face_sets
                                    .get_mut(name)
                                    .expect("face set created above")
                                    .push(FaceRef { cell, face });
                            }
                        }
                        cell += 1;
                    }
                    ElementKind::Meridian(_) => unreachable!("meridian kinds return above"),
                    ElementKind::Tet4 | ElementKind::Tet10 => {
                        for t in HEX_TO_TETS {
                            let tet = [h[t[0]], h[t[1]], h[t[2]], h[t[3]]];
                            connectivity.extend_from_slice(&tet);
                            cell += 1;
                        }
                    }
                }
            }
        }
    }
    let mut mesh = Mesh {
        kind,
        nodes,
        connectivity,
        node_sets: BTreeMap::new(),
        face_sets,
        cell_sets: BTreeMap::new(),
    };
    if kind != ElementKind::Hex8 {
        mesh.face_sets = boundary_faces_on_planes(&mesh, size);
    }
    for (name, axis, value) in [
        ("x0", 0, 0.0),
        ("x1", 0, size[0]),
        ("y0", 1, 0.0),
        ("y1", 1, size[1]),
        ("z0", 2, 0.0),
        ("z1", 2, size[2]),
    ] {
        let tol = 1e-9 * size[axis];
        let set: Vec<usize> = (0..mesh.n_nodes())
            .filter(|&n| (mesh.nodes[n][axis] - value).abs() <= tol)
            .collect();
        mesh.node_sets.insert(name.to_string(), set);
    }
    mesh.cell_sets
        .insert("all".to_string(), (0..mesh.n_cells()).collect());
    mesh
}

/// Faces of a tetrahedral block lying on its six bounding planes.
fn boundary_faces_on_planes(mesh: &Mesh, size: [f64; 3]) -> BTreeMap<String, Vec<FaceRef>> {
    let mut sets: BTreeMap<String, Vec<FaceRef>> = BTreeMap::new();
    let planes = [
        ("x0", 0, 0.0),
        ("x1", 0, size[0]),
        ("y0", 1, 0.0),
        ("y1", 1, size[1]),
        ("z0", 2, 0.0),
        ("z1", 2, size[2]),
    ];
    for (name, _, _) in planes {
        sets.insert(name.to_string(), Vec::new());
    }
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for (f, local) in mesh.kind.faces().iter().enumerate() {
            for (name, axis, value) in planes {
                let tol = 1e-9 * size[axis];
                if local
                    .iter()
                    .all(|&l| (mesh.nodes[cell[l]][axis] - value).abs() <= tol)
                {
                    sets.get_mut(name)
                        .expect("created above")
                        .push(FaceRef { cell: c, face: f });
                }
            }
        }
    }
    sets
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ReferenceElement;

    fn total_volume(mesh: &Mesh) -> f64 {
        let el = ReferenceElement::new(mesh.kind);
        let mut coords = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
        let mut v = 0.0;
        for c in 0..mesh.n_cells() {
            mesh.cell_coords_into(c, &mut coords);
            let g = el.geometry(&coords).expect("valid cell");
            v += g.weights.iter().sum::<f64>();
        }
        v
    }

    #[test]
    fn box_counts_sets_and_volume() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10] {
            let m = box_mesh([2.0, 3.0, 0.5], [2, 3, 1], kind);
            if kind != ElementKind::Tet10 {
                assert_eq!(m.n_nodes(), 3 * 4 * 2);
            }
            let per_hex = if kind == ElementKind::Hex8 { 1 } else { 6 };
            assert_eq!(m.n_cells(), 6 * per_hex);
            let (z1, x0) = if kind == ElementKind::Tet10 {
                (5 * 7, 7 * 3)
            } else {
                (12, 4 * 2)
            };
            assert_eq!(m.node_sets["z1"].len(), z1);
            assert_eq!(m.face_set_nodes("x0").unwrap().len(), x0);
            let faces_z0 = m.face_sets["z0"].len();
            assert_eq!(faces_z0, 6 * if kind == ElementKind::Hex8 { 1 } else { 2 });
            assert!((total_volume(&m) - 3.0).abs() < 1e-12, "{kind:?}");
        }
    }

    #[test]
    fn face_normals_point_outwards() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10] {
            let m = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], kind);
            let expect = [
                ("x0", [-1.0, 0.0, 0.0]),
                ("x1", [1.0, 0.0, 0.0]),
                ("y0", [0.0, -1.0, 0.0]),
                ("y1", [0.0, 1.0, 0.0]),
                ("z0", [0.0, 0.0, -1.0]),
                ("z1", [0.0, 0.0, 1.0]),
            ];
            for (name, n) in expect {
                for f in &m.face_sets[name] {
                    let cell = m.cell(f.cell);
                    let l = kind.faces()[f.face];
                    let p: Vec<[f64; 3]> = l.iter().map(|&i| m.nodes[cell[i]]).collect();
                    let a = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
                    let b = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
                    let cr = [
                        a[1] * b[2] - a[2] * b[1],
                        a[2] * b[0] - a[0] * b[2],
                        a[0] * b[1] - a[1] * b[0],
                    ];
                    let dot = cr[0] * n[0] + cr[1] * n[1] + cr[2] * n[2];
                    assert!(dot > 0.0, "{kind:?} face set {name}");
                }
            }
        }
    }

    #[test]
    fn colouring_separates_cells_sharing_nodes() {
        let m = box_mesh([1.0, 1.0, 1.0], [3, 3, 2], ElementKind::Tet4);
        let colours = m.cell_colours();
        let total: usize = colours.iter().map(|c| c.len()).sum();
        assert_eq!(total, m.n_cells());
        for colour in &colours {
            let mut seen = vec![false; m.n_nodes()];
            for &c in colour {
                for &n in m.cell(c) {
                    assert!(!seen[n], "two cells of one colour share node {n}");
                    seen[n] = true;
                }
            }
        }
    }
}
