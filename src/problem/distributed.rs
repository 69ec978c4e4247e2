//! One rank's equations among those of the whole problem, for models built on a rank's part of
//! the mesh ([`crate::mesh::distribute::LocalMesh`]).
//!
//! A rank's model numbers its own free unknowns; a distributed vector or matrix numbers the
//! whole problem's. [`LocalEquations`] connects the two: the global number of each of the rank's
//! equations in a numbering where each rank owns one contiguous block (PETSc's ownership
//! ranges), and which of them the rank owns. An equation is owned by the owner of its lowest
//! node, the rule of the shared assembly's term equations, so a tied equation (a rigid pad's
//! translation, a charge-controlled electrode's potential) whose nodes lie on several ranks is
//! one row of one rank and a ghost of the others.
//!
//! What is summed over the ranks: the cell terms at the nodes they share. What a rank's model
//! must not hold twice: the terms that are not cell terms (point forces and charges, dashpots,
//! circuits) at a node another rank holds too; they belong to the owner of their equation.
//!
//! [`OwnedSystem`] is a rank's nonlinear system over the unknowns it owns, in their global order
//! (the rank's part of a distributed vector): it evaluates the rank's model, adds the ghosts'
//! contributions into their owners' entries, and hands the owners' updates to the ghosts, all
//! through an [`Exchange`]; Newton's norms are sums over the ranks. So Newton, the load ramp and
//! the linear solver's vectors hold only the rank's part of the problem.

use crate::algebra::csr::CsrMatrix;
use crate::algebra::exchange::{Exchange, LocalEquations};
use crate::algebra::system::{DofLayout, LoadedSystem, NonlinearSystem};
use crate::mesh::distribute::{LocalMesh, Numbering};
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS};
use std::sync::Arc;

/// The owner of each equation of `dofs`: the owner of its lowest node (`node_owner` per node).
pub fn equation_owners(dofs: &DofMap, node_owner: &[usize]) -> Vec<usize> {
    lowest_nodes(dofs).iter().map(|&n| node_owner[n]).collect()
}

/// The lowest node of every equation of `dofs` (a tie's equation spans several nodes).
fn lowest_nodes(dofs: &DofMap) -> Vec<usize> {
    let mut lowest = vec![usize::MAX; dofs.n_free];
    for (d, &e) in dofs.eq.iter().enumerate() {
        if e != CONSTRAINED {
            lowest[e] = lowest[e].min(d / FIELDS);
        }
    }
    lowest
}

/// A whole problem's node blocks of rows ([`node_blocks`]): made once, they serve every rank's
/// [`LocalEquations::in_blocks`] (rank 0 cuts every rank's part).
pub struct NodeBlocks {
    lowest: Vec<usize>,
    block: Vec<usize>,
    row_start: Vec<usize>,
}

impl NodeBlocks {
    /// The blocks of the equations of `whole`, numbered by `numbering`.
    pub fn new(whole: &DofMap, numbering: &Numbering) -> Self {
        let (lowest, block, row_start) = node_blocks(whole, numbering);
        NodeBlocks {
            lowest,
            block,
            row_start,
        }
    }
}

/// The lowest node of every equation of `whole`; the block of four rows of every node that is
/// the lowest node of an equation (`usize::MAX` for the others), the blocks rank after rank (a
/// node's rank: its equations' owner under `numbering`), ascending within a rank; and the first
/// row of each rank with the number of rows at the end.
fn node_blocks(whole: &DofMap, numbering: &Numbering) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let ranks = numbering.start.len().saturating_sub(1);
    let rank_of = |g: usize| numbering.start.partition_point(|&s| s <= g) - 1;
    let lowest = lowest_nodes(whole);
    let mut owner = vec![usize::MAX; whole.n_nodes];
    for (e, &n) in lowest.iter().enumerate() {
        owner[n] = rank_of(numbering.number[e]);
    }
    let nodes: Vec<usize> = (0..whole.n_nodes)
        .filter(|&n| owner[n] != usize::MAX)
        .collect();
    let owners: Vec<usize> = nodes.iter().map(|&n| owner[n]).collect();
    let blocks = Numbering::contiguous(&owners, ranks.max(1));
    let mut block = vec![usize::MAX; whole.n_nodes];
    for (&n, &b) in nodes.iter().zip(&blocks.number) {
        block[n] = b;
    }
    (
        lowest,
        block,
        blocks.start.iter().map(|&b| FIELDS * b).collect(),
    )
}

impl LocalEquations {
    /// The equations of the model on `local` (numbered by `local_dofs`) in the whole problem
    /// (numbered by `whole`, its equations renumbered by `numbering`, whose blocks say which
    /// rank owns each: see [`equation_owners`] and [`Numbering::contiguous`]). Fails
    /// when the two disagree: a dof free in one and held in the other, or two dofs of one local
    /// equation that are two equations of the whole problem (a tie or support that the rank's
    /// part of the sets does not reproduce).
    pub fn new(
        whole: &DofMap,
        numbering: &Numbering,
        local: &LocalMesh,
        local_dofs: &DofMap,
    ) -> Result<Self, String> {
        let blocks = NodeBlocks::new(whole, numbering);
        Self::in_blocks(&blocks, whole, numbering, local, local_dofs)
    }

    /// As [`LocalEquations::new`], with the whole problem's node `blocks` made beforehand.
    pub fn in_blocks(
        blocks: &NodeBlocks,
        whole: &DofMap,
        numbering: &Numbering,
        local: &LocalMesh,
        local_dofs: &DofMap,
    ) -> Result<Self, String> {
        let rank_of = |g: usize| numbering.start.partition_point(|&s| s <= g) - 1;
        let NodeBlocks {
            lowest,
            block,
            row_start,
        } = blocks;
        let mut global = vec![usize::MAX; local_dofs.n_free];
        let mut rows = vec![usize::MAX; local_dofs.n_free];
        for (d, &e) in local_dofs.eq.iter().enumerate() {
            let (node, field) = (local.nodes[d / FIELDS], d % FIELDS);
            let g = whole.eq[node * FIELDS + field];
            match (e == CONSTRAINED, g == CONSTRAINED) {
                (true, true) => continue,
                (false, false) => {}
                (held, _) => {
                    return Err(format!(
                        "rank {}: field {field} of node {node} is {} on this rank but {} in the \
                         whole problem",
                        local.rank,
                        if held { "held" } else { "free" },
                        if held { "free" } else { "held" },
                    ))
                }
            }
            rows[e] = FIELDS * block[lowest[g]] + field;
            let g = numbering.number[g];
            if global[e] == usize::MAX {
                global[e] = g;
            } else if global[e] != g {
                return Err(format!(
                    "rank {}: field {field} of node {node} shares a local equation with another \
                     node whose equation in the whole problem is another one",
                    local.rank
                ));
            }
        }
        let owned = global.iter().map(|&g| rank_of(g) == local.rank).collect();
        Ok(LocalEquations {
            rank: local.rank,
            global,
            owned,
            start: numbering.start.clone(),
            rows,
            row_start: row_start.clone(),
        })
    }
}

/// A rank's part of a nonlinear system whose unknowns the ranks divide: the system of the
/// rank's model (`local`, over its owned and ghost equations) seen over its owned unknowns only,
/// in their global order. Every method that Newton calls is collective.
pub struct OwnedSystem<S> {
    /// The system of the rank's model.
    pub local: S,
    equations: Arc<LocalEquations>,
    exchange: Arc<dyn Exchange>,
    /// Per local equation, its index among the owned ones.
    slots: Vec<Option<usize>>,
    n_owned: usize,
    floor: f64,
    negative: usize,
    /// A local vector to work in.
    work: Vec<f64>,
    /// An exchange that failed where no error could be returned (an increment): reported by
    /// the next evaluation.
    failed: Option<String>,
}

impl<S: NonlinearSystem> OwnedSystem<S> {
    /// The rank's part of the system whose rank's model has the system `local`, its equations
    /// `equations` in the whole problem, exchanging through `exchange`; `floor` is the whole
    /// problem's static residual floor (the same on every rank; a time step scales it by its
    /// [`NonlinearSystem::residual_factor`]). Collective. Fails on every rank when
    /// a rank owns no equation or its system does not fit its equations, or has a bordering
    /// unknown (not divided between the ranks yet).
    pub fn new(
        local: S,
        equations: Arc<LocalEquations>,
        exchange: Arc<dyn Exchange>,
        floor: f64,
    ) -> Result<Self, String> {
        let slots = equations.slots();
        let n_owned = equations.n_owned();
        let groups = local.groups();
        let problem = if local.n() != equations.global.len() {
            Some(format!(
                "rank {}: the system has {} unknowns for {} equations",
                equations.rank,
                local.n(),
                equations.global.len()
            ))
        } else if n_owned == 0 {
            Some(format!(
                "rank {} owns no unknown: the problem is too small for this many ranks",
                equations.rank
            ))
        } else {
            None
        };
        let owned_potentials = slots
            .iter()
            .zip(&groups)
            .filter(|(s, &g)| s.is_some() && g == 1)
            .count();
        let mut counts = [problem.is_some() as u8 as f64, owned_potentials as f64];
        exchange.sum(&mut counts)?;
        if let Some(p) = problem {
            return Err(p);
        }
        if counts[0] > 0.0 {
            return Err("the system does not fit its equations on another rank".into());
        }
        Ok(OwnedSystem {
            work: vec![0.0; local.n()],
            local,
            equations,
            exchange,
            slots,
            n_owned,
            floor,
            negative: counts[1] as usize,
            failed: None,
        })
    }

    /// The rank's equations in the whole problem.
    pub fn equations(&self) -> &Arc<LocalEquations> {
        &self.equations
    }

    fn agree<T>(&self, outcome: Result<T, String>) -> Result<T, String> {
        agree(self.exchange.as_ref(), outcome)
    }
}

/// Whether any rank's `outcome` failed (collective): this rank's error, or one naming the other
/// ranks, so that every rank takes the same path.
pub fn agree<T>(exchange: &dyn Exchange, outcome: Result<T, String>) -> Result<T, String> {
    let mut failed = [outcome.is_err() as u8 as f64];
    exchange.sum(&mut failed)?;
    match outcome {
        Err(e) => Err(e),
        Ok(_) if failed[0] > 0.0 => Err(format!(
            "the evaluation failed on {} other rank(s) (the message is on those ranks)",
            failed[0]
        )),
        ok => ok,
    }
}

/// How the ranks divide the unknowns of one kind of problem (a plan's stages', its
/// pre-stretch's, or the electrostatic projection's of its dynamic stages).
pub struct Division {
    /// The rank's equations in the whole problem.
    pub equations: Arc<LocalEquations>,
    /// How the ranks exchange their parts of vectors (collective calls).
    pub exchange: Arc<dyn Exchange>,
    /// The whole problem's static residual floor (N).
    pub floor: f64,
}

/// A nonlinear system of the whole problem, or of a rank's part seen over its owned unknowns
/// ([`OwnedSystem`]): one type for drivers that run either way.
pub enum Held<S> {
    Whole(S),
    Owned(OwnedSystem<S>),
}

impl<S: NonlinearSystem> Held<S> {
    /// `system` whole, or over the rank's owned unknowns of `part` (collective; see
    /// [`OwnedSystem::new`]).
    pub fn new(system: S, part: Option<&Division>) -> Result<Self, String> {
        Ok(match part {
            None => Held::Whole(system),
            Some(d) => Held::Owned(OwnedSystem::new(
                system,
                Arc::clone(&d.equations),
                Arc::clone(&d.exchange),
                d.floor,
            )?),
        })
    }

    /// The system of the whole problem or of the rank's model.
    pub fn inner(&self) -> &S {
        match self {
            Held::Whole(s) => s,
            Held::Owned(o) => &o.local,
        }
    }

    /// [`Held::inner`], to change its state between solves.
    pub fn inner_mut(&mut self) -> &mut S {
        match self {
            Held::Whole(s) => s,
            Held::Owned(o) => &mut o.local,
        }
    }

    /// The system Newton solves.
    pub fn system(&mut self) -> &mut dyn NonlinearSystem {
        match self {
            Held::Whole(s) => s,
            Held::Owned(o) => o,
        }
    }

    /// [`agree`] over the ranks of a part; `outcome` itself for the whole problem.
    pub fn agree<T>(&self, outcome: Result<T, String>) -> Result<T, String> {
        match self {
            Held::Whole(_) => outcome,
            Held::Owned(o) => o.agree(outcome),
        }
    }

    /// The system of the whole problem or of the rank's model, given back.
    pub fn into_inner(self) -> S {
        match self {
            Held::Whole(s) => s,
            Held::Owned(o) => o.local,
        }
    }
}

/// `Held::Whole(s)` or `Held::Owned(o)`: `$body` with `$s` the system either is.
macro_rules! either {
    ($held:expr, $s:ident => $body:expr) => {
        match $held {
            Held::Whole($s) => $body,
            Held::Owned($s) => $body,
        }
    };
}

/// A held system is the system it holds, whole or over the rank's owned unknowns: drivers that
/// hand the system back to their caller (a path's observer) take it as it is.
impl<S: NonlinearSystem> NonlinearSystem for Held<S> {
    fn n(&self) -> usize {
        either!(self, s => s.n())
    }
    fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
        either!(self, s => s.evaluate(r, k))
    }
    fn increment(&mut self, dx: &[f64], alpha: f64) {
        either!(self, s => s.increment(dx, alpha))
    }
    fn snapshot(&self) -> Vec<f64> {
        either!(self, s => s.snapshot())
    }
    fn restore(&mut self, snapshot: &[f64]) {
        either!(self, s => s.restore(snapshot))
    }
    fn new_matrix(&self) -> CsrMatrix {
        either!(self, s => s.new_matrix())
    }
    fn expected_negative_pivots(&self) -> usize {
        either!(self, s => s.expected_negative_pivots())
    }
    fn residual_floor(&self) -> f64 {
        either!(self, s => s.residual_floor())
    }
    fn residual_factor(&self) -> f64 {
        either!(self, s => s.residual_factor())
    }
    fn groups(&self) -> Vec<u8> {
        either!(self, s => s.groups())
    }
    fn difference_step(&self) -> Option<f64> {
        either!(self, s => s.difference_step())
    }
    fn shares_cells(&self) -> bool {
        either!(self, s => s.shares_cells())
    }
    fn layout(&self) -> Option<DofLayout> {
        either!(self, s => s.layout())
    }
    fn factored(&mut self) {
        either!(self, s => s.factored())
    }
    fn border(&self) -> Result<Option<crate::algebra::system::Border>, String> {
        either!(self, s => s.border())
    }
    fn increment_border(&mut self, delta: f64) {
        either!(self, s => s.increment_border(delta))
    }
    fn sum_over_processes(&self, values: &mut [f64]) -> Result<(), String> {
        either!(self, s => s.sum_over_processes(values))
    }
}

impl<S: LoadedSystem> LoadedSystem for Held<S> {
    fn set_load(&mut self, load: f64) {
        either!(self, s => s.set_load(load))
    }
    fn accept(&mut self) -> Result<bool, String> {
        either!(self, s => s.accept())
    }
}

impl<S: NonlinearSystem> NonlinearSystem for OwnedSystem<S> {
    fn n(&self) -> usize {
        self.n_owned
    }

    fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
        let mut work = std::mem::take(&mut self.work);
        let outcome = match self.failed.take() {
            Some(e) => Err(e),
            None => self.local.evaluate(&mut work, k),
        };
        let outcome = self
            .agree(outcome)
            .and_then(|()| self.exchange.add_to_owners(&mut work));
        if outcome.is_ok() {
            for (e, slot) in self.slots.iter().enumerate() {
                if let Some(i) = *slot {
                    r[i] = work[e];
                }
            }
        }
        self.work = work;
        outcome
    }

    fn increment(&mut self, dx: &[f64], alpha: f64) {
        let mut work = std::mem::take(&mut self.work);
        for (e, slot) in self.slots.iter().enumerate() {
            work[e] = slot.map_or(0.0, |i| dx[i]);
        }
        match self.exchange.to_ghosts(&mut work) {
            Ok(()) => self.local.increment(&work, alpha),
            Err(e) => self.failed = Some(e),
        }
        self.work = work;
    }

    fn snapshot(&self) -> Vec<f64> {
        self.local.snapshot()
    }

    fn restore(&mut self, s: &[f64]) {
        self.local.restore(s)
    }

    fn new_matrix(&self) -> CsrMatrix {
        self.local.new_matrix()
    }

    fn expected_negative_pivots(&self) -> usize {
        self.negative
    }

    fn residual_floor(&self) -> f64 {
        self.floor * self.local.residual_factor()
    }

    fn residual_factor(&self) -> f64 {
        self.local.residual_factor()
    }

    fn groups(&self) -> Vec<u8> {
        let mut groups = vec![0; self.n_owned];
        for (g, slot) in self.local.groups().into_iter().zip(&self.slots) {
            if let Some(i) = *slot {
                groups[i] = g;
            }
        }
        groups
    }

    fn shares_cells(&self) -> bool {
        true
    }

    fn layout(&self) -> Option<DofLayout> {
        let mut layout = self.local.layout()?;
        layout.shared = true;
        layout.equations = Some(Arc::clone(&self.equations));
        Some(layout)
    }

    fn factored(&mut self) {
        self.local.factored()
    }

    fn sum_over_processes(&self, values: &mut [f64]) -> Result<(), String> {
        self.exchange.sum(values)
    }

    /// The rank's border over its owned unknowns: its column and row summed into their owners'
    /// entries, the measure's shares summed over the ranks (collective).
    fn border(&self) -> Result<Option<crate::algebra::system::Border>, String> {
        let Some(local) = self.local.border()? else {
            return Ok(None);
        };
        let owned = |mut v: Vec<f64>| -> Result<Vec<f64>, String> {
            self.exchange.add_to_owners(&mut v)?;
            let mut out = vec![0.0; self.n_owned];
            for (e, slot) in self.slots.iter().enumerate() {
                if let Some(i) = *slot {
                    out[i] = v[e];
                }
            }
            Ok(out)
        };
        let mut shares = [local.measure, local.start];
        self.exchange.sum(&mut shares)?;
        Ok(Some(crate::algebra::system::Border {
            b: owned(local.b)?,
            c: owned(local.c)?,
            measure: shares[0],
            start: shares[1],
            ..local
        }))
    }

    fn increment_border(&mut self, delta: f64) {
        self.local.increment_border(delta)
    }
}

impl<S: LoadedSystem> LoadedSystem for OwnedSystem<S> {
    fn set_load(&mut self, s: f64) {
        self.local.set_load(s)
    }

    fn accept(&mut self) -> Result<bool, String> {
        let outcome = self.local.accept();
        let committed = matches!(outcome, Ok(true));
        let outcome = self.agree(outcome)?;
        let mut any = [committed as u8 as f64];
        self.exchange.sum(&mut any)?;
        Ok(outcome || any[0] > 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algebra::exchange::{SumExchange, SumOverProcesses};
    use crate::algebra::system::NonlinearSystem;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::partition::partition_cells;
    use crate::mesh::{ElementKind, Mesh};
    use crate::problem::assembly::{node_processes, on_threads};
    use crate::problem::dofs::Field;
    use crate::problem::examples::{film_on, tied_film, wavy_state, FILM_SIZE};
    use crate::problem::model::Model;
    use crate::problem::statics::StaticProblem;
    use crate::solve::linear::{Inertia, LinearSolver, LinearSolverError};
    use crate::solve::newton::{newton, NewtonSettings};

    /// The film on `mesh`, with its top face's displacement tied in z when `tied` (as a rigid
    /// pad holds it), so that one equation spans the ranks.
    fn film(mesh: Mesh, tied: bool) -> Model {
        if tied {
            tied_film(mesh, 1000.0).unwrap()
        } else {
            film_on(mesh, 1000.0).unwrap()
        }
    }

    /// Residual and dense tangent of `model` at `state` over its free unknowns.
    fn evaluate(model: &Model, state: Vec<f64>) -> (DofMap, Vec<f64>, Vec<Vec<f64>>) {
        let mut p = StaticProblem::new(model, Some(state));
        let mut k = p.new_matrix();
        let mut r = vec![0.0; p.n()];
        p.evaluate(&mut r, Some(&mut k)).unwrap();
        let mut dense = vec![vec![0.0; k.n]; k.n];
        for i in 0..k.n {
            for q in k.row_ptr[i]..k.row_ptr[i + 1] {
                dense[i][k.col_idx[q] as usize] += k.values[q];
            }
        }
        (p.dofs.clone(), r, dense)
    }

    /// The models that the ranks build on their parts of the mesh add up, at their global
    /// equations, to the whole model's residual and tangent; each equation is owned by one rank,
    /// and a rank's owned equations are its block of the contiguous numbering.
    #[test]
    fn the_ranks_models_add_up_to_the_whole_problem() {
        for tied in [false, true] {
            let mesh = box_mesh(FILM_SIZE, [6, 6, 3], ElementKind::Hex8);
            let whole_model = film(mesh.clone(), tied);
            let state = wavy_state(&whole_model, 0.0, 1e-5, 1000.0);
            let (dofs, r, k) = evaluate(&whole_model, state.clone());
            for ranks in [2, 3] {
                let part = partition_cells(&mesh, ranks, None);
                let node_owner = node_processes(&mesh, &dofs, &part, ranks);
                let owner = equation_owners(&dofs, &node_owner);
                let numbering = Numbering::contiguous(&owner, ranks);
                let n = dofs.n_free;
                let (mut r_sum, mut k_sum) = (vec![0.0; n], vec![vec![0.0; n]; n]);
                let mut owned_by = vec![0; n];
                for rank in 0..ranks {
                    let local = LocalMesh::of_rank(&mesh, &part, &node_owner, rank, ranks).unwrap();
                    let model = film(local.mesh.clone(), tied);
                    let (local_dofs, rl, kl) = evaluate(&model, local.gather_nodes(&state, FIELDS));
                    let eqs = LocalEquations::new(&dofs, &numbering, &local, &local_dofs).unwrap();
                    for (e, &g) in eqs.global.iter().enumerate() {
                        r_sum[g] += rl[e];
                        for (f, &h) in eqs.global.iter().enumerate() {
                            k_sum[g][h] += kl[e][f];
                        }
                        if eqs.owned[e] {
                            owned_by[g] += 1;
                            assert!((eqs.start[rank]..eqs.start[rank + 1]).contains(&g));
                        }
                    }
                    assert_eq!(eqs.n_owned(), eqs.start[rank + 1] - eqs.start[rank]);
                }
                assert!(
                    owned_by.iter().all(|&c| c == 1),
                    "{ranks} ranks: owned once"
                );
                let rs = r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                let ks = k.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
                for e in 0..n {
                    let g = numbering.number[e];
                    assert!(
                        (r_sum[g] - r[e]).abs() <= 1e-13 * rs,
                        "tied {tied}, {ranks} ranks, equation {e}: {} against {}",
                        r_sum[g],
                        r[e]
                    );
                    for f in 0..n {
                        let h = numbering.number[f];
                        assert!((k_sum[g][h] - k[e][f]).abs() <= 1e-13 * ks);
                    }
                }
            }
        }
    }

    /// A direct solver for ranks simulated by threads: the ranks' parts of the tangent summed
    /// into one dense matrix of the whole problem on every rank and factored by LU; each rank
    /// keeps its owned part of the solution.
    struct GatherSolver {
        sum: Arc<SumOverProcesses>,
        equations: Option<Arc<LocalEquations>>,
        lu: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    }

    impl LinearSolver for GatherSolver {
        fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
            let eq = self
                .equations
                .as_ref()
                .ok_or(LinearSolverError::NotFactored)?;
            let n = eq.n_global();
            let mut dense = vec![0.0; n * n];
            for i in 0..a.n {
                for q in a.row_ptr[i]..a.row_ptr[i + 1] {
                    dense[eq.global[i] * n + eq.global[a.col_idx[q] as usize]] += a.values[q];
                }
            }
            (self.sum)(&mut dense).map_err(LinearSolverError::Failed)?;
            self.lu = Some(nalgebra::DMatrix::from_row_slice(n, n, &dense).lu());
            Ok(None)
        }

        fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
            let (eq, lu) = match (&self.equations, &self.lu) {
                (Some(eq), Some(lu)) => (eq, lu),
                _ => return Err(LinearSolverError::NotFactored),
            };
            let first = eq.start[eq.rank];
            let mut whole = vec![0.0; eq.n_global()];
            whole[first..first + b.len()].copy_from_slice(b);
            (self.sum)(&mut whole).map_err(LinearSolverError::Failed)?;
            let x = lu
                .solve(&nalgebra::DVector::from_vec(whole))
                .ok_or(LinearSolverError::Singular(0))?;
            b.copy_from_slice(&x.as_slice()[first..first + b.len()]);
            Ok(())
        }

        fn name(&self) -> &'static str {
            "gather"
        }

        fn is_factored(&self) -> bool {
            self.lu.is_some()
        }

        fn sums_shared_entries(&self) -> bool {
            true
        }

        fn needs_layout(&self, _n: usize) -> bool {
            true
        }

        fn set_layout(&mut self, layout: DofLayout) {
            self.equations = layout.equations;
        }
    }

    /// Newton at load 1 on the whole of `whole` with the serial direct solver: the solved
    /// problem, Newton's report and the problem's residual floor.
    fn serial_newton<'m>(
        whole: &'m Model,
        settings: &NewtonSettings,
    ) -> (StaticProblem<'m>, crate::solve::newton::NewtonReport, f64) {
        let mut serial = StaticProblem::new(whole, None);
        serial.set_load(1.0);
        let floor = serial.residual_floor();
        let mut k = serial.new_matrix();
        let mut solver = crate::solve::linear::FaerLdlt::new();
        let report = newton(&mut serial, &mut solver, &mut k, settings).unwrap();
        (serial, report, floor)
    }

    /// Newton at load 1 on each of `ranks` simulated ranks, over its owned unknowns of the part of
    /// `whole` (whose free unknowns are numbered by `dofs`, with the residual floor `floor`) that
    /// it holds: per rank its part of the mesh, its final state, Newton's report and the
    /// pressures' fractions.
    fn newton_on_ranks(
        whole: &Model,
        dofs: &DofMap,
        floor: f64,
        ranks: usize,
        settings: &NewtonSettings,
    ) -> Vec<(
        LocalMesh,
        Vec<f64>,
        crate::solve::newton::NewtonReport,
        Vec<f64>,
    )> {
        let mesh = &whole.mesh;
        let part = partition_cells(mesh, ranks, None);
        let node_owner = node_processes(mesh, dofs, &part, ranks);
        let numbering = Numbering::contiguous(&equation_owners(dofs, &node_owner), ranks);
        on_threads(ranks, |rank, sum| {
            let sum = Arc::new(sum);
            let local = LocalMesh::of_rank(mesh, &part, &node_owner, rank, ranks).unwrap();
            let model = whole.part(&local).unwrap();
            let mut problem = StaticProblem::new(&model, None);
            problem.set_load(1.0);
            let eqs =
                Arc::new(LocalEquations::new(dofs, &numbering, &local, &problem.dofs).unwrap());
            let to_ranks = Arc::clone(&sum);
            let exchange =
                SumExchange::new(Arc::clone(&eqs), Box::new(move |v: &mut [f64]| to_ranks(v)));
            let mut system = OwnedSystem::new(problem, eqs, Arc::new(exchange), floor).unwrap();
            assert!(system.n() < dofs.n_free);
            let mut solver = GatherSolver {
                sum,
                equations: None,
                lu: None,
            };
            let mut k = system.new_matrix();
            let report = newton(&mut system, &mut solver, &mut k, settings).unwrap();
            let levels = system.local.pressure_fractions();
            (local, system.local.state.clone(), report, levels)
        })
    }

    /// The film at 20 kV solved by Newton on 2 and 3 simulated ranks, each holding the vectors
    /// of its owned unknowns only, reaches the serial solution to 1e-10 (of the largest
    /// displacement and potential), in the same number of iterations, with the same residuals
    /// to 1e-9 of the first (the last ones are round-off, which the ranks' sums change).
    #[test]
    fn newton_on_the_ranks_owned_unknowns_reaches_the_serial_solution() {
        let voltage = 20e3;
        let mesh = box_mesh(FILM_SIZE, [5, 5, 3], ElementKind::Hex8);
        let whole = film_on(mesh.clone(), voltage).unwrap();
        let settings = NewtonSettings {
            check_stability: false,
            ..NewtonSettings::default()
        };
        let (serial, report, floor) = serial_newton(&whole, &settings);
        assert!(report.iterations >= 3, "a nonlinear solve: {report:?}");
        let scale = |f: usize| {
            (0..mesh.n_nodes())
                .map(|n| serial.state[n * FIELDS + f].abs())
                .fold(0.0_f64, f64::max)
        };
        let (u_scale, phi_scale) = (scale(2), scale(3));
        for ranks in [2, 3] {
            let results = newton_on_ranks(&whole, &serial.dofs, floor, ranks, &settings);
            for (local, state, part_report, _) in results {
                assert_eq!(part_report.iterations, report.iterations, "{ranks} ranks");
                for (a, b) in part_report.residuals.iter().zip(&report.residuals) {
                    let tol = 1e-9 * report.residuals[0];
                    assert!((a - b).abs() <= tol, "{ranks} ranks: {a} against {b}");
                }
                for (l, &n) in local.nodes.iter().enumerate() {
                    for f in 0..FIELDS {
                        let (a, b) = (state[l * FIELDS + f], serial.state[n * FIELDS + f]);
                        let s = if f == 3 { phi_scale } else { u_scale };
                        assert!(
                            (a - b).abs() <= 1e-10 * s,
                            "{ranks} ranks, node {n}, field {f}: {a} against {b}"
                        );
                    }
                }
            }
        }
    }

    /// A volume-controlled pressure on the film's top face (the pressure an unknown of the whole
    /// problem, the bordered Newton step) on 2 and 3 simulated ranks, each holding its faces:
    /// the ranks' volume shares sum to the whole volume, the border's column and row to the
    /// whole ones, and Newton reaches the serial solution and pressure to 1e-10 in as many
    /// iterations.
    #[test]
    fn a_volume_controlled_pressure_on_the_ranks_owned_unknowns_reaches_the_serial_solution() {
        let mesh = box_mesh(FILM_SIZE, [4, 4, 2], ElementKind::Hex8);
        let mut whole = film_on(mesh.clone(), 5e3).unwrap();
        let top = mesh.face_sets["z1"].clone();
        let faces = crate::problem::pressure::surface(&mesh, &top);
        let start =
            crate::problem::pressure::enclosed_volume(&faces, &vec![0.0; mesh.n_nodes() * FIELDS]);
        let mut pressure = crate::problem::pressure::Pressure::new(faces, 1e4);
        // the top face's volume −⅓∮x·n da 2 % larger in magnitude: the top pushed down
        pressure.volume = Some(1.02 * start);
        whole.pressures.push(pressure);
        let settings = NewtonSettings {
            check_stability: false,
            ..NewtonSettings::default()
        };
        let (serial, report, floor) = serial_newton(&whole, &settings);
        let level = serial.pressure_fractions()[0];
        assert!(level.abs() > 1e-3, "the pressure holds the volume: {level}");
        let u_scale = serial
            .state
            .chunks(FIELDS)
            .map(|x| x[2].abs())
            .fold(0.0_f64, f64::max);
        for ranks in [2, 3] {
            let results = newton_on_ranks(&whole, &serial.dofs, floor, ranks, &settings);
            for (local, state, part_report, part_levels) in results {
                let part_level = part_levels[0];
                assert_eq!(part_report.iterations, report.iterations, "{ranks} ranks");
                assert!(
                    (part_level - level).abs() <= 1e-10 * level.abs(),
                    "{ranks} ranks: pressure {part_level} against {level}"
                );
                for (l, &n) in local.nodes.iter().enumerate() {
                    for f in 0..3 {
                        let (a, b) = (state[l * FIELDS + f], serial.state[n * FIELDS + f]);
                        assert!(
                            (a - b).abs() <= 1e-10 * u_scale,
                            "{ranks} ranks, node {n}, field {f}: {a} against {b}"
                        );
                    }
                }
            }
        }
    }

    /// A rank whose part of a tie is held while the whole tie is free (a support that the
    /// rank's sets reproduce differently) is refused, naming the node.
    #[test]
    fn a_rank_that_holds_what_the_whole_frees_is_refused() {
        let mesh = box_mesh(FILM_SIZE, [2, 1, 1], ElementKind::Hex8);
        let whole = film(mesh.clone(), false);
        let (dofs, _, _) = evaluate(&whole, vec![0.0; mesh.n_nodes() * FIELDS]);
        let part = vec![0, 1];
        let node_owner = node_processes(&mesh, &dofs, &part, 2);
        let owner = equation_owners(&dofs, &node_owner);
        let numbering = Numbering::contiguous(&owner, 2);
        let local = LocalMesh::of_rank(&mesh, &part, &node_owner, 1, 2).unwrap();
        let mut model = film(local.mesh.clone(), false);
        model.fix("z1", Field::Ux, 0.0).unwrap();
        let (local_dofs, _, _) = evaluate(&model, vec![0.0; local.nodes.len() * FIELDS]);
        let err = LocalEquations::new(&dofs, &numbering, &local, &local_dofs).unwrap_err();
        assert!(err.contains("held on this rank but free"), "{err}");
    }
}
