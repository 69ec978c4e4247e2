//! The factory of the linear solvers: [`SolverSettings::build`] is the one place where the
//! concrete solver types are named, so that the solver trait (`solve::linear`) depends on none
//! of them.

use super::auto::AutoSolver;
use super::iterative::AmgGmres;
use super::linear::{FactorPrecision, FaerLdlt, LinearSolver, SolverKind, SolverSettings};
use super::reused::ReusedLdlt;

impl SolverSettings {
    /// A new solver of these settings: the one place where concrete solver types are named.
    /// `auto` holds its reused factors in double precision unless `precision = "single"`.
    pub fn build(&self) -> Box<dyn LinearSolver> {
        self.build_in(self.precision == FactorPrecision::Single)
    }

    /// A solver for the load steps of a static stage: as [`SolverSettings::build`], except that
    /// with `precision = "auto"` and adaptive solves `auto` holds its reused factors in single
    /// precision ([`FactorPrecision::Auto`]).
    pub fn build_for_load_steps(&self) -> Box<dyn LinearSolver> {
        self.build_in(match self.precision {
            FactorPrecision::Auto => self.adaptive,
            FactorPrecision::Double => false,
            FactorPrecision::Single => true,
        })
    }

    /// [`SolverSettings::build`] with `auto`'s reused factors in single precision or not.
    fn build_in(&self, single: bool) -> Box<dyn LinearSolver> {
        match self.kind {
            SolverKind::Direct => {
                let s = FaerLdlt::with_ordering(self.ordering);
                Box::new(match self.memory_limit {
                    Some(bytes) => s.memory_limit(bytes),
                    None => s,
                })
            }
            SolverKind::Auto => {
                let mut s = ReusedLdlt::with_ordering(self.ordering)
                    .from_unknowns(self.reuse_from)
                    .adaptive(self.adaptive);
                if single {
                    s = s.single_precision();
                }
                if let Some(bytes) = self.memory_limit {
                    s = s.memory_limit(bytes);
                }
                Box::new(AutoSolver::new(s, self.rtol).adaptive(self.adaptive))
            }
            SolverKind::Iterative => Box::new(AmgGmres::new(self.rtol).adaptive(self.adaptive)),
            #[cfg(feature = "petsc")]
            SolverKind::Petsc => Box::new(
                super::petsc::PetscSolver::new(&self.petsc_options)
                    .adaptive(self.adaptive)
                    .keep_preconditioner(self.keep_preconditioner),
            ),
        }
    }

    /// A solver for the unsymmetric exact Jacobian of a dynamic step (`jacobian = "exact"`):
    /// FGMRES on the matrix preconditioned by a held LDLᵀ factor of its symmetric part
    /// ([`ReusedLdlt::unsymmetric`]). `None` for the kinds that do not factor (they take the
    /// symmetric iteration matrix).
    pub fn build_unsymmetric(&self) -> Option<Box<dyn LinearSolver>> {
        match self.kind {
            SolverKind::Direct | SolverKind::Auto => {
                // every solve to full accuracy: Newton then converges quadratically, and each
                // of its iterations costs a tangent, far more than the Krylov iterations
                let mut s = ReusedLdlt::with_ordering(self.ordering).unsymmetric();
                if self.precision == FactorPrecision::Single {
                    s = s.single_precision();
                }
                if let Some(bytes) = self.memory_limit {
                    s = s.memory_limit(bytes);
                }
                Some(Box::new(s))
            }
            _ => None,
        }
    }

    /// For a solver that sums the parts of processes that share the cells: an exact direct
    /// solver of the same kind for symmetric indefinite matrices whose diagonal may vanish
    /// (pivoting), whatever the options of the run's solver or `PETSC_OPTIONS` say: PETSc with
    /// MUMPS's LDLᵀ. `None` for the kinds that take whole matrices.
    pub fn distributed_direct(&self) -> Option<Box<dyn LinearSolver>> {
        match self.kind {
            SolverKind::Direct | SolverKind::Auto | SolverKind::Iterative => None,
            #[cfg(feature = "petsc")]
            SolverKind::Petsc => Some(Box::new(super::petsc::PetscSolver::mumps_ldlt())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algebra::csr::CsrMatrix;

    /// The 1-D Laplacian of `n` unknowns with a unit shift, in CSR.
    fn tridiagonal(n: usize) -> CsrMatrix {
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::new());
        for i in 0..n {
            for (j, v) in [(i.wrapping_sub(1), -1.0), (i, 3.0), (i + 1, -1.0)] {
                if j < n {
                    col_idx.push(j);
                    values.push(v);
                }
            }
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n, row_ptr, col_idx, values)
    }

    /// Krylov iterations of one solve right after the factorisation, and the solution's error:
    /// a double-precision factor of the operator solves exactly (none), a single-precision one
    /// through FGMRES.
    fn first_solve(mut solver: Box<dyn LinearSolver>) -> (usize, f64) {
        let a = tridiagonal(200);
        let x: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; a.n];
        a.mul_vec(&x, &mut b);
        solver.set_operator(&a).unwrap();
        solver.solve_in_place(&mut b).unwrap();
        let error = b
            .iter()
            .zip(&x)
            .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
        (solver.stats().krylov_iterations, error)
    }

    #[test]
    fn auto_precision_is_single_in_load_steps_and_double_elsewhere() {
        let with = |precision| SolverSettings {
            reuse_from: 0,
            precision,
            ..SolverSettings::default()
        };
        for (precision, load_steps, elsewhere) in [
            (FactorPrecision::Auto, true, false),
            (FactorPrecision::Double, false, false),
            (FactorPrecision::Single, true, true),
        ] {
            let s = with(precision);
            for (solver, single) in [
                (s.build_for_load_steps(), load_steps),
                (s.build(), elsewhere),
            ] {
                let (iterations, error) = first_solve(solver);
                assert_eq!(
                    iterations > 0,
                    single,
                    "{precision:?}: {iterations} iterations"
                );
                assert!(error < 1e-9, "{precision:?}: error {error:e}");
            }
        }
        // solves to a fixed tolerance take no products, so `auto` keeps double precision
        let fixed = SolverSettings {
            adaptive: false,
            ..with(FactorPrecision::Auto)
        };
        assert_eq!(first_solve(fixed.build_for_load_steps()).0, 0);
        // the direct kind factors in double precision whatever the setting says
        let direct = SolverSettings {
            kind: SolverKind::Direct,
            ..with(FactorPrecision::Single)
        };
        assert_eq!(first_solve(direct.build_for_load_steps()).0, 0);
    }
}
