//! Partition of a mesh's cells over processes, for an assembly shared between MPI ranks.

use super::Mesh;
use metis_sys::{idx_t, METIS_PartMeshDual, METIS_SetDefaultOptions, METIS_NOPTIONS};

/// METIS keeps its random state in process globals: every call of METIS in this crate (the
/// partitions here, the orderings of the sparse factorisations) holds this lock, so that an
/// ordering or a partition, and with it every result, is the same when several start together.
pub(crate) static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The part (0..`parts`) of every cell: METIS's k-way partition of the cells' dual graph, in
/// which two cells are adjacent when they share a node, so that the parts' interfaces (the
/// unknowns that several processes add to) are small. METIS runs with its default (fixed) seed:
/// the same mesh gives the same partition on every process. When METIS cannot partition (fewer
/// cells than parts, indices beyond 32 bits, a METIS error) the cells are split into contiguous
/// blocks of their numbering instead.
pub fn partition_cells(mesh: &Mesh, parts: usize) -> Vec<usize> {
    let n = mesh.n_cells();
    if parts <= 1 || n == 0 {
        return vec![0; n];
    }
    metis_parts(mesh, parts).unwrap_or_else(|| (0..n).map(|c| c * parts / n).collect())
}

fn metis_parts(mesh: &Mesh, parts: usize) -> Option<Vec<usize>> {
    let n = mesh.n_cells();
    let npc = mesh.kind.nodes_per_cell();
    if n < parts || n * npc >= idx_t::MAX as usize || mesh.n_nodes() >= idx_t::MAX as usize {
        return None;
    }
    let eptr: Vec<idx_t> = (0..=n).map(|c| (c * npc) as idx_t).collect();
    let eind: Vec<idx_t> = (0..n)
        .flat_map(|c| mesh.cell(c).iter().map(|&v| v as idx_t))
        .collect();
    let (mut eptr, mut eind) = (eptr, eind);
    let mut ne = n as idx_t;
    let mut nn = mesh.n_nodes() as idx_t;
    let mut ncommon: idx_t = 1;
    let mut nparts = parts as idx_t;
    let mut options = vec![0 as idx_t; METIS_NOPTIONS as usize];
    let mut objval: idx_t = 0;
    let mut epart = vec![0 as idx_t; n];
    let mut npart = vec![0 as idx_t; mesh.n_nodes()];
    let _one_at_a_time = METIS.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: the arrays have the sizes METIS documents (eptr ne+1, eind eptr[ne], epart ne,
    // npart nn, options METIS_NOPTIONS) and outlive the call; the weights may be null.
    let status = unsafe {
        METIS_SetDefaultOptions(options.as_mut_ptr());
        METIS_PartMeshDual(
            &mut ne,
            &mut nn,
            eptr.as_mut_ptr(),
            eind.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            &mut ncommon,
            &mut nparts,
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            &mut objval,
            epart.as_mut_ptr(),
            npart.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    let part: Vec<usize> = epart.into_iter().map(|p| p as usize).collect();
    part.iter().all(|&p| p < parts).then_some(part)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::ElementKind;

    #[test]
    fn cells_split_into_connected_balanced_parts() {
        let mesh = box_mesh([1.0, 1.0, 0.25], [8, 8, 2], ElementKind::Hex8);
        let part = partition_cells(&mesh, 2);
        assert_eq!(part, partition_cells(&mesh, 2), "deterministic");
        let count = |p: usize| part.iter().filter(|&&q| q == p).count();
        assert_eq!(count(0) + count(1), 128);
        assert!(
            count(0).abs_diff(count(1)) <= 8,
            "{} {}",
            count(0),
            count(1)
        );
        assert_eq!(partition_cells(&mesh, 1), vec![0; 128]);
        // more parts than cells: contiguous blocks
        let tiny = box_mesh([1.0, 1.0, 1.0], [1, 1, 2], ElementKind::Hex8);
        assert_eq!(partition_cells(&tiny, 3), vec![0, 1]);
    }
}
