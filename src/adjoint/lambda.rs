//! The adjoint of one step's equations: λ with Jᵀλ = ∂J/∂y over the free unknowns y of a
//! system, J the system's Jacobian, solved with its transpose's LU.

use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::NonlinearSystem;
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS};
use crate::problem::statics::StaticProblem;
use crate::solve::krylov::{fgmres, KrylovSettings};
use crate::solve::transposed::TransposedLu;
use crate::time::integrator::TimeStep;

/// How many factorisations and GMRES iterations adjoint solves took.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct SolveCounts {
    pub factorizations: usize,
    pub iterations: usize,
}

impl std::ops::AddAssign for SolveCounts {
    fn add_assign(&mut self, o: SolveCounts) {
        self.factorizations += o.factorizations;
        self.iterations += o.iterations;
    }
}

/// Solves the adjoint equations of a run of steps whose Jacobians change little from one step
/// to the next (the same pattern, a slowly moving state): it keeps the LU factors of the last
/// Jacobian it factored and solves the next steps' transposed systems by flexible GMRES
/// preconditioned with them, factoring again only when GMRES needs more than
/// [`AdjointSolver::MAX_ITERATIONS`] iterations. The forward run reuses its factorisations the
/// same way (modified Newton); the adjoint's solves are linear, so a good preconditioner
/// converges in a few iterations to the tolerance: 10⁻¹³ of the right-hand side, or what the
/// last solve with a fresh factorisation attained if that is more (a step's Jacobian of a
/// pre-stretched membrane with its mass and potentials leaves a direct solve about 2·10⁻¹² of
/// the right-hand side, and asking GMRES for less made every step factor again).
#[derive(Default)]
pub struct AdjointSolver {
    held: Option<TransposedLu>,
    /// ‖ȳ − Jᵀλ‖/‖ȳ‖ of the last solve with a fresh factorisation.
    attained: f64,
    /// Factorisations and GMRES iterations so far.
    pub factorizations: usize,
    pub iterations: usize,
}

impl AdjointSolver {
    /// Most GMRES iterations with a held factorisation before the Jacobian is factored again.
    pub const MAX_ITERATIONS: usize = 12;
    /// The relative residual the GMRES solves reach, where a direct solve reaches it.
    pub const RTOL: f64 = 1e-13;
    /// The GMRES solves reach this multiple of the relative residual the last direct solve
    /// attained, where that is above [`AdjointSolver::RTOL`]: as accurate as a new
    /// factorisation would be, up to its spread from one right-hand side to the next.
    pub const ATTAINED_FACTOR: f64 = 2.0;

    /// The factorisations and GMRES iterations so far.
    pub fn counts(&self) -> SolveCounts {
        SolveCounts {
            factorizations: self.factorizations,
            iterations: self.iterations,
        }
    }

    /// λ with Jᵀλ = ȳ over the free unknowns of `system` (its scaled equations: ȳ over every
    /// dof, each free one weighted by its field's scale), J the matrix of
    /// [`NonlinearSystem::evaluate`] at the system's current point, evaluated here.
    pub fn solve(
        &mut self,
        system: &mut (impl NonlinearSystem + HasDofs),
        cy: &[f64],
    ) -> Result<Vec<f64>, String> {
        let mut k = system.new_matrix();
        system.jacobian(&mut k)?;
        self.solve_assembled(&k, system.dof_map(), cy)
    }

    /// [`AdjointSolver::solve`] with the Jacobian `k` already evaluated, over the unknowns of
    /// `dofs`.
    pub fn solve_assembled(
        &mut self,
        k: &CsrMatrix,
        dofs: &DofMap,
        cy: &[f64],
    ) -> Result<Vec<f64>, String> {
        let mut b = vec![0.0; dofs.n_free];
        for (d, &e) in dofs.eq.iter().enumerate() {
            if e != CONSTRAINED {
                b[e] += dofs.scale[d % FIELDS] * cy[d];
            }
        }
        if let Some(lu) = self.held.as_ref().filter(|lu| lu.n() == b.len()) {
            let mut lambda = vec![0.0; b.len()];
            let report = fgmres(
                |v, y| k.mul_transposed(v, y),
                |v, z| {
                    z.copy_from_slice(v);
                    lu.solve_in_place(z);
                },
                &b,
                &mut lambda,
                &KrylovSettings {
                    rtol: Self::RTOL.max(Self::ATTAINED_FACTOR * self.attained),
                    max_iterations: Self::MAX_ITERATIONS,
                    restart: Self::MAX_ITERATIONS,
                },
            );
            self.iterations += report.iterations;
            if report.converged {
                return Ok(lambda);
            }
        }
        let lu = TransposedLu::factor(k)?;
        self.factorizations += 1;
        let mut lambda = b.clone();
        lu.solve_in_place(&mut lambda);
        self.attained = relative_residual(k, &lambda, &b);
        self.held = Some(lu);
        Ok(lambda)
    }
}

/// ‖b − Kᵀx‖/‖b‖ (0 for b = 0).
fn relative_residual(k: &CsrMatrix, x: &[f64], b: &[f64]) -> f64 {
    let mut y = vec![0.0; b.len()];
    k.mul_transposed(x, &mut y);
    let r = y.iter().zip(b).map(|(a, c)| (a - c) * (a - c)).sum::<f64>();
    let nb = b.iter().map(|a| a * a).sum::<f64>();
    if nb > 0.0 {
        (r / nb).sqrt()
    } else {
        0.0
    }
}

/// λ with Jᵀλ = ȳ by a factorisation of its own ([`AdjointSolver::solve`] without a held one).
pub fn solve_adjoint(
    system: &mut (impl NonlinearSystem + HasDofs),
    cy: &[f64],
) -> Result<Vec<f64>, String> {
    AdjointSolver::default().solve(system, cy)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algebra::system::LoadedSystem;
    use crate::problem::statics::StaticProblem;

    /// Two load steps of the film, the second a little further: the solver factors the first
    /// step's Jacobian and solves the second's transposed system by GMRES preconditioned with
    /// it, to the solution of a factorisation of its own (10⁻¹¹ of its size).
    #[test]
    fn a_held_factorisation_preconditions_the_next_steps() {
        let model =
            crate::problem::examples::film([2, 2, 1], crate::mesh::ElementKind::Hex8, 2e4).unwrap();
        let state = crate::problem::examples::wavy_state(&model, 1e-2, 1e-6, 0.0);
        let n = state.len();
        let cy: Vec<f64> = (0..n)
            .map(|d| ((d * 37 % 11) as f64 - 5.0) * 1e-3)
            .collect();
        let mut problem = StaticProblem::new(&model, Some(state.clone()));
        problem.set_load(0.9);
        let mut solver = AdjointSolver::default();
        solver.solve(&mut problem, &cy).unwrap();
        assert_eq!((solver.factorizations, solver.iterations), (1, 0));
        problem.set_load(1.0);
        let reused = solver.solve(&mut problem, &cy).unwrap();
        assert_eq!(solver.factorizations, 1, "the held factors served");
        assert!(solver.iterations > 0);
        let own = solve_adjoint(&mut problem, &cy).unwrap();
        let size = own.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(size > 0.0);
        for (a, b) in reused.iter().zip(&own) {
            assert!((a - b).abs() <= 1e-11 * size, "{a} against {b}");
        }
    }
}
