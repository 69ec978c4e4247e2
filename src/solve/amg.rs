//! Smoothed-aggregation algebraic multigrid (SA-AMG): a symmetric positive definite
//! preconditioner for elasticity or a scalar, Laplacian-like operator, for use inside CG or
//! MINRES, and (with [`AmgParams::indefinite`]) a preconditioner of the whole coupled,
//! symmetric indefinite tangent for flexible GMRES.
//!
//! The method is that of Vaněk, Mandel & Brezina, "Algebraic multigrid by smoothed aggregation
//! for second and fourth order elliptic problems", Computing 56 (1996) 179–196: nodes are grouped
//! into aggregates along strong couplings, a tentative prolongator interpolates the near-null space
//! (the rigid-body modes of elasticity, the constant of a scalar problem) exactly on each
//! aggregate, one damped-Jacobi step smooths it, and the coarse operators are the Galerkin
//! products PᵀAP. The smoother is a Chebyshev polynomial in D⁻¹A, as proposed for parallel
//! multigrid by Adams, Brezina, Hu & Tuminaro, "Parallel multigrid smoothing: polynomial versus
//! Gauss–Seidel", J. Comput. Phys. 188 (2003) 593–610: it needs only matrix-vector products (row
//! parallel and deterministic) and, used before and after the coarse correction, keeps the V-cycle
//! symmetric.
//!
//! Why a module of our own: the pure-Rust `kryst` crate (4.3) was tried on the clamped-cube
//! elasticity matrices of the tests below, with the rigid-body modes as near-null space, inside
//! the same CG. Its aggregation path reached the same iteration count (13 on 8³ cells) but its
//! setup took 2.5–6 s on 1944 unknowns (this module: under 0.1 s) and had not finished the 16³
//! case (13 872 unknowns) after 7 minutes; with classical interpolation and a near-null space its
//! setup panicked (an index out of bounds) instead of returning an error. Its source also appears
//! to use the given near-null space on the first level only, where this module carries the coarse
//! near-null space (the R factors of the local QR) down every level.
//!
//! Memory: the fine matrix is borrowed, never copied (unless [`SmootherStorage`] asks for node
//! blocks, which then replace it); each coarser level stores its operator, P and R = Pᵀ (32-bit
//! column indices), the inverse diagonal and four work vectors. Only the coarsest operator is
//! dense.

use crate::algebra::csr::CsrMatrix;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltParams, LltRegularization};
use faer::{Mat, Par, Spec};
use rayon::prelude::*;
use std::borrow::Cow;
use std::sync::Mutex;

/// Rows per parallel task; matrices and vectors shorter than [`PARALLEL_MIN_ROWS`] are handled on
/// the calling thread. Results do not depend on either: every row is summed in the same order,
/// and dot products are summed per fixed chunk, then over chunks in order.
const CHUNK: usize = 4096;
const PARALLEL_MIN_ROWS: usize = 32_768;

/// Settings of the hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct AmgParams {
    /// Strength-of-connection threshold θ on the finest level: nodes i, j are strongly coupled
    /// when ‖A_ij‖ > θ √(‖A_ii‖ ‖A_jj‖) (Frobenius norms of the node blocks). Halved on each
    /// coarser level, as in Vaněk, Mandel & Brezina. 0.08 suits elasticity.
    pub theta: f64,
    /// Degree of the Chebyshev smoother (matrix-vector products per smoothing sweep).
    pub smoother_degree: usize,
    /// The Chebyshev interval is [λ_max / ratio, λ_max]: the upper part of the spectrum of D⁻¹A
    /// is damped, the lower part is left to the coarse grid.
    pub chebyshev_ratio: f64,
    /// Safety factor on the estimated largest eigenvalue of D⁻¹A (the estimate is from below).
    pub lambda_safety: f64,
    /// Lanczos steps for the eigenvalue estimate.
    pub lanczos_steps: usize,
    /// Most levels, the finest included.
    pub max_levels: usize,
    /// Coarsening stops once a level has at most this many unknowns; that level is factored densely.
    pub coarse_size: usize,
    /// Largest coarsest level accepted for the dense factorisation (when coarsening stalls).
    pub max_dense_size: usize,
    /// Accept a symmetric indefinite matrix with a nonzero diagonal of either sign (a coupled
    /// saddle-point tangent): the smoother and the prolongator smoothing then use the signed
    /// diagonal, whose scaled operator |D|⁻¹ S A has its spectrum in the disc of radius
    /// ‖|D|^{-1/2} A |D|^{-1/2}‖ (S the signs), and the coarsest level is factored by LBLᵀ.
    /// The cycle is then not symmetric: use it in flexible GMRES.
    pub indefinite: bool,
    /// How the smoother stores the level operators once the hierarchy is built
    /// ([`SmootherStorage`]).
    pub smoother_storage: SmootherStorage,
}

/// Storage of the level operators for the smoother. The smoother streams each operator several
/// times per V-cycle and that traffic bounds its speed on large problems: node blocks with 32-bit
/// block columns need about half the bytes of scalar CSR with word-sized columns, single-precision
/// blocks a quarter. Set-up (strength, prolongator smoothing, Galerkin products) always works on
/// scalar matrices in double precision; the scalar operators of the smoothed levels (an owned fine
/// matrix included) are released after it, so only the blocks remain. The coarsest level keeps
/// its dense factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmootherStorage {
    /// The scalar CSR operators as they are.
    Csr,
    /// Dense node blocks (block × block, the level's block size), double precision.
    BlockDouble,
    /// Dense node blocks with single-precision values (products still summed in double). The
    /// smoother then works on a matrix rounded to about 7 digits: it remains a fixed linear
    /// operator (symmetric when the matrix is), so a Krylov method stays exact at its tolerance.
    BlockSingle,
}

impl Default for AmgParams {
    fn default() -> Self {
        AmgParams {
            theta: 0.08,
            smoother_degree: 2,
            chebyshev_ratio: 30.0,
            lambda_safety: 1.1,
            lanczos_steps: 15,
            max_levels: 12,
            coarse_size: 2000,
            max_dense_size: 6000,
            indefinite: false,
            smoother_storage: SmootherStorage::Csr,
        }
    }
}

/// Why the hierarchy could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AmgError {
    #[error("empty matrix (no unknowns)")]
    Empty,
    #[error("malformed matrix: {0}")]
    Malformed(String),
    #[error("matrix is not square: column {col} in row {row} is outside the {n} columns")]
    NotSquare { row: usize, col: usize, n: usize },
    #[error("non-finite matrix entry at ({row}, {col})")]
    NonFinite { row: usize, col: usize },
    #[error(
        "diagonal entry {row} is not positive ({value}); the matrix must be positive definite"
    )]
    NonPositiveDiagonal { row: usize, value: f64 },
    #[error("block size {block} does not divide the {n} unknowns (or is zero)")]
    BlockSize { n: usize, block: usize },
    #[error("no near-null-space vectors given (pass the constant vector for a scalar problem)")]
    NoNearNull,
    #[error("near-null-space vector {index} has {len} entries, the matrix has {n} rows")]
    NearNullLength { index: usize, len: usize, n: usize },
    #[error("near-null-space vector {index} has a non-finite entry at row {row}")]
    NearNullNonFinite { index: usize, row: usize },
    #[error("invalid parameter: {0}")]
    Params(String),
    #[error(
        "coarsening stalled at level {level} with {n} unknowns, too many for the dense coarse solve"
    )]
    Stalled { level: usize, n: usize },
    #[error(
        "the coarsest operator ({n} unknowns) could not be factored even with a diagonal shift"
    )]
    CoarseFactorisation { n: usize },
}

// ---------------------------------------------------------------------------------------------
// Sparse matrices

/// A borrowed CSR matrix (columns sorted within each row).
#[derive(Clone, Copy)]
struct View<'m> {
    nrows: usize,
    ncols: usize,
    row_ptr: &'m [usize],
    col: &'m [u32],
    val: &'m [f64],
}

/// A CSR matrix owned by the hierarchy.
#[derive(Debug, Clone, Default)]
struct Csr {
    nrows: usize,
    ncols: usize,
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

impl Csr {
    fn view(&self) -> View<'_> {
        View {
            nrows: self.nrows,
            ncols: self.ncols,
            row_ptr: &self.row_ptr,
            col: &self.col,
            val: &self.val,
        }
    }

    fn nnz(&self) -> usize {
        self.val.len()
    }

    /// Pᵀ by a counting sort (columns come out sorted because rows are visited in order).
    fn transpose(&self) -> Csr {
        let mut count = vec![0usize; self.ncols + 1];
        for &c in &self.col {
            count[c as usize + 1] += 1;
        }
        for j in 0..self.ncols {
            count[j + 1] += count[j];
        }
        let row_ptr = count.clone();
        let mut next = count;
        let mut col = vec![0u32; self.nnz()];
        let mut val = vec![0.0; self.nnz()];
        for i in 0..self.nrows {
            for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                let j = self.col[p] as usize;
                col[next[j]] = i as u32;
                val[next[j]] = self.val[p];
                next[j] += 1;
            }
        }
        Csr {
            nrows: self.ncols,
            ncols: self.nrows,
            row_ptr,
            col,
            val,
        }
    }

    /// Averages a structurally symmetric matrix with its transpose, entry by entry, so that the
    /// Galerkin operator is symmetric to the last bit (and the V-cycle with it).
    fn symmetrise(&mut self) {
        for i in 0..self.nrows {
            for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                let j = self.col[p] as usize;
                if j <= i {
                    continue;
                }
                let row = &self.col[self.row_ptr[j]..self.row_ptr[j + 1]];
                if let Ok(q) = row.binary_search(&(i as u32)) {
                    let q = self.row_ptr[j] + q;
                    let m = 0.5 * (self.val[p] + self.val[q]);
                    self.val[p] = m;
                    self.val[q] = m;
                }
            }
        }
    }
}

/// The operator of one level: the caller's matrix on the finest level, ours below.
#[derive(Clone, Copy)]
enum Op<'m> {
    Fine(View<'m>),
    Coarse(View<'m>),
}

impl Op<'_> {
    fn n(&self) -> usize {
        match self {
            Op::Fine(v) => v.nrows,
            Op::Coarse(v) => v.nrows,
        }
    }

    /// y_i ← f(i, (A x)_i, y_i) for every row, rows in parallel for large matrices.
    fn apply_with<F>(&self, x: &[f64], y: &mut [f64], f: F)
    where
        F: Fn(usize, f64, &mut f64) + Sync,
    {
        match self {
            Op::Fine(v) => spmv_with(*v, x, y, f),
            Op::Coarse(v) => spmv_with(*v, x, y, f),
        }
    }
}

/// y_i ← f(i, (A x)_i, y_i); each row is summed in storage order whatever the threads.
fn spmv_with<F>(a: View<'_>, x: &[f64], y: &mut [f64], f: F)
where
    F: Fn(usize, f64, &mut f64) + Sync,
{
    let row = |i: usize| {
        let mut s = 0.0;
        for p in a.row_ptr[i]..a.row_ptr[i + 1] {
            s += a.val[p] * x[a.col[p] as usize];
        }
        s
    };
    if a.nrows >= PARALLEL_MIN_ROWS {
        y[..a.nrows]
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, ys)| {
                for (k, yi) in ys.iter_mut().enumerate() {
                    let i = c * CHUNK + k;
                    f(i, row(i), yi);
                }
            });
    } else {
        for (i, yi) in y[..a.nrows].iter_mut().enumerate() {
            f(i, row(i), yi);
        }
    }
}

/// A matrix the smoother can multiply: a level operator in CSR, or the node-blocked finest one.
trait Apply: Sync {
    /// y_i ← f(i, (A x)_i, y_i) for every row.
    fn apply_with<F>(&self, x: &[f64], y: &mut [f64], f: F)
    where
        F: Fn(usize, f64, &mut f64) + Sync;
}

impl Apply for Op<'_> {
    fn apply_with<F>(&self, x: &[f64], y: &mut [f64], f: F)
    where
        F: Fn(usize, f64, &mut f64) + Sync,
    {
        Op::apply_with(self, x, y, f)
    }
}

/// Values of the node blocks, each block row-major.
#[derive(Debug, Clone)]
enum BlockValues {
    Double(Vec<f64>),
    Single(Vec<f32>),
}

/// A square matrix in block compressed rows: dense `b` × `b` node blocks with 32-bit block
/// columns, missing entries of a stored block held as zeros.
#[derive(Debug, Clone)]
struct Bsr {
    b: usize,
    /// Block rows (= block columns).
    nb: usize,
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    val: BlockValues,
}

impl Bsr {
    /// The blocks of `a` (n a multiple of `b`, columns sorted within each row), or `None` when
    /// the dense blocks would store more than `max_fill` times the entries of `a`.
    fn from_csr(a: View<'_>, b: usize, single: bool, max_fill: f64) -> Option<Bsr> {
        if b == 0 || !a.nrows.is_multiple_of(b) || a.nrows != a.ncols {
            return None;
        }
        let nb = a.nrows / b;
        let per = (CHUNK / b).max(1);
        let chunks = nb.div_ceil(per);
        // block pattern, per chunk of block rows in parallel: the sorted distinct block columns
        // of the b rows of each block row
        let parts: Vec<(Vec<usize>, Vec<u32>)> = (0..chunks)
            .into_par_iter()
            .map(|k| {
                let (mut counts, mut cols, mut row) = (Vec::new(), Vec::new(), Vec::new());
                for ib in k * per..((k + 1) * per).min(nb) {
                    row.clear();
                    for i in ib * b..(ib + 1) * b {
                        row.extend(
                            a.col[a.row_ptr[i]..a.row_ptr[i + 1]]
                                .iter()
                                .map(|c| (*c as usize / b) as u32),
                        );
                    }
                    row.sort_unstable();
                    row.dedup();
                    counts.push(row.len());
                    cols.extend_from_slice(&row);
                }
                (counts, cols)
            })
            .collect();
        let mut row_ptr = Vec::with_capacity(nb + 1);
        row_ptr.push(0usize);
        let mut col: Vec<u32> = Vec::with_capacity(parts.iter().map(|p| p.1.len()).sum());
        for (counts, cols) in parts {
            for c in counts {
                row_ptr.push(row_ptr[row_ptr.len() - 1] + c);
            }
            col.extend_from_slice(&cols);
        }
        let stored = col.len() * b * b;
        if stored as f64 > max_fill * a.val.len().max(1) as f64 {
            return None;
        }
        // values, per chunk of block rows in parallel, each into its own slice
        fn fill<T: Copy + Send>(
            a: View<'_>,
            b: usize,
            per: usize,
            row_ptr: &[usize],
            col: &[u32],
            convert: fn(f64) -> T,
            zero: T,
        ) -> Vec<T> {
            let mut values = vec![zero; col.len() * b * b];
            block_row_chunks(row_ptr, b, per, &mut values)
                .into_par_iter()
                .for_each(|(first, last, vals)| {
                    let base = row_ptr[first];
                    for ib in first..last {
                        let blocks = &col[row_ptr[ib]..row_ptr[ib + 1]];
                        for r in 0..b {
                            let i = ib * b + r;
                            // the row's columns are sorted, and so are the blocks: walk both forward
                            let mut q = 0;
                            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                                let j = a.col[p] as usize;
                                while blocks[q] as usize != j / b {
                                    q += 1;
                                }
                                vals[((row_ptr[ib] + q - base) * b + r) * b + j % b] =
                                    convert(a.val[p]);
                            }
                        }
                    }
                });
            values
        }
        let val = if single {
            BlockValues::Single(fill(a, b, per, &row_ptr, &col, |x| x as f32, 0.0))
        } else {
            BlockValues::Double(fill(a, b, per, &row_ptr, &col, |x| x, 0.0))
        };
        Some(Bsr {
            b,
            nb,
            row_ptr,
            col,
            val,
        })
    }

    /// The stored entries of double-precision blocks that are not zero, and every diagonal entry,
    /// in scalar CSR with 32-bit columns.
    fn to_compact(&self) -> Csr {
        let BlockValues::Double(values) = &self.val else {
            unreachable!("only double-precision blocks are converted back")
        };
        let (b, n) = (self.b, self.nb * self.b);
        let mut row_ptr = Vec::with_capacity(n + 1);
        row_ptr.push(0);
        let mut col = Vec::new();
        let mut val = Vec::new();
        for ib in 0..self.nb {
            for r in 0..b {
                let i = ib * b + r;
                for q in self.row_ptr[ib]..self.row_ptr[ib + 1] {
                    let jb = self.col[q] as usize;
                    for c in 0..b {
                        let v = values[(q * b + r) * b + c];
                        let j = jb * b + c;
                        if v != 0.0 || j == i {
                            col.push(j as u32);
                            val.push(v);
                        }
                    }
                }
                row_ptr.push(col.len());
            }
        }
        Csr {
            nrows: n,
            ncols: n,
            row_ptr,
            col,
            val,
        }
    }

    /// Stored values (zeros of the blocks included).
    fn stored(&self) -> usize {
        self.col.len() * self.b * self.b
    }

    fn storage(&self) -> SmootherStorage {
        match self.val {
            BlockValues::Double(_) => SmootherStorage::BlockDouble,
            BlockValues::Single(_) => SmootherStorage::BlockSingle,
        }
    }
}

/// The values of a block matrix cut into runs of `per` block rows, as (first block row, end,
/// that run's values), for filling the runs in parallel.
fn block_row_chunks<'v, T>(
    row_ptr: &[usize],
    b: usize,
    per: usize,
    values: &'v mut [T],
) -> Vec<(usize, usize, &'v mut [T])> {
    let nb = row_ptr.len() - 1;
    let mut chunks = Vec::with_capacity(nb.div_ceil(per.max(1)));
    let mut rest = values;
    let mut first = 0;
    while first < nb {
        let last = (first + per).min(nb);
        let (head, tail) = rest.split_at_mut((row_ptr[last] - row_ptr[first]) * b * b);
        chunks.push((first, last, head));
        rest = tail;
        first = last;
    }
    chunks
}

/// y_i ← f(i, (A x)_i, y_i) over the block rows of a matrix with `B` × `B` blocks; each row is
/// summed block by block in storage order, whatever the threads.
fn bsr_apply<const B: usize, T, F>(m: &Bsr, val: &[T], x: &[f64], y: &mut [f64], f: &F)
where
    T: Copy + Into<f64> + Sync,
    F: Fn(usize, f64, &mut f64) + Sync,
{
    let block_row = |ib: usize| {
        let mut acc = [0.0f64; B];
        for p in m.row_ptr[ib]..m.row_ptr[ib + 1] {
            let j = m.col[p] as usize * B;
            let xs: &[f64; B] = x[j..j + B].try_into().expect("block of x");
            let blk: &[T] = &val[p * B * B..(p + 1) * B * B];
            for (r, a) in acc.iter_mut().enumerate() {
                let mut s = 0.0;
                for (c, xc) in xs.iter().enumerate() {
                    s += blk[r * B + c].into() * xc;
                }
                *a += s;
            }
        }
        acc
    };
    let rows = |first_block: usize, ys: &mut [f64]| {
        for (k, yb) in ys.chunks_mut(B).enumerate() {
            let ib = first_block + k;
            let acc = block_row(ib);
            for (r, yi) in yb.iter_mut().enumerate() {
                f(ib * B + r, acc[r], yi);
            }
        }
    };
    let n = m.nb * B;
    let per_task = (CHUNK / B).max(1) * B;
    if n >= PARALLEL_MIN_ROWS {
        y[..n]
            .par_chunks_mut(per_task)
            .enumerate()
            .for_each(|(c, ys)| rows(c * per_task / B, ys));
    } else {
        rows(0, &mut y[..n]);
    }
}

impl Apply for Bsr {
    fn apply_with<F>(&self, x: &[f64], y: &mut [f64], f: F)
    where
        F: Fn(usize, f64, &mut f64) + Sync,
    {
        macro_rules! dispatch {
            ($v:expr) => {
                match self.b {
                    1 => bsr_apply::<1, _, _>(self, $v, x, y, &f),
                    2 => bsr_apply::<2, _, _>(self, $v, x, y, &f),
                    3 => bsr_apply::<3, _, _>(self, $v, x, y, &f),
                    4 => bsr_apply::<4, _, _>(self, $v, x, y, &f),
                    5 => bsr_apply::<5, _, _>(self, $v, x, y, &f),
                    6 => bsr_apply::<6, _, _>(self, $v, x, y, &f),
                    7 => bsr_apply::<7, _, _>(self, $v, x, y, &f),
                    8 => bsr_apply::<8, _, _>(self, $v, x, y, &f),
                    b => unreachable!("blocks of {b} are not built (see BLOCK_MAX)"),
                }
            };
        }
        match &self.val {
            BlockValues::Double(v) => dispatch!(v),
            BlockValues::Single(v) => dispatch!(v),
        }
    }
}

/// A square matrix in double-precision node blocks (see [`SmootherStorage`]): the operator of a
/// Krylov method at about half the bytes per entry of a [`CsrMatrix`], whose products are what
/// bounds an iteration on large problems.
#[derive(Debug, Clone)]
pub struct BlockMatrix {
    m: Bsr,
}

impl BlockMatrix {
    /// The node blocks of `a` (rows node-major, `block` unknowns per node), or `None` when
    /// `block` does not divide the rows, exceeds 8, or the blocks would be more than half zeros.
    pub fn from_csr(a: &CsrMatrix, block: usize) -> Option<BlockMatrix> {
        if block > BLOCK_MAX {
            return None;
        }
        let view = View {
            nrows: a.n,
            ncols: a.n,
            row_ptr: &a.row_ptr,
            col: &a.col_idx,
            val: &a.values,
        };
        Bsr::from_csr(view, block, false, BLOCK_MAX_FILL).map(|m| BlockMatrix { m })
    }

    /// Rows (= columns).
    pub fn n(&self) -> usize {
        self.m.nb * self.m.b
    }

    /// Stored values (zeros of the blocks included).
    pub fn stored(&self) -> usize {
        self.m.stored()
    }

    /// y = A x (rows in parallel for large matrices; each row summed in the same order).
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        self.m.apply_with(x, y, |_, s, yi| *yi = s);
    }

    /// Overwrites the values with those of `a`, renumbered: unknown e of `a` is row `row[e]`
    /// here, `eq[r]` is the unknown of row r (`usize::MAX` for none), and a column without a row
    /// is dropped. A row without an unknown gets `pad` on its diagonal and zeros elsewhere.
    /// Returns false, leaving the values undefined, when an entry of `a` falls outside the stored
    /// blocks (build a new matrix then).
    pub fn assign_renumbered(
        &mut self,
        a: &CsrMatrix,
        eq: &[usize],
        row: &[usize],
        pad: f64,
    ) -> bool {
        let b = self.m.b;
        let (row_ptr, col) = (&self.m.row_ptr, &self.m.col);
        let BlockValues::Double(values) = &mut self.m.val else {
            return false;
        };
        let slices = block_row_chunks(row_ptr, b, (CHUNK / b).max(1), values);
        let fill = |(first, last, vals): (usize, usize, &mut [f64])| -> bool {
            vals.fill(0.0);
            let base = row_ptr[first];
            for ib in first..last {
                let blocks = &col[row_ptr[ib]..row_ptr[ib + 1]];
                for r in 0..b {
                    let e = eq[ib * b + r];
                    if e == usize::MAX {
                        match blocks.binary_search(&(ib as u32)) {
                            Ok(q) => vals[((row_ptr[ib] + q - base) * b + r) * b + r] = pad,
                            Err(_) => return false,
                        }
                        continue;
                    }
                    for p in a.row_ptr[e]..a.row_ptr[e + 1] {
                        let c = row[a.col_idx[p] as usize];
                        if c == usize::MAX {
                            continue;
                        }
                        match blocks.binary_search(&((c / b) as u32)) {
                            Ok(q) => {
                                vals[((row_ptr[ib] + q - base) * b + r) * b + c % b] = a.values[p]
                            }
                            Err(_) => return false,
                        }
                    }
                }
            }
            true
        };
        if self.m.nb * b >= PARALLEL_MIN_ROWS {
            slices
                .into_par_iter()
                .map(fill)
                .reduce(|| true, |x, y| x && y)
        } else {
            slices.into_iter().all(fill)
        }
    }

    /// The stored entries that are not zero, and every diagonal entry, in scalar CSR.
    pub fn to_csr(&self) -> CsrMatrix {
        let c = self.m.to_compact();
        CsrMatrix::new(c.nrows, c.row_ptr, c.col, c.val)
    }
}

/// Largest node block stored as blocks (7 = the near-null space of 3-D coupled problems); larger
/// ones stay in CSR.
const BLOCK_MAX: usize = 8;
/// Blocks are not used when their zeros would more than double the stored entries.
const BLOCK_MAX_FILL: f64 = 2.0;

/// xᵀy summed per fixed chunk, then over the chunks in order: the same bits on any number of
/// threads.
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let part = |(a, b): (&[f64], &[f64])| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    if x.len() >= PARALLEL_MIN_ROWS {
        let parts: Vec<f64> = x
            .par_chunks(CHUNK)
            .zip(y.par_chunks(CHUNK))
            .map(part)
            .collect();
        parts.iter().sum()
    } else {
        x.chunks(CHUNK).zip(y.chunks(CHUNK)).map(part).sum()
    }
}

/// Scratch of the sparse product: a dense accumulator over the columns of the result.
struct ProductScratch {
    acc: Vec<f64>,
    mark: Vec<usize>,
    cols: Vec<u32>,
}

/// C = S + D·(A·B) for sparse A, B (Gustavson's row-by-row algorithm), with an optional sparse S
/// of the shape of C and an optional diagonal row scaling D. Two passes over the rows, each in
/// parallel chunks: the first counts each row's entries, the second writes them into the result,
/// allocated once at its final size (collecting chunks and concatenating them held the product
/// twice, which set the peak memory of a large hierarchy's set-up). Each row's sums run in a
/// fixed order, so the result does not depend on the threads.
fn product(a: View<'_>, b: View<'_>, add: Option<View<'_>>, scale: Option<&[f64]>) -> Csr {
    let n = a.nrows;
    let ncols = b.ncols;
    let nchunks = n.div_ceil(CHUNK);
    let rows_of = |c: usize| c * CHUNK..((c + 1) * CHUNK).min(n);
    // the columns of row i of C, unsorted, in s.cols (and their sums in s.acc when `numeric`)
    let row = |s: &mut ProductScratch, i: usize, numeric: bool| {
        s.cols.clear();
        let mut push = |j: usize, v: f64| {
            if s.mark[j] != i {
                s.mark[j] = i;
                s.cols.push(j as u32);
                if numeric {
                    s.acc[j] = v;
                }
            } else if numeric {
                s.acc[j] += v;
            }
        };
        if let Some(sm) = add {
            for p in sm.row_ptr[i]..sm.row_ptr[i + 1] {
                push(sm.col[p] as usize, sm.val[p]);
            }
        }
        let d = scale.map_or(1.0, |d| d[i]);
        for p in a.row_ptr[i]..a.row_ptr[i + 1] {
            let k = a.col[p] as usize;
            let aik = d * a.val[p];
            for q in b.row_ptr[k]..b.row_ptr[k + 1] {
                push(b.col[q] as usize, aik * b.val[q]);
            }
        }
    };
    let init = || ProductScratch {
        acc: vec![0.0; ncols],
        mark: vec![usize::MAX; ncols],
        cols: Vec::new(),
    };
    let parallel = n >= PARALLEL_MIN_ROWS;
    // pass 1: the entries of each row
    let count = |s: &mut ProductScratch, c: usize| -> Vec<usize> {
        rows_of(c)
            .map(|i| {
                row(s, i, false);
                s.cols.len()
            })
            .collect()
    };
    let lens: Vec<Vec<usize>> = if parallel {
        (0..nchunks).into_par_iter().map_init(init, count).collect()
    } else {
        let mut s = init();
        (0..nchunks).map(|c| count(&mut s, c)).collect()
    };
    let mut row_ptr = Vec::with_capacity(n + 1);
    row_ptr.push(0);
    for l in lens.iter().flatten() {
        row_ptr.push(row_ptr[row_ptr.len() - 1] + l);
    }
    drop(lens);
    let nnz = row_ptr[n];
    let mut col = vec![0u32; nnz];
    let mut val = vec![0.0; nnz];
    // pass 2: each chunk's rows into its own part of the result
    let mut parts: Vec<(usize, &mut [u32], &mut [f64])> = Vec::with_capacity(nchunks);
    let (mut col_rest, mut val_rest) = (col.as_mut_slice(), val.as_mut_slice());
    for c in 0..nchunks {
        let r = rows_of(c);
        let len = row_ptr[r.end] - row_ptr[r.start];
        let (cc, cr) = std::mem::take(&mut col_rest).split_at_mut(len);
        let (vc, vr) = std::mem::take(&mut val_rest).split_at_mut(len);
        parts.push((c, cc, vc));
        col_rest = cr;
        val_rest = vr;
    }
    let fill = |s: &mut ProductScratch, (c, cc, vc): (usize, &mut [u32], &mut [f64])| {
        let mut at = 0;
        for i in rows_of(c) {
            row(s, i, true);
            s.cols.sort_unstable();
            for &j in &s.cols {
                cc[at] = j;
                vc[at] = s.acc[j as usize];
                at += 1;
            }
        }
    };
    if parallel {
        parts.into_par_iter().for_each_init(init, fill);
    } else {
        let mut s = init();
        parts.into_iter().for_each(|p| fill(&mut s, p));
    }
    Csr {
        nrows: n,
        ncols,
        row_ptr,
        col,
        val,
    }
}

// ---------------------------------------------------------------------------------------------
// Input checks

fn check_matrix(a: View<'_>, indefinite: bool) -> Result<(), AmgError> {
    let n = a.nrows;
    if n == 0 {
        return Err(AmgError::Empty);
    }
    if a.row_ptr.len() != n + 1 {
        return Err(AmgError::Malformed(format!(
            "{} row pointers for {n} rows",
            a.row_ptr.len()
        )));
    }
    if a.row_ptr[0] != 0
        || a.row_ptr[n] != a.col.len()
        || a.col.len() != a.val.len()
        || a.row_ptr.windows(2).any(|w| w[1] < w[0])
    {
        return Err(AmgError::Malformed(format!(
            "row pointers, {} column indices and {} values do not agree",
            a.col.len(),
            a.val.len()
        )));
    }
    if n > u32::MAX as usize {
        return Err(AmgError::Malformed(format!(
            "{n} rows exceed 32-bit indices"
        )));
    }
    for i in 0..n {
        let mut diag = None;
        let mut last = None;
        for p in a.row_ptr[i]..a.row_ptr[i + 1] {
            let j = a.col[p] as usize;
            if j >= n {
                return Err(AmgError::NotSquare { row: i, col: j, n });
            }
            if last.is_some_and(|l| j <= l) {
                return Err(AmgError::Malformed(format!(
                    "columns of row {i} are not sorted and distinct"
                )));
            }
            last = Some(j);
            if !a.val[p].is_finite() {
                return Err(AmgError::NonFinite { row: i, col: j });
            }
            if j == i {
                diag = Some(a.val[p]);
            }
        }
        let d = diag.unwrap_or(0.0);
        if d <= 0.0 && !(indefinite && d < 0.0) {
            return Err(AmgError::NonPositiveDiagonal { row: i, value: d });
        }
    }
    Ok(())
}

fn check_params(p: &AmgParams) -> Result<(), AmgError> {
    let bad = |s: &str| Err(AmgError::Params(s.to_string()));
    if !(p.theta.is_finite() && (0.0..1.0).contains(&p.theta)) {
        return bad("theta must be in [0, 1)");
    }
    if p.smoother_degree == 0 {
        return bad("smoother_degree must be at least 1");
    }
    if !(p.chebyshev_ratio.is_finite() && p.chebyshev_ratio > 1.0) {
        return bad("chebyshev_ratio must be greater than 1");
    }
    if !(p.lambda_safety.is_finite() && p.lambda_safety >= 1.0) {
        return bad("lambda_safety must be at least 1");
    }
    if p.lanczos_steps == 0 || p.max_levels == 0 || p.coarse_size == 0 {
        return bad("lanczos_steps, max_levels and coarse_size must be positive");
    }
    if p.max_dense_size < p.coarse_size {
        return bad("max_dense_size must be at least coarse_size");
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Setup: strength, aggregation, prolongators, eigenvalue estimates

/// Strong couplings of the node graph: for node i, the nodes j ≠ i with
/// ‖A_ij‖²_F > θ² ‖A_ii‖_F ‖A_jj‖_F, with their normalised strength.
struct Strength {
    ptr: Vec<usize>,
    nbr: Vec<u32>,
    value: Vec<f64>,
}

fn strength(a: View<'_>, block: usize, theta: f64) -> Strength {
    let nodes = a.nrows / block;
    // ‖A_ii‖_F of the diagonal blocks
    let mut diag = vec![0.0f64; nodes];
    for (node, d) in diag.iter_mut().enumerate() {
        for i in node * block..(node + 1) * block {
            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                if a.col[p] as usize / block == node {
                    *d += a.val[p] * a.val[p];
                }
            }
        }
        *d = d.sqrt();
    }
    let mut acc = vec![0.0f64; nodes];
    let mut mark = vec![usize::MAX; nodes];
    let mut touched: Vec<usize> = Vec::new();
    let mut s = Strength {
        ptr: vec![0],
        nbr: Vec::new(),
        value: Vec::new(),
    };
    let t2 = theta * theta;
    for node in 0..nodes {
        touched.clear();
        for i in node * block..(node + 1) * block {
            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                let j = a.col[p] as usize / block;
                if j == node {
                    continue;
                }
                if mark[j] != node {
                    mark[j] = node;
                    acc[j] = 0.0;
                    touched.push(j);
                }
                acc[j] += a.val[p] * a.val[p];
            }
        }
        touched.sort_unstable();
        for &j in &touched {
            let scale = diag[node] * diag[j];
            if scale > 0.0 && acc[j] > t2 * scale {
                s.nbr.push(j as u32);
                s.value.push(acc[j] / scale);
            }
        }
        s.ptr.push(s.nbr.len());
    }
    s
}

/// Marks a node outside every aggregate (no strong neighbours: the smoother alone handles it).
const NONE: u32 = u32::MAX;

/// Greedy aggregation in the three phases of Vaněk, Mandel & Brezina (1996): (1) a node whose
/// strong neighbours are all free forms an aggregate with them; (2) a left-over node joins the
/// phase-1 aggregate it is most strongly coupled to; (3) what is still left forms aggregates with
/// its free strong neighbours. Nodes are visited in index order (deterministic). Returns the
/// aggregate of each node and the number of aggregates.
fn aggregate(s: &Strength, nodes: usize) -> (Vec<u32>, usize) {
    let mut agg = vec![NONE; nodes];
    let mut count = 0u32;
    let nbrs = |i: usize| &s.nbr[s.ptr[i]..s.ptr[i + 1]];
    // phase 1
    for i in 0..nodes {
        let nb = nbrs(i);
        if nb.is_empty() || agg[i] != NONE || nb.iter().any(|&j| agg[j as usize] != NONE) {
            continue;
        }
        agg[i] = count;
        for &j in nb {
            agg[j as usize] = count;
        }
        count += 1;
    }
    // phase 2: join the strongest neighbouring phase-1 aggregate
    let phase1 = agg.clone();
    for i in 0..nodes {
        if agg[i] != NONE {
            continue;
        }
        let mut best: Option<(f64, u32)> = None;
        for p in s.ptr[i]..s.ptr[i + 1] {
            let a = phase1[s.nbr[p] as usize];
            if a != NONE && best.is_none_or(|(v, _)| s.value[p] > v) {
                best = Some((s.value[p], a));
            }
        }
        if let Some((_, a)) = best {
            agg[i] = a;
        }
    }
    // phase 3
    for i in 0..nodes {
        if agg[i] != NONE || nbrs(i).is_empty() {
            continue;
        }
        agg[i] = count;
        for &j in nbrs(i) {
            if agg[j as usize] == NONE {
                agg[j as usize] = count;
            }
        }
        count += 1;
    }
    (agg, count as usize)
}

/// The tentative prolongator: on each aggregate, the rows of the near-null space B are factored
/// B_agg = Q R (Gram–Schmidt twice, dependent columns dropped); Q gives the aggregate's k columns
/// of P, R its k rows of the coarse near-null space. Returns P (n × k·aggregates) and the coarse
/// near-null space, row-major (k values per coarse row).
fn tentative<B>(
    n: usize,
    block: usize,
    k: usize,
    agg: &[u32],
    n_agg: usize,
    near_null: B,
) -> (Csr, Vec<f64>)
where
    B: Fn(usize, usize) -> f64,
{
    let nodes = n / block;
    // nodes of each aggregate, in index order
    let mut ptr = vec![0usize; n_agg + 1];
    for &a in agg {
        if a != NONE {
            ptr[a as usize + 1] += 1;
        }
    }
    for a in 0..n_agg {
        ptr[a + 1] += ptr[a];
    }
    let mut next = ptr.clone();
    let mut members = vec![0usize; ptr[n_agg]];
    for (i, &a) in agg.iter().enumerate().take(nodes) {
        if a != NONE {
            members[next[a as usize]] = i;
            next[a as usize] += 1;
        }
    }
    // Q values: k per fine row; coarse near-null: k×k per aggregate
    let mut q = vec![0.0; n * k];
    let mut bc = vec![0.0; n_agg * k * k];
    let mut local: Vec<f64> = Vec::new();
    for a in 0..n_agg {
        let nodes_a = &members[ptr[a]..ptr[a + 1]];
        let m = nodes_a.len() * block;
        // column-major m × k block of B
        local.clear();
        for j in 0..k {
            for &node in nodes_a {
                for c in 0..block {
                    local.push(near_null(node * block + c, j));
                }
            }
        }
        let r = &mut bc[a * k * k..(a + 1) * k * k];
        for j in 0..k {
            let (done, rest) = local.split_at_mut(j * m);
            let v = &mut rest[..m];
            let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for _pass in 0..2 {
                for i in 0..j {
                    let qi = &done[i * m..(i + 1) * m];
                    let h: f64 = qi.iter().zip(v.iter()).map(|(x, y)| x * y).sum();
                    for (vv, qq) in v.iter_mut().zip(qi) {
                        *vv -= h * qq;
                    }
                    r[i * k + j] += h;
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 1e-10 * norm0 && norm > 0.0 {
                for vv in v.iter_mut() {
                    *vv /= norm;
                }
                r[j * k + j] = norm;
            } else {
                v.iter_mut().for_each(|x| *x = 0.0);
            }
        }
        for (li, &node) in nodes_a.iter().enumerate() {
            for c in 0..block {
                let row = node * block + c;
                for j in 0..k {
                    q[row * k + j] = local[j * m + li * block + c];
                }
            }
        }
    }
    let mut p = Csr {
        nrows: n,
        ncols: n_agg * k,
        row_ptr: Vec::with_capacity(n + 1),
        col: Vec::new(),
        val: Vec::new(),
    };
    p.row_ptr.push(0);
    for row in 0..n {
        let a = agg[row / block];
        if a != NONE {
            for j in 0..k {
                let v = q[row * k + j];
                if v != 0.0 {
                    p.col.push((a as usize * k + j) as u32);
                    p.val.push(v);
                }
            }
        }
        p.row_ptr.push(p.col.len());
    }
    (p, bc)
}

/// Largest eigenvalue of D⁻¹A (self-adjoint in the D inner product) by a few Lanczos steps from a
/// fixed start vector: the largest Ritz value, an estimate from below. With `indefinite`, the
/// Lanczos process runs on |D|⁻¹A in the |D| inner product and the largest Ritz value in
/// magnitude is returned: it bounds the spectral radius of the signed D⁻¹A (see
/// [`AmgParams::indefinite`]).
fn lambda_max(op: Op<'_>, dinv: &[f64], steps: usize, indefinite: bool) -> f64 {
    let absolute: Vec<f64>;
    let dinv = if indefinite {
        absolute = dinv.iter().map(|d| d.abs()).collect();
        &absolute[..]
    } else {
        dinv
    };
    let n = op.n();
    let steps = steps.min(n);
    // deterministic pseudo-random start (a hash of the index), D-normalised
    let mut v: Vec<f64> = (0..n)
        .map(|i| {
            let mut h = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            h ^= h >> 29;
            h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            h ^= h >> 32;
            (h as f64 / u64::MAX as f64) - 0.5
        })
        .collect();
    let dnorm = |x: &[f64], w: &mut Vec<f64>| {
        // ‖x‖_D = √(xᵀ D x)
        w.clear();
        w.extend(x.iter().zip(dinv).map(|(a, b)| a / b));
        dot(x, w).sqrt()
    };
    let mut scratch = Vec::with_capacity(n);
    let nv = dnorm(&v, &mut scratch);
    if nv == 0.0 {
        return 1.0;
    }
    v.iter_mut().for_each(|x| *x /= nv);
    let mut v_prev = vec![0.0; n];
    let mut w = vec![0.0; n];
    let mut alpha = Vec::with_capacity(steps);
    let mut beta: Vec<f64> = Vec::with_capacity(steps);
    let mut av = vec![0.0; n];
    for it in 0..steps {
        op.apply_with(&v, &mut av, |_, s, y| *y = s);
        // α = vᵀ A v (= ⟨D⁻¹A v, v⟩_D)
        let a = dot(&v, &av);
        alpha.push(a);
        let b_prev = if it > 0 { beta[it - 1] } else { 0.0 };
        for i in 0..n {
            w[i] = dinv[i] * av[i] - a * v[i] - b_prev * v_prev[i];
        }
        let b = dnorm(&w, &mut scratch);
        if b.is_nan() || b <= 1e-12 * a.abs() || it + 1 == steps {
            break;
        }
        beta.push(b);
        std::mem::swap(&mut v_prev, &mut v);
        for i in 0..n {
            v[i] = w[i] / b;
        }
    }
    let top = tridiagonal_max_eigenvalue(&alpha, &beta);
    if indefinite {
        let negated: Vec<f64> = alpha.iter().map(|a| -a).collect();
        top.abs()
            .max(tridiagonal_max_eigenvalue(&negated, &beta).abs())
    } else {
        top
    }
}

/// Largest eigenvalue of the symmetric tridiagonal matrix (diagonal `a`, off-diagonal `b`) by
/// bisection on the Sturm sequence.
fn tridiagonal_max_eigenvalue(a: &[f64], b: &[f64]) -> f64 {
    let m = a.len();
    let off = |i: usize| if i < b.len() { b[i].abs() } else { 0.0 };
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for i in 0..m {
        let r = off(i) + if i > 0 { off(i - 1) } else { 0.0 };
        lo = lo.min(a[i] - r);
        hi = hi.max(a[i] + r);
    }
    // number of eigenvalues below x
    let below = |x: f64| {
        let mut count = 0;
        let mut d = 1.0;
        for i in 0..m {
            let bb = if i > 0 { off(i - 1) } else { 0.0 };
            d = a[i] - x - if i > 0 { bb * bb / d } else { 0.0 };
            if d == 0.0 {
                d = -1e-300;
            }
            if d < 0.0 {
                count += 1;
            }
        }
        count
    };
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if below(mid) < m {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi.abs() {
            break;
        }
    }
    hi
}

// ---------------------------------------------------------------------------------------------
// The hierarchy

/// Chebyshev smoother data of one level.
#[derive(Debug, Clone)]
struct Smoother {
    dinv: Vec<f64>,
    /// Interval [lo, hi] of the Chebyshev polynomial.
    lo: f64,
    hi: f64,
}

/// The dense factor of the coarsest operator: Cholesky (row-major lower triangle `l`) for a
/// positive definite level, LBLᵀ (Bunch–Kaufman) for an indefinite one.
struct CoarseSolver {
    n: usize,
    l: Vec<f64>,
    shift: f64,
    lblt: Option<faer::linalg::solvers::Lblt<f64>>,
}

impl CoarseSolver {
    fn new(a: View<'_>, indefinite: bool) -> Result<CoarseSolver, AmgError> {
        let n = a.nrows;
        let mut dense = Mat::<f64>::zeros(n, n);
        let mut dmax = 0.0f64;
        for i in 0..n {
            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                dense[(i, a.col[p] as usize)] = a.val[p];
            }
            dmax = dmax.max(dense[(i, i)].abs());
        }
        if indefinite {
            use faer::linalg::solvers::Solve;
            let lblt = dense.lblt(faer::Side::Lower);
            // a singular level shows as a non-finite solution of a test right-hand side
            let mut probe = Mat::<f64>::from_fn(n, 1, |i, _| 1.0 + (i % 7) as f64);
            lblt.solve_in_place(probe.as_mut());
            super::vector_state::clear_after(faer::get_global_parallelism(), n);
            if (0..n).any(|i| !probe[(i, 0)].is_finite()) {
                return Err(AmgError::CoarseFactorisation { n });
            }
            return Ok(CoarseSolver {
                n,
                l: Vec::new(),
                shift: 0.0,
                lblt: Some(lblt),
            });
        }
        let params = Spec::<LltParams, f64>::default();
        let mut mem = MemBuffer::new(
            faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
                n,
                Par::Seq,
                params,
            ),
        );
        // a singular coarse operator (e.g. a floating body) gets a tiny shift
        for shift in [0.0, 1e-12, 1e-10, 1e-8] {
            let mut f = dense.clone();
            for i in 0..n {
                f[(i, i)] += shift * dmax;
            }
            let ok = faer::linalg::cholesky::llt::factor::cholesky_in_place(
                f.as_mut(),
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                params,
            )
            .is_ok();
            super::vector_state::clear_after(Par::Seq, n);
            if ok {
                let mut l = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..=i {
                        l[i * n + j] = f[(i, j)];
                    }
                }
                return Ok(CoarseSolver {
                    n,
                    l,
                    shift: shift * dmax,
                    lblt: None,
                });
            }
        }
        Err(AmgError::CoarseFactorisation { n })
    }

    /// x = (L Lᵀ)⁻¹ b, or the LBLᵀ solve.
    fn solve(&self, b: &[f64], x: &mut [f64]) {
        let n = self.n;
        if let Some(lblt) = &self.lblt {
            use faer::linalg::solvers::Solve;
            let mut rhs = faer::MatMut::from_column_major_slice_mut(x, n, 1);
            rhs.copy_from(faer::MatRef::from_column_major_slice(b, n, 1));
            lblt.solve_in_place(rhs);
            super::vector_state::clear_after(faer::get_global_parallelism(), n);
            return;
        }
        for i in 0..n {
            let row = &self.l[i * n..i * n + i];
            let s: f64 = row.iter().zip(&x[..i]).map(|(l, y)| l * y).sum();
            x[i] = (b[i] - s) / self.l[i * n + i];
        }
        for i in (0..n).rev() {
            x[i] /= self.l[i * n + i];
            let xi = x[i];
            for j in 0..i {
                x[j] -= self.l[i * n + j] * xi;
            }
        }
    }
}

/// Work vectors of one level (b and x unused on the finest level, where the caller's are used).
#[derive(Debug, Default)]
struct Work {
    b: Vec<f64>,
    x: Vec<f64>,
    r: Vec<f64>,
    d: Vec<f64>,
}

/// Sizes of one level, for reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelInfo {
    /// Unknowns.
    pub n: usize,
    /// Stored entries of the operator.
    pub nnz: usize,
    /// Unknowns per node (the near-null-space dimension below the finest level).
    pub block: usize,
    /// Estimated ρ(D⁻¹A); zero on the coarsest level (solved directly).
    pub rho: f64,
}

/// The fine operator in scalar form: the caller's matrix (borrowed or owned), a compact copy
/// with 32-bit columns ([`Amg::from_blocks`]), or nothing once node blocks replaced it.
enum Source<'a> {
    Matrix(Cow<'a, CsrMatrix>),
    Compact(Csr),
    Released,
}

impl Source<'_> {
    fn op(&self) -> Op<'_> {
        match self {
            Source::Matrix(m) => Op::Fine(View {
                nrows: m.n,
                ncols: m.n,
                row_ptr: &m.row_ptr,
                col: &m.col_idx,
                val: &m.values,
            }),
            Source::Compact(c) => Op::Coarse(c.view()),
            Source::Released => unreachable!("the fine operator is used only while it is held"),
        }
    }
}

/// A smoothed-aggregation AMG hierarchy over a borrowed fine matrix; [`Amg::apply`] is one
/// V-cycle, a symmetric positive definite preconditioner.
///
/// `apply` takes `&self` so that a Krylov solver can hold the matrix and the preconditioner side
/// by side (and the preconditioner can be shared between threads); the V-cycle's work vectors sit
/// behind a mutex, locked once per cycle (uncontended, so it costs nothing measurable) instead of
/// being allocated per call.
pub struct Amg<'a> {
    /// Unknowns of the fine level.
    n: usize,
    /// The fine operator: borrowed ([`Amg::new`]), owned ([`Amg::owning`]) or compact
    /// ([`Amg::from_blocks`]); released once `blocks[0]` replaces it.
    fine: Source<'a>,
    /// Per smoothed level: its operator in node blocks ([`SmootherStorage`]), which replaces the
    /// scalar one.
    blocks: Vec<Option<Bsr>>,
    /// Operators of levels 1.. (level 0 is `fine`); emptied where `blocks` replaces them, the
    /// coarsest always kept.
    ops: Vec<Csr>,
    /// Prolongators from level l+1 to level l, and their transposes.
    p: Vec<Csr>,
    r: Vec<Csr>,
    /// Smoothers of every level but the coarsest.
    smoothers: Vec<Smoother>,
    coarse: CoarseSolver,
    info: Vec<LevelInfo>,
    degree: usize,
    work: Mutex<Vec<Work>>,
}

impl std::fmt::Debug for Amg<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "Amg: {} levels, operator complexity {:.3}, coarse shift {:.1e}, fine level {:?}",
            self.levels(),
            self.operator_complexity(),
            self.coarse.shift,
            self.smoother_storage()
        )?;
        for (l, i) in self.info.iter().enumerate() {
            writeln!(
                f,
                "  level {l}: {:>9} unknowns, {:>11} entries, block {}, rho(D^-1 A) {:.3}",
                i.n, i.nnz, i.block, i.rho
            )?;
        }
        Ok(())
    }
}

impl<'a> Amg<'a> {
    /// Builds the hierarchy for the symmetric positive definite `a` with `block` unknowns per node
    /// (rows node-major) and the near-null space `near_null` (columns over all rows: the rigid-body
    /// modes of [`rigid_body_modes`] for elasticity, the constant for a scalar problem).
    pub fn new(
        a: &'a CsrMatrix,
        block: usize,
        near_null: &[Vec<f64>],
        params: &AmgParams,
    ) -> Result<Amg<'a>, AmgError> {
        Self::build(Source::Matrix(Cow::Borrowed(a)), block, near_null, params)
    }

    /// As [`Amg::new`], owning the matrix: for a preconditioner built from a matrix of its own
    /// (a block or an approximate Schur complement of the tangent).
    pub fn owning(
        a: CsrMatrix,
        block: usize,
        near_null: &[Vec<f64>],
        params: &AmgParams,
    ) -> Result<Amg<'static>, AmgError> {
        Amg::build(Source::Matrix(Cow::Owned(a)), block, near_null, params)
    }

    /// As [`Amg::owning`], from node blocks (with `block` unknowns per node, as `a` stores
    /// them): the set-up works on a scalar copy with 32-bit columns (the blocks' zeros left out),
    /// which is released as soon as the fine level's smoother blocks exist, before the coarse
    /// operator is formed. The caller keeps `a`, e.g. as its Krylov operator.
    pub fn from_blocks(
        a: &BlockMatrix,
        near_null: &[Vec<f64>],
        params: &AmgParams,
    ) -> Result<Amg<'static>, AmgError> {
        Amg::build(Source::Compact(a.m.to_compact()), a.m.b, near_null, params)
    }

    fn build(
        mut fine: Source<'a>,
        block: usize,
        near_null: &[Vec<f64>],
        params: &AmgParams,
    ) -> Result<Amg<'a>, AmgError> {
        check_params(params)?;
        let n = match fine.op() {
            Op::Fine(v) => {
                check_matrix(v, params.indefinite)?;
                v.nrows
            }
            Op::Coarse(v) => {
                check_matrix(v, params.indefinite)?;
                v.nrows
            }
        };
        if block == 0 || !n.is_multiple_of(block) {
            return Err(AmgError::BlockSize { n, block });
        }
        if near_null.is_empty() {
            return Err(AmgError::NoNearNull);
        }
        for (index, v) in near_null.iter().enumerate() {
            if v.len() != n {
                return Err(AmgError::NearNullLength {
                    index,
                    len: v.len(),
                    n,
                });
            }
            if let Some(row) = v.iter().position(|x| !x.is_finite()) {
                return Err(AmgError::NearNullNonFinite { index, row });
            }
        }
        let k = near_null.len();
        // the smoother's storage of a level of block size b: Some(single precision) for blocks
        let as_blocks = |b: usize| match params.smoother_storage {
            _ if b > BLOCK_MAX => None,
            SmootherStorage::Csr => None,
            SmootherStorage::BlockDouble => Some(false),
            SmootherStorage::BlockSingle => Some(true),
        };
        let mut fine_blocks: Option<Bsr> = None;
        let mut ops: Vec<Csr> = Vec::new();
        let mut ps: Vec<Csr> = Vec::new();
        let mut rs: Vec<Csr> = Vec::new();
        let mut smoothers = Vec::new();
        let mut info = Vec::new();
        let mut coarse_nn: Vec<f64> = Vec::new();
        let mut level_block = block;
        let mut theta = params.theta;
        loop {
            let level = ops.len();
            let op = match ops.last() {
                None => fine.op(),
                Some(c) => Op::Coarse(c.view()),
            };
            let nl = op.n();
            let nnz = match op {
                Op::Fine(v) => v.val.len(),
                Op::Coarse(v) => v.val.len(),
            };
            info.push(LevelInfo {
                n: nl,
                nnz,
                block: level_block,
                rho: 0.0,
            });
            if nl <= params.coarse_size || level + 1 >= params.max_levels {
                break;
            }
            let (agg, n_agg) = match op {
                Op::Fine(v) => {
                    let s = strength(v, level_block, theta);
                    aggregate(&s, nl / level_block)
                }
                Op::Coarse(v) => {
                    let s = strength(v, level_block, theta);
                    aggregate(&s, nl / level_block)
                }
            };
            let nc = n_agg * k;
            if n_agg == 0 || nc >= nl {
                // no coarsening possible: this level is the coarsest
                break;
            }
            let (pt, bc) = if level == 0 {
                tentative(nl, level_block, k, &agg, n_agg, |i, j| near_null[j][i])
            } else {
                tentative(nl, level_block, k, &agg, n_agg, |i, j| coarse_nn[i * k + j])
            };
            let dinv = diagonal_inverse(op, params.indefinite);
            let rho = lambda_max(op, &dinv, params.lanczos_steps, params.indefinite);
            // P = (I − ω D⁻¹A) P_tent with ω = 4 / (3 ρ(D⁻¹A))
            let omega = 4.0 / (3.0 * rho);
            let scale: Vec<f64> = dinv.iter().map(|d| -omega * d).collect();
            let p = match op {
                Op::Fine(v) => product(v, pt.view(), Some(pt.view()), Some(&scale)),
                Op::Coarse(v) => product(v, pt.view(), Some(pt.view()), Some(&scale)),
            };
            drop(scale);
            drop(pt);
            let r = p.transpose();
            let ap = match op {
                Op::Fine(v) => product(v, p.view(), None, None),
                Op::Coarse(v) => product(v, p.view(), None, None),
            };
            // a compact fine copy is needed no more: its smoother blocks replace it before the
            // coarse product, the set-up's largest
            if let (0, Source::Compact(c), Some(single)) = (level, &fine, as_blocks(block)) {
                fine_blocks = Bsr::from_csr(c.view(), block, single, BLOCK_MAX_FILL);
                if fine_blocks.is_some() {
                    fine = Source::Released;
                }
            }
            let mut ac = product(r.view(), ap.view(), None, None);
            drop(ap);
            ac.symmetrise();
            fix_empty_diagonal(&mut ac);
            let hi = params.lambda_safety * rho;
            smoothers.push(Smoother {
                dinv,
                lo: hi / params.chebyshev_ratio,
                hi,
            });
            if let Some(last) = info.last_mut() {
                last.rho = rho;
            }
            ps.push(p);
            rs.push(r);
            ops.push(ac);
            coarse_nn = bc;
            level_block = k;
            theta *= 0.5;
        }
        let last = info.len() - 1;
        if info[last].n > params.max_dense_size {
            return Err(AmgError::Stalled {
                level: last,
                n: info[last].n,
            });
        }
        let coarse = match ops.last() {
            None => match fine.op() {
                Op::Fine(v) => CoarseSolver::new(v, params.indefinite)?,
                Op::Coarse(v) => CoarseSolver::new(v, params.indefinite)?,
            },
            Some(c) => CoarseSolver::new(c.view(), params.indefinite)?,
        };
        // the smoother's block copies of the level operators, which replace the scalar ones
        let smoothed = ops.len();
        let mut blocks: Vec<Option<Bsr>> = Vec::with_capacity(smoothed);
        for l in 0..smoothed {
            let b = info[l].block;
            let m = match l {
                0 if fine_blocks.is_some() => fine_blocks.take(),
                0 => as_blocks(b).and_then(|single| match fine.op() {
                    Op::Fine(v) => Bsr::from_csr(v, b, single, BLOCK_MAX_FILL),
                    Op::Coarse(v) => Bsr::from_csr(v, b, single, BLOCK_MAX_FILL),
                }),
                _ => as_blocks(b)
                    .and_then(|single| Bsr::from_csr(ops[l - 1].view(), b, single, BLOCK_MAX_FILL)),
            };
            if let Some(m) = &m {
                info[l].nnz = m.stored();
                match l {
                    0 => fine = Source::Released,
                    _ => ops[l - 1] = Csr::default(),
                }
            }
            blocks.push(m);
        }
        let work = info
            .iter()
            .enumerate()
            .map(|(l, i)| {
                let v = |len: usize| vec![0.0; len];
                let own = if l == 0 { 0 } else { i.n };
                Work {
                    b: v(own),
                    x: v(own),
                    r: v(i.n),
                    d: v(i.n),
                }
            })
            .collect();
        Ok(Amg {
            n,
            fine,
            blocks,
            ops,
            p: ps,
            r: rs,
            smoothers,
            coarse,
            info,
            degree: params.smoother_degree,
            work: Mutex::new(work),
        })
    }

    /// Number of levels, the finest and the coarsest included.
    pub fn levels(&self) -> usize {
        self.info.len()
    }

    /// Σ nnz(A_l) / nnz(A_0): the memory and work of the hierarchy relative to the fine matrix.
    pub fn operator_complexity(&self) -> f64 {
        let total: usize = self.info.iter().map(|i| i.nnz).sum();
        total as f64 / self.info[0].nnz as f64
    }

    /// Sizes of every level.
    pub fn level_info(&self) -> &[LevelInfo] {
        &self.info
    }

    /// Number of unknowns of the fine level.
    pub fn n(&self) -> usize {
        self.n
    }

    /// How the smoother holds the fine operator: as asked in [`AmgParams::smoother_storage`], or
    /// [`SmootherStorage::Csr`] where blocks did not apply (a single level, a block size above 8,
    /// or blocks more than half zeros).
    pub fn smoother_storage(&self) -> SmootherStorage {
        match self.blocks.first() {
            Some(Some(m)) => m.storage(),
            _ => SmootherStorage::Csr,
        }
    }

    /// z = M⁻¹ r: one V-cycle from a zero initial guess (Chebyshev pre- and post-smoothing).
    ///
    /// # Panics
    /// When `r` or `z` do not have [`Amg::n`] entries (a programming error).
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        assert_eq!(r.len(), self.n, "AMG apply: residual length");
        assert_eq!(z.len(), self.n, "AMG apply: output length");
        let mut work = self.work.lock().unwrap_or_else(|e| e.into_inner());
        self.cycle(0, r, z, &mut work);
    }

    /// The CSR operator of level l > 0, or of the fine level when it is kept in CSR.
    fn op(&self, l: usize) -> Op<'_> {
        match l {
            0 => self.fine.op(),
            _ => Op::Coarse(self.ops[l - 1].view()),
        }
    }

    /// Chebyshev smoothing on level l (see [`chebyshev`]).
    #[allow(clippy::too_many_arguments)]
    fn smooth(&self, l: usize, b: &[f64], x: &mut [f64], r: &mut [f64], d: &mut [f64], zero: bool) {
        let sm = &self.smoothers[l];
        match &self.blocks[l] {
            Some(m) => chebyshev(m, sm, self.degree, b, x, r, d, zero),
            None => chebyshev(&self.op(l), sm, self.degree, b, x, r, d, zero),
        }
    }

    /// x = V-cycle(b) on level l, from x = 0.
    fn cycle(&self, l: usize, b: &[f64], x: &mut [f64], work: &mut [Work]) {
        if l + 1 == self.levels() {
            self.coarse.solve(b, x);
            return;
        }
        let (r, d) = {
            let w = &mut work[l];
            (std::mem::take(&mut w.r), std::mem::take(&mut w.d))
        };
        let (mut r, mut d) = (r, d);
        self.smooth(l, b, x, &mut r, &mut d, true);
        // r = b − A x on return; restrict it
        let mut bc = std::mem::take(&mut work[l + 1].b);
        let mut xc = std::mem::take(&mut work[l + 1].x);
        spmv_with(self.r[l].view(), &r, &mut bc, |_, s, y| *y = s);
        self.cycle(l + 1, &bc, &mut xc, work);
        spmv_with(self.p[l].view(), &xc, x, |_, s, y| *y += s);
        self.smooth(l, b, x, &mut r, &mut d, false);
        work[l + 1].b = bc;
        work[l + 1].x = xc;
        work[l].r = r;
        work[l].d = d;
    }
}

/// Inverse of the diagonal of a level operator (0 where the diagonal is zero, or not positive
/// unless `indefinite`).
fn diagonal_inverse(op: Op<'_>, indefinite: bool) -> Vec<f64> {
    fn diag(a: View<'_>, indefinite: bool) -> Vec<f64> {
        (0..a.nrows)
            .map(|i| {
                let cols = &a.col[a.row_ptr[i]..a.row_ptr[i + 1]];
                let p = cols.iter().position(|c| *c as usize == i);
                let d = p.map_or(0.0, |p| a.val[a.row_ptr[i] + p]);
                if d > 0.0 || (indefinite && d < 0.0) {
                    1.0 / d
                } else {
                    0.0
                }
            })
            .collect()
    }
    match op {
        Op::Fine(v) => diag(v, indefinite),
        Op::Coarse(v) => diag(v, indefinite),
    }
}

/// A coarse unknown whose tentative prolongator column was dropped (a rank-deficient aggregate)
/// has an empty row and column; give it a positive diagonal so that the level stays definite.
fn fix_empty_diagonal(a: &mut Csr) {
    let row_max = |i: usize| {
        a.val[a.row_ptr[i]..a.row_ptr[i + 1]]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    let maxes: Vec<f64> = (0..a.nrows).map(row_max).collect();
    let top = maxes.iter().fold(0.0f64, |m, &v| m.max(v));
    let empty: Vec<bool> = maxes.iter().map(|&m| m <= 1e-14 * top).collect();
    if !empty.iter().any(|&e| e) {
        return;
    }
    let fill = if top > 0.0 { top } else { 1.0 };
    let mut rebuilt = Csr {
        nrows: a.nrows,
        ncols: a.ncols,
        row_ptr: Vec::with_capacity(a.nrows + 1),
        col: Vec::with_capacity(a.nnz()),
        val: Vec::with_capacity(a.nnz()),
    };
    rebuilt.row_ptr.push(0);
    for i in 0..a.nrows {
        if empty[i] {
            rebuilt.col.push(i as u32);
            rebuilt.val.push(fill);
        } else {
            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                // couplings to an empty unknown are round-off: drop them
                if !empty[a.col[p] as usize] {
                    rebuilt.col.push(a.col[p]);
                    rebuilt.val.push(a.val[p]);
                }
            }
        }
        rebuilt.row_ptr.push(rebuilt.col.len());
    }
    *a = rebuilt;
}

/// Chebyshev smoothing of A x = b with D⁻¹ as the preconditioner and the polynomial of the given
/// degree on [lo, hi] (Saad, Iterative Methods for Sparse Linear Systems, Alg. 12.1). With `zero`,
/// x is taken as zero on entry (no product needed). On return r = b − A x.
#[allow(clippy::too_many_arguments)]
fn chebyshev<A: Apply>(
    op: &A,
    sm: &Smoother,
    degree: usize,
    b: &[f64],
    x: &mut [f64],
    r: &mut [f64],
    d: &mut [f64],
    zero: bool,
) {
    let theta = 0.5 * (sm.hi + sm.lo);
    let delta = 0.5 * (sm.hi - sm.lo);
    let sigma = theta / delta;
    let mut rho = 1.0 / sigma;
    let dinv = &sm.dinv;
    if zero {
        r.copy_from_slice(b);
        vector_pass(x, d, r, dinv, |_x, _d, r, di| {
            let dd = di * r / theta;
            (dd, dd)
        });
    } else {
        op.apply_with(x, r, |i, s, y| *y = b[i] - s);
        vector_pass(x, d, r, dinv, |x, _d, r, di| {
            let dd = di * r / theta;
            (x + dd, dd)
        });
    }
    for _ in 1..degree {
        op.apply_with(d, r, |_, s, y| *y -= s);
        let rho_new = 1.0 / (2.0 * sigma - rho);
        let c1 = rho_new * rho;
        let c2 = 2.0 * rho_new / delta;
        vector_pass(x, d, r, dinv, |x, d, r, di| {
            let dd = c1 * d + c2 * di * r;
            (x + dd, dd)
        });
        rho = rho_new;
    }
    // the residual of the final iterate
    op.apply_with(d, r, |_, s, y| *y -= s);
}

/// (x_i, d_i) ← f(x_i, d_i, r_i, dinv_i) for every row, in parallel chunks for long vectors.
fn vector_pass<F>(x: &mut [f64], d: &mut [f64], r: &[f64], dinv: &[f64], f: F)
where
    F: Fn(f64, f64, f64, f64) -> (f64, f64) + Sync,
{
    let kernel = |xs: &mut [f64], ds: &mut [f64], rs: &[f64], ws: &[f64]| {
        for i in 0..xs.len() {
            let (xn, dn) = f(xs[i], ds[i], rs[i], ws[i]);
            xs[i] = xn;
            ds[i] = dn;
        }
    };
    if x.len() >= PARALLEL_MIN_ROWS {
        x.par_chunks_mut(CHUNK)
            .zip(d.par_chunks_mut(CHUNK))
            .zip(r.par_chunks(CHUNK))
            .zip(dinv.par_chunks(CHUNK))
            .for_each(|(((xs, ds), rs), ws)| kernel(xs, ds, rs, ws));
    } else {
        kernel(x, d, r, dinv);
    }
}

/// The rigid-body modes of a body with the given node coordinates, node-major (`dim` unknowns per
/// node), centred on the centroid so that rotations and translations are well separated:
/// `dim` = 3 gives 3 translations and 3 rotations, `dim` = 2 the 2 translations and the in-plane
/// rotation (plane problems), `dim` = 1 the constant. (For axisymmetric displacement (u_r, u_z)
/// only the axial translation is a rigid mode; pass that one alone.)
pub fn rigid_body_modes(coords: &[[f64; 3]], dim: usize) -> Vec<Vec<f64>> {
    let nn = coords.len();
    let mut c = [0.0; 3];
    for x in coords {
        for k in 0..3 {
            c[k] += x[k] / nn.max(1) as f64;
        }
    }
    match dim {
        1 => vec![vec![1.0; nn]],
        2 => {
            let mut m = vec![vec![0.0; 2 * nn]; 3];
            for (i, x) in coords.iter().enumerate() {
                let (px, py) = (x[0] - c[0], x[1] - c[1]);
                m[0][2 * i] = 1.0;
                m[1][2 * i + 1] = 1.0;
                m[2][2 * i] = -py;
                m[2][2 * i + 1] = px;
            }
            m
        }
        _ => {
            let mut m = vec![vec![0.0; 3 * nn]; 6];
            for (i, x) in coords.iter().enumerate() {
                let p = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
                for k in 0..3 {
                    m[k][3 * i + k] = 1.0;
                }
                // rotation about x: (0, −z, y); about y: (z, 0, −x); about z: (−y, x, 0)
                m[3][3 * i + 1] = -p[2];
                m[3][3 * i + 2] = p[1];
                m[4][3 * i] = p[2];
                m[4][3 * i + 2] = -p[0];
                m[5][3 * i] = -p[1];
                m[5][3 * i + 1] = p[0];
            }
            m
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    /// Preconditioned conjugate gradients: (iterations, relative residual).
    pub(super) fn pcg(
        a: &CsrMatrix,
        m: &Amg<'_>,
        b: &[f64],
        x: &mut [f64],
        tol: f64,
        max_iter: usize,
    ) -> (usize, f64) {
        pcg_with(a, |r, z| m.apply(r, z), b, x, tol, max_iter)
    }

    /// [`pcg`] with any preconditioner z = M⁻¹ r.
    pub(super) fn pcg_with(
        a: &CsrMatrix,
        mut m: impl FnMut(&[f64], &mut [f64]),
        b: &[f64],
        x: &mut [f64],
        tol: f64,
        max_iter: usize,
    ) -> (usize, f64) {
        let n = a.n;
        let mut r = vec![0.0; n];
        a.mul_vec(x, &mut r);
        for i in 0..n {
            r[i] = b[i] - r[i];
        }
        let bnorm = dot(b, b).sqrt();
        let mut z = vec![0.0; n];
        m(&r, &mut z);
        let mut p = z.clone();
        let mut q = vec![0.0; n];
        let mut rz = dot(&r, &z);
        for it in 1..=max_iter {
            a.mul_vec(&p, &mut q);
            let alpha = rz / dot(&p, &q);
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
            }
            let rel = dot(&r, &r).sqrt() / bnorm;
            if rel < tol {
                return (it, rel);
            }
            m(&r, &mut z);
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        (max_iter, dot(&r, &r).sqrt() / bnorm)
    }

    /// Deterministic pseudo-random vector in [−0.5, 0.5).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(0x2545_F491_4F6C_DD1D) | 1;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    fn csr_from_rows(rows: Vec<Vec<(usize, f64)>>) -> CsrMatrix {
        let n_rows = rows.len();
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::<f64>::new());
        for mut row in rows {
            row.sort_by_key(|e| e.0);
            for (j, v) in row {
                col_idx.push(j);
                values.push(v);
            }
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values)
    }

    /// The 7-point Laplacian on the interior points of an n³ grid (Dirichlet boundary eliminated).
    fn laplace7(n: usize) -> CsrMatrix {
        let id = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        let mut rows = Vec::with_capacity(n * n * n);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let mut row = vec![(id(i, j, k), 6.0)];
                    if i > 0 {
                        row.push((id(i - 1, j, k), -1.0));
                    }
                    if i + 1 < n {
                        row.push((id(i + 1, j, k), -1.0));
                    }
                    if j > 0 {
                        row.push((id(i, j - 1, k), -1.0));
                    }
                    if j + 1 < n {
                        row.push((id(i, j + 1, k), -1.0));
                    }
                    if k > 0 {
                        row.push((id(i, j, k - 1), -1.0));
                    }
                    if k + 1 < n {
                        row.push((id(i, j, k + 1), -1.0));
                    }
                    rows.push(row);
                }
            }
        }
        csr_from_rows(rows)
    }

    /// Stiffness of a trilinear (Q1) hexahedron of size h, 2×2×2 Gauss points, isotropic linear
    /// elasticity; local node a = dx + 2 dy + 4 dz, dofs node-major.
    fn hex_stiffness(h: [f64; 3], young: f64, nu: f64) -> [[f64; 24]; 24] {
        let lambda = young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = young / (2.0 * (1.0 + nu));
        let g = 1.0 / 3.0f64.sqrt();
        let det = h[0] * h[1] * h[2] / 8.0;
        let mut k = [[0.0; 24]; 24];
        for gp in 0..8 {
            let xi = [
                if gp & 1 == 0 { -g } else { g },
                if gp & 2 == 0 { -g } else { g },
                if gp & 4 == 0 { -g } else { g },
            ];
            // ∂N_a/∂x
            let mut dn = [[0.0; 3]; 8];
            for a in 0..8 {
                let s = [
                    if a & 1 == 0 { -1.0 } else { 1.0 },
                    if a & 2 == 0 { -1.0 } else { 1.0 },
                    if a & 4 == 0 { -1.0 } else { 1.0 },
                ];
                let f = |d: usize| 1.0 + s[d] * xi[d];
                dn[a][0] = s[0] * f(1) * f(2) / 8.0 * 2.0 / h[0];
                dn[a][1] = f(0) * s[1] * f(2) / 8.0 * 2.0 / h[1];
                dn[a][2] = f(0) * f(1) * s[2] / 8.0 * 2.0 / h[2];
            }
            // K_ab,ij = ∫ λ ∂_i N_a ∂_j N_b + μ (∂_j N_a ∂_i N_b + δ_ij ∇N_a·∇N_b)
            for a in 0..8 {
                for b in 0..8 {
                    let dot_ab: f64 = (0..3).map(|d| dn[a][d] * dn[b][d]).sum();
                    for i in 0..3 {
                        for j in 0..3 {
                            let mut v = lambda * dn[a][i] * dn[b][j] + mu * dn[a][j] * dn[b][i];
                            if i == j {
                                v += mu * dot_ab;
                            }
                            k[3 * a + i][3 * b + j] += v * det;
                        }
                    }
                }
            }
        }
        k
    }

    /// Q1 elasticity on a box of `cells` × `size`, clamped on the face x = 0. Returns the matrix
    /// over the free dofs (node-major) and the coordinates of the free nodes.
    fn elasticity(cells: [usize; 3], size: [f64; 3], nu: f64) -> (CsrMatrix, Vec<[f64; 3]>) {
        let [nx, ny, nz] = cells;
        let h = [
            size[0] / nx as f64,
            size[1] / ny as f64,
            size[2] / nz as f64,
        ];
        let ke = hex_stiffness(h, 1.0, nu);
        let node = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        let nn = (nx + 1) * (ny + 1) * (nz + 1);
        let mut free = vec![usize::MAX; nn];
        let mut coords = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 1..=nx {
                    free[node(i, j, k)] = coords.len();
                    coords.push([i as f64 * h[0], j as f64 * h[1], k as f64 * h[2]]);
                }
            }
        }
        let nf = coords.len();
        // pattern: the 27 neighbours (in increasing node order, so columns come out sorted)
        let n_rows = 3 * nf;
        let (mut row_ptr, mut col_idx) = (vec![0usize], Vec::new());
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 1..=nx {
                    let mut nbrs = Vec::with_capacity(27);
                    for kk in k.saturating_sub(1)..=(k + 1).min(nz) {
                        for jj in j.saturating_sub(1)..=(j + 1).min(ny) {
                            for ii in i.saturating_sub(1)..=(i + 1).min(nx) {
                                let f = free[node(ii, jj, kk)];
                                if f != usize::MAX {
                                    nbrs.push(f);
                                }
                            }
                        }
                    }
                    for _c in 0..3 {
                        for &f in &nbrs {
                            for d in 0..3 {
                                col_idx.push(3 * f + d);
                            }
                        }
                        row_ptr.push(col_idx.len());
                    }
                }
            }
        }
        let values = vec![0.0; col_idx.len()];
        let mut a = CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let mut dofs = [usize::MAX; 8];
                    for (l, d) in dofs.iter_mut().enumerate() {
                        *d = free[node(i + (l & 1), j + ((l >> 1) & 1), k + ((l >> 2) & 1))];
                    }
                    for la in 0..8 {
                        if dofs[la] == usize::MAX {
                            continue;
                        }
                        for lb in 0..8 {
                            if dofs[lb] == usize::MAX {
                                continue;
                            }
                            for ci in 0..3 {
                                for cj in 0..3 {
                                    let p = a
                                        .position(3 * dofs[la] + ci, 3 * dofs[lb] + cj)
                                        .expect("in pattern");
                                    a.values[p] += ke[3 * la + ci][3 * lb + cj];
                                }
                            }
                        }
                    }
                }
            }
        }
        (a, coords)
    }

    fn solve_report(
        name: &str,
        a: &CsrMatrix,
        block: usize,
        nn: &[Vec<f64>],
        params: &AmgParams,
    ) -> usize {
        let t0 = Instant::now();
        let amg = Amg::new(a, block, nn, params).expect("hierarchy");
        let setup = t0.elapsed();
        let b = noise(a.n, 7);
        let mut x = vec![0.0; a.n];
        let t1 = Instant::now();
        let (it, rel) = pcg(a, &amg, &b, &mut x, 1e-8, 500);
        let solve = t1.elapsed();
        let t2 = Instant::now();
        let mut z = vec![0.0; a.n];
        let cycles = 5;
        for _ in 0..cycles {
            amg.apply(&b, &mut z);
        }
        let vcycle = t2.elapsed() / cycles;
        println!(
            "{name}: n = {}, {} levels, operator complexity {:.3}, PCG iterations {it} \
             (rel. residual {rel:.1e}), setup {:.3} s, solve {:.3} s, V-cycle {:.4} s",
            a.n,
            amg.levels(),
            amg.operator_complexity(),
            setup.as_secs_f64(),
            solve.as_secs_f64(),
            vcycle.as_secs_f64()
        );
        assert!(
            rel < 1e-8,
            "{name}: PCG did not converge: {rel:e} after {it}"
        );
        // the true residual, not only the recursively updated one
        let mut ax = vec![0.0; a.n];
        a.mul_vec(&x, &mut ax);
        let true_res: f64 = ax
            .iter()
            .zip(&b)
            .map(|(u, v)| (u - v) * (u - v))
            .sum::<f64>();
        assert!(
            true_res.sqrt() / dot(&b, &b).sqrt() < 1e-7,
            "{name}: true residual"
        );
        it
    }

    /// Small coarse size, so that even the small test problems get several levels.
    fn test_params() -> AmgParams {
        AmgParams {
            coarse_size: 200,
            ..AmgParams::default()
        }
    }

    #[test]
    fn amg_poisson_iterations_bounded_under_refinement() {
        let mut counts = Vec::new();
        for n in [8, 16, 24, 32, 48] {
            let a = laplace7(n);
            let it = solve_report(
                &format!("poisson {n}^3"),
                &a,
                1,
                &[vec![1.0; a.n]],
                &test_params(),
            );
            counts.push((n, it));
        }
        println!("poisson iterations: {counts:?}");
        let first = counts[0].1 as f64;
        let last = counts[counts.len() - 1].1 as f64;
        assert!(last <= 1.5 * first, "{counts:?}");
    }

    /// PCG iterations on the clamped unit cube under refinement, with the rigid-body modes; with
    /// `compare_scalar` also with scalar-per-dof aggregation (block 1, the constant vector).
    fn elasticity_scaling(nu: f64, sizes: &[usize], compare_scalar: bool) {
        let mut counts = Vec::new();
        for &n in sizes {
            let (a, coords) = elasticity([n, n, n], [1.0, 1.0, 1.0], nu);
            let rbm = rigid_body_modes(&coords, 3);
            let params = test_params();
            let name = format!("elasticity nu={nu} {n}^3 rigid-body modes");
            let it = solve_report(&name, &a, 3, &rbm, &params);
            let scalar = if compare_scalar && n <= 24 {
                let name = format!("elasticity nu={nu} {n}^3 scalar (block 1, constant)");
                solve_report(&name, &a, 1, &[vec![1.0; a.n]], &params)
            } else {
                0
            };
            counts.push((n, it, scalar));
        }
        println!(
            "elasticity nu={nu} (cells, iterations with rigid-body modes, scalar): {counts:?}"
        );
        let first = counts[0].1 as f64;
        let last = counts[counts.len() - 1];
        assert!(last.1 as f64 <= 1.5 * first, "{counts:?}");
        if compare_scalar {
            // the near-null space is what makes aggregation work for elasticity
            for c in &counts {
                assert!(c.2 == 0 || 2 * c.1 < c.2, "{counts:?}");
            }
        }
    }

    #[test]
    fn amg_elasticity_iterations_bounded_under_refinement() {
        elasticity_scaling(0.3, &[8, 16, 24, 32], true);
    }

    #[test]
    fn amg_elasticity_nearly_incompressible_bounded() {
        elasticity_scaling(0.45, &[8, 16, 24], false);
    }

    #[test]
    fn amg_thin_plate_converges() {
        // a 1 × 1 × 0.02 cantilever plate (aspect 1:50 like a film), clamped on one edge
        let (a, coords) = elasticity([32, 32, 2], [1.0, 1.0, 0.02], 0.3);
        let rbm = rigid_body_modes(&coords, 3);
        solve_report("thin plate 32x32x2", &a, 3, &rbm, &AmgParams::default());
        solve_report(
            "thin plate 32x32x2 (coarse 200)",
            &a,
            3,
            &rbm,
            &test_params(),
        );
    }

    #[test]
    fn amg_vcycle_is_symmetric_and_positive() {
        let (a, coords) = elasticity([8, 8, 6], [1.0, 1.0, 0.75], 0.3);
        let rbm = rigid_body_modes(&coords, 3);
        let params = AmgParams {
            coarse_size: 60,
            ..AmgParams::default()
        };
        let amg = Amg::new(&a, 3, &rbm, &params).expect("hierarchy");
        assert!(amg.levels() >= 3, "{amg:?}");
        let (mut mx, mut my) = (vec![0.0; a.n], vec![0.0; a.n]);
        for seed in 1..4 {
            let x = noise(a.n, seed);
            let y = noise(a.n, seed + 100);
            amg.apply(&x, &mut mx);
            amg.apply(&y, &mut my);
            let (ymx, xmy) = (dot(&y, &mx), dot(&x, &my));
            let scale = dot(&y, &y).sqrt() * dot(&mx, &mx).sqrt();
            assert!(
                (ymx - xmy).abs() <= 1e-10 * scale,
                "yᵀM⁻¹x = {ymx:e}, xᵀM⁻¹y = {xmy:e}"
            );
            let xmx = dot(&x, &mx);
            assert!(xmx > 0.0, "xᵀM⁻¹x = {xmx:e}");
            // the same input gives the same output (work vectors left no trace)
            let mut again = vec![0.0; a.n];
            amg.apply(&x, &mut again);
            assert_eq!(again, mx);
        }
    }

    /// A symmetric matrix of `nb` node blocks of size `b`, each block row coupled to a few
    /// others, with some entries of the stored blocks missing from the CSR.
    fn blocked(nb: usize, b: usize) -> CsrMatrix {
        let n = nb * b;
        let value = |i: usize, j: usize| {
            let (lo, hi) = (i.min(j), i.max(j));
            if i == j {
                10.0 + (i % 7) as f64
            } else {
                ((lo * 31 + hi * 17) % 13) as f64 / 13.0 - 0.45
            }
        };
        let rows = (0..n)
            .map(|i| {
                let ib = i / b;
                let mut row = Vec::new();
                for jb in [ib.wrapping_sub(3), ib.wrapping_sub(1), ib, ib + 1, ib + 3] {
                    if jb >= nb {
                        continue;
                    }
                    for j in jb * b..(jb + 1) * b {
                        // a symmetric hole pattern inside the blocks
                        if i == j || (i + j) % 5 != 0 {
                            row.push((j, value(i, j)));
                        }
                    }
                }
                row
            })
            .collect();
        csr_from_rows(rows)
    }

    fn view(a: &CsrMatrix) -> View<'_> {
        View {
            nrows: a.n,
            ncols: a.n,
            row_ptr: &a.row_ptr,
            col: &a.col_idx,
            val: &a.values,
        }
    }

    #[test]
    fn node_blocks_multiply_as_the_scalar_matrix() {
        // small (one thread) and large (parallel chunks, 3 not dividing the chunk length)
        for (nb, b) in [(30, 1), (30, 3), (30, 4), (30, 7), (12_000, 3), (9_000, 4)] {
            let a = blocked(nb, b);
            let x = noise(a.n, 3);
            let mut want = vec![0.0; a.n];
            spmv_with(view(&a), &x, &mut want, |_, s, y| *y = s);
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let m = Bsr::from_csr(view(&a), b, false, BLOCK_MAX_FILL).expect("blocks");
            assert_eq!(m.storage(), SmootherStorage::BlockDouble);
            assert!(m.stored() >= a.nnz() && m.stored() < 2 * a.nnz());
            // the row index handed to the update is the scalar row
            let mut got = vec![1.0; a.n];
            m.apply_with(&x, &mut got, |i, s, y| *y = 2.0 * s - *y + i as f64);
            for i in 0..a.n {
                let expected = 2.0 * want[i] - 1.0 + i as f64;
                assert!(
                    (got[i] - expected).abs() <= 1e-13 * (scale + i as f64),
                    "b = {b}, row {i}: {} against {expected}",
                    got[i]
                );
            }
            // single precision: the product of the rounded matrix, summed in double
            let rounded = CsrMatrix::new(
                a.n,
                a.row_ptr.to_vec(),
                a.col_idx.to_vec(),
                a.values.iter().map(|&v| v as f32 as f64).collect(),
            );
            let mut want32 = vec![0.0; a.n];
            spmv_with(view(&rounded), &x, &mut want32, |_, s, y| *y = s);
            let m = Bsr::from_csr(view(&a), b, true, BLOCK_MAX_FILL).expect("blocks");
            assert_eq!(m.storage(), SmootherStorage::BlockSingle);
            let mut got = vec![0.0; a.n];
            m.apply_with(&x, &mut got, |_, s, y| *y = s);
            let (mut err32, mut rounding) = (0.0f64, 0.0f64);
            for i in 0..a.n {
                err32 = err32.max((got[i] - want32[i]).abs());
                rounding = rounding.max((got[i] - want[i]).abs());
            }
            assert!(err32 <= 1e-13 * scale, "b = {b}: {err32:e}");
            // and the rounding itself is that of single precision, not more
            assert!(
                rounding > 0.0 && rounding < 1e-6 * scale,
                "b = {b}: {rounding:e}"
            );
        }
        // blocks mostly zeros are refused
        let diagonal = csr_from_rows((0..40).map(|i| vec![(i, 1.0)]).collect());
        assert!(Bsr::from_csr(view(&diagonal), 4, true, BLOCK_MAX_FILL).is_none());
        assert!(Bsr::from_csr(view(&diagonal), 1, true, BLOCK_MAX_FILL).is_some());
        // a size the block does not divide
        assert!(Bsr::from_csr(view(&diagonal), 3, true, BLOCK_MAX_FILL).is_none());
    }

    #[test]
    fn a_block_matrix_takes_renumbered_values_and_gives_them_back() {
        for (nb, b) in [(30, 4), (9_000, 4), (40, 3)] {
            let a = blocked(nb, b);
            let n = a.n;
            // nodes in reverse order, a padding node after every fourth, and the first unknown
            // of every third node held (no row of its own: a padding row in its node)
            let slots = nb + nb / 4 + 1;
            let rows = slots * b;
            let mut eq = vec![usize::MAX; rows];
            let mut row = vec![usize::MAX; n];
            let mut slot = 0;
            for node in (0..nb).rev() {
                if slot % 5 == 4 {
                    slot += 1;
                }
                for c in 0..b {
                    if node % 3 != 0 || c != 0 {
                        eq[slot * b + c] = node * b + c;
                        row[node * b + c] = slot * b + c;
                    }
                }
                slot += 1;
            }
            assert!(slot <= slots);
            // the renumbered matrix as the solver's `extract` builds it
            let pad = 3.5;
            let renumbered_of = |a: &CsrMatrix, pad: f64| {
                csr_from_rows(
                    (0..rows)
                        .map(|r| match eq[r] {
                            usize::MAX => vec![(r, pad)],
                            e => (a.row_ptr[e]..a.row_ptr[e + 1])
                                .filter(|&p| row[a.col_idx[p] as usize] != usize::MAX)
                                .map(|p| (row[a.col_idx[p] as usize], a.values[p]))
                                .collect(),
                        })
                        .collect(),
                )
            };
            let renumbered = renumbered_of(&a, pad);
            let mut m = BlockMatrix::from_csr(&renumbered, b).expect("blocks");
            assert_eq!(m.n(), rows);
            // scalar copy: the same entries
            let back = m.to_csr();
            assert_eq!(back.row_ptr, renumbered.row_ptr);
            assert_eq!(back.col_idx, renumbered.col_idx);
            assert_eq!(back.values, renumbered.values);
            // new values of the same pattern, scattered in place, multiply as the scalar matrix
            let scaled = CsrMatrix::new(
                n,
                a.row_ptr.to_vec(),
                a.col_idx.to_vec(),
                a.values.iter().map(|v| 2.0 * v - 0.25).collect(),
            );
            assert!(m.assign_renumbered(&scaled, &eq, &row, 7.0));
            let want_matrix = renumbered_of(&scaled, 7.0);
            let x = noise(rows, 5);
            let mut got = vec![0.0; rows];
            m.mul_vec(&x, &mut got);
            let mut want = vec![0.0; rows];
            want_matrix.mul_vec(&x, &mut want);
            for r in 0..rows {
                assert!(
                    (got[r] - want[r]).abs() <= 1e-12 * (1.0 + want[r].abs()),
                    "row {r}: {} against {}",
                    got[r],
                    want[r]
                );
            }
            // an entry outside the stored blocks is refused
            let mut wide: Vec<Vec<(usize, f64)>> = (0..n)
                .map(|i| {
                    (a.row_ptr[i]..a.row_ptr[i + 1])
                        .map(|p| (a.col_idx[p] as usize, a.values[p]))
                        .collect()
                })
                .collect();
            wide[n - 1].push((b + 1, 1.0));
            wide[b + 1].push((n - 1, 1.0));
            assert!(!m.assign_renumbered(&csr_from_rows(wide), &eq, &row, 7.0));
        }
    }

    #[test]
    fn a_hierarchy_from_blocks_is_the_hierarchy_of_the_matrix() {
        let (a, coords) = elasticity([10, 10, 8], [1.0, 1.0, 0.8], 0.3);
        let rbm = rigid_body_modes(&coords, 3);
        let params = AmgParams {
            coarse_size: 60,
            smoother_storage: SmootherStorage::BlockSingle,
            ..AmgParams::default()
        };
        let m = BlockMatrix::from_csr(&a, 3).expect("blocks");
        let from_blocks = Amg::from_blocks(&m, &rbm, &params).expect("hierarchy");
        let from_matrix = Amg::new(&a, 3, &rbm, &params).expect("hierarchy");
        assert!(from_blocks.levels() >= 3);
        assert_eq!(from_blocks.levels(), from_matrix.levels());
        assert_eq!(from_blocks.smoother_storage(), SmootherStorage::BlockSingle);
        // the compact copy was released: no scalar fine operator is held
        assert!(matches!(from_blocks.fine, Source::Released));
        let x = noise(a.n, 9);
        let (mut y1, mut y2) = (vec![0.0; a.n], vec![0.0; a.n]);
        from_blocks.apply(&x, &mut y1);
        from_matrix.apply(&x, &mut y2);
        let scale = dot(&y2, &y2).sqrt();
        let diff = y1
            .iter()
            .zip(&y2)
            .map(|(u, v)| (u - v) * (u - v))
            .sum::<f64>()
            .sqrt();
        assert!(diff <= 1e-12 * scale, "{diff:e} of {scale:e}");
    }

    #[test]
    fn block_smoothers_precondition_as_the_scalar_one() {
        let (a, coords) = elasticity([10, 10, 8], [1.0, 1.0, 0.8], 0.3);
        let rbm = rigid_body_modes(&coords, 3);
        let mut iterations = Vec::new();
        for storage in [
            SmootherStorage::Csr,
            SmootherStorage::BlockDouble,
            SmootherStorage::BlockSingle,
        ] {
            let params = AmgParams {
                coarse_size: 60,
                smoother_storage: storage,
                ..AmgParams::default()
            };
            let amg = Amg::new(&a, 3, &rbm, &params).expect("hierarchy");
            assert!(amg.levels() >= 3, "{amg:?}");
            assert_eq!(amg.smoother_storage(), storage);
            // the single-precision cycle is still symmetric (the rounded matrix is) and positive
            let (x, y) = (noise(a.n, 1), noise(a.n, 2));
            let (mut mx, mut my) = (vec![0.0; a.n], vec![0.0; a.n]);
            amg.apply(&x, &mut mx);
            amg.apply(&y, &mut my);
            let scale = dot(&y, &y).sqrt() * dot(&mx, &mx).sqrt();
            assert!((dot(&y, &mx) - dot(&x, &my)).abs() <= 1e-10 * scale);
            assert!(dot(&x, &mx) > 0.0);
            iterations.push(solve_report(
                &format!("elasticity, smoother {storage:?}"),
                &a,
                3,
                &rbm,
                &params,
            ));
        }
        // the same operators: the same count; rounded to single precision: at most one more
        assert_eq!(iterations[1], iterations[0], "{iterations:?}");
        assert!(iterations[2] <= iterations[0] + 1, "{iterations:?}");
    }

    #[test]
    fn amg_same_result_on_one_and_two_threads() {
        // large enough for the parallel code paths
        let (a, coords) = elasticity([24, 24, 24], [1.0, 1.0, 1.0], 0.3);
        assert!(a.n >= PARALLEL_MIN_ROWS);
        let rbm = rigid_body_modes(&coords, 3);
        let b = noise(a.n, 3);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            pool.install(|| {
                let amg = Amg::new(&a, 3, &rbm, &test_params()).expect("hierarchy");
                let mut z = vec![0.0; a.n];
                amg.apply(&b, &mut z);
                (format!("{amg:?}"), z)
            })
        };
        let (d1, z1) = run(1);
        let (d2, z2) = run(2);
        assert_eq!(d1, d2);
        assert!(z1.iter().zip(&z2).all(|(u, v)| u.to_bits() == v.to_bits()));
    }

    #[test]
    fn amg_rejects_bad_input() {
        let a = laplace7(4);
        let ones = vec![vec![1.0; a.n]];
        let p = AmgParams::default();
        let mut nan = a.clone();
        nan.values[5] = f64::NAN;
        assert!(matches!(
            Amg::new(&nan, 1, &ones, &p),
            Err(AmgError::NonFinite { .. })
        ));
        assert!(matches!(
            Amg::new(&a, 1, &[vec![1.0; a.n - 1]], &p),
            Err(AmgError::NearNullLength { index: 0, .. })
        ));
        assert!(matches!(
            Amg::new(&a, 1, &[vec![f64::INFINITY; a.n]], &p),
            Err(AmgError::NearNullNonFinite { .. })
        ));
        assert!(matches!(
            Amg::new(&a, 1, &[], &p),
            Err(AmgError::NoNearNull)
        ));
        assert!(matches!(
            Amg::new(&a, 3, &ones, &p),
            Err(AmgError::BlockSize { block: 3, .. })
        ));
        let empty = CsrMatrix::new(0, vec![0], vec![], vec![]);
        assert!(matches!(
            Amg::new(&empty, 1, &[vec![]], &p),
            Err(AmgError::Empty)
        ));
        let mut cols = a.col_idx.to_vec();
        let last = cols.len() - 1;
        cols[last] = (a.n + 2) as u32;
        let wide = CsrMatrix::new(a.n, a.row_ptr.to_vec(), cols, a.values.clone());
        let e = Amg::new(&wide, 1, &ones, &p).expect_err("not square");
        assert!(matches!(e, AmgError::NotSquare { .. }), "{e}");
        let rows = a.row_ptr.len() - 1;
        let short = CsrMatrix::new(
            a.n,
            a.row_ptr[..rows].to_vec(),
            a.col_idx.to_vec(),
            a.values.clone(),
        );
        assert!(matches!(
            Amg::new(&short, 1, &ones, &p),
            Err(AmgError::Malformed(_))
        ));
        let mut negative = a.clone();
        negative.values[0] = -1.0;
        assert!(matches!(
            Amg::new(&negative, 1, &ones, &p),
            Err(AmgError::NonPositiveDiagonal { row: 0, .. })
        ));
        let bad_params = AmgParams {
            theta: f64::NAN,
            ..AmgParams::default()
        };
        assert!(matches!(
            Amg::new(&a, 1, &ones, &bad_params),
            Err(AmgError::Params(_))
        ));
        // the messages say what is wrong
        let msg = Amg::new(&a, 1, &[vec![1.0; 3]], &p)
            .expect_err("length")
            .to_string();
        assert!(
            msg.contains("3 entries") && msg.contains("64 rows"),
            "{msg}"
        );
    }
    #[test]
    fn an_indefinite_matrix_needs_the_indefinite_setting() {
        // a Laplacian block coupled weakly to a negative definite one: node-major, two unknowns
        // per node (a stand-in for displacement and potential)
        let m = 30;
        let mut rows = vec![Vec::new(); 2 * m];
        for i in 0..m {
            for (f, sign) in [(0, 1.0), (1, -1.0)] {
                let r = 2 * i + f;
                rows[r].push((r, sign * 2.0));
                if i > 0 {
                    rows[r].push((r - 2, -sign));
                }
                if i + 1 < m {
                    rows[r].push((r + 2, -sign));
                }
                rows[r].push((2 * i + 1 - f, 0.1));
            }
            rows[2 * i].sort_by_key(|e| e.0);
            rows[2 * i + 1].sort_by_key(|e| e.0);
        }
        let a = csr_from_rows(rows);
        let modes = vec![
            (0..2 * m)
                .map(|r| if r % 2 == 0 { 1.0 } else { 0.0 })
                .collect::<Vec<_>>(),
            (0..2 * m)
                .map(|r| if r % 2 == 1 { 1.0 } else { 0.0 })
                .collect(),
        ];
        let params = AmgParams {
            coarse_size: 8,
            ..test_params()
        };
        assert!(matches!(
            Amg::new(&a, 2, &modes, &params),
            Err(AmgError::NonPositiveDiagonal { row: 1, .. })
        ));
        let indefinite = AmgParams {
            indefinite: true,
            ..params
        };
        let amg = Amg::new(&a, 2, &modes, &indefinite).unwrap();
        assert!(amg.levels() >= 2, "{amg:?}");
        // the spectral radius bound covers both signs: |D|^(-1/2) A |D|^(-1/2) has eigenvalues
        // near ±2 here, so ρ > 1.5
        assert!(amg.level_info()[0].rho > 1.5, "{:?}", amg.level_info());
        // as the preconditioner of flexible GMRES it solves to the tolerance
        let b: Vec<f64> = (0..2 * m).map(|i| ((i * 5) % 7) as f64 - 3.0).collect();
        let mut x = vec![0.0; 2 * m];
        let report = crate::solve::krylov::fgmres(
            |v, y| a.mul_vec(v, y),
            |r, z| amg.apply(r, z),
            &b,
            &mut x,
            &crate::solve::krylov::KrylovSettings {
                rtol: 1e-10,
                max_iterations: 100,
                restart: 50,
            },
        );
        assert!(report.converged && report.iterations < 30, "{report:?}");
        let mut ax = vec![0.0; 2 * m];
        a.mul_vec(&x, &mut ax);
        let res = ax
            .iter()
            .zip(&b)
            .fold(0.0f64, |s, (p, q)| s.max((p - q).abs()));
        assert!(res < 1e-8, "{res:e}");
    }

    #[test]
    fn amg_rigid_body_modes_are_in_the_element_kernel() {
        // the free-floating element: K·(rigid mode) = 0
        let h = [0.3, 0.2, 0.5];
        let k = hex_stiffness(h, 1.0, 0.3);
        let coords: Vec<[f64; 3]> = (0..8)
            .map(|a| {
                [
                    (a & 1) as f64 * h[0] + 1.0,
                    ((a >> 1) & 1) as f64 * h[1],
                    ((a >> 2) & 1) as f64 * h[2] - 2.0,
                ]
            })
            .collect();
        let modes = rigid_body_modes(&coords, 3);
        assert_eq!(modes.len(), 6);
        let kmax = k.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for m in &modes {
            for row in &k {
                let s: f64 = row.iter().zip(m).map(|(u, v)| u * v).sum();
                assert!(s.abs() < 1e-12 * kmax, "K·mode = {s:e}");
            }
        }
        assert_eq!(rigid_body_modes(&coords, 2).len(), 3);
        assert_eq!(rigid_body_modes(&coords, 1), vec![vec![1.0; 8]]);
    }

    #[test]
    fn amg_small_problem_is_one_direct_level() {
        let a = laplace7(5);
        let amg = Amg::new(&a, 1, &[vec![1.0; a.n]], &AmgParams::default()).expect("hierarchy");
        assert_eq!(amg.levels(), 1);
        assert_eq!(amg.operator_complexity(), 1.0);
        let b = noise(a.n, 1);
        let mut x = vec![0.0; a.n];
        amg.apply(&b, &mut x);
        let mut ax = vec![0.0; a.n];
        a.mul_vec(&x, &mut ax);
        for (u, v) in ax.iter().zip(&b) {
            assert!((u - v).abs() < 1e-12);
        }
    }
}
