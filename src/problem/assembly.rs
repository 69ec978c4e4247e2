//! Assembly of the global residual and tangent from cell contributions.
//!
//! Knows the mesh topology and the dof map, nothing of physics: a cell kernel (a closure) turns a
//! cell's local values into a local residual and tangent. The CSR pattern over the free dofs is built
//! once. Cells are coloured so that no two cells of one colour share a node; the cells of one colour
//! are assembled in parallel and write into disjoint entries, colours one after the other. Cells
//! on tied nodes share equations: their kernels run in parallel, and their results are added one
//! after the other. Every matrix and vector entry therefore receives its contributions in the
//! same order whatever the number of threads: results are bitwise reproducible.
//!
//! **Shared assembly.** Several processes (MPI ranks) may share the cells: with a [`CellShare`]
//! each process assembles only the cells it owns, [`Assembler::combine`] sums the residual's cell
//! part over the processes (every process then holds the same full residual, so the nonlinear
//! solvers run unchanged), and the tangent stays this process's part, to be summed by a
//! distributed linear solver. That part has a pattern of its own: the couplings of the owned
//! cells, and the whole rows of its term equations ([`Assembler::term_rows`]), into which this
//! process adds the tangent's terms that are not cell terms ([`Assembler::global_terms`]). An
//! equation is a term equation of one process whose cells meet its node, the nodes on the
//! partition's boundary dealt out so that the processes get nearly equal numbers of equations
//! (`term_processes`), so the term equations of the processes cover every equation once and
//! each lies among the process's own cells' rows. So no process holds the whole tangent or its
//! whole pattern, nor more rows than its cells touch. Without a share nothing changes.

use crate::algebra::csr::{col, Col, CsrMatrix};
use crate::algebra::exchange::SumOverProcesses;
use crate::algebra::spin;
use crate::element::{LocalMatrix, MAX_LOCAL};
use crate::mesh::Mesh;
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};
use std::sync::Arc;
use std::time::Instant;

/// Below this many cells the assembly with the tangent, and [`map_cells`], run on the calling
/// thread: handing cells to the pool costs more than evaluating them. On the hex8 film with 2 threads the
/// pool is already faster at 128 cells (docs/validation.md).
const PARALLEL_MIN_CELLS: usize = 128;

/// From this many cells a residual without tangent is computed on the pool: the cells' local
/// residuals go into one buffer in parallel (a single hand-off per assembly), then are added in
/// the serial order. A cell of a nearly incompressible hex8 costs a few microseconds, so a few
/// hundred cells outweigh the hand-off.
const PARALLEL_MIN_RESIDUAL_CELLS: usize = 128;

/// From this many cells up to [`PARALLEL_MIN_RESIDUAL_CELLS`] a residual may run on the caller and
/// the helper threads of [`spin`] too, if it is faster there: the first [`TRIALS`] residuals of
/// each kind are timed, alternately, and the faster kind taken from then on. Whether a small
/// model gains depends on what its cells cost against the hand-off (a few microseconds), so it
/// is measured rather than guessed: `diaphragm-visco`'s meridian cells (Maxwell branches at
/// every point) run in 0.70 of the time they took on the calling thread alone. Either way the
/// sums are the same bits.
const SPIN_MIN_CELLS: usize = 16;

/// Residuals of each kind (serial, parallel) timed before the choice.
const TRIALS: u64 = 8;

/// The faster way to a small model's residual, chosen by timing the first ones (see
/// [`SPIN_MIN_CELLS`]).
#[derive(Debug)]
struct PathChoice {
    /// Residuals asked for so far.
    calls: AtomicU64,
    /// The shortest time of each kind (ns): serial, parallel.
    best: [AtomicU64; 2],
}

impl Default for PathChoice {
    fn default() -> Self {
        PathChoice {
            calls: AtomicU64::new(0),
            best: [AtomicU64::new(u64::MAX), AtomicU64::new(u64::MAX)],
        }
    }
}

impl Clone for PathChoice {
    /// A copy chooses anew: it may assemble other systems.
    fn clone(&self) -> Self {
        PathChoice::default()
    }
}

impl PathChoice {
    /// Whether the next residual runs in parallel, and whether it is one of the timed trials.
    fn next(&self) -> (bool, bool) {
        let call = self.calls.fetch_add(1, AtomicOrdering::Relaxed);
        if call < 2 * TRIALS {
            (call % 2 == 1, true)
        } else {
            let best = |k: usize| self.best[k].load(AtomicOrdering::Relaxed);
            (best(1) < best(0), false)
        }
    }

    /// Takes the time of a trial.
    fn record(&self, parallel: bool, start: Instant) {
        let ns = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.best[usize::from(parallel)].fetch_min(ns, AtomicOrdering::Relaxed);
    }
}

/// The cells on tied nodes (a rigid pad's, which may be a third of a model's) are evaluated on
/// the pool this many at a time into a buffer before being added in order: a bounded buffer
/// (0.5 MB for hex8 cells) that still gives each thread many cells.
const SERIAL_CHUNK: usize = 64;

/// `f` of each of `cells`, the results in their order: on the calling thread and the helpers of
/// [`spin`] from [`PARALLEL_MIN_CELLS`] cells (when rayon has more than one thread), one by one
/// below. A caller that adds the results
/// in this order gets the same sums, bit for bit, on any number of threads (the record, the
/// internal forces, the adjoint's cell products).
pub fn map_cells<R: Send>(cells: &[usize], f: impl Fn(usize) -> R + Sync + Send) -> Vec<R> {
    if cells.len() >= PARALLEL_MIN_CELLS && rayon::current_num_threads() > 1 {
        spin::map(cells.len(), |i| f(cells[i]))
    } else {
        cells.iter().map(|&c| f(c)).collect()
    }
}

/// The cells this process assembles, and how its partial sums meet the other processes'.
/// Built by the run set-up; the physics sees only this.
pub struct CellShare {
    /// Per cell: the process that assembles it (the same on every process).
    pub part: Vec<usize>,
    /// This process's index among the processes ...
    pub rank: usize,
    /// ... and their number.
    pub size: usize,
    /// Sums a vector over the processes in place; every process receives the same bits.
    pub sum: SumOverProcesses,
}

impl CellShare {
    /// Whether this process assembles cell `c`.
    pub fn owns(&self, c: usize) -> bool {
        self.part.get(c) == Some(&self.rank)
    }

    /// Sums `v` over the processes after a pass over their cells in which this process's cell
    /// `failed` failed (if any): every process then fails alike when a cell failed on any (so
    /// that all take the same path), with this process's own message when the cell was its
    /// own. The caller reports its own failure; `Ok` here means no other process failed.
    pub fn sum_unless_failed(&self, v: &mut [f64], failed: Option<usize>) -> Result<(), String> {
        // two more slots: the count of failed processes and the sum of their failed cells + 1
        let mut w = Vec::with_capacity(v.len() + 2);
        w.extend_from_slice(v);
        w.extend_from_slice(&failed.map_or([0.0, 0.0], |c| [1.0, c as f64 + 1.0]));
        (self.sum)(&mut w)?;
        v.copy_from_slice(&w[..v.len()]);
        let (count, cell) = (w[v.len()], w[v.len() + 1]);
        if count == 0.0 || failed.is_some() {
            Ok(())
        } else if count == 1.0 {
            Err(format!(
                "cell {}: the kernel failed on another MPI rank (its message is on that rank)",
                cell as usize - 1
            ))
        } else {
            Err(format!("cell kernels failed on {count} MPI ranks"))
        }
    }

    /// Every process's `local` (of the same length on every process), in rank order.
    pub fn gather(&self, local: &[f64]) -> Result<Vec<Vec<f64>>, String> {
        let m = local.len();
        if m == 0 {
            return Ok(vec![Vec::new(); self.size]);
        }
        let mut all = vec![0.0; m * self.size];
        all[self.rank * m..(self.rank + 1) * m].copy_from_slice(local);
        (self.sum)(&mut all)?;
        Ok(all.chunks(m).map(<[f64]>::to_vec).collect())
    }
}

impl std::fmt::Debug for CellShare {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CellShare")
            .field(
                "owned",
                &(0..self.part.len()).filter(|&c| self.owns(c)).count(),
            )
            .field("rank", &self.rank)
            .field("size", &self.size)
            .finish()
    }
}

/// The process that takes the non-cell terms (and, in a distributed solver, the rows) of each
/// node: always one whose cells meet the node, so that a process's term rows lie among its own
/// cells' rows. A node inside one process's cells goes to that process; the nodes on the
/// partition's boundary are dealt out so that the processes get nearly equal numbers of free
/// unknowns, where a fixed rule (e.g. the process of the node's first cell) gives one process
/// the whole boundary: first each to whichever of its cells' processes has the fewest so far (in
/// node order, the lowest rank on a tie), then moved one by one to a less loaded process of its
/// cells while that evens the loads. Nodes in no cell go to process 0. The same on every
/// process.
fn term_processes(
    dofs: &DofMap,
    part: &[usize],
    size: usize,
    node_cells: &[Vec<usize>],
) -> Vec<usize> {
    const BOUNDARY: usize = usize::MAX;
    let free = |n: usize| {
        (0..FIELDS)
            .filter(|&f| dofs.eq[n * FIELDS + f] != CONSTRAINED)
            .count()
    };
    let mut load = vec![0usize; size.max(1)];
    let mut owner: Vec<usize> = node_cells
        .iter()
        .enumerate()
        .map(|(n, cells)| {
            let mut parts = cells.iter().map(|&c| part[c]);
            let first = parts.next().unwrap_or(0);
            if parts.all(|p| p == first) {
                load[first] += free(n);
                first
            } else {
                BOUNDARY
            }
        })
        .collect();
    // the least loaded process among those whose cells meet node n
    let lightest = |n: usize, load: &[usize]| {
        node_cells[n]
            .iter()
            .map(|&c| part[c])
            .min_by_key(|&p| (load[p], p))
            .expect("a boundary node has cells")
    };
    let boundary: Vec<usize> = (0..owner.len()).filter(|&n| owner[n] == BOUNDARY).collect();
    for &n in &boundary {
        let best = lightest(n, &load);
        load[best] += free(n);
        owner[n] = best;
    }
    // that order can leave a process short (its boundary dealt before another process's load
    // was known): move boundary nodes to a less loaded process while that lowers the sum of
    // squared loads (so this ends), in passes over the boundary
    for _ in 0..100 {
        let mut moved = false;
        for &n in &boundary {
            let (w, from, to) = (free(n), owner[n], lightest(n, &load));
            if w > 0 && load[to] + w < load[from] {
                load[from] -= w;
                load[to] += w;
                owner[n] = to;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    owner
}

/// The process that owns each node of `mesh` when `size` processes share its cells by `part`
/// (the rule of the shared assembly's term equations, `term_processes`): always one whose cells
/// meet the node, the partition's boundary dealt out so that the processes own nearly equal
/// numbers of the free unknowns of `dofs`. The same on every process.
pub fn node_processes(mesh: &Mesh, dofs: &DofMap, part: &[usize], size: usize) -> Vec<usize> {
    let mut node_cells: Vec<Vec<usize>> = vec![Vec::new(); mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        for &n in mesh.cell(c) {
            node_cells[n].push(c);
        }
    }
    term_processes(dofs, part, size, &node_cells)
}

/// A cell kernel failed.
#[derive(Debug, Clone, PartialEq)]
pub struct CellFailure<E> {
    pub cell: usize,
    pub error: E,
}

/// Assembles cell contributions into global systems over the free dofs.
#[derive(Debug, Clone)]
pub struct Assembler {
    colours: Vec<Vec<usize>>,
    /// Every cell in the order of the serial assembly: the colours, then the serial cells.
    order: Vec<usize>,
    /// Cells touching tied nodes (which share equations with other cells' nodes): added one
    /// after the other, in cell order, after the colours (their kernels run on the pool).
    serial: Vec<usize>,
    pattern: CsrMatrix,
    nodes_per_cell: usize,
    /// The share of the cells of this process, if the cells are shared.
    share: Option<std::sync::Arc<CellShare>>,
    /// Per equation: whether its tangent row takes this process's non-cell terms (`None`: all
    /// do, without a share).
    term_rows: Option<Arc<Vec<bool>>>,
    /// Whether a small model's residual runs in parallel.
    choice: PathChoice,
}

/// A pointer that may be shared between threads because the colouring guarantees that concurrent
/// writes go to disjoint entries.
#[derive(Clone, Copy)]
struct SharedMut(*mut f64);
unsafe impl Send for SharedMut {}
unsafe impl Sync for SharedMut {}
impl SharedMut {
    /// # Safety
    /// `i` is in bounds and no other thread touches entry `i` concurrently.
    unsafe fn add(self, i: usize, v: f64) {
        *self.0.add(i) += v;
    }
}

/// The tangent as it takes the terms that are not cell terms (loads, pressures, inertia,
/// circuits): on this process, only the rows of [`Assembler::term_rows`], so that the processes
/// sharing the cells add each such term once between them.
#[derive(Debug)]
pub struct GlobalTerms<'a> {
    k: &'a mut CsrMatrix,
    rows: Option<Arc<Vec<bool>>>,
}

impl GlobalTerms<'_> {
    /// Position of entry (i, j) in the tangent's values when this process adds the non-cell
    /// terms of row i and the entry is in the pattern.
    pub fn position(&self, i: usize, j: usize) -> Option<usize> {
        if self.rows.as_ref().is_none_or(|r| r[i]) {
            self.k.position(i, j)
        } else {
            None
        }
    }

    /// Adds `v` to entry (i, j) when [`GlobalTerms::position`] has it; nothing otherwise.
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        if let Some(p) = self.position(i, j) {
            self.k.values[p] += v;
        }
    }

    /// The tangent's values, for adding at positions found by [`GlobalTerms::position`].
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.k.values
    }
}

impl Assembler {
    /// Builds the colouring and the CSR pattern of the free dofs of `mesh` under `dofs`.
    pub fn new(mesh: &Mesh, dofs: &DofMap) -> Self {
        Self::build(mesh, dofs, None)
    }

    /// The assembler of this process when `share` gives it some of the cells (see the module
    /// documentation): its colours and serial list are those of [`Assembler::new`] restricted
    /// to the owned cells, in the same order, so every cell's contributions are added in the
    /// same order as without a share; its pattern holds the owned cells' couplings and the
    /// whole rows of its [`Assembler::term_rows`].
    pub fn shared(mesh: &Mesh, dofs: &DofMap, share: Arc<CellShare>) -> Self {
        Self::build(mesh, dofs, Some(share))
    }

    fn build(mesh: &Mesh, dofs: &DofMap, share: Option<Arc<CellShare>>) -> Self {
        let npc = mesh.kind.nodes_per_cell();
        let owned = |c: usize| share.as_ref().is_none_or(|s| s.owns(c));
        // node adjacency through cells
        let mut node_cells: Vec<Vec<usize>> = vec![Vec::new(); mesh.n_nodes()];
        for c in 0..mesh.n_cells() {
            for &n in mesh.cell(c) {
                node_cells[n].push(c);
            }
        }
        // an equation is a term equation of the process that takes its lowest node
        let node_owner = share
            .as_ref()
            .map(|s| term_processes(dofs, &s.part, s.size, &node_cells));
        let takes_terms = |nodes: &[usize]| match (&share, &node_owner) {
            (Some(s), Some(owner)) => nodes.iter().min().is_some_and(|&n| owner[n] == s.rank),
            _ => true,
        };
        let mut terms = share.as_ref().map(|_| vec![false; dofs.n_free]);
        let mut row_ptr = Vec::with_capacity(dofs.n_free + 1);
        let mut col_idx = Vec::new();
        row_ptr.push(0);
        // (equation, node) of every free dof; a tied equation has several nodes
        let mut order: Vec<(usize, usize)> = Vec::new();
        for node in 0..mesh.n_nodes() {
            for f in 0..FIELDS {
                let e = dofs.eq[node * FIELDS + f];
                if e != CONSTRAINED {
                    order.push((e, node));
                }
            }
        }
        order.sort_unstable();
        order.dedup();
        let mut cols: Vec<usize> = Vec::new();
        let mut neighbours: Vec<usize> = Vec::new();
        let mut last: (Vec<usize>, bool) = (Vec::new(), false);
        let mut i = 0;
        while i < order.len() {
            let e = order[i].0;
            let mut j = i;
            while j < order.len() && order[j].0 == e {
                j += 1;
            }
            let nodes: Vec<usize> = order[i..j].iter().map(|p| p.1).collect();
            debug_assert_eq!(row_ptr.len() - 1, e, "equations are numbered densely");
            // a term equation's row couples through every cell, another through the owned
            let whole = takes_terms(&nodes);
            if let Some(t) = terms.as_mut() {
                t[e] = whole;
            }
            // consecutive equations of one node (or one tie) share their columns
            if nodes != last.0 || whole != last.1 {
                neighbours.clear();
                for &node in &nodes {
                    for &c in node_cells[node].iter().filter(|&&c| whole || owned(c)) {
                        neighbours.extend_from_slice(mesh.cell(c));
                    }
                }
                neighbours.sort_unstable();
                neighbours.dedup();
                cols.clear();
                for &m in &neighbours {
                    for g in 0..FIELDS {
                        let ce = dofs.eq[m * FIELDS + g];
                        if ce != CONSTRAINED {
                            cols.push(ce);
                        }
                    }
                }
                cols.sort_unstable();
                cols.dedup();
                last = (nodes, whole);
            }
            col_idx.extend(cols.iter().map(|&c| col(c)));
            row_ptr.push(col_idx.len());
            i = j;
        }
        drop(node_cells);
        // cells of one colour share no node; cells on tied nodes go to the serial list
        let rep = dofs.node_representatives();
        let mut class_size = vec![0usize; mesh.n_nodes()];
        for &r in &rep {
            class_size[r] += 1;
        }
        let tied = |c: usize| mesh.cell(c).iter().any(|&n| class_size[rep[n]] > 1);
        let serial: Vec<usize> = (0..mesh.n_cells())
            .filter(|&c| tied(c) && owned(c))
            .collect();
        let colours: Vec<Vec<usize>> = mesh
            .cell_colours()
            .into_iter()
            .map(|colour| {
                colour
                    .into_iter()
                    .filter(|&c| !tied(c) && owned(c))
                    .collect::<Vec<_>>()
            })
            .filter(|colour| !colour.is_empty())
            .collect();
        let order = colours.iter().flatten().chain(&serial).copied().collect();
        Assembler {
            colours,
            order,
            serial,
            // the structure only: every matrix is made by `new_matrix`
            pattern: CsrMatrix::new(dofs.n_free, row_ptr, col_idx, Vec::new()),
            nodes_per_cell: npc,
            share,
            term_rows: terms.map(Arc::new),
            choice: PathChoice::default(),
        }
    }

    /// The equations whose tangent rows take this process's non-cell terms, ascending: all of
    /// them without a share.
    pub fn term_rows(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.pattern.n).filter(|&e| self.term_rows.as_ref().is_none_or(|t| t[e]))
    }

    /// With a share, one flag per equation: whether it is among [`Assembler::term_rows`].
    pub fn term_flags(&self) -> Option<Arc<Vec<bool>>> {
        self.term_rows.clone()
    }

    /// Whether the cells are shared between processes.
    pub fn is_shared(&self) -> bool {
        self.share.is_some()
    }

    /// Number of cells this process assembles.
    pub fn n_assembled(&self) -> usize {
        self.colours.iter().map(Vec::len).sum::<usize>() + self.serial.len()
    }

    /// The tangent as it takes the terms that are not cell terms (loads, pressures, inertia,
    /// circuits): the rows of [`Assembler::term_rows`] of `k`, so that the processes that
    /// share the cells add each such term once between them.
    pub fn global_terms<'a>(&self, k: Option<&'a mut CsrMatrix>) -> Option<GlobalTerms<'a>> {
        k.map(|k| GlobalTerms {
            k,
            rows: self.term_rows.clone(),
        })
    }

    /// Completes the residual's cell part after [`Assembler::assemble`], whose outcome on this
    /// process is `outcome`: with a share, sums `r` over the processes, and fails on every
    /// process when a cell failed on any (so that all take the same path). Without a share it
    /// passes `outcome` through.
    pub fn combine<E: std::fmt::Display>(
        &self,
        r: &mut [f64],
        outcome: Result<f64, CellFailure<E>>,
    ) -> Result<(), String> {
        let failed_cell = outcome.as_ref().err().map(|f| f.cell);
        let local = outcome
            .map(|_| ())
            .map_err(|f| format!("cell {}: {}", f.cell, f.error));
        let Some(share) = &self.share else {
            return local;
        };
        share.sum_unless_failed(r, failed_cell)?;
        local
    }

    /// A zeroed matrix with the assembler's pattern (the structure shared, not copied).
    pub fn new_matrix(&self) -> CsrMatrix {
        self.pattern.zeros_like()
    }

    /// Number of colours (for reports); the serial cells count as one.
    pub fn n_colours(&self) -> usize {
        self.colours.len() + usize::from(!self.serial.is_empty())
    }

    /// Assembles the scaled residual r̂ (length `n_free`) and, when `k` is given, the scaled tangent.
    /// `state` holds the physical values of all dofs (`FIELDS` per node). The kernel receives the
    /// cell index and its local values and fills the local residual (and tangent); it returns the
    /// cell's energy. Returns the per-cell energies' sum, added in cell order.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble<E, K>(
        &self,
        mesh: &Mesh,
        dofs: &DofMap,
        state: &[f64],
        kernel: K,
        r: &mut [f64],
        mut k: Option<&mut CsrMatrix>,
        cell_energy: &mut Vec<f64>,
    ) -> Result<f64, CellFailure<E>>
    where
        E: Send,
        K: Fn(usize, &[f64], &mut [f64], Option<&mut [f64]>) -> Result<f64, E> + Sync,
    {
        let npc = self.nodes_per_cell;
        let nl = npc * FIELDS;
        r.iter_mut().for_each(|v| *v = 0.0);
        cell_energy.clear();
        cell_energy.resize(mesh.n_cells(), 0.0);
        let cells = self.order.len();
        let (in_parallel, timed) = match (k.is_none(), rayon::current_num_threads() > 1) {
            (true, true) if cells >= PARALLEL_MIN_RESIDUAL_CELLS => (true, false),
            (true, true) if cells >= SPIN_MIN_CELLS => self.choice.next(),
            _ => (false, false),
        };
        let start = Instant::now();
        if in_parallel && self.residual_in_parallel(mesh, dofs, state, &kernel, r, cell_energy) {
            if timed {
                self.choice.record(true, start);
            }
            return Ok(cell_energy.iter().sum());
        }
        let want_k = k.is_some();
        if let Some(k) = k.as_deref_mut() {
            k.values.iter_mut().for_each(|v| *v = 0.0);
        }
        let r_ptr = SharedMut(r.as_mut_ptr());
        let k_ptr = k.as_deref_mut().map(|k| SharedMut(k.values.as_mut_ptr()));
        let e_ptr = SharedMut(cell_energy.as_mut_ptr());
        let pattern = k.as_deref().map(|k| (&k.row_ptr, &k.col_idx));
        let init = || {
            (
                vec![0.0; MAX_LOCAL],
                Box::new([0.0; MAX_LOCAL * MAX_LOCAL]) as Box<LocalMatrix>,
                [0usize; MAX_LOCAL],
                [0.0; MAX_LOCAL],
            )
        };
        type Work = (
            Vec<f64>,
            Box<LocalMatrix>,
            [usize; MAX_LOCAL],
            [f64; MAX_LOCAL],
        );
        // a cell's local values
        let values = |c: usize| {
            let mut local = [0.0; MAX_LOCAL];
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                local[a * FIELDS..(a + 1) * FIELDS]
                    .copy_from_slice(&state[node * FIELDS..(node + 1) * FIELDS]);
            }
            local
        };
        // a cell's equations and their scales
        let equations = |c: usize, eqs: &mut [usize; MAX_LOCAL], scale: &mut [f64; MAX_LOCAL]| {
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                for f in 0..FIELDS {
                    eqs[a * FIELDS + f] = dofs.eq[node * FIELDS + f];
                    scale[a * FIELDS + f] = dofs.scale[f];
                }
            }
        };
        // adds a cell's evaluated residual, tangent and energy to the global ones
        // SAFETY (the caller's): no other thread adds to the cell's entries concurrently
        let scatter = |c: usize,
                       eqs: &[usize; MAX_LOCAL],
                       scale: &[f64; MAX_LOCAL],
                       rl: &[f64],
                       kl: &[f64],
                       energy: f64| {
            unsafe {
                e_ptr.add(c, energy);
                for i in 0..nl {
                    if eqs[i] != CONSTRAINED {
                        r_ptr.add(eqs[i], scale[i] * rl[i]);
                    }
                }
            }
            if let (Some(kp), Some((row_ptr, col_idx))) = (k_ptr, pattern) {
                // the cell's free columns in increasing equation order: each row's entries are
                // then found by one forward walk through its sorted columns (a node's dofs are
                // consecutive equations, so most are the next entry)
                let mut order = [0usize; MAX_LOCAL];
                let mut m = 0;
                for j in 0..nl {
                    if eqs[j] != CONSTRAINED {
                        let mut k = m;
                        while k > 0 && eqs[order[k - 1]] > eqs[j] {
                            order[k] = order[k - 1];
                            k -= 1;
                        }
                        order[k] = j;
                        m += 1;
                    }
                }
                let order = &order[..m];
                // runs of consecutive equations among those columns (a node's free dofs, or
                // several nodes numbered one after the other): (first index in `order`, length).
                // A row holds a run's columns side by side (its columns are sorted and every cell
                // coupling is among them), so a run is found once and added as one stretch
                let mut runs = [(0usize, 0usize); MAX_LOCAL];
                let mut n_runs = 0;
                for t in 0..m {
                    if t > 0 && eqs[order[t]] == eqs[order[t - 1]] + 1 {
                        runs[n_runs - 1].1 += 1;
                    } else {
                        runs[n_runs] = (t, 1);
                        n_runs += 1;
                    }
                }
                let runs = &runs[..n_runs];
                // where each run started in the previous row: the rows of one node have the same
                // columns, so after a node's first row every position is a guess that holds
                let mut rel = [0usize; MAX_LOCAL];
                for i in 0..nl {
                    let ei = eqs[i];
                    if ei == CONSTRAINED {
                        continue;
                    }
                    let start = row_ptr[ei];
                    let cols = &col_idx[start..row_ptr[ei + 1]];
                    let kl_row = &kl[i * nl..(i + 1) * nl];
                    let mut prev = 0;
                    for (&(t0, len), guess) in runs.iter().zip(rel.iter_mut()) {
                        let run = &order[t0..t0 + len];
                        // equations of the pattern, whose columns were checked to fit a Col
                        let (first, last) = (eqs[run[0]] as Col, eqs[run[len - 1]] as Col);
                        let pos = if cols.get(*guess) == Some(&first) {
                            *guess
                        } else {
                            prev + cols[prev..]
                                .binary_search(&first)
                                .expect("pattern holds every cell coupling")
                        };
                        assert!(
                            cols.get(pos + len - 1) == Some(&last),
                            "pattern holds every cell coupling"
                        );
                        *guess = pos;
                        prev = pos + len - 1;
                        for (u, &j) in run.iter().enumerate() {
                            // SAFETY: as above, row ei belongs to a node of this cell only.
                            unsafe { kp.add(start + pos + u, scale[i] * scale[j] * kl_row[j]) };
                        }
                    }
                }
            }
        };
        let body = |(rl, kl, eqs, scale): &mut Work, &c: &usize| {
            let local = values(c);
            equations(c, eqs, scale);
            let kl_opt = if want_k {
                Some(&mut kl[..nl * nl])
            } else {
                None
            };
            let energy = kernel(c, &local[..nl], &mut rl[..nl], kl_opt)
                .map_err(|error| CellFailure { cell: c, error })?;
            // cells of one colour share no node, hence no dof (tied cells run alone): disjoint
            // entries
            scatter(c, eqs, scale, &rl[..nl], &kl[..nl * nl], energy);
            Ok(())
        };
        let parallel = mesh.n_cells() >= PARALLEL_MIN_CELLS && rayon::current_num_threads() > 1;
        if !parallel {
            // the same colour order as the parallel path: identical sums
            let mut work = init();
            for colour in &self.colours {
                for c in colour {
                    body(&mut work, c)?;
                }
            }
            for c in &self.serial {
                body(&mut work, c)?;
            }
            if timed && !in_parallel {
                self.choice.record(false, start);
            }
            return Ok(cell_energy.iter().sum());
        }
        for colour in &self.colours {
            colour.par_iter().try_for_each_init(init, body)?;
        }
        // the cells on tied nodes share equations: their kernels run on the pool a chunk at a
        // time into a buffer, then are added one after the other in the serial order
        let stride = nl + if want_k { nl * nl } else { 0 };
        let mut buffer = vec![0.0; SERIAL_CHUNK.min(self.serial.len()) * stride];
        let mut energies = Vec::with_capacity(SERIAL_CHUNK);
        for chunk in self.serial.chunks(SERIAL_CHUNK) {
            chunk
                .par_iter()
                .zip(buffer.par_chunks_mut(stride))
                .map(|(&c, out)| {
                    let local = values(c);
                    let (rl, kl) = out.split_at_mut(nl);
                    kernel(c, &local[..nl], rl, want_k.then_some(kl))
                        .map_err(|error| CellFailure { cell: c, error })
                })
                .collect_into_vec(&mut energies);
            for ((&c, out), energy) in chunk
                .iter()
                .zip(buffer.chunks(stride))
                .zip(energies.drain(..))
            {
                let (mut eqs, mut scale) = ([0; MAX_LOCAL], [0.0; MAX_LOCAL]);
                equations(c, &mut eqs, &mut scale);
                scatter(c, &eqs, &scale, &out[..nl], &out[nl..], energy?);
            }
        }
        Ok(cell_energy.iter().sum())
    }

    /// The residual of [`Assembler::assemble`] (no tangent) with the cells evaluated on the pool
    /// into a buffer and added in the serial order: the same sums, bit for bit, for any number
    /// of threads. Returns false, with `r` and `cell_energy` to be redone, when a cell fails (the
    /// serial path then reports the failure it would have met first).
    fn residual_in_parallel<E, K>(
        &self,
        mesh: &Mesh,
        dofs: &DofMap,
        state: &[f64],
        kernel: &K,
        r: &mut [f64],
        cell_energy: &mut [f64],
    ) -> bool
    where
        E: Send,
        K: Fn(usize, &[f64], &mut [f64], Option<&mut [f64]>) -> Result<f64, E> + Sync,
    {
        let nl = self.nodes_per_cell * FIELDS;
        // per cell: its local residual, then its energy
        let stride = nl + 1;
        let mut buffer = vec![0.0; self.order.len() * stride];
        let ok = spin::try_fill(&mut buffer, stride, |i, out| {
            let c = self.order[i];
            let mut local = [0.0; MAX_LOCAL];
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                local[a * FIELDS..(a + 1) * FIELDS]
                    .copy_from_slice(&state[node * FIELDS..(node + 1) * FIELDS]);
            }
            let (rl, energy) = out.split_at_mut(nl);
            match kernel(c, &local[..nl], rl, None) {
                Ok(e) => {
                    energy[0] = e;
                    true
                }
                Err(_) => false,
            }
        });
        if !ok {
            return false;
        }
        for (out, &c) in buffer.chunks_exact(stride).zip(&self.order) {
            cell_energy[c] += out[nl];
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                for f in 0..FIELDS {
                    let e = dofs.eq[node * FIELDS + f];
                    if e != CONSTRAINED {
                        r[e] += dofs.scale[f] * out[a * FIELDS + f];
                    }
                }
            }
        }
        true
    }
}

/// Processes simulated by threads, for tests of what the processes that share the cells do
/// together: calls `f(rank, sum)` on `size` threads and returns their results in rank order,
/// where `sum` adds a vector over the threads in rank order, each receiving the same bits, as
/// the sum over MPI ranks does.
#[cfg(test)]
pub(crate) fn on_threads<T: Send>(
    size: usize,
    f: impl Fn(usize, SumOverProcesses) -> T + Sync,
) -> Vec<T> {
    use std::sync::{Barrier, Mutex};
    let shared = Arc::new((Mutex::new(vec![Vec::new(); size]), Barrier::new(size)));
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..size)
            .map(|rank| {
                let shared = Arc::clone(&shared);
                let f = &f;
                scope.spawn(move || {
                    let sum: SumOverProcesses = Box::new(move |v: &mut [f64]| {
                        let (slots, barrier) = &*shared;
                        slots.lock().map_err(|e| e.to_string())?[rank] = v.to_vec();
                        barrier.wait();
                        {
                            let slots = slots.lock().map_err(|e| e.to_string())?;
                            v.copy_from_slice(&slots[0]);
                            for other in &slots[1..] {
                                v.iter_mut().zip(other).for_each(|(a, b)| *a += b);
                            }
                        }
                        // nobody writes the next sum's slot before all have read this one
                        barrier.wait();
                        Ok(())
                    });
                    f(rank, sum)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a simulated process panicked"))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::ElementKind;
    use crate::problem::dofs::Tie;

    /// The residual computed on the pool (cells into a buffer, added in the serial order) is the
    /// serial residual bit for bit, and so is the residual of the coloured path that assembles a
    /// tangent alongside; the tangent assembled on the pool is the serial tangent bit for bit.
    /// Also with tied nodes, whose cells (three chunks of them here) are evaluated on the pool
    /// and added in order; a failing cell among them is reported as the serial path reports it.
    #[test]
    fn parallel_residual_equals_serial_bit_for_bit() {
        let mesh = box_mesh([1.0, 1.0, 0.5], [8, 8, 4], ElementKind::Hex8);
        assert!(mesh.n_cells() >= PARALLEL_MIN_RESIDUAL_CELLS);
        assert!(mesh.n_cells() >= PARALLEL_MIN_CELLS);
        let n = mesh.n_nodes();
        // the bottom face held, and every tenth potential
        let constrained: Vec<bool> = (0..n * FIELDS)
            .map(|d| mesh.nodes[d / FIELDS][2] == 0.0 || (d % FIELDS == 3 && d % 40 == 3))
            .collect();
        // the upper half's vertical displacements tied, as a rigid pad ties its nodes'
        let tie = Tie {
            nodes: (0..n).filter(|&a| mesh.nodes[a][2] >= 0.25).collect(),
            field: crate::problem::dofs::Field::Uz,
            held: false,
        };
        let state: Vec<f64> = (0..n * FIELDS)
            .map(|d| ((d as f64 * 12.9898).sin() * 43758.5453).fract())
            .collect();
        for ties in [vec![], vec![tie]] {
            let dofs = DofMap::with_ties(n, &constrained, 3.0, &ties);
            let asm = Assembler::new(&mesh, &dofs);
            assert_eq!(asm.serial.len(), if ties.is_empty() { 0 } else { 192 });
            let kernel = |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
                for (i, (r, x)) in rl.iter_mut().zip(local).enumerate() {
                    *r = (c as f64 + 1.0).sin() * x * x + 0.1 * i as f64;
                }
                if let Some(kl) = kl {
                    // values whose sums depend on the order of the cells
                    for (p, v) in kl.iter_mut().enumerate() {
                        *v = ((c * 131 + p) as f64 * 0.37).sin() * 1e3 + 1e-7 * c as f64;
                    }
                }
                Ok::<f64, usize>(local.iter().sum::<f64>() * 1e-3)
            };
            let run = |threads: usize, tangent: bool, failing: &[usize]| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let mut r = vec![0.0; dofs.n_free];
                    let mut k = asm.new_matrix();
                    let mut e = Vec::new();
                    let kernel =
                        |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
                            if failing.contains(&c) {
                                return Err(c);
                            }
                            kernel(c, local, rl, kl)
                        };
                    let total = asm.assemble(
                        &mesh,
                        &dofs,
                        &state,
                        kernel,
                        &mut r,
                        tangent.then_some(&mut k),
                        &mut e,
                    );
                    (total.map(|t| (r, e, t)), tangent.then(|| k.values.clone()))
                })
            };
            let (serial, _) = run(1, false, &[]);
            let serial = serial.unwrap();
            assert!(serial.0.iter().any(|&v| v != 0.0));
            assert_eq!(run(2, false, &[]).0.unwrap(), serial);
            let (with_tangent, k_pool) = run(2, true, &[]);
            assert_eq!(with_tangent.unwrap(), serial);
            let (_, k_serial) = run(1, true, &[]);
            let (k_serial, k_pool) = (k_serial.unwrap(), k_pool.unwrap());
            assert!(k_serial.iter().any(|&v| v != 0.0));
            let bits = |k: &[f64]| k.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&k_pool), bits(&k_serial));
            if let [.., second, last] = asm.serial[..] {
                // two failing tied cells in the last chunk: the first in the serial order
                let failure = CellFailure {
                    cell: second,
                    error: second,
                };
                for threads in [1, 2] {
                    let (out, _) = run(threads, true, &[last, second]);
                    assert_eq!(out.unwrap_err(), failure);
                }
            }
        }
    }

    /// Called from outside rayon's pool (the caller and the helpers of `spin`), a residual is
    /// the same bits as on one thread: a model of 32 cells through its timed trials, serial and
    /// parallel alternately, and after the choice; one of 256 cells, always in parallel.
    #[test]
    fn residuals_outside_the_pool_are_the_serial_bits() {
        for (divisions, calls) in [([4, 4, 2], 2 * TRIALS as usize + 4), ([8, 8, 4], 4)] {
            let mesh = box_mesh([1.0, 1.0, 0.5], divisions, ElementKind::Hex8);
            let n = mesh.n_nodes();
            let constrained: Vec<bool> = (0..n * FIELDS)
                .map(|d| mesh.nodes[d / FIELDS][2] == 0.0)
                .collect();
            let dofs = DofMap::with_ties(n, &constrained, 3.0, &[]);
            let asm = Assembler::new(&mesh, &dofs);
            assert!(asm.order.len() >= SPIN_MIN_CELLS);
            let state: Vec<f64> = (0..n * FIELDS)
                .map(|d| ((d as f64 * 78.233).sin() * 43758.5453).fract())
                .collect();
            let kernel = |c: usize, local: &[f64], rl: &mut [f64], _: Option<&mut [f64]>| {
                for (i, (r, x)) in rl.iter_mut().zip(local).enumerate() {
                    *r = (c as f64 + 0.5).cos() * x * x + 0.3 * i as f64;
                }
                Ok::<f64, usize>(local.iter().sum::<f64>() * 1e-3)
            };
            let residual = || {
                let (mut r, mut e) = (vec![0.0; dofs.n_free], Vec::new());
                let total = asm
                    .assemble(&mesh, &dofs, &state, kernel, &mut r, None, &mut e)
                    .unwrap();
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                (bits(&r), bits(&e), total.to_bits())
            };
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            let serial = one.install(residual);
            assert!(serial.0.iter().any(|&v| v != 0));
            for _ in 0..calls {
                assert!(residual() == serial);
            }
        }
    }

    /// Processes that share the cells hold only their part of the pattern, and their parts of
    /// the tangent, each with the non-cell terms of its own rows, add up to the whole tangent
    /// with each such term once.
    #[test]
    fn shared_parts_add_up_to_the_whole_tangent() {
        let mesh = box_mesh([1.0, 1.0, 0.5], [6, 6, 3], ElementKind::Hex8);
        let n = mesh.n_nodes();
        let constrained: Vec<bool> = (0..n * FIELDS)
            .map(|d| mesh.nodes[d / FIELDS][2] == 0.0)
            .collect();
        let dofs = DofMap::new(n, &constrained, 3.0);
        let state: Vec<f64> = (0..n * FIELDS)
            .map(|d| ((d as f64 * 12.9898).sin() * 43758.5453).fract())
            .collect();
        let kernel = |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
            rl.iter_mut().zip(local).for_each(|(r, x)| *r = x * x);
            if let Some(kl) = kl {
                for (p, v) in kl.iter_mut().enumerate() {
                    *v = ((c * 131 + p) as f64 * 0.37).sin();
                }
            }
            Ok::<f64, ()>(0.0)
        };
        // the whole tangent, and 1 added once to every diagonal entry as a non-cell term
        let assemble = |asm: &Assembler| {
            let mut k = asm.new_matrix();
            let mut r = vec![0.0; dofs.n_free];
            asm.assemble(
                &mesh,
                &dofs,
                &state,
                kernel,
                &mut r,
                Some(&mut k),
                &mut Vec::new(),
            )
            .unwrap();
            let mut terms = asm.global_terms(Some(&mut k)).unwrap();
            (0..dofs.n_free).for_each(|e| terms.add(e, e, 1.0));
            k
        };
        let whole = assemble(&Assembler::new(&mesh, &dofs));
        // the cells in blocks of cell order (slabs across the thickness), and in slices across
        // x as a graph partition cuts a plate (not aligned with the equations' order)
        let slabs = |c: usize, size: usize| c * size / mesh.n_cells();
        let slices = |c: usize, size: usize| {
            let x = mesh.cell_centroid(c)[0];
            ((x * size as f64) as usize).min(size - 1)
        };
        for (size, part_of) in [
            (2, &slabs as &dyn Fn(usize, usize) -> usize),
            (3, &slabs),
            (2, &slices),
            (3, &slices),
        ] {
            let mut sum = whole.zeros_like();
            let mut covered = vec![0; dofs.n_free];
            let mut term_counts = Vec::new();
            let part: Vec<usize> = (0..mesh.n_cells()).map(|c| part_of(c, size)).collect();
            for rank in 0..size {
                let owned: Vec<bool> = part.iter().map(|&p| p == rank).collect();
                // the rows of the owned cells' equations
                let mut touched = vec![false; dofs.n_free];
                for c in (0..mesh.n_cells()).filter(|&c| owned[c]) {
                    for &node in mesh.cell(c) {
                        for f in 0..FIELDS {
                            let e = dofs.eq[node * FIELDS + f];
                            if e != CONSTRAINED {
                                touched[e] = true;
                            }
                        }
                    }
                }
                let share = Arc::new(CellShare {
                    part: part.clone(),
                    rank,
                    size,
                    sum: Box::new(|_| Ok(())),
                });
                let asm = Assembler::shared(&mesh, &dofs, share);
                asm.term_rows().for_each(|e| covered[e] += 1);
                term_counts.push(asm.term_rows().count());
                // a part holds only the rows of its own cells
                assert!(asm.term_rows().all(|e| touched[e]), "{size} processes");
                let part = assemble(&asm);
                let rows = (0..part.n).filter(|&i| part.row_ptr[i + 1] > part.row_ptr[i]);
                assert!(rows.clone().all(|i| touched[i]), "{size} processes");
                assert!(
                    part.nnz() < whole.nnz(),
                    "{size} processes: a part is smaller"
                );
                for i in 0..part.n {
                    for p in part.row_ptr[i]..part.row_ptr[i + 1] {
                        let at = whole
                            .position(i, part.col_idx[p] as usize)
                            .expect("a whole entry");
                        sum.values[at] += part.values[p];
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "the term rows cover once");
            // the boundary's rows dealt out: nearly equal rows per process
            let (least, most) = (
                *term_counts.iter().min().unwrap(),
                *term_counts.iter().max().unwrap(),
            );
            eprintln!("{size} processes: term rows {term_counts:?}");
            assert!(
                most - least <= dofs.n_free / 20,
                "{size} processes: term rows {term_counts:?} of {}",
                dofs.n_free
            );
            let scale = whole.values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in sum.values.iter().zip(&whole.values) {
                assert!(
                    (a - b).abs() <= 1e-13 * scale,
                    "{size} processes: {a} against {b}"
                );
            }
        }
    }

    /// Matrices made by the assembler share one structure; assigning one to another copies the
    /// values only, and a matrix of another structure is copied whole.
    #[test]
    fn matrices_share_their_structure() {
        let a = CsrMatrix::new(2, vec![0, 2, 3], vec![0, 1, 1], vec![1.0, 2.0, 3.0]);
        let mut z = a.zeros_like();
        assert!(Arc::ptr_eq(&a.col_idx, &z.col_idx) && Arc::ptr_eq(&a.row_ptr, &z.row_ptr));
        assert_eq!(z.values, vec![0.0; 3]);
        assert!(z.same_pattern(&a));
        z.assign(&a);
        assert_eq!(z.values, a.values);
        assert!(Arc::ptr_eq(&a.col_idx, &z.col_idx));
        // an equal structure in other arrays is the same pattern; a different one is not
        let b = CsrMatrix::new(2, vec![0, 2, 3], vec![0, 1, 1], vec![4.0, 5.0, 6.0]);
        assert!(z.same_pattern(&b));
        let c = CsrMatrix::new(2, vec![0, 1, 2], vec![0, 1], vec![7.0, 8.0]);
        assert!(!z.same_pattern(&c));
        z.assign(&c);
        assert_eq!((z.nnz(), z.values.clone()), (2, vec![7.0, 8.0]));
        assert!(Arc::ptr_eq(&z.col_idx, &c.col_idx));
    }
}
