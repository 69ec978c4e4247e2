//! Meshes: nodes, cells of one element kind, and named node, face and cell sets.
//!
//! Coordinates are in metres (reference configuration). Generators live in submodules.

pub mod disc;
pub mod distribute;
pub mod generate;
pub mod gmsh;
pub mod meridian;
pub mod partition;
pub mod quadratic;
pub mod sphere;
pub mod stack;
#[cfg(test)]
pub(crate) mod test_geometry;

use std::collections::BTreeMap;

/// The corners of the reference tetrahedron are (0,0,0), (1,0,0), (0,1,0), (0,0,1); the local
/// edges of the tet10 mid-edge nodes 4..9 (VTK order).
pub const TET10_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];

/// Cell kinds of the meridian plane, with Gmsh's node order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum MeridianKind {
    /// Bilinear quadrilateral, 2 × 2 Gauss points.
    Quad4,
    /// Serendipity quadrilateral (corners, then the mid-side nodes of sides 0–1, 1–2, 2–3, 3–0),
    /// 3 × 3 Gauss points.
    Quad8,
    /// Biquadratic quadrilateral (Quad8's nodes and the centre), 3 × 3 Gauss points.
    Quad9,
    /// Linear triangle, one point at the centroid.
    Tri3,
    /// Quadratic triangle (corners, then the mid-edge nodes of edges 0–1, 1–2, 2–0), the
    /// 3-point interior rule of degree 2.
    Tri6,
}

impl MeridianKind {
    /// Every kind.
    pub const ALL: [MeridianKind; 5] = [
        MeridianKind::Quad4,
        MeridianKind::Quad8,
        MeridianKind::Quad9,
        MeridianKind::Tri3,
        MeridianKind::Tri6,
    ];

    pub fn nodes_per_cell(self) -> usize {
        match self {
            MeridianKind::Quad4 => 4,
            MeridianKind::Quad8 => 8,
            MeridianKind::Quad9 => 9,
            MeridianKind::Tri3 => 3,
            MeridianKind::Tri6 => 6,
        }
    }

    /// Reference coordinates of the nodes.
    pub fn reference_nodes(self) -> Vec<[f64; 2]> {
        const Q: [[f64; 2]; 9] = [
            [-1.0, -1.0],
            [1.0, -1.0],
            [1.0, 1.0],
            [-1.0, 1.0],
            [0.0, -1.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [-1.0, 0.0],
            [0.0, 0.0],
        ];
        const T: [[f64; 2]; 6] = [
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [0.5, 0.0],
            [0.5, 0.5],
            [0.0, 0.5],
        ];
        match self {
            MeridianKind::Quad4 | MeridianKind::Quad8 | MeridianKind::Quad9 => {
                Q[..self.nodes_per_cell()].to_vec()
            }
            MeridianKind::Tri3 | MeridianKind::Tri6 => T[..self.nodes_per_cell()].to_vec(),
        }
    }

    /// Local node lists of the sides (the "faces" of a meridian cell, each sweeping a ring
    /// surface), in counter-clockwise order: the two corners, then the mid-side node of the
    /// quadratic kinds.
    pub fn sides(self) -> &'static [&'static [usize]] {
        match self {
            MeridianKind::Quad4 => &[&[0, 1], &[1, 2], &[2, 3], &[3, 0]],
            MeridianKind::Quad8 | MeridianKind::Quad9 => {
                &[&[0, 1, 4], &[1, 2, 5], &[2, 3, 6], &[3, 0, 7]]
            }
            MeridianKind::Tri3 => &[&[0, 1], &[1, 2], &[2, 0]],
            MeridianKind::Tri6 => &[&[0, 1, 3], &[1, 2, 4], &[2, 0, 5]],
        }
    }

    /// Name for messages and files.
    pub fn name(self) -> &'static str {
        match self {
            MeridianKind::Quad4 => "quad4",
            MeridianKind::Quad8 => "quad8",
            MeridianKind::Quad9 => "quad9",
            MeridianKind::Tri3 => "tri3",
            MeridianKind::Tri6 => "tri6",
        }
    }

    /// Whether the kind has quadratic shape functions.
    pub fn is_quadratic(self) -> bool {
        !matches!(self, MeridianKind::Quad4 | MeridianKind::Tri3)
    }
}

/// The element kinds deasim knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ElementKind {
    /// Trilinear hexahedron, VTK node order.
    Hex8,
    /// Linear tetrahedron.
    Tet4,
    /// Quadratic tetrahedron, VTK node order: corners 0–3, then the mid-edge nodes of the edges
    /// 0–1, 1–2, 2–0, 0–3, 1–3, 2–3.
    Tet10,
    /// A cell of the meridian plane (R, Z) of an axisymmetric model: node coordinates
    /// (R, Z, 0) with R ≥ 0, each cell standing for the ring it sweeps about the Z axis.
    Meridian(MeridianKind),
}

impl ElementKind {
    /// Nodes per cell.
    pub fn nodes_per_cell(self) -> usize {
        match self {
            ElementKind::Hex8 => 8,
            ElementKind::Tet4 => 4,
            ElementKind::Tet10 => 10,
            ElementKind::Meridian(k) => k.nodes_per_cell(),
        }
    }

    /// The meridian kind of an axisymmetric model's cells (`None` for 3-D cells).
    pub fn meridian(self) -> Option<MeridianKind> {
        match self {
            ElementKind::Meridian(k) => Some(k),
            _ => None,
        }
    }

    /// Local node lists of the faces, ordered so that the normal points outwards
    /// (counter-clockwise seen from outside; a meridian cell's faces are its sides): the corners first, then (tet10) the mid-edge nodes
    /// of the edges corner 0–1, 1–2, 2–0 of the face.
    pub fn faces(self) -> &'static [&'static [usize]] {
        match self {
            ElementKind::Hex8 => &[
                &[0, 3, 2, 1],
                &[4, 5, 6, 7],
                &[0, 1, 5, 4],
                &[1, 2, 6, 5],
                &[2, 3, 7, 6],
                &[3, 0, 4, 7],
            ],
            ElementKind::Tet4 => &[&[0, 2, 1], &[0, 1, 3], &[1, 2, 3], &[0, 3, 2]],
            ElementKind::Tet10 => &[
                &[0, 2, 1, 6, 5, 4],
                &[0, 1, 3, 4, 8, 7],
                &[1, 2, 3, 5, 9, 8],
                &[0, 3, 2, 7, 9, 6],
            ],
            ElementKind::Meridian(k) => k.sides(),
        }
    }

    /// Number of corner nodes of each face (3 for triangles, 4 for quadrilaterals, 2 for the
    /// sides of meridian cells): the corners
    /// come first in [`ElementKind::faces`].
    pub fn face_corners(self) -> usize {
        match self {
            ElementKind::Hex8 => 4,
            ElementKind::Tet4 | ElementKind::Tet10 => 3,
            ElementKind::Meridian(_) => 2,
        }
    }

    /// Name for messages and files.
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Hex8 => "hex8",
            ElementKind::Tet4 => "tet4",
            ElementKind::Tet10 => "tet10",
            ElementKind::Meridian(k) => k.name(),
        }
    }
}

/// A face of a cell: the cell index and the local face number of [`ElementKind::faces`].
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct FaceRef {
    pub cell: usize,
    pub face: usize,
}

/// A mesh of cells of one kind with named sets.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    pub kind: ElementKind,
    /// Reference coordinates (m).
    pub nodes: Vec<[f64; 3]>,
    /// Connectivity, `nodes_per_cell` indices per cell, flattened.
    pub connectivity: Vec<usize>,
    /// Named node sets (sorted, unique).
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// Named face sets.
    pub face_sets: BTreeMap<String, Vec<FaceRef>>,
    /// Named cell sets (sorted, unique).
    pub cell_sets: BTreeMap<String, Vec<usize>>,
}

impl Mesh {
    /// The cells `connectivity` of `kind` on `nodes`, without sets yet.
    pub fn new(kind: ElementKind, nodes: Vec<[f64; 3]>, connectivity: Vec<usize>) -> Self {
        Mesh {
            kind,
            nodes,
            connectivity,
            node_sets: BTreeMap::new(),
            face_sets: BTreeMap::new(),
            cell_sets: BTreeMap::new(),
        }
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.connectivity.len() / self.kind.nodes_per_cell()
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Node indices of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let n = self.kind.nodes_per_cell();
        &self.connectivity[c * n..(c + 1) * n]
    }

    /// Reference coordinates of the nodes of cell `c`, written into `out`.
    pub fn cell_coords_into(&self, c: usize, out: &mut [[f64; 3]]) {
        for (o, &n) in out.iter_mut().zip(self.cell(c)) {
            *o = self.nodes[n];
        }
    }

    /// The nodes of a face set (sorted, unique).
    pub fn face_set_nodes(&self, name: &str) -> Option<Vec<usize>> {
        let faces = self.face_sets.get(name)?;
        let mut nodes: Vec<usize> = faces
            .iter()
            .flat_map(|f| {
                let cell = self.cell(f.cell);
                self.kind.faces()[f.face].iter().map(move |&l| cell[l])
            })
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        Some(nodes)
    }

    /// Gives every face set a node set of the same name: the nodes of its faces (a node set of
    /// that name is replaced). The generators and the Gmsh reader name a boundary once.
    pub fn insert_face_set_nodes(&mut self) {
        let sets: Vec<(String, Vec<usize>)> = self
            .face_sets
            .keys()
            .map(|name| (name.clone(), self.face_set_nodes(name).unwrap_or_default()))
            .collect();
        self.node_sets.extend(sets);
    }

    /// Nodes of a named set: a node set, or else the nodes of a face set, or else of a cell set.
    pub fn set_nodes(&self, name: &str) -> Option<Vec<usize>> {
        if let Some(n) = self.node_sets.get(name) {
            return Some(n.clone());
        }
        if let Some(n) = self.face_set_nodes(name) {
            return Some(n);
        }
        let cells = self.cell_sets.get(name)?;
        let mut nodes: Vec<usize> = cells.iter().flat_map(|&c| self.cell(c).to_vec()).collect();
        nodes.sort_unstable();
        nodes.dedup();
        Some(nodes)
    }

    /// Names of every set, for messages.
    pub fn set_names(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .node_sets
            .keys()
            .chain(self.face_sets.keys())
            .chain(self.cell_sets.keys())
            .cloned()
            .collect();
        v.sort();
        v.dedup();
        v
    }

    /// Node index nearest to a point (ties: the lowest index).
    /// The bounding box of the nodes: lower and upper corner (m).
    pub fn extents(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for x in &self.nodes {
            for c in 0..3 {
                lo[c] = lo[c].min(x[c]);
                hi[c] = hi[c].max(x[c]);
            }
        }
        (lo, hi)
    }

    /// The node nearest to `p`.
    pub fn nearest_node(&self, p: [f64; 3]) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (i, x) in self.nodes.iter().enumerate() {
            let d = (x[0] - p[0]).powi(2) + (x[1] - p[1]).powi(2) + (x[2] - p[2]).powi(2);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// Every cell face (its sorted node list) with the number of cells it bounds: 1 on the
    /// boundary, 2 inside a conforming mesh.
    pub fn face_use_counts(&self) -> BTreeMap<Vec<usize>, usize> {
        let mut count: BTreeMap<Vec<usize>, usize> = BTreeMap::new();
        for c in 0..self.n_cells() {
            let cell = self.cell(c);
            for local in self.kind.faces() {
                let mut key: Vec<usize> = local.iter().map(|&l| cell[l]).collect();
                key.sort_unstable();
                *count.entry(key).or_default() += 1;
            }
        }
        count
    }

    /// Mean of the corner coordinates of cell `c` (m).
    pub fn cell_centroid(&self, c: usize) -> [f64; 3] {
        let nodes = self.cell(c);
        let mut x = [0.0; 3];
        for &n in nodes {
            for i in 0..3 {
                x[i] += self.nodes[n][i] / nodes.len() as f64;
            }
        }
        x
    }

    /// Greedy colouring of the cells so that no two cells of one colour share a node.
    /// Deterministic: cells are visited in index order and take the lowest free colour.
    pub fn cell_colours(&self) -> Vec<Vec<usize>> {
        let identity: Vec<usize> = (0..self.n_nodes()).collect();
        self.cell_colours_grouped(&identity)
    }

    /// As [`Mesh::cell_colours`], with nodes of one representative (`rep[node]`) counting as one
    /// node (tied nodes share equations).
    pub fn cell_colours_grouped(&self, rep: &[usize]) -> Vec<Vec<usize>> {
        let mut node_cells: Vec<Vec<usize>> = vec![Vec::new(); self.n_nodes()];
        for c in 0..self.n_cells() {
            for &n in self.cell(c) {
                node_cells[rep[n]].push(c);
            }
        }
        let mut colour = vec![usize::MAX; self.n_cells()];
        let mut colours: Vec<Vec<usize>> = Vec::new();
        let mut used: Vec<bool> = Vec::new();
        for c in 0..self.n_cells() {
            used.iter_mut().for_each(|u| *u = false);
            for &n in self.cell(c) {
                for &o in &node_cells[rep[n]] {
                    if colour[o] != usize::MAX {
                        used[colour[o]] = true;
                    }
                }
            }
            let k = used.iter().position(|u| !u).unwrap_or(used.len());
            if k == colours.len() {
                colours.push(Vec::new());
                used.push(false);
            }
            colour[c] = k;
            colours[k].push(c);
        }
        colours
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mesh starts without sets; every face set then gets the node set of its faces, replacing
    /// one of the same name and leaving the others.
    #[test]
    fn face_sets_give_node_sets_of_the_same_name() {
        let nodes = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let mut m = Mesh::new(ElementKind::Tet4, nodes, vec![0, 1, 2, 3]);
        assert!(m.node_sets.is_empty() && m.face_sets.is_empty() && m.cell_sets.is_empty());
        m.face_sets
            .insert("a".into(), vec![FaceRef { cell: 0, face: 0 }]);
        m.face_sets.insert("none".into(), vec![]);
        m.node_sets.insert("a".into(), vec![3]);
        m.node_sets.insert("b".into(), vec![1]);
        m.insert_face_set_nodes();
        let mut a: Vec<usize> = ElementKind::Tet4.faces()[0].to_vec();
        a.sort_unstable();
        assert_eq!(m.node_sets["a"], a);
        assert_eq!(m.node_sets["none"], Vec::<usize>::new());
        assert_eq!(m.node_sets["b"], [1]);
        assert_eq!(m.node_sets.len(), 3);
    }
}
