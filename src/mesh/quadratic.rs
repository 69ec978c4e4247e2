//! Quadratic meshes from linear ones: a tet4 mesh becomes a tet10 mesh with straight edges by adding
//! a node at the midpoint of every edge (shared by the cells around the edge, so the mesh stays
//! conforming).

use super::TET10_EDGES;
use super::{ElementKind, Mesh};
use std::collections::HashMap;

/// The tet10 mesh of a tet4 mesh: the same cells (cell and face sets keep their meaning) with
/// mid-edge nodes numbered after the corner nodes, in order of first appearance. A mid-edge node
/// joins a node set when both ends of its edge are in it (exact for sets on planes, such as the
/// faces of a box). Any other mesh is returned unchanged.
pub fn to_tet10(mesh: &Mesh) -> Mesh {
    if mesh.kind != ElementKind::Tet4 {
        return mesh.clone();
    }
    let mut nodes = mesh.nodes.clone();
    let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
    let mut edges: Vec<(usize, usize)> = Vec::new();
    let mut connectivity = Vec::with_capacity(mesh.n_cells() * 10);
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        connectivity.extend_from_slice(cell);
        for [i, j] in TET10_EDGES {
            let (a, b) = (cell[i].min(cell[j]), cell[i].max(cell[j]));
            let id = *mid.entry((a, b)).or_insert_with(|| {
                let (p, q) = (mesh.nodes[a], mesh.nodes[b]);
                nodes.push([
                    0.5 * (p[0] + q[0]),
                    0.5 * (p[1] + q[1]),
                    0.5 * (p[2] + q[2]),
                ]);
                edges.push((a, b));
                nodes.len() - 1
            });
            connectivity.push(id);
        }
    }
    let n0 = mesh.n_nodes();
    let node_sets = mesh
        .node_sets
        .iter()
        .map(|(name, set)| {
            let mut s = set.clone();
            for (k, &(a, b)) in edges.iter().enumerate() {
                if set.binary_search(&a).is_ok() && set.binary_search(&b).is_ok() {
                    s.push(n0 + k);
                }
            }
            (name.clone(), s)
        })
        .collect();
    Mesh {
        kind: ElementKind::Tet10,
        nodes,
        connectivity,
        node_sets,
        face_sets: mesh.face_sets.clone(),
        cell_sets: mesh.cell_sets.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;

    #[test]
    fn mid_edge_nodes_are_shared_and_sets_extended() {
        let lin = box_mesh([1.0, 2.0, 3.0], [2, 1, 1], ElementKind::Tet4);
        let q = to_tet10(&lin);
        assert_eq!(q.n_cells(), lin.n_cells());
        // Euler: edges of the Kuhn-split box grid = nodes + cells − 1 − faces... counted directly
        let mut edges: Vec<(usize, usize)> = Vec::new();
        for c in 0..lin.n_cells() {
            let cell = lin.cell(c);
            for [i, j] in TET10_EDGES {
                edges.push((cell[i].min(cell[j]), cell[i].max(cell[j])));
            }
        }
        edges.sort_unstable();
        edges.dedup();
        assert_eq!(q.n_nodes(), lin.n_nodes() + edges.len());
        for c in 0..q.n_cells() {
            let cell = q.cell(c);
            for (e, [i, j]) in TET10_EDGES.iter().enumerate() {
                let (p, r, m) = (q.nodes[cell[*i]], q.nodes[cell[*j]], q.nodes[cell[4 + e]]);
                for k in 0..3 {
                    assert_eq!(m[k], 0.5 * (p[k] + r[k]));
                }
            }
        }
        // the set z1 holds every node on the plane z = 3 and no other
        let z1 = &q.node_sets["z1"];
        for n in 0..q.n_nodes() {
            let on = (q.nodes[n][2] - 3.0).abs() < 1e-12;
            assert_eq!(on, z1.contains(&n), "node {n}");
        }
        assert_eq!(q.face_set_nodes("z1").unwrap().len(), z1.len());
    }
}
