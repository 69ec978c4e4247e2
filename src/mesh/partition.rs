//! Partition of a mesh's cells over processes, for an assembly shared between MPI ranks.

use super::Mesh;
use metis_sys::{
    idx_t, METIS_Free, METIS_MeshToDual, METIS_PartGraphKway, METIS_PartMeshDual,
    METIS_SetDefaultOptions, METIS_NOPTIONS,
};

/// METIS keeps its random state in process globals: every call of METIS in this crate (the
/// partitions here, the orderings of the sparse factorisations) holds this lock, so that an
/// ordering or a partition, and with it every result, is the same when several start together.
pub(crate) static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The part (0..`parts`) of every cell: METIS's k-way partition of the cells' dual graph, in
/// which two cells are adjacent when they share a node, so that the parts' interfaces (the
/// unknowns that several processes add to) are small. With `unknowns` (the free unknowns of each
/// node) the parts balance two things at once (METIS's multi-constraint partitioning): their
/// cells, the work of assembly, and their share of the unknowns, the rows of the linear systems
/// (each node's unknowns divided among its cells); a mesh with many held nodes, such as a
/// clamped rim, otherwise gives one part far more rows than the other. METIS runs with its
/// default (fixed) seed: the same mesh gives the same partition on every process. When the
/// two-constraint partition fails, the cells alone are balanced; when METIS cannot partition at
/// all (fewer cells than parts, indices beyond 32 bits, a METIS error) the cells are split into
/// contiguous blocks of their numbering instead.
pub fn partition_cells(mesh: &Mesh, parts: usize, unknowns: Option<&[usize]>) -> Vec<usize> {
    let n = mesh.n_cells();
    if parts <= 1 || n == 0 {
        return vec![0; n];
    }
    let unknowns = unknowns.filter(|u| u.len() == mesh.n_nodes());
    with_fallbacks(n, parts, unknowns, |weights| {
        metis_parts(mesh, parts, weights)
    })
}

/// The partition of `n` cells by `partition` (given the unknowns of the nodes, or `None` for
/// the cells alone): with the unknowns when there are any, else, or when that fails, the cells
/// alone, and when that fails too, contiguous blocks of the numbering.
fn with_fallbacks<'a>(
    n: usize,
    parts: usize,
    unknowns: Option<&'a [usize]>,
    partition: impl Fn(Option<&'a [usize]>) -> Option<Vec<usize>>,
) -> Vec<usize> {
    partition(unknowns)
        .or_else(|| unknowns.and_then(|_| partition(None)))
        .unwrap_or_else(|| (0..n).map(|c| c * parts / n).collect())
}

/// Per cell: its share of its nodes' unknowns, each node's divided evenly among its cells, in
/// units of 1/840 (840 is divisible by 1 to 8, the cells at a node of a structured mesh).
fn row_weights(mesh: &Mesh, unknowns: &[usize]) -> Vec<idx_t> {
    let mut cells_at = vec![0usize; mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        mesh.cell(c).iter().for_each(|&v| cells_at[v] += 1);
    }
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell(c)
                .iter()
                .map(|&v| (840 * unknowns[v] + cells_at[v] / 2) / cells_at[v])
                .sum::<usize>()
                .min(idx_t::MAX as usize / mesh.n_cells()) as idx_t
        })
        .collect()
}

fn metis_parts(mesh: &Mesh, parts: usize, unknowns: Option<&[usize]>) -> Option<Vec<usize>> {
    let n = mesh.n_cells();
    let npc = mesh.kind.nodes_per_cell();
    if n < parts || n * npc >= idx_t::MAX as usize || mesh.n_nodes() >= idx_t::MAX as usize {
        return None;
    }
    let mut eptr: Vec<idx_t> = (0..=n).map(|c| (c * npc) as idx_t).collect();
    let mut eind: Vec<idx_t> = (0..n)
        .flat_map(|c| mesh.cell(c).iter().map(|&v| v as idx_t))
        .collect();
    let mut ne = n as idx_t;
    let mut nn = mesh.n_nodes() as idx_t;
    let mut ncommon: idx_t = 1;
    let mut nparts = parts as idx_t;
    let mut options = vec![0 as idx_t; METIS_NOPTIONS as usize];
    let mut objval: idx_t = 0;
    let mut epart = vec![0 as idx_t; n];
    let _one_at_a_time = METIS.lock().unwrap_or_else(|e| e.into_inner());
    let status = if let Some(unknowns) = unknowns {
        // two weights per cell: 1 (its assembly) and its share of the rows
        let mut vwgt: Vec<idx_t> = row_weights(mesh, unknowns)
            .into_iter()
            .flat_map(|w| [1, w.max(1)])
            .collect();
        let mut ncon: idx_t = 2;
        let mut numflag: idx_t = 0;
        let (mut xadj, mut adjncy): (*mut idx_t, *mut idx_t) =
            (std::ptr::null_mut(), std::ptr::null_mut());
        // SAFETY: the arrays have the sizes METIS documents (eptr ne+1, eind eptr[ne], vwgt
        // ncon·ne, epart ne, options METIS_NOPTIONS) and outlive the calls; the dual graph is
        // allocated by METIS (xadj ne+1 entries, adjncy xadj[ne]), read only by METIS and freed
        // by METIS_Free; null weights and targets mean METIS's defaults
        unsafe {
            METIS_SetDefaultOptions(options.as_mut_ptr());
            let mut status = METIS_MeshToDual(
                &mut ne,
                &mut nn,
                eptr.as_mut_ptr(),
                eind.as_mut_ptr(),
                &mut ncommon,
                &mut numflag,
                &mut xadj,
                &mut adjncy,
            );
            if status == metis_sys::rstatus_et_METIS_OK {
                status = METIS_PartGraphKway(
                    &mut ne,
                    &mut ncon,
                    xadj,
                    adjncy,
                    vwgt.as_mut_ptr(),
                    std::ptr::null_mut(),
                    std::ptr::null_mut(),
                    &mut nparts,
                    std::ptr::null_mut(),
                    std::ptr::null_mut(),
                    options.as_mut_ptr(),
                    &mut objval,
                    epart.as_mut_ptr(),
                );
            }
            if !xadj.is_null() {
                METIS_Free(xadj.cast());
            }
            if !adjncy.is_null() {
                METIS_Free(adjncy.cast());
            }
            status
        }
    } else {
        let mut npart = vec![0 as idx_t; mesh.n_nodes()];
        // SAFETY: the arrays have the sizes METIS documents (eptr ne+1, eind eptr[ne], epart ne,
        // npart nn, options METIS_NOPTIONS) and outlive the call; the weights may be null.
        unsafe {
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
        }
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
        let part = partition_cells(&mesh, 2, None);
        assert_eq!(part, partition_cells(&mesh, 2, None), "deterministic");
        let count = |p: usize| part.iter().filter(|&&q| q == p).count();
        assert_eq!(count(0) + count(1), 128);
        assert!(
            count(0).abs_diff(count(1)) <= 8,
            "{} {}",
            count(0),
            count(1)
        );
        assert_eq!(partition_cells(&mesh, 1, None), vec![0; 128]);
        // held nodes (no unknowns) in one corner: the parts balance the cells and the unknowns
        let shares = |held: &dyn Fn(&[f64; 3]) -> bool, parts: usize, weighted: bool| {
            let unknowns: Vec<usize> = mesh
                .nodes
                .iter()
                .map(|x| if held(x) { 0 } else { 4 })
                .collect();
            let part = partition_cells(&mesh, parts, weighted.then_some(&unknowns[..]));
            let mut cells = vec![0usize; parts];
            part.iter().for_each(|&p| cells[p] += 1);
            // each part's share of the unknowns (a node's divided among its cells)
            let mut rows = vec![0usize; parts];
            for (c, w) in row_weights(&mesh, &unknowns).into_iter().enumerate() {
                rows[part[c]] += w as usize;
            }
            (cells, rows)
        };
        // the largest relative departure from an even share
        let uneven = |v: &[usize]| {
            let all: usize = v.iter().sum();
            v.iter()
                .map(|&x| (x as f64 * v.len() as f64 / all as f64 - 1.0).abs())
                .fold(0.0, f64::max)
        };
        let third = |x: &[f64; 3]| x[0] < 0.3;
        let quadrant = |x: &[f64; 3]| x[0] < 0.55 && x[1] < 0.55;
        for (held, parts) in [
            (&third as &dyn Fn(&[f64; 3]) -> bool, 2),
            (&third, 3),
            (&quadrant, 2),
        ] {
            let (cells, rows) = shares(held, parts, true);
            assert!(uneven(&cells) <= 0.1, "{parts} parts: cells {cells:?}");
            assert!(uneven(&rows) <= 0.1, "{parts} parts: rows {rows:?}");
            eprintln!("{parts} parts: cells {cells:?}, rows {rows:?}");
        }
        // the weights are what balances them: a cut of the cells alone leaves the held corner
        // on one part, which then holds far fewer unknowns
        let (cells, rows) = shares(&quadrant, 2, false);
        eprintln!("cells alone: cells {cells:?}, rows {rows:?}");
        assert!(
            uneven(&cells) <= 0.1 && uneven(&rows) > 0.2,
            "{cells:?} {rows:?}"
        );
        // a failed two-constraint partition falls back to the cells alone, a failed METIS to
        // contiguous blocks
        let unknowns = vec![4; mesh.n_nodes()];
        let calls = std::cell::RefCell::new(Vec::new());
        let cells_alone = partition_cells(&mesh, 2, None);
        let fallback = with_fallbacks(128, 2, Some(&unknowns), |w| {
            calls.borrow_mut().push(w.is_some());
            w.is_none().then(|| cells_alone.clone())
        });
        assert_eq!(fallback, cells_alone);
        assert_eq!(*calls.borrow(), [true, false]);
        let blocks = with_fallbacks(6, 3, Some(&unknowns), |_| None);
        assert_eq!(blocks, [0, 0, 1, 1, 2, 2]);
        // without unknowns METIS is asked once
        calls.borrow_mut().clear();
        with_fallbacks(6, 3, None, |w| {
            calls.borrow_mut().push(w.is_some());
            None
        });
        assert_eq!(*calls.borrow(), [false]);
        // more parts than cells: contiguous blocks
        let tiny = box_mesh([1.0, 1.0, 1.0], [1, 1, 2], ElementKind::Hex8);
        assert_eq!(partition_cells(&tiny, 3, None), vec![0, 1]);
    }
}
