//! FGMRES preconditioned by smoothed-aggregation AMG of the whole coupled tangent, for large
//! problems: no factorisation, memory linear in the number of unknowns.
//!
//! The tangent K = [A B; Bᵀ −C] (A the displacement block, C = −K_ΦΦ positive definite) is
//! symmetric indefinite. One smoothed-aggregation hierarchy ([`super::amg`]) is built on K itself,
//! renumbered by whole nodes ((u, Φ) per node; a held unknown becomes a decoupled padding row),
//! with the rigid-body modes at zero potential and the constant potential as near-null space:
//! aggregates of nodes carry both fields, and the Galerkin coarse operators PᵀKP keep the
//! electromechanical coupling on every level. This is how PETSc's GAMG treats a block-4 matrix
//! (Adams, Brezina, Hu & Tuminaro, J. Comput. Phys. 188 (2003) 593–610, for the smoothing); the
//! Chebyshev smoother works on D⁻¹K with the signed diagonal, whose spectrum has a positive real
//! part while A is positive definite. The cycle is not symmetric, so the Krylov method is flexible
//! GMRES (Saad, SIAM J. Sci. Comput. 14 (1993) 461–469) with a restart of [`RESTART`].
//!
//! On large matrices (from [`SINGLE_MIN_ENTRIES`] on) the smoother holds each level's operator
//! in node blocks with single-precision values ([`SmootherStorage::BlockSingle`]): its products
//! stream a quarter of the bytes of the scalar double-precision matrix, which is what bounds a
//! solve on large meshes (1.75× faster per iteration at 1.2·10⁵ unknowns, with the same iteration
//! counts). The preconditioner is then a fixed linear operator built from the rounded matrix;
//! FGMRES multiplies by the exact tangent, in double-precision node blocks ([`BlockMatrix`]), so
//! each solve still reaches its tolerance.
//!
//! Why not a block-diagonal preconditioner in MINRES (Murphy, Golub & Wathen 2000), which this
//! module used before: its V-cycle on the displacement block alone degraded on the nearly
//! incompressible film (Λ = 100 μ): 61.5, 72 and 119 iterations per solve at 2.7·10³, 5.8·10³ and
//! 6·10⁴ unknowns, where the coupled hierarchy needs about 52, 60 and 78, and 80 at 1.2·10⁵
//! (docs/validation.md).
//!
//! Each solve stops at Newton's forcing term when that is looser than the tolerance
//! ([`AmgGmres::adaptive`]), so solves reach different tolerances; the hierarchy's quality is
//! therefore judged by iterations per decade of residual reduction. It is kept across Newton
//! iterations and steps while that rate stays near the one of its first solve (the tangent
//! changes little), and rebuilt when it grows or a solve fails. Close to a stability limit a hierarchy of the current tangent can precondition worse
//! than the older one (the displacement block at fixed potential is then indefinite): the
//! hierarchy a rebuild replaced is kept until the first solve with the new one, and restored when
//! the new one needed more iterations than the old one's last solve. Above
//! [`KEEP_PREVIOUS_MAX_ENTRIES`] the old hierarchy is dropped before the new one is built, so that
//! a large problem holds one at a time. There is no inertia: a limit point (pull-in) shows as a
//! Newton failure at the step that passes it, and load stepping cuts back towards it. A system
//! that cannot tell where its unknowns sit ([`DofLayout`]) is solved by the direct LDLᵀ instead.

use super::amg::{rigid_body_modes, Amg, AmgParams, BlockMatrix, SmootherStorage};
use super::krylov::{fgmres, KrylovSettings};
use super::linear::{
    forced_tolerance, FaerLdlt, Inertia, LinearSolver, LinearSolverError, Ordering, SolverStats,
};
use crate::algebra::csr::{col, Col, CsrMatrix};
use crate::algebra::system::DofLayout;

/// Default relative residual of each solve (the solver settings' default).
pub use super::linear::DEFAULT_RTOL;
/// Most FGMRES iterations of one solve.
const MAX_ITERATIONS: usize = 2000;
/// FGMRES restart: basis vectors kept (two vectors of the unknowns' length each).
const RESTART: usize = 60;
/// Degree of the Chebyshev smoother: on the nearly incompressible film, degree 2 needed about 90
/// iterations per solve at 1.75·10⁴ unknowns and degree 3 about 67 for the same time; with the
/// single-precision block smoother (products at a quarter of the bytes) degree 4 needs 72 instead
/// of 78 at 1.2·10⁵ and is about 15 % faster, degree 5 needs 64 and gains nothing more.
const SMOOTHER_DEGREE: usize = 4;
/// The hierarchy is rebuilt when a solve needs more than this factor times the iterations of the
/// first solve with it.
const GROWTH: f64 = 1.5;
/// From this many matrix entries on (about 10⁴ unknowns of a hex8 mesh) the smoother's blocks are
/// single precision: below it the matrices stay in cache and rounding them gains no time, while
/// the double-precision blocks keep small, stiff problems (the axisymmetric diaphragm with its
/// pre-stretch and tied pad) solvable to tight tolerances.
const SINGLE_MIN_ENTRIES: usize = 1_000_000;
/// Above this many matrix entries (about 10⁵ unknowns of a hex8 mesh) the hierarchy a rebuild
/// replaces is dropped first, not kept for the comparison with its successor: memory comes first.
const KEEP_PREVIOUS_MAX_ENTRIES: usize = 10_000_000;
/// Only solves over at least this many decades of residual reduction and [`MIN_ITERATIONS`]
/// iterations count in the comparison of rates: a solve stopped after a decade or a few
/// iterations (a loose forcing term, an easy right-hand side) says little about the hierarchy.
const MIN_DECADES: f64 = 2.0;
const MIN_ITERATIONS: usize = 5;
/// A row index meaning "none".
const NONE: usize = usize::MAX;

/// FGMRES with the coupled AMG preconditioner; the direct LDLᵀ without a layout.
pub struct AmgGmres {
    rtol: f64,
    /// Stop at Newton's forcing term when it is looser than `rtol`.
    adaptive: bool,
    /// Newton's forcing term for the next solves.
    forcing: Option<f64>,
    layout: Option<DofLayout>,
    nodal: Option<Nodal>,
    /// The matrix of the next solves, renumbered by nodes.
    op: Option<NodalOperator>,
    amg: Option<Amg<'static>>,
    /// The hierarchy the last rebuild replaced, with the rate of its last solve, until the
    /// first solve with the new one.
    previous: Option<(Amg<'static>, f64)>,
    /// Iterations per decade of residual reduction ([`rate`]) of the first solve with the
    /// current hierarchy, and of the latest solve. Rates, not counts: with Newton's forcing
    /// term the solves stop at different tolerances.
    first_rate: Option<f64>,
    last_rate: f64,
    /// A rebuild is due.
    rebuild: bool,
    /// Used when the system gives no layout.
    direct: FaerLdlt,
    stats: SolverStats,
    /// Hierarchy builds.
    builds: usize,
    /// Print each solve's iterations and each build's levels on stderr (with Newton's table).
    verbose: bool,
}

impl AmgGmres {
    /// A solver that stops each solve at `rtol` (relative residual).
    pub fn new(rtol: f64) -> Self {
        AmgGmres {
            rtol,
            adaptive: true,
            forcing: None,
            layout: None,
            nodal: None,
            op: None,
            amg: None,
            previous: None,
            first_rate: None,
            last_rate: f64::INFINITY,
            rebuild: true,
            direct: FaerLdlt::with_ordering(Ordering::NestedDissection),
            stats: SolverStats::default(),
            builds: 0,
            verbose: std::env::var_os("DEASIM_NEWTON_VERBOSE").is_some(),
        }
    }

    /// Whether a solve stops at Newton's forcing term ([`LinearSolver::set_forcing`]) when that
    /// is looser than the solver's tolerance (default), or always at the tolerance. Newton's
    /// first iterations of a step remove the large residual only approximately anyway: solving
    /// them to 1e-8 spends Krylov iterations that the next Newton iteration throws away
    /// (Eisenstat & Walker, SIAM J. Sci. Comput. 17 (1996) 16–32).
    pub fn adaptive(mut self, on: bool) -> Self {
        self.adaptive = on;
        self
    }

    /// The relative residual the next solve stops at.
    fn tolerance(&self) -> f64 {
        forced_tolerance(self.rtol, self.adaptive, self.forcing)
    }

    /// Number of times the hierarchy was built.
    pub fn builds(&self) -> usize {
        self.builds
    }

    /// Takes `a` as the matrix of the next solves (renumbered by nodes).
    fn keep(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        let Some(nodal) = &self.nodal else {
            return Err(LinearSolverError::NotFactored);
        };
        let pad = nodal.pad(a);
        if let Some(NodalOperator::Blocks(m)) = &mut self.op {
            if m.assign_renumbered(a, &nodal.eq, &nodal.row, pad) {
                return Ok(());
            }
        }
        // a first matrix, a new pattern, or blocks that did not pay: renumber it whole
        self.op = None;
        let (row_ptr, col_idx, values) = extract(a, &nodal.eq, &nodal.row, pad);
        let scalar = CsrMatrix::new(nodal.eq.len(), row_ptr, col_idx, values);
        self.op = Some(match BlockMatrix::from_csr(&scalar, nodal.block) {
            Some(m) => NodalOperator::Blocks(m),
            None => NodalOperator::Scalar(scalar),
        });
        Ok(())
    }

    fn build(&mut self) -> Result<(), LinearSolverError> {
        let (Some(nodal), Some(op)) = (&self.nodal, &self.op) else {
            return Err(LinearSolverError::NotFactored);
        };
        // a large problem holds one hierarchy at a time: the old one goes before the new one is
        // built (two hierarchies of the 10⁶-unknown film took 11.7 GB at their peak)
        if op.nnz() > KEEP_PREVIOUS_MAX_ENTRIES {
            self.amg = None;
            self.previous = None;
        }
        let start = std::time::Instant::now();
        let fresh = nodal.hierarchy(op)?;
        if self.verbose {
            log::info!(
                "    AMG of the coupled tangent built in {:.2} s: {fresh:?}",
                start.elapsed().as_secs_f64()
            );
        }
        self.previous = self.amg.replace(fresh).map(|old| (old, self.last_rate));
        self.first_rate = None;
        // no informative solve with the new hierarchy yet: nothing to compare against
        self.last_rate = f64::INFINITY;
        self.rebuild = false;
        self.builds += 1;
        Ok(())
    }

    /// One FGMRES solve with the current hierarchy: (converged, iterations, decades of residual
    /// reduction); `b` holds the solution when converged.
    fn gmres(&mut self, b: &mut [f64]) -> Result<(bool, usize, f64), LinearSolverError> {
        let (Some(nodal), Some(op), Some(amg)) = (&self.nodal, &self.op, &self.amg) else {
            return Err(LinearSolverError::NotFactored);
        };
        let settings = KrylovSettings {
            rtol: self.tolerance(),
            max_iterations: MAX_ITERATIONS,
            restart: RESTART,
        };
        // FGMRES in the node numbering: padding rows have a zero right-hand side
        let rhs: Vec<f64> = nodal
            .eq
            .iter()
            .map(|&e| if e == NONE { 0.0 } else { b[e] })
            .collect();
        let mut x = vec![0.0; rhs.len()];
        let start = std::time::Instant::now();
        let report = fgmres(
            |v, y| op.mul_vec(v, y),
            |r, z| amg.apply(r, z),
            &rhs,
            &mut x,
            &settings,
        );
        self.stats.krylov_iterations += report.iterations;
        self.stats.solves += 1;
        if self.verbose {
            log::info!(
                "    FGMRES: {} iterations, relative residual {:.2e}, {:.2} s",
                report.iterations,
                report.relative_residual,
                start.elapsed().as_secs_f64()
            );
        }
        if report.converged {
            for (be, &r) in b.iter_mut().zip(&nodal.row) {
                *be = x[r];
            }
        }
        let decades = -report.relative_residual.max(1e-16).log10();
        self.stats.krylov_decades += decades;
        Ok((report.converged, report.iterations, decades))
    }

    /// Bookkeeping after a converged solve of `iterations` over `decades`: the first solve with a
    /// new hierarchy decides between it and the one it replaced; later ones may call for a
    /// rebuild when they need more than [`GROWTH`] times the iterations the first one's rate
    /// predicts (plus two).
    fn converged(&mut self, iterations: usize, decades: f64) {
        if decades < MIN_DECADES || iterations < MIN_ITERATIONS {
            return;
        }
        let now = rate(iterations, decades);
        match self.first_rate {
            None => {
                self.first_rate = Some(now);
                if let Some((old, old_rate)) = self.previous.take() {
                    if now > old_rate {
                        self.amg = Some(old);
                        self.first_rate = Some(old_rate);
                    }
                }
            }
            Some(first) => {
                self.rebuild |= iterations as f64 > GROWTH * first * decades + 2.0;
            }
        }
        self.last_rate = now;
    }
}

impl LinearSolver for AmgGmres {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        if self.nodal.is_none() {
            return self.direct.factor(a);
        }
        // no factorisation and no inertia: the matrix is taken, and the hierarchy is built only
        // when there is none (a stability test right after Newton reuses it)
        self.keep(a)?;
        if self.amg.is_none() {
            self.build()?;
        }
        Ok(None)
    }

    fn set_operator(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        if self.nodal.is_none() {
            return self.direct.factor(a).map(|_| ());
        }
        self.keep(a)?;
        if self.rebuild || self.amg.is_none() {
            self.build()?;
        }
        Ok(())
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        if self.nodal.is_none() {
            return self.direct.solve_in_place(b);
        }
        let rhs = b.to_vec();
        let (converged, iterations, decades) = self.gmres(b)?;
        if converged {
            self.converged(iterations, decades);
            return Ok(());
        }
        // a hierarchy of an older tangent: rebuild it for this one; a new one that failed: go
        // back to the one it replaced
        let retry = if self.first_rate.is_some() {
            self.build()?;
            self.previous = None;
            true
        } else if let Some((old, old_rate)) = self.previous.take() {
            self.amg = Some(old);
            self.first_rate = old_rate.is_finite().then_some(old_rate);
            true
        } else {
            false
        };
        if retry {
            b.copy_from_slice(&rhs);
            let (converged, iterations, decades) = self.gmres(b)?;
            if converged {
                self.converged(iterations, decades);
                return Ok(());
            }
        }
        self.rebuild = true;
        Err(LinearSolverError::NotConverged(format!(
            "FGMRES with coupled AMG did not reach {:.0e} in {MAX_ITERATIONS} iterations \
             (an unstable state, or a tangent the preconditioner does not suit)",
            self.tolerance()
        )))
    }

    fn name(&self) -> &'static str {
        "FGMRES with coupled AMG"
    }

    fn is_factored(&self) -> bool {
        match &self.nodal {
            None => self.direct.is_factored(),
            Some(_) => self.amg.is_some(),
        }
    }

    fn invalidate(&mut self) {
        self.direct.invalidate();
        self.amg = None;
        self.previous = None;
        self.rebuild = true;
    }

    fn needs_layout(&self, n: usize) -> bool {
        self.layout.as_ref().is_none_or(|l| l.node.len() != n)
    }

    fn set_layout(&mut self, layout: DofLayout) {
        self.nodal = Nodal::new(&layout);
        self.layout = Some(layout);
        self.amg = None;
        self.previous = None;
        self.op = None;
        self.rebuild = true;
    }

    fn set_forcing(&mut self, rtol: Option<f64>) {
        self.forcing = rtol;
    }

    fn stats(&self) -> SolverStats {
        let d = self.direct.stats();
        SolverStats {
            factorizations: d.factorizations,
            solves: d.solves + self.stats.solves,
            krylov_iterations: self.stats.krylov_iterations,
            krylov_decades: self.stats.krylov_decades,
        }
    }
}

/// Iterations per decade of residual reduction: how well a hierarchy preconditions, comparable
/// between solves to different tolerances.
fn rate(iterations: usize, decades: f64) -> f64 {
    iterations as f64 / decades
}

/// The unknowns renumbered by whole nodes, (dim + 1) rows per node (the displacement components,
/// then the potential; a held unknown becomes a decoupled padding row), for one smoothed-aggregation
/// hierarchy of the whole coupled tangent.
struct Nodal {
    block: usize,
    /// Per unknown: its row.
    row: Vec<usize>,
    /// Per row: its unknown, or [`NONE`] (padding).
    eq: Vec<usize>,
    /// The near-null space: the rigid-body modes (zero potential) and the constant potential.
    modes: Vec<Vec<f64>>,
}

impl Nodal {
    /// `None` when the layout does not fit (a displacement component the geometry has not).
    fn new(layout: &DofLayout) -> Option<Nodal> {
        let n = layout.node.len();
        let dim = if layout.axisymmetric { 2 } else { 3 };
        let block = dim + 1;
        let mut slot = vec![NONE; layout.coords.len()];
        let mut coords = Vec::new();
        let mut row = vec![NONE; n];
        for e in 0..n {
            let f = match layout.field[e] as usize {
                3 => dim,
                f if f < dim => f,
                _ => return None,
            };
            let node = layout.node[e];
            if node >= slot.len() {
                return None;
            }
            if slot[node] == NONE {
                slot[node] = coords.len();
                coords.push(layout.coords[node]);
            }
            row[e] = slot[node] * block + f;
        }
        let rows = coords.len() * block;
        let mut eq = vec![NONE; rows];
        for (e, &r) in row.iter().enumerate() {
            eq[r] = e;
        }
        let rigid = if layout.axisymmetric {
            let mut z = vec![0.0; coords.len() * dim];
            z.iter_mut().skip(1).step_by(2).for_each(|v| *v = 1.0);
            vec![z]
        } else {
            rigid_body_modes(&coords, dim)
        };
        let mut modes: Vec<Vec<f64>> = rigid
            .iter()
            .map(|m| {
                let mut v = vec![0.0; rows];
                for node in 0..coords.len() {
                    for c in 0..dim {
                        v[node * block + c] = m[node * dim + c];
                    }
                }
                v
            })
            .collect();
        let mut phi = vec![0.0; rows];
        for node in 0..coords.len() {
            phi[node * block + dim] = 1.0;
        }
        modes.push(phi);
        for m in &mut modes {
            for (v, &e) in m.iter_mut().zip(&eq) {
                if e == NONE {
                    *v = 0.0;
                }
            }
        }
        Some(Nodal {
            block,
            row,
            eq,
            modes,
        })
    }

    /// The diagonal of a padding row: the mean magnitude of `k`'s diagonal, so that padding
    /// neither dominates nor vanishes in the smoother's scaling.
    fn pad(&self, k: &CsrMatrix) -> f64 {
        let mut sum = 0.0;
        let mut count = 0usize;
        for &e in self.eq.iter().filter(|&&e| e != NONE) {
            if let Some(p) = k.position(e, e) {
                sum += k.values[p].abs();
                count += 1;
            }
        }
        if count > 0 && sum > 0.0 {
            sum / count as f64
        } else {
            1.0
        }
    }

    /// The hierarchy of the renumbered tangent.
    fn hierarchy(&self, op: &NodalOperator) -> Result<Amg<'static>, LinearSolverError> {
        let params = AmgParams {
            smoother_degree: SMOOTHER_DEGREE,
            indefinite: true,
            smoother_storage: if op.nnz() >= SINGLE_MIN_ENTRIES {
                SmootherStorage::BlockSingle
            } else {
                SmootherStorage::BlockDouble
            },
            ..AmgParams::default()
        };
        match op {
            NodalOperator::Blocks(m) => Amg::from_blocks(m, &self.modes, &params),
            NodalOperator::Scalar(m) => Amg::owning(m.clone(), self.block, &self.modes, &params),
        }
        .map_err(|e| LinearSolverError::Failed(format!("AMG of the coupled tangent: {e}")))
    }
}

/// The tangent renumbered by nodes, as FGMRES multiplies by it: double-precision node blocks
/// (about half the bytes per entry of scalar CSR), or scalar CSR where blocks would be mostly
/// zeros.
enum NodalOperator {
    Blocks(BlockMatrix),
    Scalar(CsrMatrix),
}

impl NodalOperator {
    fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        match self {
            NodalOperator::Blocks(m) => m.mul_vec(x, y),
            NodalOperator::Scalar(m) => m.par_mul_vec(x, y),
        }
    }

    /// Stored entries (zeros of the blocks included).
    fn nnz(&self) -> usize {
        match self {
            NodalOperator::Blocks(m) => m.stored(),
            NodalOperator::Scalar(m) => m.nnz(),
        }
    }
}

/// The rows `rows` of `k` with their columns renumbered by `col_of` (columns without an index
/// dropped), sorted; `pad` on the diagonal of a row without unknown.
fn extract(
    k: &CsrMatrix,
    rows: &[usize],
    col_of: &[usize],
    pad: f64,
) -> (Vec<usize>, Vec<Col>, Vec<f64>) {
    let mut row_ptr = Vec::with_capacity(rows.len() + 1);
    row_ptr.push(0);
    let mut cols = Vec::new();
    let mut vals = Vec::new();
    let mut entries: Vec<(usize, f64)> = Vec::new();
    for (r, &e) in rows.iter().enumerate() {
        entries.clear();
        if e == NONE {
            entries.push((r, pad));
        } else {
            for p in k.row_ptr[e]..k.row_ptr[e + 1] {
                let c = col_of[k.col_idx[p] as usize];
                if c != NONE {
                    entries.push((c, k.values[p]));
                }
            }
            entries.sort_unstable_by_key(|x| x.0);
        }
        for &(c, v) in &entries {
            cols.push(col(c));
            vals.push(v);
        }
        row_ptr.push(cols.len());
    }
    (row_ptr, cols, vals)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CSR from a dense matrix, keeping the entries that are nonzero or on the diagonal.
    fn csr(dense: &[Vec<f64>]) -> CsrMatrix {
        let n = dense.len();
        let n_rows = n;
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::<f64>::new());
        for (i, row) in dense.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                if v != 0.0 || i == j {
                    col_idx.push(j);
                    values.push(v);
                }
            }
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values)
    }

    /// A coupled tangent on an m³ grid of nodes, four unknowns per node (u, Φ), node-major:
    /// A = L ⊗ I₃ + shift (stiffness-like), C = L + shift (permittivity-like), B a weak coupling
    /// of each displacement to its neighbours' potential. With x0 nodes holding u_x (a symmetry
    /// plane), so that the displacement block needs padding.
    fn coupled(m: usize) -> (CsrMatrix, DofLayout) {
        let nodes = m * m * m;
        let id = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
        let mut coords = vec![[0.0; 3]; nodes];
        let mut eq = vec![usize::MAX; nodes * 4];
        let mut layout = DofLayout {
            node: vec![],
            field: vec![],
            coords: vec![],
            axisymmetric: false,
            shared: false,
            owned: None,
            equations: None,
        };
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    let n = id(i, j, k);
                    coords[n] = [i as f64, j as f64, k as f64];
                    for f in 0..4 {
                        if f == 0 && i == 0 {
                            continue;
                        }
                        eq[n * 4 + f] = layout.node.len();
                        layout.node.push(n);
                        layout.field.push(f as u8);
                    }
                }
            }
        }
        layout.coords = coords;
        let n = layout.node.len();
        let mut dense = vec![vec![0.0; n]; n];
        let neighbours = |a: usize| {
            let (i, j, k) = (a / (m * m), (a / m) % m, a % m);
            let mut v = vec![];
            for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                let (p, q, r) = (i + di, j + dj, k + dk);
                if p < m && q < m && r < m {
                    v.push(id(p, q, r));
                }
            }
            v
        };
        let mut add = |a: usize, b: usize, v: f64| {
            if a != usize::MAX && b != usize::MAX {
                dense[a][b] += v;
                if a != b {
                    dense[b][a] += v;
                }
            }
        };
        for a in 0..nodes {
            for f in 0..3 {
                add(eq[a * 4 + f], eq[a * 4 + f], 6.5);
            }
            add(eq[a * 4 + 3], eq[a * 4 + 3], -6.2);
            for b in neighbours(a) {
                for f in 0..3 {
                    add(eq[a * 4 + f], eq[b * 4 + f], -1.0);
                    add(eq[a * 4 + f], eq[b * 4 + 3], 0.1 * (f as f64 + 1.0));
                }
                add(eq[a * 4 + 3], eq[b * 4 + 3], 1.0);
            }
        }
        (csr(&dense), layout)
    }

    #[test]
    fn gmres_with_coupled_amg_solves_a_coupled_system_to_its_tolerance() {
        // 9³ nodes: 2 835 unknowns, more than one level below the fine one
        let (k, layout) = coupled(9);
        let n = k.n;
        let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
        let mut direct = FaerLdlt::new();
        direct.factor(&k).unwrap();
        let mut reference = b.clone();
        direct.solve_in_place(&mut reference).unwrap();
        let mut s = AmgGmres::new(1e-10);
        assert!(s.needs_layout(n));
        s.set_layout(layout);
        assert!(!s.needs_layout(n));
        s.set_operator(&k).unwrap();
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        let scale = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = x
            .iter()
            .zip(&reference)
            .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
        assert!(err < 1e-8 * scale, "{err:e}");
        let st = s.stats();
        assert_eq!((st.factorizations, st.solves), (0, 1), "{st:?}");
        assert!(
            st.krylov_iterations > 1 && st.krylov_iterations < 100,
            "{st:?}"
        );
        assert!(s.amg.as_ref().is_some_and(|a| a.levels() >= 2));
        // no inertia from a factorisation it never makes
        assert_eq!(s.factor(&k).unwrap(), None);
        assert_eq!(s.builds(), 1);
    }

    /// With a forcing term looser than its tolerance an adaptive solver stops there, in fewer
    /// iterations; a fixed one ignores it; clearing the forcing term restores the tolerance.
    #[test]
    fn a_solve_stops_at_the_forcing_term_when_adaptive() {
        // more than one level: a one-level hierarchy solves exactly
        let (k, layout) = coupled(9);
        let n = k.n;
        let b: Vec<f64> = (0..n).map(|i| ((i * 5) % 13) as f64 - 6.0).collect();
        let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let relative = |x: &[f64]| {
            let mut ax = vec![0.0; n];
            k.mul_vec(x, &mut ax);
            ax.iter()
                .zip(&b)
                .map(|(u, v)| (u - v).powi(2))
                .sum::<f64>()
                .sqrt()
                / bn
        };
        let run = |adaptive: bool, forcing: Option<f64>| {
            let mut s = AmgGmres::new(1e-10).adaptive(adaptive);
            s.set_layout(layout.clone());
            s.set_operator(&k).unwrap();
            s.set_forcing(forcing);
            let mut x = b.clone();
            s.solve_in_place(&mut x).unwrap();
            (relative(&x), s.stats().krylov_iterations)
        };
        let (tight, tight_iterations) = run(true, None);
        let (loose, loose_iterations) = run(true, Some(1e-3));
        let (fixed, fixed_iterations) = run(false, Some(1e-3));
        assert!(tight < 1e-9, "{tight:e}");
        assert!(loose < 1e-3 && loose > 1e-9, "{loose:e}");
        assert!(
            loose_iterations < tight_iterations,
            "{loose_iterations} {tight_iterations}"
        );
        assert!(fixed < 1e-9, "{fixed:e}");
        assert_eq!(fixed_iterations, tight_iterations);
        // a forcing term tighter than the tolerance does not tighten it
        let (_, floor_iterations) = run(true, Some(1e-14));
        assert_eq!(floor_iterations, tight_iterations);
    }

    /// Rates compare solves to different tolerances: a hierarchy is not rebuilt because a tight
    /// solve needs more iterations than a loose one, and loose or short solves are not compared.
    #[test]
    fn rebuilds_compare_iterations_per_decade() {
        let (k, layout) = coupled(5);
        let mut s = AmgGmres::new(1e-10);
        s.set_layout(layout);
        s.set_operator(&k).unwrap();
        s.converged(30, 4.0);
        assert_eq!(s.first_rate, Some(7.5));
        // 60 iterations over 8 decades: the same rate
        s.converged(60, 8.0);
        assert!(!s.rebuild);
        // a loose solve says nothing
        s.converged(40, 1.0);
        assert!(!s.rebuild);
        // twice the rate: rebuild
        s.converged(60, 4.0);
        assert!(s.rebuild);
    }

    #[test]
    fn without_a_layout_the_direct_factorisation_solves() {
        let (k, _) = coupled(3);
        let mut s = AmgGmres::new(1e-8);
        let inertia = s
            .factor(&k)
            .unwrap()
            .expect("the direct LDLT gives the inertia");
        assert_eq!(inertia.positive + inertia.negative, k.n);
        assert_eq!(s.stats().factorizations, 1);
    }
}
