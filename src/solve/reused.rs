//! A direct factorisation kept across Newton iterations and load or time steps, used as the
//! preconditioner of flexible GMRES on the current tangent ("Krylov-accelerated modified Newton").
//!
//! Factoring a 3-D tangent costs tens of solves with its factor. Newton's tangent changes little
//! from one iteration, or one step, to the next, so an earlier factorisation is a nearly exact
//! preconditioner: GMRES then needs a few iterations for a solve to full accuracy, and Newton keeps
//! its quadratic convergence. The solver refactors when the Krylov work since the last
//! factorisation has cost about as much as a factorisation (operation counts from the symbolic
//! analysis, a streamed entry weighed as [`STREAMING_COST`] flops, so the choice is the same on
//! every machine and run), or when a solve does not converge. [`LinearSolver::factor`] always
//! factors, so the inertia of a stability test is exact.
//! When adaptive, a Krylov solve stops at Newton's forcing term where that is looser than its
//! own tolerance (Eisenstat & Walker, SIAM J. Sci. Comput. 17 (1996) 16–32): fewer sweeps over
//! the factor, which are bound by memory traffic, in the Newton iterations that need little.
//! Reference: Knoll & Keyes, J. Comput. Phys. 193 (2004) 357–397, §3 (preconditioner lagging).

use super::krylov::{fgmres, KrylovReport, KrylovSettings};
use super::linear::{
    forced_tolerance, FaerLdlt, Inertia, LinearSolver, LinearSolverError, Ordering, SolverStats,
};
use crate::algebra::csr::CsrMatrix;

/// Relative residual of each Krylov solve (Newton's own tolerance is 1e-10 of its first
/// residual, so a step solved to 1e-9 of the current residual keeps it converging quadratically
/// down to that level).
const KRYLOV_RTOL: f64 = 1e-9;
/// Iterations of one solve before the factorisation is renewed.
const MAX_ITERATIONS: usize = 40;
/// The cost of an operation on a streamed entry of the factor or the matrix (a Krylov
/// iteration), in flops of the factorisation: the solves are bound by memory traffic, the
/// factorisation runs dense kernels. On the 40 × 40 × 8 film a factorisation costs 20 to 25
/// solves where the operation counts alone give over 400 (docs/validation.md); a fixed constant
/// keeps the choice the same on every machine and run.
const STREAMING_COST: f64 = 16.0;
/// The tightest relative residual of a solve on products that are differences of residuals
/// ([`LinearSolver::solve_with_products`]): those carry the residual's round-off over the
/// difference's step. On the film 40 × 40 × 8 with a step of √ε of the cell size FGMRES stalled
/// at 1.1–1.2·10⁻⁴; with 10⁻⁶ of it (the step used) and this floor its 15 steps took 117 Krylov
/// iterations and no factorisation beyond the stability tests', against 514 and 26 when each
/// solve aimed at the forcing term alone. Newton's last iterations then reduce the residual by
/// about this factor each, not more.
const PRODUCTS_RTOL: f64 = 1e-4;
/// A solve that did not reach [`KRYLOV_RTOL`] but this is still a useful inexact Newton step.
const ACCEPTABLE_RTOL: f64 = 1e-4;

/// The Krylov iterations of one solve on an unsymmetric operator above which the held factor
/// is renewed: a fresh factor of the symmetric part takes a few (the skew part), and a solve
/// that needs half of the iterations a factorisation costs says the factor has grown stale.
fn unsymmetric_limit(budget: usize) -> usize {
    (budget / 2).clamp(8, MAX_ITERATIONS / 2)
}

/// A sparse LDLᵀ ([`FaerLdlt`]) reused as the preconditioner of FGMRES while it pays.
pub struct ReusedLdlt {
    direct: FaerLdlt,
    /// The matrix of the next solves.
    op: Option<CsrMatrix>,
    /// The held factorisation is of `op`.
    current: bool,
    /// Krylov iterations since the last factorisation, and the budget for them.
    since_factor: usize,
    budget: usize,
    /// Renew the factorisation at the next [`LinearSolver::set_operator`].
    renew: bool,
    /// Below this many unknowns every operator is factored (no Krylov iterations).
    min_unknowns: usize,
    /// Reused factorisations in single precision ([`ReusedLdlt::single_precision`]).
    single: bool,
    /// Whether a Krylov solve stops at Newton's forcing term when that is looser.
    adaptive: bool,
    /// Newton's forcing term for the next solves.
    forcing: Option<f64>,
    stats: SolverStats,
    /// The operators are unsymmetric: the factor is of their symmetric part, and every solve
    /// runs FGMRES on the operator ([`ReusedLdlt::unsymmetric`]).
    unsymmetric: bool,
    /// For an unsymmetric operator: the position of the transposed entry of each entry (its
    /// pattern is structurally symmetric), and the symmetric part's matrix.
    transpose: Vec<usize>,
    symmetric: Option<CsrMatrix>,
}

impl ReusedLdlt {
    /// A new solver with the given ordering of the factorisation.
    pub fn with_ordering(ordering: Ordering) -> Self {
        ReusedLdlt {
            direct: FaerLdlt::with_ordering(ordering),
            op: None,
            current: false,
            since_factor: 0,
            budget: 0,
            renew: false,
            min_unknowns: 0,
            single: false,
            adaptive: false,
            forcing: None,
            stats: SolverStats::default(),
            unsymmetric: false,
            transpose: Vec::new(),
            symmetric: None,
        }
    }

    /// For unsymmetric operators with a structurally symmetric pattern (the exact Jacobian of a
    /// dynamic step): the held factor is of the symmetric part ½(A + Aᵀ) of the operator it was
    /// made from, and every solve runs FGMRES on the operator itself. The factor is kept across
    /// operators while a solve needs few iterations and renewed, at the operator of that solve,
    /// when one needs many or fails; the choice depends on the solve alone, so a run resumed
    /// with the same factor takes the same decisions. [`LinearSolver::factor`] factors the
    /// symmetric part (its inertia).
    pub fn unsymmetric(mut self) -> Self {
        self.unsymmetric = true;
        self
    }

    /// The symmetric part of the held operator, into `self.symmetric`.
    fn symmetric_part(&mut self) -> Result<(), LinearSolverError> {
        let op = self.op.as_ref().ok_or(LinearSolverError::NotFactored)?;
        let fresh = match &self.symmetric {
            Some(s) => !s.same_pattern(op),
            None => true,
        };
        if fresh {
            self.transpose = (0..op.n)
                .flat_map(|i| op.row_cols(i).iter().map(move |&j| (i, j as usize)))
                .map(|(i, j)| {
                    op.position(j, i).ok_or_else(|| {
                        LinearSolverError::NotConverged(
                            "the unsymmetric operator's pattern is not structurally symmetric"
                                .into(),
                        )
                    })
                })
                .collect::<Result<_, _>>()?;
            self.symmetric = Some(op.zeros_like());
        }
        let sym = self.symmetric.as_mut().expect("made above");
        for (p, &t) in self.transpose.iter().enumerate() {
            sym.values[p] = 0.5 * (op.values[p] + op.values[t]);
        }
        Ok(())
    }

    /// Lets a Krylov solve stop at Newton's forcing term ([`LinearSolver::set_forcing`]) when
    /// that is looser than its own tolerance: fewer sweeps over the factor in Newton's early
    /// iterations. A solve with a fresh factorisation is exact either way.
    pub fn adaptive(mut self, on: bool) -> Self {
        self.adaptive = on;
        self
    }

    /// Holds the factorisations it reuses (of systems of at least
    /// [`ReusedLdlt::from_unknowns`] unknowns) in single precision
    /// ([`FaerLdlt::single_precision`]); every solve with them then runs FGMRES, which restores
    /// double-precision accuracy. Smaller systems are still factored in double precision at
    /// every operator and solved exactly.
    pub fn single_precision(mut self) -> Self {
        self.single = true;
        self
    }

    /// Refuses factors of more than `bytes` ([`FaerLdlt::memory_limit`]).
    pub fn memory_limit(mut self, bytes: usize) -> Self {
        self.direct = self.direct.memory_limit(bytes);
        self
    }

    /// Reuses factorisations only for systems of at least `n` unknowns; smaller ones are factored
    /// at every [`LinearSolver::set_operator`], exactly as [`FaerLdlt`] would.
    pub fn from_unknowns(mut self, n: usize) -> Self {
        self.min_unknowns = n;
        self
    }

    fn keep(&mut self, a: &CsrMatrix) {
        match &mut self.op {
            Some(op) => op.assign(a),
            None => self.op = Some(a.clone()),
        }
    }

    fn factor_op(&mut self) -> Result<Option<Inertia>, LinearSolverError> {
        if self.unsymmetric {
            self.symmetric_part()?;
        }
        let op = self.op.as_ref().ok_or(LinearSolverError::NotFactored)?;
        self.direct
            .set_single(self.single && op.n >= self.min_unknowns);
        let inertia = match (&self.symmetric, self.unsymmetric) {
            (Some(sym), true) => self.direct.factor(sym)?,
            _ => self.direct.factor(op)?,
        };
        self.current = true;
        self.renew = false;
        self.since_factor = 0;
        // a Krylov iteration costs a solve (two triangular sweeps over the factor) and a product
        // with the matrix, whose entries stream from memory at a fraction of the rate the
        // factorisation's dense kernels run at; spend on them at most what one factorisation costs
        let flops = self.direct.factor_flops().unwrap_or(0.0);
        let per_iteration = 2.0 * self.direct.factor_nnz().unwrap_or(0) as f64 + op.nnz() as f64;
        self.budget = if per_iteration > 0.0 {
            (flops / (STREAMING_COST * per_iteration)).clamp(4.0, 400.0) as usize
        } else {
            4
        };
        Ok(inertia)
    }

    /// Adds a Krylov solve's iterations to the statistics and to the work since the factor.
    fn count(&mut self, report: &KrylovReport) {
        self.stats.krylov_iterations += report.iterations;
        self.stats.krylov_decades += -report.relative_residual.max(1e-16).log10();
        self.since_factor += report.iterations;
    }

    /// FGMRES on the held operator, preconditioned by the held factorisation; `Ok(true)` with
    /// the solution in `b` when it converged (or came close enough for an inexact Newton step).
    fn krylov(&mut self, b: &mut [f64]) -> Result<bool, LinearSolverError> {
        let op = self.op.as_ref().ok_or(LinearSolverError::NotFactored)?;
        let rtol = forced_tolerance(KRYLOV_RTOL, self.adaptive, self.forcing);
        let mut x = vec![0.0; b.len()];
        let report = preconditioned(
            &mut self.direct,
            |v, y| op.par_mul_vec(v, y),
            b,
            &mut x,
            rtol,
        )?;
        self.count(&report);
        if self.unsymmetric {
            if report.converged || report.relative_residual <= ACCEPTABLE_RTOL {
                b.copy_from_slice(&x);
                // renewed at once, at this operator: the held factor then always comes from the
                // operator of the iterate where it was made
                if !report.converged || report.iterations > unsymmetric_limit(self.budget) {
                    self.factor_op()?;
                }
                return Ok(true);
            }
            return Ok(false);
        }
        if report.converged || report.relative_residual <= ACCEPTABLE_RTOL {
            b.copy_from_slice(&x);
            if !report.converged || self.since_factor >= self.budget {
                self.renew = true;
            }
            return Ok(true);
        }
        Ok(false)
    }
}

impl LinearSolver for ReusedLdlt {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        self.keep(a);
        self.factor_op()
    }

    fn set_operator(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        self.keep(a);
        if self.unsymmetric {
            if !self.direct.is_factored() {
                self.factor_op()?;
            }
            self.current = false;
            return Ok(());
        }
        if self.renew || !self.direct.is_factored() || a.n < self.min_unknowns {
            self.factor_op()?;
        } else {
            self.current = false;
        }
        Ok(())
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        if self.op.is_none() || (self.current && !self.direct.is_single() && !self.unsymmetric) {
            return self.direct.solve_in_place(b);
        }
        if self.krylov(b)? {
            return Ok(());
        }
        // the held factorisation no longer describes the matrix: renew it and solve again
        self.factor_op()?;
        if !self.direct.is_single() && !self.unsymmetric {
            return self.direct.solve_in_place(b);
        }
        if self.krylov(b)? {
            return Ok(());
        }
        Err(LinearSolverError::NotConverged(
            "FGMRES with a fresh single-precision factorisation".into(),
        ))
    }

    fn accepts_products(&self, n: usize) -> bool {
        self.adaptive && !self.unsymmetric && n >= self.min_unknowns
    }

    /// FGMRES on the products, preconditioned by the held factorisation (in either precision),
    /// while it is that of a symmetric operator and not due for renewal, and the solves follow
    /// Newton's forcing term (adaptive), to it or [`PRODUCTS_RTOL`]. The factor is renewed at
    /// the next operator after a solve that needs more than [`unsymmetric_limit`] iterations or
    /// does not converge: a renewal costs a tangent besides the factorisation, and a stability
    /// test renews it anyway.
    fn solve_with_products(
        &mut self,
        apply: &mut dyn FnMut(&[f64], &mut [f64]) -> bool,
        b: &mut [f64],
    ) -> Result<bool, LinearSolverError> {
        let usable = self.accepts_products(b.len())
            && !self.renew
            && self.op.as_ref().is_some_and(|op| op.n == b.len())
            && self.direct.is_factored();
        if !usable {
            return Ok(false);
        }
        let rtol = forced_tolerance(KRYLOV_RTOL, self.adaptive, self.forcing).max(PRODUCTS_RTOL);
        let mut x = vec![0.0; b.len()];
        let mut unevaluated = false;
        let products = |v: &[f64], y: &mut [f64]| {
            if unevaluated || !apply(v, y) {
                // no further useful product: a zero ends the Krylov iteration
                unevaluated = true;
                y.fill(0.0);
            }
        };
        let report = preconditioned(&mut self.direct, products, b, &mut x, rtol)?;
        self.count(&report);
        if unevaluated || !(report.converged || report.relative_residual <= ACCEPTABLE_RTOL) {
            self.renew = true;
            return Ok(false);
        }
        b.copy_from_slice(&x);
        // as on unsymmetric operators: a solve that needs many iterations says the factor has
        // grown stale (the Krylov work alone weighs little against a tangent and a factor)
        if !report.converged || report.iterations > unsymmetric_limit(self.budget) {
            self.renew = true;
        }
        Ok(true)
    }

    fn name(&self) -> &'static str {
        "faer sparse LDLT reused as the preconditioner of FGMRES"
    }

    fn is_factored(&self) -> bool {
        self.direct.is_factored()
    }

    fn invalidate(&mut self) {
        self.direct.invalidate();
        self.current = false;
    }

    fn factor_nnz(&self) -> Option<usize> {
        self.direct.factor_nnz()
    }

    fn set_forcing(&mut self, rtol: Option<f64>) {
        self.forcing = rtol;
    }

    fn reports_factor_points(&self) -> bool {
        self.unsymmetric
    }

    fn stats(&self) -> SolverStats {
        let d = self.direct.stats();
        SolverStats {
            factorizations: d.factorizations,
            solves: d.solves,
            krylov_iterations: self.stats.krylov_iterations,
            krylov_decades: self.stats.krylov_decades,
        }
    }
}

/// FGMRES on the products `apply` to `rtol`, preconditioned by the solves of `direct`, from
/// x = 0 into `x`.
fn preconditioned(
    direct: &mut FaerLdlt,
    apply: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    rtol: f64,
) -> Result<KrylovReport, LinearSolverError> {
    let mut failed = None;
    let report = fgmres(
        apply,
        |v, z| {
            z.copy_from_slice(v);
            if let Err(e) = direct.solve_in_place(z) {
                failed = Some(e);
            }
        },
        b,
        x,
        &KrylovSettings {
            rtol,
            max_iterations: MAX_ITERATIONS,
            restart: MAX_ITERATIONS,
        },
    );
    match failed {
        Some(e) => Err(e),
        None => Ok(report),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2-D Laplacian (n × n grid) shifted by `shift` on the diagonal, in CSR.
    fn laplacian(n: usize, shift: f64) -> CsrMatrix {
        let m = n * n;
        let n_rows = m;
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::<f64>::new());
        for i in 0..n {
            for j in 0..n {
                let mut row = vec![(i * n + j, 4.0 + shift)];
                if i > 0 {
                    row.push(((i - 1) * n + j, -1.0));
                }
                if i + 1 < n {
                    row.push(((i + 1) * n + j, -1.0));
                }
                if j > 0 {
                    row.push((i * n + j - 1, -1.0));
                }
                if j + 1 < n {
                    row.push((i * n + j + 1, -1.0));
                }
                row.sort_by_key(|e| e.0);
                for (c, v) in row {
                    col_idx.push(c);
                    values.push(v);
                }
                row_ptr.push(col_idx.len());
            }
        }
        CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values)
    }

    fn exact(a: &CsrMatrix, b: &[f64]) -> Vec<f64> {
        let mut s = FaerLdlt::new();
        s.factor(a).unwrap();
        let mut x = b.to_vec();
        s.solve_in_place(&mut x).unwrap();
        x
    }

    /// Single precision applies to the factorisations it reuses only: a system below the
    /// reuse threshold is factored in double precision and solved exactly, a larger one through
    /// FGMRES on its single-precision factor, both to the solver's tolerance.
    #[test]
    fn single_precision_only_from_the_reuse_threshold_on() {
        for (grid, single) in [(8, false), (12, true)] {
            let a = laplacian(grid, 0.1);
            let x: Vec<f64> = (0..a.n).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut b = vec![0.0; a.n];
            a.mul_vec(&x, &mut b);
            let mut s = ReusedLdlt::with_ordering(Ordering::default())
                .from_unknowns(100)
                .single_precision();
            s.set_operator(&a).unwrap();
            s.solve_in_place(&mut b).unwrap();
            assert_eq!(s.direct.is_single(), single, "{} unknowns", a.n);
            assert_eq!(s.stats().krylov_iterations > 0, single, "{} unknowns", a.n);
            let error = b
                .iter()
                .zip(&x)
                .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
            assert!(error < 1e-8, "{} unknowns: {error:e}", a.n);
        }
    }

    #[test]
    fn a_held_factorisation_preconditions_the_changed_matrix_to_full_accuracy() {
        let n = 30;
        let b: Vec<f64> = (0..n * n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
        let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection);
        s.factor(&laplacian(n, 0.0)).unwrap();
        assert_eq!(s.stats().factorizations, 1);
        // a 5 % change of the diagonal: solved by FGMRES without a new factorisation
        let changed = laplacian(n, 0.2);
        s.set_operator(&changed).unwrap();
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        let reference = exact(&changed, &b);
        let err = x
            .iter()
            .zip(&reference)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        let scale = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(err <= 1e-8 * scale, "{err:e}");
        let st = s.stats();
        assert_eq!(st.factorizations, 1, "{st:?}");
        assert!(
            st.krylov_iterations >= 2 && st.krylov_iterations < 15,
            "{st:?}"
        );
    }

    /// A solve on products of a changed matrix, preconditioned by the held factor: to the
    /// forcing term (no tighter than [`PRODUCTS_RTOL`]) without a new factorisation; when a
    /// product cannot be evaluated it declines, leaves the right-hand side as it was, and the
    /// next operator is factored.
    #[test]
    fn a_solve_on_products_follows_the_forcing_term_and_declines_when_a_product_fails() {
        let n = 30;
        let b: Vec<f64> = (0..n * n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
        let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection).adaptive(true);
        s.factor(&laplacian(n, 0.0)).unwrap();
        let changed = laplacian(n, 0.2);
        for forcing in [1e-2, 1e-8] {
            s.set_forcing(Some(forcing));
            let mut x = b.clone();
            let solved = s
                .solve_with_products(
                    &mut |v, y| {
                        changed.mul_vec(v, y);
                        true
                    },
                    &mut x,
                )
                .unwrap();
            assert!(solved);
            let mut r = vec![0.0; b.len()];
            changed.mul_vec(&x, &mut r);
            let residual = r.iter().zip(&b).map(|(u, v)| (u - v).powi(2)).sum::<f64>();
            let size = b.iter().map(|v| v * v).sum::<f64>();
            let relative = (residual / size).sqrt();
            assert!(
                relative <= forcing.max(PRODUCTS_RTOL),
                "{forcing:e}: {relative:e}"
            );
            // a solve to the floor, not to 1e-8: the products carry a difference's round-off
            assert!(relative > 1e-9, "{forcing:e}: {relative:e}");
        }
        assert_eq!(s.stats().factorizations, 1);
        let mut x = b.clone();
        let solved = s.solve_with_products(&mut |_, _| false, &mut x).unwrap();
        assert!(!solved);
        assert_eq!(x, b, "the right-hand side is left as it was");
        s.set_operator(&changed).unwrap();
        assert_eq!(s.stats().factorizations, 2, "renewed at the next operator");
    }

    /// An adaptive solver stops a Krylov solve at a looser forcing term, with fewer iterations
    /// and a residual within it; a fixed one ignores the forcing term.
    #[test]
    fn a_krylov_solve_stops_at_the_forcing_term_when_adaptive() {
        let n = 30;
        let b: Vec<f64> = (0..n * n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
        let changed = laplacian(n, 0.5);
        let run = |adaptive: bool, forcing: Option<f64>| {
            let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection).adaptive(adaptive);
            s.factor(&laplacian(n, 0.0)).unwrap();
            s.set_operator(&changed).unwrap();
            s.set_forcing(forcing);
            let mut x = b.clone();
            s.solve_in_place(&mut x).unwrap();
            let mut ax = vec![0.0; x.len()];
            changed.mul_vec(&x, &mut ax);
            let res = ax
                .iter()
                .zip(&b)
                .map(|(p, q)| (p - q).powi(2))
                .sum::<f64>()
                .sqrt();
            let relative = res / b.iter().map(|v| v * v).sum::<f64>().sqrt();
            (s.stats().krylov_iterations, relative)
        };
        let (exact, r_exact) = run(true, None);
        let (loose, r_loose) = run(true, Some(1e-3));
        let (fixed, r_fixed) = run(false, Some(1e-3));
        assert!(
            r_exact <= 1e-9 && r_fixed <= 1e-9,
            "{r_exact:e} {r_fixed:e}"
        );
        assert_eq!(fixed, exact);
        assert!(r_loose <= 1e-3 && r_loose > 1e-9, "{r_loose:e}");
        assert!(loose < exact, "{loose} {exact}");
    }

    #[test]
    fn the_factorisation_is_renewed_when_the_krylov_work_exceeds_its_cost() {
        let n = 12;
        let b: Vec<f64> = (0..n * n).map(|i| (i as f64 * 0.1).cos()).collect();
        let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection);
        s.factor(&laplacian(n, 0.0)).unwrap();
        // a small 2-D factorisation is cheap: the budget is a few iterations, soon spent
        for k in 1..=10 {
            let a = laplacian(n, 0.3 * k as f64);
            s.set_operator(&a).unwrap();
            let mut x = b.clone();
            s.solve_in_place(&mut x).unwrap();
            let reference = exact(&a, &b);
            for (u, v) in x.iter().zip(&reference) {
                assert!((u - v).abs() <= 1e-7 * v.abs().max(1e-3), "{u} {v}");
            }
        }
        let st = s.stats();
        assert!(st.factorizations > 1 && st.factorizations < 11, "{st:?}");
    }

    /// An unsymmetric operator (a Laplacian plus a skew convection-like part) is solved to
    /// full accuracy with a factor of its symmetric part.
    #[test]
    fn an_unsymmetric_operator_is_solved_with_a_factor_of_its_symmetric_part() {
        let n = 20;
        let skewed = |shift: f64| {
            let mut a = laplacian(n, shift);
            for i in 0..a.n {
                for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                    let j = a.col_idx[p] as usize;
                    if j == i + 1 {
                        a.values[p] += 0.05;
                    } else if j + 1 == i {
                        a.values[p] -= 0.05;
                    }
                }
            }
            a
        };
        let b: Vec<f64> = (0..n * n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
        let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection).unsymmetric();
        for shift in [0.0, 0.1] {
            let a = skewed(shift);
            s.set_operator(&a).unwrap();
            let mut x = b.clone();
            s.solve_in_place(&mut x).unwrap();
            let mut ax = vec![0.0; x.len()];
            a.mul_vec(&x, &mut ax);
            let res = ax.iter().zip(&b).map(|(p, q)| (p - q).powi(2)).sum::<f64>();
            let bb = b.iter().map(|v| v * v).sum::<f64>();
            assert!(
                (res / bb).sqrt() <= 1e-9,
                "shift {shift}: {:e}",
                (res / bb).sqrt()
            );
        }
        // FGMRES iterates on the operator itself (a direct solve with the factor of the
        // symmetric part alone would miss the skew part)
        let st = s.stats();
        assert!(st.factorizations <= 2, "{st:?}");
        assert!(st.krylov_iterations >= 4, "{st:?}");
    }

    #[test]
    fn factor_gives_the_exact_inertia_of_the_matrix_it_is_given() {
        let n = 10;
        let mut s = ReusedLdlt::with_ordering(Ordering::NestedDissection);
        s.factor(&laplacian(n, 0.0)).unwrap();
        // shifted far enough to make it indefinite: set_operator alone would not tell, factor does
        let shifted = laplacian(n, -4.5);
        let inertia = s.factor(&shifted).unwrap().unwrap();
        assert!(inertia.negative > 0, "{inertia:?}");
    }
}
