//! What a nonlinear solver sees of a problem: residual and tangent over the free unknowns at a
//! state the problem owns. Newton, load stepping and the time integrators work on these traits
//! and know nothing of elements.

use super::csr::CsrMatrix;
use super::exchange::LocalEquations;

/// One extra scalar unknown μ of a system, closed by one scalar equation g(x, μ) = 0: Newton
/// solves the bordered system [K b; cᵀ 0] [δx; δμ] = −[r; g] (a pressure held at the value that
/// gives a prescribed volume, with μ the pressure and g the volume's error).
///
/// g = m − (m₀ + s (m₁ − m₀)): a measure m of the state (the volume) against its target, reached
/// linearly in the load factor s from the measure m₀ at the stage's start. m and m₀ are sums
/// over the mesh (over faces), so that each process of a divided problem holds its share of
/// them and the whole problem's sum is theirs.
#[derive(Debug, Clone)]
pub struct Border {
    /// ∂r/∂μ over the free unknowns.
    pub b: Vec<f64>,
    /// ∂g/∂x over the free unknowns.
    pub c: Vec<f64>,
    /// m at the current state and m₀ at the stage's start (this process's shares when the
    /// unknowns are divided).
    pub measure: f64,
    pub start: f64,
    /// m₁, the target at load factor 1, and the load factor s.
    pub end: f64,
    pub load: f64,
    /// |g| at or below this fraction of max(|m₀|, |m₁|) counts as satisfied.
    pub rtol: f64,
}

impl Border {
    /// g at the current state.
    pub fn g(&self) -> f64 {
        self.measure - (self.start + self.load * (self.end - self.start))
    }

    /// |g| at or below which the equation counts as satisfied.
    pub fn tol(&self) -> f64 {
        self.rtol * self.start.abs().max(self.end.abs())
    }
}

/// Where each free unknown of a system sits in the mesh: what a block preconditioner needs to
/// split the tangent into its displacement and potential blocks and to build the displacement
/// block's rigid-body modes.
#[derive(Debug, Clone, PartialEq)]
pub struct DofLayout {
    /// Per free unknown: its node (the first node of a tie) ...
    pub node: Vec<usize>,
    /// ... and its field: 0, 1, 2 the displacement components, 3 the potential.
    pub field: Vec<u8>,
    /// Reference coordinates of every node (m).
    pub coords: Vec<[f64; 3]>,
    /// True for the meridian plane of an axisymmetric model (components r, z): its only rigid
    /// motion is the axial translation.
    pub axisymmetric: bool,
    /// Whether the cells are shared between processes: the tangent is then this process's part,
    /// with a pattern of its own, and a distributed solver sums every entry of every process's
    /// part (otherwise the tangent is whole on every process).
    pub shared: bool,
    /// With shared cells, the unknowns whose equations take this process's non-cell terms (each
    /// unknown is one process's): a distributed solver gives those rows to this process, so that
    /// most of its cells' entries stay on it.
    pub owned: Option<std::sync::Arc<Vec<bool>>>,
    /// With the unknowns divided between the processes (each holding the vectors' entries of
    /// the equations it owns, in their global order): this process's equations in the whole
    /// problem. The tangent is then this process's part over its own equations (owned and
    /// ghosts), to be summed at their global numbers.
    pub equations: Option<std::sync::Arc<LocalEquations>>,
}

/// A nonlinear system R(x) = 0 with a symmetric tangent.
pub trait NonlinearSystem {
    /// Number of unknowns.
    fn n(&self) -> usize;
    /// Residual at the current state, and the tangent when `k` is given.
    fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String>;
    /// The tangent of [`NonlinearSystem::evaluate`] alone (a system may skip work that only
    /// its residual needs).
    fn jacobian(&mut self, k: &mut CsrMatrix) -> Result<(), String> {
        let mut r = vec![0.0; self.n()];
        self.evaluate(&mut r, Some(k))
    }
    /// x ← x + α·dx.
    fn increment(&mut self, dx: &[f64], alpha: f64);
    /// A copy of the state, to come back to.
    fn snapshot(&self) -> Vec<f64>;
    /// Returns to a snapshot.
    fn restore(&mut self, s: &[f64]);
    /// A zeroed tangent with the system's pattern.
    fn new_matrix(&self) -> CsrMatrix;
    /// Negative pivots of a stable state (the count of free potential unknowns).
    fn expected_negative_pivots(&self) -> usize;
    /// Absolute residual norm below which the state is converged whatever the first residual.
    fn residual_floor(&self) -> f64;
    /// The factor the residual carries relative to a static residual of the same model (a time
    /// step's ½Δt or βΔt²; 1 by default): a floor computed for the static problem, such as the
    /// whole problem's on a rank's part, scales by it.
    fn residual_factor(&self) -> f64 {
        1.0
    }
    /// For each unknown, its field group (0: displacement, 1: potential), for the printed table.
    fn groups(&self) -> Vec<u8>;
    /// The largest change of an unknown for a difference of residuals that stands for the
    /// tangent's product with a vector, (R(x + hv) − R(x))/h: small against the unknowns' own
    /// scale, large enough that the residual's round-off does not swamp the difference;
    /// `None` when the tangent must be assembled (the default).
    fn difference_step(&self) -> Option<f64> {
        None
    }
    /// Whether this process assembles only its share of the cells (a distributed run): the
    /// tangent is then this process's part, which only a solver that sums the processes' parts
    /// can take ([`LinearSolver::sums_shared_entries`](crate::solve::linear::LinearSolver)).
    fn shares_cells(&self) -> bool {
        false
    }
    /// Where the unknowns sit (for block preconditioners); `None` when the system cannot tell.
    fn layout(&self) -> Option<DofLayout> {
        None
    }
    /// The solver has just factored the tangent of the current state: a system whose
    /// factorisation is reused (modified Newton) records here where that was, so that a resumed
    /// run can factor the same matrix again.
    fn factored(&mut self) {}
    /// The bordering unknown's column, row and equation at the current state (`None`: the
    /// system has none); an error when the processes could not combine their shares.
    fn border(&self) -> Result<Option<Border>, String> {
        Ok(None)
    }
    /// μ ← μ + δ (the snapshot holds μ).
    fn increment_border(&mut self, _delta: f64) {}
    /// Sums `values` over the processes when each holds only its own part of the unknowns
    /// (Newton's norms and its other decisions are then reductions over all of them, so that
    /// every process takes the same path); nothing to do when the unknowns are all here.
    fn sum_over_processes(&self, _values: &mut [f64]) -> Result<(), String> {
        Ok(())
    }
}

/// A nonlinear system driven by a load factor s ∈ [0, 1].
pub trait LoadedSystem: NonlinearSystem {
    /// Sets the prescribed values and loads for load factor `s`.
    fn set_load(&mut self, s: f64);
    /// The current state was accepted: commit what depends on the history (the material points'
    /// internal variables). A state that is not accepted is never committed. Returns whether a
    /// history was committed (the tangent at the state then changed).
    fn accept(&mut self) -> Result<bool, String> {
        Ok(false)
    }
}
