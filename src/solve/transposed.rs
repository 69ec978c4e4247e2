//! Solves with the transpose of an assembled matrix, Aᵀx = b: the adjoint equations of a step,
//! whose Jacobian may be unsymmetric (follower pressures, Kelvin–Voigt viscosity). A matrix in
//! compressed sparse rows read as compressed sparse columns is its transpose, so a sparse LU
//! with partial pivoting (faer's) of that view solves with Aᵀ without forming it.

use crate::algebra::csr::CsrMatrix;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Lu;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

/// The LU factors of Aᵀ for a [`CsrMatrix`] A.
pub struct TransposedLu {
    lu: Lu<u32, f64>,
    n: usize,
}

impl TransposedLu {
    /// Factors Aᵀ; an error says why (a singular matrix, too many entries for 32-bit indices).
    pub fn factor(a: &CsrMatrix) -> Result<TransposedLu, String> {
        let row_ptr = a
            .row_ptr_u32()
            .ok_or("the matrix has more than 2^32 entries")?;
        let sym = SymbolicSparseColMatRef::new_checked(a.n, a.n, &row_ptr, None, &a.col_idx);
        let at = SparseColMatRef::new(sym, &a.values);
        let lu = at.sp_lu();
        super::vector_state::clear_after(faer::get_global_parallelism(), a.n);
        let lu = lu.map_err(|e| {
            format!("the LU factorisation of the transposed Jacobian failed: {e:?}")
        })?;
        Ok(TransposedLu { lu, n: a.n })
    }

    /// The order of the matrix.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Overwrites `b` with x, Aᵀx = b.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        assert_eq!(b.len(), self.n, "right-hand side of the wrong length");
        let mut rhs = faer::MatMut::from_column_major_slice_mut(b, self.n, 1);
        self.lu.solve_in_place(rhs.as_mut());
        super::vector_state::clear_after(faer::get_global_parallelism(), self.n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solution of Aᵀx = b for an unsymmetric A satisfies the transposed equations.
    #[test]
    fn solves_with_the_transpose() {
        // A = [[4, 1, 0], [2, 5, 1], [0, 3, 6]]
        let a = CsrMatrix::from_usize(
            3,
            vec![0, 2, 5, 7],
            vec![0, 1, 0, 1, 2, 1, 2],
            vec![4.0, 1.0, 2.0, 5.0, 1.0, 3.0, 6.0],
        );
        let b = [1.0, -2.0, 0.5];
        let mut x = b;
        TransposedLu::factor(&a).unwrap().solve_in_place(&mut x);
        let dense = [[4.0, 1.0, 0.0], [2.0, 5.0, 1.0], [0.0, 3.0, 6.0]];
        for j in 0..3 {
            let atx: f64 = (0..3).map(|i| dense[i][j] * x[i]).sum();
            assert!((atx - b[j]).abs() < 1e-13, "column {j}: {atx} vs {}", b[j]);
        }
        // and not the equations of A itself
        let ax: f64 = (0..3).map(|j| dense[0][j] * x[j]).sum();
        assert!((ax - b[0]).abs() > 1e-3);
    }
}
