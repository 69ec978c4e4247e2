//! The `auto` solver: a sparse LDLᵀ (reused across Newton iterations from a size on) while its
//! factor fits in memory, FGMRES with a coupled AMG preconditioner once it does not.
//!
//! The size of the factor is known exactly after the symbolic analysis, before any numeric work:
//! the factorisation refuses to start when it exceeds the memory limit
//! ([`LinearSolverError::OutOfMemory`]) or the 2³² entries its indices count
//! ([`LinearSolverError::TooLarge`]), and from then on this solver hands every system to
//! [`AmgGmres`], whose memory is linear in the unknowns.

use super::iterative::AmgGmres;
use super::linear::{Inertia, LinearSolver, LinearSolverError, SolverStats};
use super::reused::ReusedLdlt;
use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::DofLayout;

/// A reused LDLᵀ that gives way to FGMRES with AMG when its factor would not fit.
pub struct AutoSolver {
    direct: ReusedLdlt,
    iterative: Option<AmgGmres>,
    rtol: f64,
    /// Whether the iterative solver follows Newton's forcing term.
    adaptive: bool,
    forcing: Option<f64>,
    layout: Option<DofLayout>,
}

impl AutoSolver {
    /// `direct` until its factor would not fit; then FGMRES with AMG to `rtol`.
    pub fn new(direct: ReusedLdlt, rtol: f64) -> Self {
        AutoSolver {
            direct,
            iterative: None,
            rtol,
            adaptive: true,
            forcing: None,
            layout: None,
        }
    }

    /// Whether the iterative solver, once switched to, stops at Newton's forcing term
    /// ([`AmgGmres::adaptive`]).
    pub fn adaptive(mut self, on: bool) -> Self {
        self.adaptive = on;
        self
    }

    /// Whether the solver has switched to the iterative solver.
    pub fn is_iterative(&self) -> bool {
        self.iterative.is_some()
    }

    /// Runs `f` on the active solver; when the direct one reports that its factor does not fit,
    /// switches to FGMRES with AMG (if the system's layout is known) and runs `f` on it.
    fn with_active<T>(
        &mut self,
        mut f: impl FnMut(&mut dyn LinearSolver) -> Result<T, LinearSolverError>,
    ) -> Result<T, LinearSolverError> {
        if let Some(it) = &mut self.iterative {
            return f(it);
        }
        match f(&mut self.direct) {
            Err(e @ (LinearSolverError::OutOfMemory { .. } | LinearSolverError::TooLarge)) => {
                let Some(layout) = self.layout.clone() else {
                    return Err(e);
                };
                log::warn!("deasim: {e}: switching to FGMRES with coupled AMG");
                let mut it = AmgGmres::new(self.rtol).adaptive(self.adaptive);
                it.set_layout(layout);
                it.set_forcing(self.forcing);
                let out = f(&mut it);
                self.iterative = Some(it);
                out
            }
            other => other,
        }
    }
}

impl LinearSolver for AutoSolver {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        self.with_active(|s| s.factor(a))
    }

    fn set_operator(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        self.with_active(|s| s.set_operator(a))
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        match &mut self.iterative {
            Some(it) => it.solve_in_place(b),
            None => self.direct.solve_in_place(b),
        }
    }

    fn name(&self) -> &'static str {
        match &self.iterative {
            Some(it) => it.name(),
            None => self.direct.name(),
        }
    }

    fn is_factored(&self) -> bool {
        match &self.iterative {
            Some(it) => it.is_factored(),
            None => self.direct.is_factored(),
        }
    }

    fn invalidate(&mut self) {
        self.direct.invalidate();
        if let Some(it) = &mut self.iterative {
            it.invalidate();
        }
    }

    fn factor_nnz(&self) -> Option<usize> {
        self.direct.factor_nnz()
    }

    fn stats(&self) -> SolverStats {
        let d = self.direct.stats();
        let i = self
            .iterative
            .as_ref()
            .map(|it| it.stats())
            .unwrap_or_default();
        SolverStats {
            factorizations: d.factorizations + i.factorizations,
            solves: d.solves + i.solves,
            krylov_iterations: d.krylov_iterations + i.krylov_iterations,
            krylov_decades: d.krylov_decades + i.krylov_decades,
        }
    }

    fn needs_layout(&self, n: usize) -> bool {
        self.layout.as_ref().is_none_or(|l| l.node.len() != n)
    }

    fn set_layout(&mut self, layout: DofLayout) {
        if let Some(it) = &mut self.iterative {
            it.set_layout(layout.clone());
        }
        self.layout = Some(layout);
    }

    fn accepts_products(&self, n: usize) -> bool {
        self.iterative.is_none() && self.direct.accepts_products(n)
    }

    fn solve_with_products(
        &mut self,
        apply: &mut dyn FnMut(&[f64], &mut [f64]) -> bool,
        b: &mut [f64],
    ) -> Result<bool, LinearSolverError> {
        match &mut self.iterative {
            Some(_) => Ok(false),
            None => self.direct.solve_with_products(apply, b),
        }
    }

    fn set_forcing(&mut self, rtol: Option<f64>) {
        self.forcing = rtol;
        self.direct.set_forcing(rtol);
        if let Some(it) = &mut self.iterative {
            it.set_forcing(rtol);
        }
    }
}
