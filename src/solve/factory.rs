//! The factory of the linear solvers: [`SolverSettings::build`] is the one place where the
//! concrete solver types are named, so that the solver trait (`solve::linear`) depends on none
//! of them.

use super::auto::AutoSolver;
use super::iterative::AmgGmres;
use super::linear::{FaerLdlt, LinearSolver, SolverKind, SolverSettings};
use super::reused::ReusedLdlt;

impl SolverSettings {
    /// A new solver of these settings: the one place where concrete solver types are named.
    pub fn build(&self) -> Box<dyn LinearSolver> {
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
                if self.single_precision {
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
                if self.single_precision {
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
