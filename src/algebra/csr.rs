//! The sparse matrix of the assembled equations, in compressed sparse row form.

use std::sync::Arc;

/// A column index of a [`CsrMatrix`]: 32 bits, half the bytes of `usize` in the structure and in
/// every product's stream of the matrix (a process's matrix has far fewer than 2³² columns).
pub type Col = u32;

/// A square sparse matrix in compressed sparse row form (full storage, sorted columns).
///
/// The structure (`row_ptr`, `col_idx`) is shared: a clone copies the values only, so the
/// tangent, its copies held by the linear solvers and the matrices of the same pattern (mass,
/// iteration matrices) hold one structure between them (at 10⁶ unknowns the column indices of
/// a 3-D tangent take about 0.43 GB).
#[derive(Debug, Clone)]
pub struct CsrMatrix {
    pub n: usize,
    pub row_ptr: Arc<[usize]>,
    pub col_idx: Arc<[Col]>,
    pub values: Vec<f64>,
}

/// The columns of a matrix as [`Col`]s. Panics only past 2³² columns: a scenario's mesh is
/// refused beyond 2·10⁶ cells (some 10⁷ unknowns), long before.
pub fn to_cols(cols: impl IntoIterator<Item = usize>) -> Vec<Col> {
    cols.into_iter().map(col).collect()
}

/// One column index as a [`Col`] (see [`to_cols`]).
#[inline]
pub fn col(j: usize) -> Col {
    Col::try_from(j).expect("a column index beyond 2^32")
}

impl CsrMatrix {
    /// A matrix of `n` rows from its parts.
    pub fn new(n: usize, row_ptr: Vec<usize>, col_idx: Vec<Col>, values: Vec<f64>) -> Self {
        CsrMatrix {
            n,
            row_ptr: row_ptr.into(),
            col_idx: col_idx.into(),
            values,
        }
    }

    /// [`CsrMatrix::new`] from `usize` column indices (the unit tests' small matrices).
    #[cfg(test)]
    pub(crate) fn from_usize(
        n: usize,
        row_ptr: Vec<usize>,
        col_idx: Vec<usize>,
        values: Vec<f64>,
    ) -> Self {
        Self::new(n, row_ptr, to_cols(col_idx), values)
    }

    /// The row pointers in 32 bits, for a solver that takes both index arrays in one type
    /// (faer); `None` past 2³² stored entries.
    pub fn row_ptr_u32(&self) -> Option<Vec<Col>> {
        self.row_ptr
            .iter()
            .map(|&p| Col::try_from(p).ok())
            .collect()
    }

    /// The columns of row `i`.
    #[inline]
    pub fn row_cols(&self, i: usize) -> &[Col] {
        &self.col_idx[self.row_ptr[i]..self.row_ptr[i + 1]]
    }

    /// A zeroed matrix with the structure of `self` (shared, not copied).
    pub fn zeros_like(&self) -> Self {
        CsrMatrix {
            n: self.n,
            row_ptr: Arc::clone(&self.row_ptr),
            col_idx: Arc::clone(&self.col_idx),
            values: vec![0.0; self.col_idx.len()],
        }
    }

    /// Whether `other` has the same structure (the same shared arrays, or equal ones).
    pub fn same_pattern(&self, other: &CsrMatrix) -> bool {
        self.n == other.n
            && (Arc::ptr_eq(&self.col_idx, &other.col_idx)
                || (self.row_ptr == other.row_ptr && self.col_idx == other.col_idx))
    }

    /// Makes `self` a copy of `other`: only the values when the structure is the same.
    pub fn assign(&mut self, other: &CsrMatrix) {
        if self.same_pattern(other) {
            self.values.copy_from_slice(&other.values);
        } else {
            *self = other.clone();
        }
    }

    /// Position of entry (i, j) in `values`, if it is in the pattern.
    pub fn position(&self, i: usize, j: usize) -> Option<usize> {
        let j = Col::try_from(j).ok()?;
        let cols = self.row_cols(i);
        cols.binary_search(&j).ok().map(|p| self.row_ptr[i] + p)
    }

    /// y = A x.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate().take(self.n) {
            let mut s = 0.0;
            for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                s += self.values[p] * x[self.col_idx[p] as usize];
            }
            *yi = s;
        }
    }

    /// y = Aᵀ x.
    pub fn mul_transposed(&self, x: &[f64], y: &mut [f64]) {
        y[..self.n].fill(0.0);
        for (i, &xi) in x.iter().enumerate().take(self.n) {
            for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                y[self.col_idx[p] as usize] += self.values[p] * xi;
            }
        }
    }

    /// y = A x, rows in parallel on the rayon pool when the matrix is large (each row is summed
    /// in the same order as by [`CsrMatrix::mul_vec`], so the result does not depend on threads).
    pub fn par_mul_vec(&self, x: &[f64], y: &mut [f64]) {
        use rayon::prelude::*;
        const ROWS: usize = 4096;
        if self.nnz() < 200_000 || rayon::current_num_threads() < 2 {
            return self.mul_vec(x, y);
        }
        y[..self.n]
            .par_chunks_mut(ROWS)
            .enumerate()
            .for_each(|(c, ys)| {
                for (k, yi) in ys.iter_mut().enumerate() {
                    let i = c * ROWS + k;
                    let mut s = 0.0;
                    for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                        s += self.values[p] * x[self.col_idx[p] as usize];
                    }
                    *yi = s;
                }
            });
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.col_idx.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Aᵀx by the rows of A equals the product with the transposed dense matrix.
    #[test]
    fn the_transposed_product() {
        // A = [[4, 1, 0], [2, 5, 1], [0, 3, 6]]
        let a = CsrMatrix::from_usize(
            3,
            vec![0, 2, 5, 7],
            vec![0, 1, 0, 1, 2, 1, 2],
            vec![4.0, 1.0, 2.0, 5.0, 1.0, 3.0, 6.0],
        );
        let mut y = [9.0; 3];
        a.mul_transposed(&[1.0, -2.0, 0.5], &mut y);
        assert_eq!(y, [4.0 - 4.0, 1.0 - 10.0 + 1.5, -2.0 + 3.0]);
    }
}
