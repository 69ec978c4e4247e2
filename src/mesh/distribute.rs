//! One rank's part of a mesh whose cells are partitioned between MPI ranks, as a mesh of its own.
//!
//! A rank of a distributed run needs only its own cells, the nodes they touch and the parts of
//! the named sets that lie on them. [`LocalMesh::of_rank`] cuts that part out of the whole mesh
//! as an ordinary [`Mesh`]: its cells in ascending order of their global numbers, its nodes
//! numbered **owned first, then ghosts** (each group ascending in global number), and every node,
//! face and cell set restricted to it under the same name (empty where the set misses the
//! rank). Built on such a mesh, a model is the rank's part of the whole model: its cells' terms,
//! its parts of the supports and electrodes; the sums over the ranks at the nodes they share are
//! then the only coupling (the whole residual is the sum of the parts at their global nodes).
//!
//! A node is **owned** by exactly one rank among those whose cells meet it (the owners are the
//! caller's: see [`crate::problem::assembly::node_processes`]); it is a **ghost** of every other
//! rank that holds it. [`Numbering::contiguous`] renumbers the nodes so that each rank owns one
//! contiguous block, rank after rank, as the rows of a distributed matrix or vector are laid out
//! (PETSc's ownership ranges).

use super::{FaceRef, Mesh};
use std::collections::BTreeMap;

/// The cells and nodes of one rank, and where they sit in the whole mesh.
#[derive(Debug, Clone)]
pub struct LocalMesh {
    /// This rank and the number of ranks.
    pub rank: usize,
    pub ranks: usize,
    /// The rank's mesh: its own cells, its nodes (owned, then ghosts), its parts of the sets.
    pub mesh: Mesh,
    /// The global number of each local cell (ascending).
    pub cells: Vec<usize>,
    /// The global number of each local node: the first [`LocalMesh::owned`] are this rank's,
    /// the rest ghosts; each group ascending.
    pub nodes: Vec<usize>,
    /// The number of owned nodes.
    pub owned: usize,
    /// The owning rank of each ghost (local node `owned + i` is owned by `ghost_owner[i]`).
    pub ghost_owner: Vec<usize>,
}

/// Why a mesh cannot be cut into a rank's part.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistributeError {
    #[error("the partition has {got} entries for {cells} cells")]
    PartitionLength { got: usize, cells: usize },
    #[error("the node owners have {got} entries for {nodes} nodes")]
    OwnersLength { got: usize, nodes: usize },
    #[error("cell {cell} is given to rank {part}, but there are only {ranks} ranks")]
    PartOutOfRange {
        cell: usize,
        part: usize,
        ranks: usize,
    },
    #[error("node {node} is owned by rank {owner}, whose cells do not meet it")]
    OwnerWithoutCells { node: usize, owner: usize },
}

impl LocalMesh {
    /// The part of `mesh` of rank `rank` of `ranks`: the cells `c` with `part[c] == rank`, and
    /// the nodes they touch, of which this rank owns those with `owner[n] == rank`. A node in no
    /// cell belongs to rank 0, as an owned node without cells. Fails when the arrays do not fit
    /// the mesh, or a rank would own a node its cells do not meet (the owner must be one of the
    /// node's ranks, so that every rank's owned rows lie among its own cells').
    pub fn of_rank(
        mesh: &Mesh,
        part: &[usize],
        owner: &[usize],
        rank: usize,
        ranks: usize,
    ) -> Result<Self, DistributeError> {
        let (n_cells, n_nodes) = (mesh.n_cells(), mesh.n_nodes());
        if part.len() != n_cells {
            return Err(DistributeError::PartitionLength {
                got: part.len(),
                cells: n_cells,
            });
        }
        if owner.len() != n_nodes {
            return Err(DistributeError::OwnersLength {
                got: owner.len(),
                nodes: n_nodes,
            });
        }
        if let Some((cell, &p)) = part.iter().enumerate().find(|(_, &p)| p >= ranks) {
            return Err(DistributeError::PartOutOfRange {
                cell,
                part: p,
                ranks,
            });
        }
        // which ranks' cells meet each node: checked for the owner of every node
        let mut meets = vec![false; n_nodes];
        let mut in_cell = vec![false; n_nodes];
        for c in 0..n_cells {
            for &n in mesh.cell(c) {
                in_cell[n] = true;
                if part[c] == owner[n] {
                    meets[n] = true;
                }
            }
        }
        if let Some(node) = (0..n_nodes).find(|&n| in_cell[n] && !meets[n]) {
            return Err(DistributeError::OwnerWithoutCells {
                node,
                owner: owner[node],
            });
        }
        let cells: Vec<usize> = (0..n_cells).filter(|&c| part[c] == rank).collect();
        let mut here = vec![false; n_nodes];
        for &c in &cells {
            mesh.cell(c).iter().for_each(|&n| here[n] = true);
        }
        if rank == 0 {
            (0..n_nodes)
                .filter(|&n| !in_cell[n])
                .for_each(|n| here[n] = true);
        }
        let owns = |n: usize| {
            if in_cell[n] {
                owner[n] == rank
            } else {
                rank == 0
            }
        };
        let mut nodes: Vec<usize> = (0..n_nodes).filter(|&n| here[n] && owns(n)).collect();
        let owned = nodes.len();
        nodes.extend((0..n_nodes).filter(|&n| here[n] && !owns(n)));
        let ghost_owner = nodes[owned..].iter().map(|&n| owner[n]).collect();
        let mut local = vec![usize::MAX; n_nodes];
        for (l, &n) in nodes.iter().enumerate() {
            local[n] = l;
        }
        let mut local_cell = vec![usize::MAX; n_cells];
        for (l, &c) in cells.iter().enumerate() {
            local_cell[c] = l;
        }
        let connectivity = cells
            .iter()
            .flat_map(|&c| mesh.cell(c).iter().map(|&n| local[n]))
            .collect();
        let node_sets = restrict(&mesh.node_sets, |&n| {
            (local[n] != usize::MAX).then_some(local[n])
        });
        let cell_sets = restrict(&mesh.cell_sets, |&c| {
            (local_cell[c] != usize::MAX).then_some(local_cell[c])
        });
        let face_sets = restrict(&mesh.face_sets, |f: &FaceRef| {
            (local_cell[f.cell] != usize::MAX).then_some(FaceRef {
                cell: local_cell[f.cell],
                face: f.face,
            })
        });
        let local_mesh = Mesh {
            kind: mesh.kind,
            nodes: nodes.iter().map(|&n| mesh.nodes[n]).collect(),
            connectivity,
            node_sets,
            face_sets,
            cell_sets,
        };
        Ok(LocalMesh {
            rank,
            ranks,
            mesh: local_mesh,
            cells,
            nodes,
            owned,
            ghost_owner,
        })
    }

    /// The rank's values of a nodal array of the whole mesh (`components` values per node), in
    /// local node order.
    pub fn gather_nodes(&self, whole: &[f64], components: usize) -> Vec<f64> {
        self.nodes
            .iter()
            .flat_map(|&n| &whole[n * components..(n + 1) * components])
            .copied()
            .collect()
    }
}

/// Every set of `sets` restricted by `map` (an element kept under its new value, or dropped),
/// under its name, in the order of the whole set.
fn restrict<T, U>(
    sets: &BTreeMap<String, Vec<T>>,
    map: impl Fn(&T) -> Option<U>,
) -> BTreeMap<String, Vec<U>> {
    sets.iter()
        .map(|(name, items)| (name.clone(), items.iter().filter_map(&map).collect()))
        .collect()
}

/// A numbering of the nodes in which each rank owns one contiguous block.
#[derive(Debug, Clone, PartialEq)]
pub struct Numbering {
    /// The new number of each node of the whole mesh.
    pub number: Vec<usize>,
    /// The first new number of each rank, and the node count at the end (`ranks + 1` entries):
    /// rank r owns the numbers `start[r]..start[r + 1]`.
    pub start: Vec<usize>,
}

impl Numbering {
    /// Nodes ordered by their owner, and within one owner by their number: the layout of the
    /// rows of a distributed vector whose ranks own their nodes' entries (`owner` as given to
    /// [`LocalMesh::of_rank`]).
    pub fn contiguous(owner: &[usize], ranks: usize) -> Self {
        let mut start = vec![0; ranks + 1];
        for &o in owner {
            start[o.min(ranks - 1) + 1] += 1;
        }
        for r in 0..ranks {
            start[r + 1] += start[r];
        }
        let mut next = start.clone();
        let number = owner
            .iter()
            .map(|&o| {
                let o = o.min(ranks - 1);
                next[o] += 1;
                next[o] - 1
            })
            .collect();
        Numbering { number, start }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::partition::partition_cells;
    use crate::mesh::ElementKind;

    /// The owner of each node: the lowest rank of its cells (a simple rule that meets the
    /// condition of [`LocalMesh::of_rank`]).
    fn lowest_owner(mesh: &Mesh, part: &[usize]) -> Vec<usize> {
        let mut owner = vec![usize::MAX; mesh.n_nodes()];
        for c in 0..mesh.n_cells() {
            for &n in mesh.cell(c) {
                owner[n] = owner[n].min(part[c]);
            }
        }
        owner
            .iter()
            .map(|&o| if o == usize::MAX { 0 } else { o })
            .collect()
    }

    /// The parts of a METIS partition cover the mesh: every cell once, every node owned once,
    /// each local cell with the global cell's nodes and coordinates, ghosts owned elsewhere.
    #[test]
    fn the_ranks_parts_cover_the_mesh_once() {
        let mesh = box_mesh([1.0, 1.0, 0.2], [8, 8, 2], ElementKind::Hex8);
        for ranks in [1, 2, 3, 4] {
            let part = partition_cells(&mesh, ranks, None);
            let owner = lowest_owner(&mesh, &part);
            let mut cell_seen = vec![0; mesh.n_cells()];
            let mut node_owned = vec![0; mesh.n_nodes()];
            let mut ghosts = 0;
            for rank in 0..ranks {
                let l = LocalMesh::of_rank(&mesh, &part, &owner, rank, ranks).unwrap();
                assert_eq!(l.mesh.n_cells(), l.cells.len());
                assert_eq!(l.mesh.n_nodes(), l.nodes.len());
                assert!(l.cells.windows(2).all(|w| w[0] < w[1]));
                assert!(l.nodes[..l.owned].windows(2).all(|w| w[0] < w[1]));
                assert!(l.nodes[l.owned..].windows(2).all(|w| w[0] < w[1]));
                for (lc, &c) in l.cells.iter().enumerate() {
                    cell_seen[c] += 1;
                    let global: Vec<usize> = l.mesh.cell(lc).iter().map(|&n| l.nodes[n]).collect();
                    assert_eq!(global, mesh.cell(c));
                }
                for (ln, &n) in l.nodes.iter().enumerate() {
                    assert_eq!(l.mesh.nodes[ln], mesh.nodes[n]);
                }
                l.nodes[..l.owned].iter().for_each(|&n| node_owned[n] += 1);
                for (i, &o) in l.ghost_owner.iter().enumerate() {
                    assert_ne!(o, rank);
                    assert_eq!(o, owner[l.nodes[l.owned + i]]);
                }
                ghosts += l.ghost_owner.len();
            }
            assert!(cell_seen.iter().all(|&s| s == 1), "{ranks} ranks");
            assert_eq!(
                ghosts > 0,
                ranks > 1,
                "{ranks} ranks: only a cut has ghosts"
            );
            assert!(node_owned.iter().all(|&s| s == 1), "{ranks} ranks");
        }
    }

    /// Each set of the whole mesh is the union of the ranks' parts of it, mapped back to global
    /// numbers; every rank has every set's name.
    #[test]
    fn the_sets_are_the_unions_of_their_parts() {
        let mut mesh = box_mesh([1.0, 1.0, 0.2], [6, 6, 2], ElementKind::Hex8);
        mesh.cell_sets
            .insert("left".into(), (0..mesh.n_cells()).step_by(3).collect());
        let ranks = 3;
        let part = partition_cells(&mesh, ranks, None);
        let owner = lowest_owner(&mesh, &part);
        let locals: Vec<LocalMesh> = (0..ranks)
            .map(|r| LocalMesh::of_rank(&mesh, &part, &owner, r, ranks).unwrap())
            .collect();
        assert!(!mesh.node_sets.is_empty() && !mesh.face_sets.is_empty());
        for name in mesh.set_names() {
            let mut union: Vec<usize> = locals
                .iter()
                .flat_map(|l| {
                    let nodes = l.mesh.set_nodes(&name).expect("every rank has every set");
                    nodes.into_iter().map(|n| l.nodes[n]).collect::<Vec<_>>()
                })
                .collect();
            union.sort_unstable();
            union.dedup();
            assert_eq!(union, mesh.set_nodes(&name).unwrap(), "set {name}");
        }
        for (name, faces) in &mesh.face_sets {
            let mut union: Vec<(usize, usize)> = locals
                .iter()
                .flat_map(|l| {
                    l.mesh.face_sets[name]
                        .iter()
                        .map(|f| (l.cells[f.cell], f.face))
                })
                .collect();
            union.sort_unstable();
            let mut whole: Vec<(usize, usize)> = faces.iter().map(|f| (f.cell, f.face)).collect();
            whole.sort_unstable();
            assert_eq!(union, whole, "face set {name}");
        }
        let mut cells: Vec<usize> = locals
            .iter()
            .flat_map(|l| l.mesh.cell_sets["left"].iter().map(|&c| l.cells[c]))
            .collect();
        cells.sort_unstable();
        assert_eq!(cells, mesh.cell_sets["left"]);
    }

    /// Owners that do not fit the partition, and arrays of the wrong length, are refused.
    #[test]
    fn owners_and_parts_that_do_not_fit_are_refused() {
        let mesh = box_mesh([1.0, 1.0, 1.0], [2, 1, 1], ElementKind::Hex8);
        let part = vec![0, 1];
        // node 0 is only in cell 0 (rank 0): rank 1 cannot own it
        let mut owner = lowest_owner(&mesh, &part);
        owner[0] = 1;
        assert_eq!(
            LocalMesh::of_rank(&mesh, &part, &owner, 0, 2).unwrap_err(),
            DistributeError::OwnerWithoutCells { node: 0, owner: 1 }
        );
        let owner = lowest_owner(&mesh, &part);
        assert!(matches!(
            LocalMesh::of_rank(&mesh, &[0], &owner, 0, 2),
            Err(DistributeError::PartitionLength { got: 1, cells: 2 })
        ));
        assert!(matches!(
            LocalMesh::of_rank(&mesh, &part, &owner[1..], 0, 2),
            Err(DistributeError::OwnersLength { .. })
        ));
        assert!(matches!(
            LocalMesh::of_rank(&mesh, &[0, 2], &owner, 0, 2),
            Err(DistributeError::PartOutOfRange {
                cell: 1,
                part: 2,
                ranks: 2
            })
        ));
    }

    /// The contiguous numbering gives each rank the block of its owned nodes, in their order.
    #[test]
    fn the_contiguous_numbering_gives_each_rank_one_block() {
        let owner = [1, 0, 2, 1, 0, 0, 2];
        let n = Numbering::contiguous(&owner, 3);
        assert_eq!(n.start, vec![0, 3, 5, 7]);
        assert_eq!(n.number, vec![3, 0, 5, 4, 1, 2, 6]);
        let mut sorted = n.number.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..7).collect::<Vec<_>>());
    }
}
