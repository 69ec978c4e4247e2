//! Block-preconditioned MINRES for large coupled tangents: no factorisation, memory linear in the
//! number of unknowns.
//!
//! The tangent K = [A B; Bᵀ −C] (A the displacement block, C = −K_ΦΦ positive definite) is
//! symmetric indefinite. MINRES (Paige & Saunders, SIAM J. Numer. Anal. 12 (1975) 617–629) solves
//! it with a symmetric positive definite block-diagonal preconditioner M = diag(Ŝ, Ĉ) (Murphy,
//! Golub & Wathen, SIAM J. Sci. Comput. 21 (2000) 1969–1972; Elman, Silvester & Wathen, *Finite
//! Elements and Fast Iterative Solvers*, 2nd ed., OUP 2014, ch. 4): Ĉ is one smoothed-aggregation
//! V-cycle ([`super::amg`]) on C with the constant as near-null space, Ŝ one V-cycle on
//! S̃ = A + B D⁻¹ Bᵀ (D = diag C) with the rigid-body modes.
//!
//! Why S̃ and not A: A is the stiffness at fixed nodal potentials. Its electrostatic softening is
//! not relieved by the redistribution of the field, so A loses definiteness before pull-in while
//! the equilibrium is still stable, and multigrid on an indefinite block fails. The stiffness at
//! fixed electrode potentials, the Schur complement A + B C⁻¹ Bᵀ, is positive definite exactly as
//! long as the equilibrium is stable; S̃ approximates it with the diagonal of C. The product
//! B D⁻¹ Bᵀ reaches two rings of neighbours; each entry g_ij outside A's pattern is moved onto the
//! diagonal as |g_ij| (this adds the positive semidefinite |g_ij|(e_i ∓ e_j)(e_i ∓ e_j)ᵀ), so S̃
//! keeps A's pattern and is at least as definite as A + B D⁻¹ Bᵀ.
//!
//! The hierarchies are kept across Newton iterations and steps while the iteration counts stay
//! near those of their first solve (the tangent changes little), and rebuilt when they grow or a
//! solve fails. There is no inertia: a limit point (pull-in) shows as a Newton failure at the
//! step that passes it, and load stepping cuts back towards it. A system that cannot tell where its
//! unknowns sit ([`DofLayout`]) is solved by the direct LDLᵀ instead.

use super::amg::{rigid_body_modes, Amg, AmgParams};
use super::krylov::{minres, KrylovSettings};
use super::linear::{FaerLdlt, Inertia, LinearSolver, LinearSolverError, Ordering, SolverStats};
use crate::problem::assembly::CsrMatrix;
use crate::problem::system::DofLayout;
use rayon::prelude::*;

/// Default relative residual of each solve. Newton's tolerance is 1e-10 of its first residual;
/// steps accurate to 1e-8 of the current residual cost it at most one more iteration.
pub const DEFAULT_RTOL: f64 = 1e-8;
/// Most MINRES iterations of one solve.
const MAX_ITERATIONS: usize = 2000;
/// The hierarchies are rebuilt when a solve needs more than this factor times the iterations of
/// the first solve with them.
const GROWTH: f64 = 1.5;
/// A row index meaning "none".
const NONE: usize = usize::MAX;

/// MINRES with the block AMG preconditioner; the direct LDLᵀ without a layout.
pub struct BlockMinres {
    rtol: f64,
    layout: Option<DofLayout>,
    split: Option<Split>,
    /// The matrix of the next solves.
    op: Option<CsrMatrix>,
    precond: Option<Preconditioner>,
    /// Iterations of the first solve with the current hierarchies, and a rebuild is due.
    first_iterations: Option<usize>,
    rebuild: bool,
    /// Used when the system gives no layout.
    direct: FaerLdlt,
    stats: SolverStats,
    /// Preconditioner builds.
    builds: usize,
}

impl BlockMinres {
    /// A solver that stops each solve at `rtol` (relative preconditioned residual).
    pub fn new(rtol: f64) -> Self {
        BlockMinres {
            rtol,
            layout: None,
            split: None,
            op: None,
            precond: None,
            first_iterations: None,
            rebuild: true,
            direct: FaerLdlt::with_ordering(Ordering::NestedDissection),
            stats: SolverStats::default(),
            builds: 0,
        }
    }

    /// Number of times the hierarchies were built.
    pub fn builds(&self) -> usize {
        self.builds
    }

    fn keep(&mut self, a: &CsrMatrix) {
        match &mut self.op {
            Some(op) => op.assign(a),
            None => self.op = Some(a.clone()),
        }
    }

    fn build_preconditioner(&mut self) -> Result<(), LinearSolverError> {
        let (Some(split), Some(op)) = (&self.split, &self.op) else {
            return Err(LinearSolverError::NotFactored);
        };
        self.precond = None;
        self.precond = Some(Preconditioner::new(split, op)?);
        self.first_iterations = None;
        self.rebuild = false;
        self.builds += 1;
        Ok(())
    }

    /// One MINRES solve with the current hierarchies: (converged, iterations).
    fn minres(&mut self, b: &mut [f64]) -> Result<(bool, usize), LinearSolverError> {
        let (Some(split), Some(op), Some(pc)) = (&self.split, &self.op, &self.precond) else {
            return Err(LinearSolverError::NotFactored);
        };
        let mut x = vec![0.0; b.len()];
        let mut work = pc.work(split);
        let settings = KrylovSettings {
            rtol: self.rtol,
            max_iterations: MAX_ITERATIONS,
            restart: 0,
        };
        let report = minres(
            |v, y| op.par_mul_vec(v, y),
            |r, z| pc.apply(split, &mut work, r, z),
            b,
            &mut x,
            &settings,
        );
        self.stats.krylov_iterations += report.iterations;
        self.stats.solves += 1;
        if report.converged {
            b.copy_from_slice(&x);
        }
        Ok((report.converged, report.iterations))
    }
}

impl LinearSolver for BlockMinres {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        if self.split.is_none() {
            return self.direct.factor(a);
        }
        // no factorisation and no inertia: the matrix is taken, and the hierarchies are built
        // only when there are none (a stability test right after Newton reuses them)
        self.keep(a);
        if self.precond.is_none() {
            self.build_preconditioner()?;
        }
        Ok(None)
    }

    fn set_operator(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        if self.split.is_none() {
            return self.direct.factor(a).map(|_| ());
        }
        self.keep(a);
        if self.rebuild || self.precond.is_none() {
            self.build_preconditioner()?;
        }
        Ok(())
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        if self.split.is_none() {
            return self.direct.solve_in_place(b);
        }
        let (converged, iterations) = self.minres(b)?;
        if converged {
            match self.first_iterations {
                None => self.first_iterations = Some(iterations.max(1)),
                Some(first) => {
                    self.rebuild |= iterations as f64 > GROWTH * first as f64 + 2.0;
                }
            }
            return Ok(());
        }
        if self.first_iterations.is_some() {
            // hierarchies of an older tangent: rebuild them for this one and try again
            self.build_preconditioner()?;
            let (converged, iterations) = self.minres(b)?;
            if converged {
                self.first_iterations = Some(iterations.max(1));
                return Ok(());
            }
        }
        self.rebuild = true;
        Err(LinearSolverError::NotConverged(format!(
            "MINRES with block AMG did not reach {:.0e} in {MAX_ITERATIONS} iterations \
             (an unstable state, or a tangent the preconditioner does not suit)",
            self.rtol
        )))
    }

    fn name(&self) -> &'static str {
        "MINRES with block AMG"
    }

    fn is_factored(&self) -> bool {
        match &self.split {
            None => self.direct.is_factored(),
            Some(_) => self.precond.is_some(),
        }
    }

    fn invalidate(&mut self) {
        self.direct.invalidate();
        self.precond = None;
        self.rebuild = true;
    }

    fn needs_layout(&self, n: usize) -> bool {
        self.layout.as_ref().is_none_or(|l| l.node.len() != n)
    }

    fn set_layout(&mut self, layout: DofLayout) {
        self.split = Split::new(&layout);
        self.layout = Some(layout);
        self.precond = None;
        self.op = None;
        self.rebuild = true;
    }

    fn stats(&self) -> SolverStats {
        let d = self.direct.stats();
        SolverStats {
            factorizations: d.factorizations,
            solves: d.solves + self.stats.solves,
            krylov_iterations: self.stats.krylov_iterations,
        }
    }
}

/// The unknowns split into the displacement block, padded to whole nodes (a held component
/// becomes an identity row), and the potential block.
struct Split {
    dim: usize,
    /// Per unknown: its row in the displacement block, or [`NONE`].
    u_row: Vec<usize>,
    /// Per unknown: its row in the potential block, or [`NONE`].
    p_row: Vec<usize>,
    /// Per displacement row: its unknown, or [`NONE`] (padding).
    u_eq: Vec<usize>,
    /// Per potential row: its unknown.
    p_eq: Vec<usize>,
    /// Reference coordinates of the displacement block's nodes.
    coords: Vec<[f64; 3]>,
    axisymmetric: bool,
}

impl Split {
    /// `None` when the layout does not fit (a displacement component the geometry has not).
    fn new(layout: &DofLayout) -> Option<Split> {
        let n = layout.node.len();
        let dim = if layout.axisymmetric { 2 } else { 3 };
        let mut block_of_node = vec![NONE; layout.coords.len()];
        let mut coords = Vec::new();
        let mut u_row = vec![NONE; n];
        let mut p_row = vec![NONE; n];
        let mut p_eq = Vec::new();
        for e in 0..n {
            let f = layout.field[e] as usize;
            let node = layout.node[e];
            if f == 3 {
                p_row[e] = p_eq.len();
                p_eq.push(e);
                continue;
            }
            if f >= dim || node >= block_of_node.len() {
                return None;
            }
            if block_of_node[node] == NONE {
                block_of_node[node] = coords.len();
                coords.push(layout.coords[node]);
            }
            u_row[e] = block_of_node[node] * dim + f;
        }
        let mut u_eq = vec![NONE; coords.len() * dim];
        for (e, &r) in u_row.iter().enumerate() {
            if r != NONE {
                u_eq[r] = e;
            }
        }
        Some(Split {
            dim,
            u_row,
            p_row,
            u_eq,
            p_eq,
            coords,
            axisymmetric: layout.axisymmetric,
        })
    }

    /// The near-null space of the displacement block: the rigid-body modes (the axial
    /// translation alone in the meridian plane), zero on padding rows.
    fn rigid_modes(&self) -> Vec<Vec<f64>> {
        let mut modes = if self.axisymmetric {
            let mut z = vec![0.0; self.u_eq.len()];
            z.iter_mut().skip(1).step_by(2).for_each(|v| *v = 1.0);
            vec![z]
        } else {
            rigid_body_modes(&self.coords, self.dim)
        };
        for m in &mut modes {
            for (v, &e) in m.iter_mut().zip(&self.u_eq) {
                if e == NONE {
                    *v = 0.0;
                }
            }
        }
        modes
    }
}

/// The rows `rows` of `k` restricted to the columns with an index in `col_of` (renumbered),
/// sorted; `pad` on the diagonal of a row without unknown (else such a row is empty); values
/// multiplied by `sign`.
fn extract(
    k: &CsrMatrix,
    rows: &[usize],
    col_of: &[usize],
    sign: f64,
    pad: Option<f64>,
) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let mut row_ptr = Vec::with_capacity(rows.len() + 1);
    row_ptr.push(0);
    let mut cols = Vec::new();
    let mut vals = Vec::new();
    let mut entries: Vec<(usize, f64)> = Vec::new();
    for (r, &e) in rows.iter().enumerate() {
        entries.clear();
        if e == NONE {
            entries.extend(pad.map(|v| (r, v)));
        } else {
            for p in k.row_ptr[e]..k.row_ptr[e + 1] {
                let c = col_of[k.col_idx[p]];
                if c != NONE {
                    entries.push((c, sign * k.values[p]));
                }
            }
            entries.sort_unstable_by_key(|x| x.0);
        }
        for &(c, v) in &entries {
            cols.push(c);
            vals.push(v);
        }
        row_ptr.push(cols.len());
    }
    (row_ptr, cols, vals)
}

/// S̃ = A + B D⁻¹ Bᵀ on A's pattern, the entries outside it moved onto the diagonal as |g_ij|.
/// `b` and `bt` are B (displacement rows) and Bᵀ (potential rows) in CSR form.
fn schur_on_pattern(
    a: &mut CsrMatrix,
    b: &(Vec<usize>, Vec<usize>, Vec<f64>),
    bt: &(Vec<usize>, Vec<usize>, Vec<f64>),
    d: &[f64],
) {
    let nu = a.n;
    let rows: Vec<Vec<f64>> = (0..nu)
        .into_par_iter()
        .map_init(
            || (vec![0.0; nu], vec![NONE; nu], Vec::<usize>::new()),
            |(acc, pos, touched), r| {
                let (lo, hi) = (a.row_ptr[r], a.row_ptr[r + 1]);
                let mut row = a.values[lo..hi].to_vec();
                for (q, &c) in a.col_idx[lo..hi].iter().enumerate() {
                    pos[c] = q;
                }
                for p in b.0[r]..b.0[r + 1] {
                    let (phi, brp) = (b.1[p], b.2[p] / d[b.1[p]]);
                    for s in bt.0[phi]..bt.0[phi + 1] {
                        let j = bt.1[s];
                        if acc[j] == 0.0 {
                            touched.push(j);
                        }
                        acc[j] += brp * bt.2[s];
                    }
                }
                let diag = a.col_idx[lo..hi].iter().position(|&c| c == r);
                let mut moved = 0.0;
                for &j in touched.iter() {
                    match pos[j] {
                        NONE => moved += acc[j].abs(),
                        q => row[q] += acc[j],
                    }
                    acc[j] = 0.0;
                }
                touched.clear();
                for &c in &a.col_idx[lo..hi] {
                    pos[c] = NONE;
                }
                if let Some(q) = diag {
                    row[q] += moved;
                }
                row
            },
        )
        .collect();
    for (r, row) in rows.into_iter().enumerate() {
        a.values[a.row_ptr[r]..a.row_ptr[r + 1]].copy_from_slice(&row);
    }
}

/// Settings of both hierarchies: a Chebyshev smoother of degree 3 (on the nearly incompressible
/// film, degree 2 needed 95 MINRES iterations per solve and degree 3 77, for the same time).
fn amg_params() -> AmgParams {
    AmgParams {
        smoother_degree: 3,
        ..AmgParams::default()
    }
}

/// The two AMG hierarchies of the block preconditioner.
struct Preconditioner {
    u: Option<Amg<'static>>,
    p: Option<Amg<'static>>,
}

/// Work vectors of one solve.
struct Work {
    ru: Vec<f64>,
    zu: Vec<f64>,
    rp: Vec<f64>,
    zp: Vec<f64>,
}

impl Preconditioner {
    fn new(split: &Split, k: &CsrMatrix) -> Result<Self, LinearSolverError> {
        let fail = |block: &str, e: String| {
            LinearSolverError::Failed(format!("AMG of the {block} block: {e}"))
        };
        let nu = split.u_eq.len();
        let np = split.p_eq.len();
        // the mean diagonal of the displacement rows, for the padding rows
        let mut sum = 0.0;
        let mut count = 0usize;
        for &e in split.u_eq.iter().filter(|&&e| e != NONE) {
            if let Some(p) = k.position(e, e) {
                sum += k.values[p].abs();
                count += 1;
            }
        }
        let pad = if count > 0 { sum / count as f64 } else { 1.0 };
        let p = if np > 0 {
            let (row_ptr, col_idx, values) = extract(k, &split.p_eq, &split.p_row, -1.0, None);
            let c = CsrMatrix::new(np, row_ptr, col_idx, values);
            Some(c)
        } else {
            None
        };
        let u = if nu > 0 {
            let (row_ptr, col_idx, values) = extract(k, &split.u_eq, &split.u_row, 1.0, Some(pad));
            let mut a = CsrMatrix::new(nu, row_ptr, col_idx, values);
            if let Some(c) = &p {
                let mut d = vec![0.0; np];
                for (i, di) in d.iter_mut().enumerate() {
                    *di = c.position(i, i).map_or(0.0, |q| c.values[q]);
                    if di.is_nan() || *di <= 0.0 {
                        return Err(fail(
                            "potential",
                            format!("diagonal entry {i} is {di:e}, not positive"),
                        ));
                    }
                }
                let b = extract(k, &split.u_eq, &split.p_row, 1.0, None);
                let bt = extract(k, &split.p_eq, &split.u_row, 1.0, None);
                schur_on_pattern(&mut a, &b, &bt, &d);
            }
            let modes = split.rigid_modes();
            let params = amg_params();
            Some(
                Amg::owning(a, split.dim, &modes, &params)
                    .map_err(|e| fail("displacement", e.to_string()))?,
            )
        } else {
            None
        };
        let p = match p {
            Some(c) => Some(
                Amg::owning(c, 1, &[vec![1.0; np]], &amg_params())
                    .map_err(|e| fail("potential", e.to_string()))?,
            ),
            None => None,
        };
        Ok(Preconditioner { u, p })
    }

    fn work(&self, split: &Split) -> Work {
        let nu = split.u_eq.len();
        let np = split.p_eq.len();
        Work {
            ru: vec![0.0; nu],
            zu: vec![0.0; nu],
            rp: vec![0.0; np],
            zp: vec![0.0; np],
        }
    }

    /// z = M⁻¹ r: one V-cycle on each block.
    fn apply(&self, split: &Split, w: &mut Work, r: &[f64], z: &mut [f64]) {
        for (ri, &e) in w.ru.iter_mut().zip(&split.u_eq) {
            *ri = if e == NONE { 0.0 } else { r[e] };
        }
        for (ri, &e) in w.rp.iter_mut().zip(&split.p_eq) {
            *ri = r[e];
        }
        let (u, p) = (&self.u, &self.p);
        let (ru, zu, rp, zp) = (&w.ru, &mut w.zu, &w.rp, &mut w.zp);
        rayon::join(
            || {
                if let Some(amg) = u {
                    amg.apply(ru, zu);
                }
            },
            || {
                if let Some(amg) = p {
                    amg.apply(rp, zp);
                }
            },
        );
        for (zi, &e) in w.zu.iter().zip(&split.u_eq) {
            if e != NONE {
                z[e] = *zi;
            }
        }
        for (zi, &e) in w.zp.iter().zip(&split.p_eq) {
            z[e] = *zi;
        }
    }
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
        CsrMatrix::new(n_rows, row_ptr, col_idx, values)
    }

    #[test]
    fn the_schur_product_keeps_the_pattern_and_adds_a_semidefinite_matrix() {
        // A diagonal, B one column: G = B D⁻¹ Bᵀ is full, so its off-diagonal entries move
        let mut a = csr(&[
            vec![4.0, 0.0, 0.0],
            vec![0.0, 5.0, 0.0],
            vec![0.0, 0.0, 6.0],
        ]);
        let b = (vec![0, 1, 2, 3], vec![0, 0, 0], vec![1.0, -2.0, 3.0]);
        let bt = (vec![0, 3], vec![0, 1, 2], vec![1.0, -2.0, 3.0]);
        schur_on_pattern(&mut a, &b, &bt, &[2.0]);
        assert_eq!(*a.col_idx, [0, 1, 2]);
        // diagonal: A_ii + G_ii + Σ_j≠i |G_ij| with G = BBᵀ/2
        let g = |i: usize, j: usize| b.2[i] * b.2[j] / 2.0;
        for i in 0..3 {
            let moved: f64 = (0..3).filter(|&j| j != i).map(|j| g(i, j).abs()).sum();
            let expected = [4.0, 5.0, 6.0][i] + g(i, i) + moved;
            assert!((a.values[i] - expected).abs() < 1e-14, "{i}");
        }
        // S̃ − A − G = Σ |g_ij| (e_i ∓ e_j)(e_i ∓ e_j)ᵀ ≥ 0: xᵀ(S̃ − A − G)x ≥ 0 for sample x
        for x in [[1.0, 1.0, 1.0], [1.0, -1.0, 0.5], [0.3, 2.0, -1.0]] {
            let mut q = 0.0;
            for i in 0..3 {
                let extra = a.values[i] - [4.0, 5.0, 6.0][i];
                q += extra * x[i] * x[i];
                for j in 0..3 {
                    q -= g(i, j) * x[i] * x[j];
                }
            }
            assert!(q >= -1e-12, "{q}");
        }
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
            entries: None,
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
    fn minres_with_block_amg_solves_a_coupled_system_to_its_tolerance() {
        let (k, layout) = coupled(7);
        let n = k.n;
        let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
        let mut direct = FaerLdlt::new();
        direct.factor(&k).unwrap();
        let mut reference = b.clone();
        direct.solve_in_place(&mut reference).unwrap();
        let mut s = BlockMinres::new(1e-10);
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
        // no inertia from a factorisation it never makes
        assert_eq!(s.factor(&k).unwrap(), None);
        assert_eq!(s.builds(), 1);
    }

    #[test]
    fn without_a_layout_the_direct_factorisation_solves() {
        let (k, _) = coupled(3);
        let mut s = BlockMinres::new(1e-8);
        let inertia = s
            .factor(&k)
            .unwrap()
            .expect("the direct LDLT gives the inertia");
        assert_eq!(inertia.positive + inertia.negative, k.n);
        assert_eq!(s.stats().factorizations, 1);
    }
}
