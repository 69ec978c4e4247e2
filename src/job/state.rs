//! The state of a run as one serialisable value: where the run stands (stage, step, the stage
//! driver's position), the nodal values, the recorder's bookkeeping and everything recorded so far.
//! Checkpoints are this value written to a file; a run continues from it bit for bit.

use super::plan::ResponseMethod;
use crate::solve::stepping::RampPosition;
pub use crate::time::integrator::FactorPoint;
pub use crate::time::stage::DynamicResume;
use serde::{Deserialize, Serialize};

/// Energies of a state (J), as in `history.csv`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Energies {
    pub kinetic: f64,
    pub stored: f64,
    pub electric: f64,
    pub gravity: f64,
    pub dissipated: f64,
    /// Residual of the energy balance (see `docs/theory.md`).
    pub energy_error: f64,
}

/// One accepted step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Time (s); pseudo-time in static stages.
    pub time: f64,
    pub stage: String,
    /// Step number within the stage (0: the state the stage starts from).
    pub step: usize,
    /// Largest electrode voltage (by magnitude, V).
    pub voltage: f64,
    pub newton_iterations: usize,
    /// Step size (s; the pseudo-time increment in static stages).
    pub dt: f64,
    pub energies: Energies,
    /// Probe values in plan order.
    pub probes: Vec<f64>,
    /// Largest spatial electric field magnitude at a quadrature point (V/m).
    pub max_electric_field: f64,
    /// Per electrode (plan order): voltage, charge, current, power, source energy, resistor loss
    /// (`probes::electrode_values`); empty in older checkpoints.
    #[serde(default)]
    pub electrodes: Vec<[f64; 6]>,
}

/// A converged point of a continuation stage.
#[derive(Debug, Clone, PartialEq)]
pub struct PathRecord {
    pub stage: String,
    /// 1 for the first point after the stage's start.
    pub point: usize,
    pub load_factor: f64,
    /// The stage's parameter (V, C or Pa; `PathParameter::column`).
    pub parameter: f64,
    /// Arc length from the stage's start (scaled unknowns).
    pub arc_length: f64,
    /// Negative pivots of the tangent at fixed load, and how many a stable state has (`None`
    /// when the solver cannot tell).
    pub negative_pivots: Option<(usize, usize)>,
    /// Stable under control of the parameter (no more negative pivots than a stable state).
    pub stable: bool,
    /// Probe values, in plan order.
    pub probes: Vec<f64>,
}

/// A limit point of the parameter located on a continuation path.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitRecord {
    pub stage: String,
    /// A maximum of the parameter (else a minimum).
    pub maximum: bool,
    pub load_factor: f64,
    pub parameter: f64,
    /// Probe values at the interpolated state, in plan order (rate probes read 0).
    pub probes: Vec<f64>,
}

/// The first loss of stability against a circumferential harmonic n ≥ 1 found in a static or
/// quasi-static stage (`stability_harmonics`), located between two load factors that differ by
/// at most twice the ramp's smallest increment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstabilityRecord {
    pub stage: String,
    /// The harmonic whose tangent first has more negative pivots than potential unknowns (the
    /// one with the most negative eigenvalue when several do at once).
    pub harmonic: u32,
    /// The last stable and the first unstable load factor.
    pub stable_load_factor: f64,
    pub load_factor: f64,
    /// The run's time (s) at the first unstable state.
    pub time: f64,
    /// Each prescribed electrode's voltage (V) there, by name.
    pub voltages: Vec<(String, f64)>,
    /// The harmonics 1…N that were unstable there.
    pub unstable: Vec<u32>,
    /// The axial (z) share of the critical mode's displacement, Σ u_z² / Σ |u|² over the nodes:
    /// near 1 for a flat membrane's out-of-plane wrinkles, near 0 for an in-plane mode.
    pub axial_share: f64,
    /// Whether the run stopped at the last stable state (else it went on).
    pub stopped: bool,
}

/// What a finished stage reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageSummary {
    pub name: String,
    pub kind: String,
    pub steps: usize,
    pub newton_iterations: usize,
    pub wall_s: f64,
    pub converged: bool,
    /// Natural frequencies (Hz) found by a `modes` stage (empty for other kinds).
    #[serde(default)]
    pub modes_hz: Vec<f64>,
    /// The circumferential harmonic of each of `modes_hz` (0 but for an axisymmetric model's
    /// `harmonic`).
    #[serde(default)]
    pub modes_harmonic: Vec<u32>,
    /// The first loss of stability against a harmonic n ≥ 1 (`stability_harmonics`).
    #[serde(default)]
    pub instability: Option<InstabilityRecord>,
    /// The linear solvers' work (static and dynamic stages; a resumed static stage's from its
    /// checkpoint on; zero for modes and frequency-response stages).
    #[serde(default)]
    pub linear: crate::solve::linear::SolverStats,
}

/// Where a stage stood.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum StagePosition {
    /// A static stage: the load ramp's position and the state the ramp started from (its
    /// prescribed values at load factor 0).
    Static {
        ramp: RampPosition,
        stage_start: Vec<f64>,
        /// Load factor of the last recorded step (for the pseudo-time increment).
        last_load: f64,
    },
    /// A dynamic stage at stage time `t`, and where its driver stands (next step size, Newton
    /// iterations, last attempted step, where the reused matrices were factored).
    Dynamic { t: f64, driver: DynamicResume },
}

/// Energy bookkeeping of the run's recorder.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RecorderState {
    pub prev_reactions: Vec<f64>,
    pub prev_state: Vec<f64>,
    pub boundary_work: f64,
    pub initial_potential: Option<f64>,
    pub external_factor: f64,
    pub prev_factor: f64,
    pub prev_external: Vec<f64>,
    pub load_change_work: f64,
    pub reference: Vec<f64>,
    pub broken_down: Vec<bool>,
    pub warnings: Vec<String>,
    /// Per electrode: circuit source energy and resistor loss (J); empty in older checkpoints.
    #[serde(default)]
    pub circuit_energy: Vec<(f64, f64)>,
    /// The fraction of each pressure at the previous record; empty in older checkpoints.
    #[serde(default)]
    pub prev_pressure: Vec<f64>,
}

/// Everything needed to continue a run bit for bit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// Accepted steps of the stages so far (pre-stretch steps excluded).
    pub accepted: usize,
    /// Index of the stage in progress and the global time at its start.
    pub stage: usize,
    pub stage_time: f64,
    /// Step number of the last recorded step within the stage.
    pub step_no: usize,
    /// Pre-stretch steps and iterations recorded under the first stage.
    pub first_step: usize,
    pub prestretch_iterations: usize,
    pub position: StagePosition,
    /// State q, velocity, acceleration (4 per node).
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    /// Committed internal variables of the material points (empty for elastic materials).
    pub points: Vec<f64>,
    /// Energy dissipated so far (J, of the modelled part).
    pub dissipated: f64,
    /// The model's dead-load factor at the stage start.
    pub dead_load_start: f64,
    /// The fraction of each pressure's value at the stage start; empty in older checkpoints.
    #[serde(default)]
    pub pressure_start: Vec<f64>,
    pub recorder: RecorderState,
    /// Summaries of the completed stages and the run's warnings so far.
    pub stages: Vec<StageSummary>,
    pub warnings: Vec<String>,
    /// Every recorded step so far (the rows of `history.csv`).
    pub records: Vec<StepRecord>,
    /// Wall time spent before this state was taken (s).
    pub wall_s: f64,
    /// The state of each electrode's controller, in the order of the plan's electrodes that
    /// have one.
    #[serde(default)]
    pub controllers: Vec<super::controller::ControllerState>,
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub converged: bool,
    pub error: Option<String>,
    pub stages: Vec<StageSummary>,
    pub wall_s: f64,
    pub dofs: usize,
    pub warnings: Vec<String>,
    /// The run stopped because a stop was requested (SIGINT/SIGTERM).
    pub interrupted: bool,
}

/// The complex response of the probes per volt at each frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct FrequencyResponse {
    pub electrode: String,
    /// DC voltage of the driven electrode (V).
    pub bias: f64,
    pub frequencies: Vec<f64>,
    /// Per probe: its name and (real, imaginary) part per volt at each frequency.
    pub probes: Vec<(String, Vec<(f64, f64)>)>,
    pub method: ResponseMethod,
    /// How the linear systems were solved, for the run's report.
    pub solved_by: String,
    /// Set when the drive reaches no motion to first order (zero bias).
    pub warning: Option<String>,
}
