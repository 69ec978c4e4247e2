//! What a rank's plan knows of the whole problem and of the other ranks, and the collective
//! operations between the ranks that divide a plan.

pub use crate::problem::distributed::Division;

/// What a rank's plan knows of the whole problem and of the other ranks.
pub struct PlanPart {
    /// This rank and the number of ranks.
    pub rank: usize,
    pub ranks: usize,
    /// The unknowns of the stages' problems.
    pub stages: Division,
    /// The unknowns of the pre-stretch's problem (`None`: the plan has no pre-stretch).
    pub prestretch: Option<Division>,
    /// The unknowns of the dynamic stages' electrostatic projection, the potentials with every
    /// displacement held (`None`: the plan has no dynamic stage).
    pub projection: Option<Division>,
    /// The unknowns of the explicit scheme's velocity equation, the displacements with every
    /// potential held (`None`: the plan has no explicit dynamic stage).
    pub explicit: Option<Division>,
    /// The whole mesh's node and cell counts.
    pub whole_nodes: usize,
    pub whole_cells: usize,
    /// The global number of each local cell, and of each local node (owned, then ghosts).
    pub cells: Vec<usize>,
    pub nodes: Vec<usize>,
    /// Per electrode (plan order): the local node of its first node when this rank owns it.
    pub electrode_first: Vec<Option<usize>>,
    /// The whole plan's [`Plan::fingerprint`] (what its checkpoints are checked against).
    pub fingerprint: u64,
}

impl std::fmt::Debug for PlanPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlanPart")
            .field("rank", &self.rank)
            .field("ranks", &self.ranks)
            .field("owned equations", &self.stages.equations.n_owned())
            .field("whole_nodes", &self.whole_nodes)
            .finish_non_exhaustive()
    }
}

impl PlanPart {
    /// The largest of each entry of `v` over the ranks (collective; every rank receives the same
    /// values): each rank's values in its own slot of a sum, exact.
    pub fn max(&self, v: &mut [f64]) -> Result<(), String> {
        let all = self.gather(v)?;
        for (i, x) in v.iter_mut().enumerate() {
            *x = all.iter().map(|r| r[i]).fold(f64::NEG_INFINITY, f64::max);
        }
        Ok(())
    }

    /// Every rank's `v` (of one length on every rank), rank after rank (collective).
    pub fn gather(&self, v: &[f64]) -> Result<Vec<Vec<f64>>, String> {
        let k = v.len();
        let mut all = vec![0.0; k * self.ranks];
        all[self.rank * k..(self.rank + 1) * k].copy_from_slice(v);
        self.stages.exchange.sum(&mut all)?;
        Ok(all
            .chunks(k.max(1))
            .take(self.ranks)
            .map(<[f64]>::to_vec)
            .collect())
    }
}
