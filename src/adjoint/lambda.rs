//! The adjoint of one step's equations: λ with Jᵀλ = ∂J/∂y over the free unknowns y of a
//! system, J the system's Jacobian, solved with its transpose's LU.

use crate::algebra::system::NonlinearSystem;
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS};
use crate::problem::statics::StaticProblem;
use crate::solve::transposed::TransposedLu;
use crate::time::integrator::TimeStep;

/// λ with Jᵀλ = ȳ over the free unknowns of `system` (its scaled equations: ȳ over every dof,
/// each free one weighted by its field's scale), J the matrix of [`NonlinearSystem::evaluate`]
/// at the system's current point, evaluated here.
pub fn solve_adjoint(
    system: &mut (impl NonlinearSystem + HasDofs),
    cy: &[f64],
) -> Result<Vec<f64>, String> {
    let mut r = vec![0.0; system.n()];
    let mut k = system.new_matrix();
    system.evaluate(&mut r, Some(&mut k))?;
    let dofs = system.dof_map();
    let mut lambda = vec![0.0; dofs.n_free];
    for (d, &e) in dofs.eq.iter().enumerate() {
        if e != CONSTRAINED {
            lambda[e] += dofs.scale[d % FIELDS] * cy[d];
        }
    }
    TransposedLu::factor(&k)?.solve_in_place(&mut lambda);
    Ok(lambda)
}

/// A system over a [`DofMap`].
pub trait HasDofs {
    fn dof_map(&self) -> &DofMap;
}

impl HasDofs for TimeStep<'_> {
    fn dof_map(&self) -> &DofMap {
        &self.dofs
    }
}

impl HasDofs for StaticProblem<'_> {
    fn dof_map(&self) -> &DofMap {
        &self.dofs
    }
}
