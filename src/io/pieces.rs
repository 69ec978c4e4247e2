//! The piece of the mesh one MPI rank writes into a distributed run's field files: the cells the
//! rank assembles and the nodes they touch, numbered locally. Rank 0 writes the `.pvtu` index
//! over all ranks' pieces, so a field file costs each rank only its part.

use crate::mesh::Mesh;

/// One rank's part of the mesh for its piece of every field file.
#[derive(Debug, Clone)]
pub struct Pieces {
    /// This process's rank and the number of ranks.
    pub rank: usize,
    pub ranks: usize,
    /// The mesh cells of this piece, ascending.
    cells: Vec<usize>,
    /// The mesh node of each of the piece's nodes, ascending.
    nodes: Vec<usize>,
    /// The piece's node coordinates (m).
    points: Vec<[f64; 3]>,
    /// The piece's connectivity in its own node numbers.
    connectivity: Vec<usize>,
}

impl Pieces {
    /// The piece of rank `rank` of `ranks`: the cells marked in `owned` (one flag per cell).
    pub fn new(mesh: &Mesh, owned: &[bool], rank: usize, ranks: usize) -> Self {
        let cells: Vec<usize> = (0..mesh.n_cells())
            .filter(|&c| owned.get(c).copied().unwrap_or(false))
            .collect();
        let mut local = vec![usize::MAX; mesh.n_nodes()];
        for &c in &cells {
            for &n in mesh.cell(c) {
                local[n] = 0;
            }
        }
        let mut nodes = Vec::new();
        for (n, l) in local.iter_mut().enumerate() {
            if *l == 0 {
                *l = nodes.len();
                nodes.push(n);
            }
        }
        let connectivity = cells
            .iter()
            .flat_map(|&c| mesh.cell(c).iter().map(|&n| local[n]))
            .collect();
        let points = nodes.iter().map(|&n| mesh.nodes[n]).collect();
        Pieces {
            rank,
            ranks,
            cells,
            nodes,
            points,
            connectivity,
        }
    }

    /// The piece's node coordinates (m).
    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// The piece's connectivity, in its own node numbers.
    pub fn connectivity(&self) -> &[usize] {
        &self.connectivity
    }

    /// The piece's part of a nodal array of the whole mesh (`components` values per node).
    pub fn node_values(&self, values: &[f64], components: usize) -> Vec<f64> {
        gather(&self.nodes, values, components)
    }

    /// The piece's part of a cell array of the whole mesh (`components` values per cell).
    pub fn cell_values(&self, values: &[f64], components: usize) -> Vec<f64> {
        gather(&self.cells, values, components)
    }

    /// The number of cells of the piece.
    pub fn n_cells(&self) -> usize {
        self.cells.len()
    }

    /// The file name of rank `rank`'s piece of field file `index`.
    pub fn file_name(index: usize, rank: usize) -> String {
        format!("step_{index:05}_p{rank:04}.vtu")
    }
}

/// The tuples `at` of an array of `components`-tuples.
fn gather(at: &[usize], values: &[f64], components: usize) -> Vec<f64> {
    at.iter()
        .flat_map(|&i| &values[i * components..(i + 1) * components])
        .copied()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::ElementKind;

    #[test]
    fn the_pieces_cover_the_mesh_once_with_local_numbers() {
        let mesh = box_mesh([1.0, 1.0, 1.0], [3, 2, 2], ElementKind::Hex8);
        let n = mesh.n_cells();
        let owned: Vec<Vec<bool>> = (0..3)
            .map(|r| (0..n).map(|c| c % 3 == r).collect())
            .collect();
        let pieces: Vec<Pieces> = (0..3)
            .map(|r| Pieces::new(&mesh, &owned[r], r, 3))
            .collect();
        assert_eq!(pieces.iter().map(Pieces::n_cells).sum::<usize>(), n);
        // a nodal array of the whole mesh: each piece's values belong to its own points
        let xs: Vec<f64> = mesh.nodes.iter().flat_map(|p| *p).collect();
        let cell_ids: Vec<f64> = (0..n).map(|c| c as f64).collect();
        let mut seen = vec![false; n];
        for p in &pieces {
            let local = p.node_values(&xs, 3);
            for (k, point) in p.points().iter().enumerate() {
                assert_eq!(&local[3 * k..3 * k + 3], point.as_slice());
            }
            let ids = p.cell_values(&cell_ids, 1);
            let npc = mesh.kind.nodes_per_cell();
            for (k, &id) in ids.iter().enumerate() {
                let c = id as usize;
                assert!(!seen[c] && owned[p.rank][c]);
                seen[c] = true;
                // the local connectivity names the same coordinates as the mesh's
                for (j, &l) in p.connectivity()[k * npc..(k + 1) * npc].iter().enumerate() {
                    assert_eq!(p.points()[l], mesh.nodes[mesh.cell(c)[j]]);
                }
            }
            assert!(p.points().len() < mesh.n_nodes());
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(Pieces::file_name(3, 1), "step_00003_p0001.vtu");
    }
}
