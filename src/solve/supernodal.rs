//! The solve L D Lᵀ x = P b with faer's supernodal LDLᵀ factor for one right-hand side, on the
//! calling thread, or with two parts of the elimination tree solved side by side.
//!
//! faer's own solve goes supernode by supernode through its general dense kernels, whose set-up
//! outweighs the few hundred flops of a supernode of a small model; this one works on the
//! columns directly. On a small model a time step's modified Newton iterations make one such
//! solve each between two residuals, and on two threads it is the longest stretch that one
//! thread does alone; on a large one the solve streams the whole factor from memory twice, and
//! two parts stream it on two cores (the film of 55 000 unknowns: 0.85–0.89 of its run time
//! with faer's solve on two threads).
//!
//! **Two parts.** Two disjoint unions of whole subtrees of the supernodal elimination tree
//! (nested dissection's two halves below a separator) touch disjoint columns: in the forward
//! sweep a supernode updates only the rows of its ancestors, in the backward sweep it reads
//! only them. Each part's sweep runs on its own thread; the updates a part makes to rows
//! outside it (the separators above) are kept and subtracted afterwards, in the supernodes'
//! order, with the rest of the tree; in the backward sweep the rest goes first and each part
//! then reads the rows above it, final by then. Every value is formed by the same operations
//! in the same order as in the sweep on one thread: the solution is the same bits either way.

use crate::algebra::spin;

pub(crate) type SupernodalSymbolic =
    faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky<u32>;

/// A part is solved apart when it holds at least this many values of the factor (about
/// 10 µs of a sweep): below, handing it to another thread costs more than it saves.
const MIN_PART_VALUES: usize = 16_384;

#[inline]
fn u(i: u32) -> usize {
    i as usize
}

/// One supernode's columns and values.
struct Supernode<'a> {
    /// First column and number of columns.
    start: usize,
    size: usize,
    /// Rows below the diagonal block, ascending.
    pattern: &'a [u32],
    /// Column-major block over the diagonal block's and the pattern's rows: L's unit lower
    /// triangle with D on its diagonal, then L's rows of the pattern.
    values: &'a [f64],
}

impl<'a> Supernode<'a> {
    fn of(sn: &'a SupernodalSymbolic, l: &'a [f64], s: usize) -> Self {
        let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
        let (row_ptr, val_ptr) = (sn.col_ptr_for_row_idx(), sn.col_ptr_for_val());
        Supernode {
            start: u(begin[s]),
            size: u(end[s]) - u(begin[s]),
            pattern: &sn.row_idx()[u(row_ptr[s])..u(row_ptr[s + 1])],
            values: &l[u(val_ptr[s])..u(val_ptr[s + 1])],
        }
    }

    fn rows(&self) -> usize {
        self.size + self.pattern.len()
    }

    /// The forward sweep's step on the supernode's columns `xs`: the diagonal block's solve,
    /// then the pattern's updates into `tmp` (the caller subtracts them).
    #[inline]
    fn forward(&self, xs: &mut [f64], tmp: &mut [f64]) {
        let (nrows, size) = (self.rows(), self.size);
        for j in 0..size {
            let xj = xs[j];
            let col = &self.values[j * nrows..(j + 1) * nrows];
            for i in j + 1..size {
                xs[i] -= col[i] * xj;
            }
        }
        let tmp = &mut tmp[..self.pattern.len()];
        tmp.fill(0.0);
        for (j, &xj) in xs.iter().enumerate() {
            let col = &self.values[j * nrows + size..(j + 1) * nrows];
            for (t, &v) in tmp.iter_mut().zip(col) {
                *t += v * xj;
            }
        }
    }

    /// The backward sweep's step on the supernode's columns `xs`, `tmp` holding the values of
    /// the pattern's rows.
    #[inline]
    fn backward(&self, xs: &mut [f64], tmp: &[f64]) {
        let (nrows, size) = (self.rows(), self.size);
        for (j, xj) in xs.iter_mut().enumerate() {
            let col = &self.values[j * nrows + size..(j + 1) * nrows];
            *xj -= dot4(col, tmp);
        }
        for j in (0..size).rev() {
            let col = &self.values[j * nrows..(j + 1) * nrows];
            let mut v = xs[j];
            for i in j + 1..size {
                v -= col[i] * xs[i];
            }
            xs[j] = v;
        }
    }

    /// x ← D⁻¹ x on the supernode's columns.
    fn diagonal(&self, x: &mut [f64]) {
        let nrows = self.rows();
        for j in 0..self.size {
            x[self.start + j] *= self.values[j * nrows + j].recip();
        }
    }

    /// The forward step on the whole vector `x`: the pattern's rows updated at once.
    fn forward_all(&self, x: &mut [f64], tmp: &mut [f64]) {
        self.forward(&mut x[self.start..self.start + self.size], tmp);
        for (&i, &t) in self.pattern.iter().zip(tmp.iter()) {
            x[u(i)] -= t;
        }
    }

    /// The backward step on the whole vector `x`.
    fn backward_all(&self, x: &mut [f64], tmp: &mut [f64]) {
        let tmp = &mut tmp[..self.pattern.len()];
        for (t, &i) in tmp.iter_mut().zip(self.pattern) {
            *t = x[u(i)];
        }
        self.backward(&mut x[self.start..self.start + self.size], tmp);
    }
}

/// Σ aᵢbᵢ with four partial sums (which the compiler keeps in vector registers).
#[inline]
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut tail = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Two parts of the tree to solve side by side, found once per symbolic factorisation.
#[derive(Debug, Default)]
pub(crate) struct Split {
    /// The supernodes of each part, ascending: whole subtrees.
    parts: [Vec<usize>; 2],
    /// Per supernode: its part (`NONE` for the rest of the tree), where its rows outside the
    /// part start in its pattern, and its offset in the part's buffer of such rows.
    of: Vec<(usize, usize, usize)>,
    /// Per part: the updates of rows outside it (forward sweep).
    buffers: [Vec<f64>; 2],
    /// Per part: the work vector of a supernode's pattern.
    tmp: [Vec<f64>; 2],
}

/// The part of a supernode that is in neither part (the rest of the tree).
const NONE: usize = usize::MAX;

impl Split {
    /// The two parts with the most values in the smaller, each a group of children of one
    /// node on the path from the root down the heaviest child; `None` where the smaller holds
    /// fewer than [`MIN_PART_VALUES`] (or the supernodes are not numbered children first).
    pub fn plan(sn: &SupernodalSymbolic) -> Option<Split> {
        let n_super = sn.n_supernodes();
        let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
        let row_ptr = sn.col_ptr_for_row_idx();
        let rows = sn.row_idx();
        let mut of_column = vec![0usize; u(*end.get(n_super.checked_sub(1)?)?)];
        for s in 0..n_super {
            of_column[u(begin[s])..u(end[s])].fill(s);
        }
        // parents (the supernode of the first row below) and the subtrees' values
        let mut parent = vec![None; n_super];
        let mut weight = vec![0usize; n_super];
        let mut children = vec![Vec::new(); n_super + 1];
        for s in 0..n_super {
            let size = u(end[s]) - u(begin[s]);
            let m = u(row_ptr[s + 1]) - u(row_ptr[s]);
            weight[s] += size * (size + m);
            if m > 0 {
                let p = of_column[u(rows[u(row_ptr[s])])];
                if p <= s {
                    return None;
                }
                parent[s] = Some(p);
                weight[p] += weight[s];
            }
            children[parent[s].unwrap_or(n_super)].push(s);
        }
        // the best two groups of children, the heavier ones placed first, each on the
        // lighter side
        let mut best: Option<(usize, [Vec<usize>; 2])> = None;
        let mut v = n_super; // the roots' common parent
        while let Some(&heaviest) = children[v].iter().max_by_key(|&&c| weight[c]) {
            let mut kids = children[v].clone();
            kids.sort_by_key(|&c| std::cmp::Reverse(weight[c]));
            let mut groups = [Vec::new(), Vec::new()];
            let mut sums = [0, 0];
            for c in kids {
                let g = usize::from(sums[1] < sums[0]);
                groups[g].push(c);
                sums[g] += weight[c];
            }
            let smaller = sums[0].min(sums[1]);
            if best.as_ref().is_none_or(|b| smaller > b.0) {
                best = Some((smaller, groups));
            }
            v = heaviest;
        }
        let (_, roots) = best.filter(|b| b.0 >= MIN_PART_VALUES)?;
        // each supernode's part and its subtree's root, parents before children
        let mut root = vec![NONE; n_super];
        let mut part = vec![NONE; n_super];
        for (p, group) in roots.iter().enumerate() {
            for &c in group {
                (root[c], part[c]) = (c, p);
            }
        }
        for s in (0..n_super).rev() {
            if let (NONE, Some(q)) = (root[s], parent[s]) {
                (root[s], part[s]) = (root[q], part[q]);
            }
        }
        let mut split = Split {
            of: vec![(NONE, 0, 0); n_super],
            ..Split::default()
        };
        let mut lens = [0, 0];
        let mut widest = [0, 0];
        for s in 0..n_super {
            let p = part[s];
            if p == NONE {
                continue;
            }
            // rows below the subtree's root belong to the part, the others lie above it
            let pattern = &rows[u(row_ptr[s])..u(row_ptr[s + 1])];
            let k = pattern.partition_point(|&r| u(r) < u(end[root[s]]));
            split.of[s] = (p, k, lens[p]);
            lens[p] += pattern.len() - k;
            widest[p] = widest[p].max(pattern.len());
            split.parts[p].push(s);
        }
        split.buffers = lens.map(|n| vec![0.0; n]);
        split.tmp = widest.map(|n| vec![0.0; n]);
        Some(split)
    }
}

/// Solves L D Lᵀ x = P b in place for one right-hand side with faer's supernodal factor `l`
/// and the fill-reducing permutation `perm` (forward, inverse), the two parts of `split` side
/// by side when it is given. `work` holds the permuted vector and a supernode's pattern values.
pub(crate) fn solve(
    sn: &SupernodalSymbolic,
    perm: Option<(&[u32], &[u32])>,
    l: &[f64],
    b: &mut [f64],
    work: &mut Vec<f64>,
    split: Option<&mut Split>,
) {
    let n = b.len();
    let n_super = sn.n_supernodes();
    let row_ptr = sn.col_ptr_for_row_idx();
    let widest = (0..n_super)
        .map(|s| u(row_ptr[s + 1]) - u(row_ptr[s]))
        .max()
        .unwrap_or(0);
    work.clear();
    work.resize(n + widest, 0.0);
    let (x, tmp) = work.split_at_mut(n);
    match perm {
        Some((fwd, _)) => x.iter_mut().zip(fwd).for_each(|(xi, &f)| *xi = b[u(f)]),
        None => x.copy_from_slice(b),
    }
    let node = |s: usize| Supernode::of(sn, l, s);
    match split {
        None => {
            // L y = b, D z = y, Lᵀ x = z
            (0..n_super).for_each(|s| node(s).forward_all(x, tmp));
            (0..n_super).for_each(|s| node(s).diagonal(x));
            (0..n_super)
                .rev()
                .for_each(|s| node(s).backward_all(x, tmp));
        }
        Some(split) => solve_split(x, tmp, &node, n_super, split),
    }
    match perm {
        Some((_, inv)) => b.iter_mut().zip(inv).for_each(|(bi, &v)| *bi = x[u(v)]),
        None => b.copy_from_slice(x),
    }
}

/// The vector the two parts' threads share: each writes only the columns of its own part's
/// supernodes, and reads those and, in the backward sweep, rows no thread writes then.
#[derive(Clone, Copy)]
struct Shared(*mut f64);
// SAFETY: see the type's documentation; the parts' supernodes have disjoint columns
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    /// Value i.
    /// # Safety
    /// i is in bounds and no other thread writes it meanwhile.
    unsafe fn get(self, i: usize) -> f64 {
        *self.0.add(i)
    }
    /// Subtracts t from value i.
    /// # Safety
    /// i is in bounds and no other thread touches it meanwhile.
    unsafe fn sub(self, i: usize, t: f64) {
        *self.0.add(i) -= t;
    }
    /// The columns of a supernode.
    /// # Safety
    /// They are in bounds and no other thread touches them meanwhile.
    #[allow(clippy::mut_from_ref)]
    unsafe fn columns(&self, sup: &Supernode) -> &mut [f64] {
        std::slice::from_raw_parts_mut(self.0.add(sup.start), sup.size)
    }
}

/// The three sweeps of [`solve`] with the parts of `split` side by side.
fn solve_split<'a>(
    x: &mut [f64],
    tmp: &mut [f64],
    node: &(dyn Fn(usize) -> Supernode<'a> + Sync),
    n_super: usize,
    split: &mut Split,
) {
    let Split {
        parts,
        of,
        buffers,
        tmp: part_tmp,
    } = split;
    let (parts, of) = (&*parts, &*of);
    // the parts' forward sweeps: rows inside a part updated there, the others kept
    {
        let shared = Shared(x.as_mut_ptr());
        let forward = |p: usize, buffer: &mut [f64], tmp: &mut [f64]| {
            for &s in &parts[p] {
                let sup = node(s);
                // SAFETY: the columns of this part's supernodes, which only this thread
                // touches during the sweep
                unsafe {
                    sup.forward(shared.columns(&sup), tmp);
                    let (_, k, at) = of[s];
                    for (&i, &t) in sup.pattern[..k].iter().zip(&tmp[..k]) {
                        shared.sub(u(i), t);
                    }
                    let kept = sup.pattern.len() - k;
                    buffer[at..at + kept].copy_from_slice(&tmp[k..k + kept]);
                }
            }
        };
        let ([b0, b1], [t0, t1]) = (&mut *buffers, &mut *part_tmp);
        spin::join(|| forward(0, b0, t0), || forward(1, b1, t1));
    }
    // the rest of the tree, and the parts' kept updates, in the supernodes' order
    for s in 0..n_super {
        let sup = node(s);
        match of[s] {
            (NONE, _, _) => sup.forward_all(x, tmp),
            (p, k, at) => {
                let kept = &buffers[p][at..at + sup.pattern.len() - k];
                for (&i, &t) in sup.pattern[k..].iter().zip(kept) {
                    x[u(i)] -= t;
                }
            }
        }
    }
    (0..n_super).for_each(|s| node(s).diagonal(x));
    // the backward sweep: the rest of the tree first, then the parts, which read the rows
    // above them, final by then
    for s in (0..n_super).rev().filter(|&s| of[s].0 == NONE) {
        node(s).backward_all(x, tmp);
    }
    let shared = Shared(x.as_mut_ptr());
    let backward = |p: usize, tmp: &mut [f64]| {
        for &s in parts[p].iter().rev() {
            let sup = node(s);
            let tmp = &mut tmp[..sup.pattern.len()];
            // SAFETY: the pattern's rows are this part's columns or rows above the parts,
            // which no thread writes in this sweep; the supernode's columns are this part's
            unsafe {
                for (t, &i) in tmp.iter_mut().zip(sup.pattern) {
                    *t = shared.get(u(i));
                }
                sup.backward(shared.columns(&sup), tmp);
            }
        }
    };
    let [t0, t1] = part_tmp;
    spin::join(|| backward(0, t0), || backward(1, t1));
}
