//! How the processes that divide a problem's unknowns hold and exchange their parts of a vector.

use std::sync::Arc;

/// Sums a vector over the processes in place, every process receiving the same bits.
pub type SumOverProcesses = Box<dyn Fn(&mut [f64]) -> Result<(), String> + Send + Sync>;

/// A rank's equations in the whole problem's numbering.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LocalEquations {
    /// This rank.
    pub rank: usize,
    /// The global number of each of the rank's equations (in the contiguous numbering).
    pub global: Vec<usize>,
    /// Whether the rank owns each of its equations.
    pub owned: Vec<bool>,
    /// The first global number of each rank, and the number of equations at the end.
    pub start: Vec<usize>,
    /// The row of each of the rank's equations among whole nodes of four rows: every node that
    /// is the lowest node of an equation takes four consecutive rows (ux, uy, uz, Φ), rank after
    /// rank, each rank's nodes ascending; an equation sits in its lowest node's block at its
    /// field, and a node's held unknowns are padding. The layout of a node-blocked distributed
    /// matrix (block size 4), whose multigrid aggregates whole nodes.
    pub rows: Vec<usize>,
    /// The first row of each rank, and the number of rows at the end.
    pub row_start: Vec<usize>,
}

impl LocalEquations {
    /// The number of equations this rank owns.
    pub fn n_owned(&self) -> usize {
        self.owned.iter().filter(|&&o| o).count()
    }

    /// The number of equations of the whole problem.
    pub fn n_global(&self) -> usize {
        self.start.last().copied().unwrap_or(0)
    }

    /// The index of each local equation among the rank's owned ones (its global number less
    /// the rank's first), `None` for a ghost.
    pub fn slots(&self) -> Vec<Option<usize>> {
        let first = self.start[self.rank];
        self.global
            .iter()
            .zip(&self.owned)
            .map(|(&g, &o)| o.then(|| g - first))
            .collect()
    }
}

/// How the ranks that divide a problem's unknowns exchange their parts of a vector. Every call
/// is collective: every rank makes it at the same point.
pub trait Exchange: Send + Sync {
    /// `local` holds this rank's values at its equations (owned and ghosts); on return each
    /// owned entry holds the sum of every rank's value at that equation (ghost entries are then
    /// unspecified).
    fn add_to_owners(&self, local: &mut [f64]) -> Result<(), String>;
    /// `local`'s owned entries given, its ghost entries are set to their owners' values.
    fn to_ghosts(&self, local: &mut [f64]) -> Result<(), String>;
    /// Sums `values` over the ranks, every rank receiving the same bits.
    fn sum(&self, values: &mut [f64]) -> Result<(), String>;
}

/// An [`Exchange`] through a sum over the ranks of vectors of the whole problem's length: simple
/// and exact, but each rank moves the whole problem's length at every exchange (a reference for
/// tests, and for ranks on one machine; a distributed run exchanges with its neighbours only).
pub struct SumExchange {
    equations: Arc<LocalEquations>,
    sum: SumOverProcesses,
}

impl SumExchange {
    /// The exchange of the rank whose equations are `equations`, through `sum`.
    pub fn new(equations: Arc<LocalEquations>, sum: SumOverProcesses) -> Self {
        SumExchange { equations, sum }
    }

    /// Every rank's entries of `local` (those `keep` keeps) summed at their global numbers.
    fn whole(&self, local: &[f64], keep: impl Fn(usize) -> bool) -> Result<Vec<f64>, String> {
        let mut whole = vec![0.0; self.equations.n_global()];
        for (e, &g) in self.equations.global.iter().enumerate() {
            if keep(e) {
                whole[g] += local[e];
            }
        }
        (self.sum)(&mut whole)?;
        Ok(whole)
    }
}

impl Exchange for SumExchange {
    fn add_to_owners(&self, local: &mut [f64]) -> Result<(), String> {
        let whole = self.whole(local, |_| true)?;
        for (e, &g) in self.equations.global.iter().enumerate() {
            local[e] = whole[g];
        }
        Ok(())
    }

    fn to_ghosts(&self, local: &mut [f64]) -> Result<(), String> {
        let owned = &self.equations.owned;
        let whole = self.whole(local, |e| owned[e])?;
        for (e, &g) in self.equations.global.iter().enumerate() {
            local[e] = whole[g];
        }
        Ok(())
    }

    fn sum(&self, values: &mut [f64]) -> Result<(), String> {
        (self.sum)(values)
    }
}
