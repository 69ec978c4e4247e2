//! Fill-reducing orderings of a symmetric sparsity pattern.
//!
//! METIS nested dissection (METIS_NodeND, compiled from source by `metis-sys`) on the graph of the
//! matrix. METIS compresses vertices with identical adjacency, so the four dofs of a node are
//! ordered together without the solver knowing about nodes. On 3-D and plate meshes nested
//! dissection gives far less fill than minimum degree (see the benchmark figures in the notes).

use metis_sys::{idx_t, METIS_NodeND, METIS_SetDefaultOptions, METIS_NOPTIONS};

/// The nested-dissection permutation of a symmetric pattern in CSR form: `perm[new] = old`.
/// Returns `None` when METIS fails or the graph is too large for 32-bit indices.
pub fn nested_dissection(n: usize, row_ptr: &[usize], col_idx: &[u32]) -> Option<Vec<usize>> {
    if n == 0 {
        return Some(Vec::new());
    }
    if n >= idx_t::MAX as usize || col_idx.len() >= idx_t::MAX as usize {
        return None;
    }
    let mut xadj: Vec<idx_t> = Vec::with_capacity(n + 1);
    let mut adjncy: Vec<idx_t> = Vec::with_capacity(col_idx.len());
    xadj.push(0);
    for i in 0..n {
        for &j in &col_idx[row_ptr[i]..row_ptr[i + 1]] {
            if j as usize != i {
                adjncy.push(j as idx_t);
            }
        }
        xadj.push(adjncy.len() as idx_t);
    }
    if adjncy.is_empty() {
        return Some((0..n).collect());
    }
    let _one_at_a_time = crate::mesh::partition::METIS
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    let mut nvtxs = n as idx_t;
    let mut options = vec![0 as idx_t; METIS_NOPTIONS as usize];
    let mut perm = vec![0 as idx_t; n];
    let mut iperm = vec![0 as idx_t; n];
    // SAFETY: the arrays have the sizes METIS documents (xadj n+1, adjncy xadj[n], perm/iperm n,
    // options METIS_NOPTIONS) and outlive the calls; vwgt may be null.
    let status = unsafe {
        METIS_SetDefaultOptions(options.as_mut_ptr());
        METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    let perm: Vec<usize> = perm.into_iter().map(|p| p as usize).collect();
    // sanity: a permutation
    let mut seen = vec![false; n];
    for &p in &perm {
        if p >= n || seen[p] {
            return None;
        }
        seen[p] = true;
    }
    Some(perm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_a_grid_graph() {
        // 2-D 20x20 5-point grid
        let m = 20;
        let n = m * m;
        let mut row_ptr = vec![0];
        let mut col_idx = vec![];
        for i in 0..m {
            for j in 0..m {
                let mut cols = vec![i * m + j];
                if i > 0 {
                    cols.push((i - 1) * m + j);
                }
                if i + 1 < m {
                    cols.push((i + 1) * m + j);
                }
                if j > 0 {
                    cols.push(i * m + j - 1);
                }
                if j + 1 < m {
                    cols.push(i * m + j + 1);
                }
                cols.sort();
                col_idx.extend(cols);
                row_ptr.push(col_idx.len());
            }
        }
        let col_idx = crate::algebra::csr::to_cols(col_idx);
        let perm = nested_dissection(n, &row_ptr, &col_idx).unwrap();
        let mut sorted = perm.clone();
        sorted.sort();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        // deterministic
        assert_eq!(perm, nested_dissection(n, &row_ptr, &col_idx).unwrap());
    }
}
