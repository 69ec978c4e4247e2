//! The plan of a run: the model, its electrodes and supports, the stages, probes and outputs —
//! everything a run needs, validated (built from a scenario by `io::build`).

use super::probes::Probe;
use crate::problem::model::Model;
use crate::solve::linear::SolverSettings;
use crate::time::mass::MassKind;
use crate::time::stage::Method;
use crate::waveform::Waveform;

/// An electrode of the plan.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Electrode {
    pub name: String,
    pub nodes: Vec<usize>,
    pub voltage: Waveform,
    /// Charge control: the electrode's total free charge (C, whole device) in stage time; its
    /// potential is then one unknown shared by its nodes and `voltage` is unused. `None`:
    /// voltage control.
    pub charge: Option<Waveform>,
    /// The charge enters through each stage's drive ([`crate::problem::drive::Drive::charges`]:
    /// a waveform that is not constant, or a control in some stage); otherwise a constant
    /// charge is one of the model's dead loads.
    #[serde(default)]
    pub charge_in_drive: bool,
    /// Circuit control: the series resistance (Ω, whole device) between the source `voltage`
    /// and the electrode, whose potential is then one unknown shared by its nodes. `None`: the
    /// electrode is at `voltage` (or under charge control).
    pub resistance: Option<f64>,
    /// A feedback controller that sets the voltage in the dynamic and quasi-static stages with
    /// the electrodes on (`voltage` applies in the other stages).
    #[serde(default)]
    pub controller: Option<super::controller::Controller>,
}

impl Electrode {
    /// Whether the stage prescribes the electrode's potential: voltage control, and circuits in
    /// static stages (their DC limit, no current: the electrode at the source's voltage).
    pub fn prescribed(&self, dynamic: bool) -> bool {
        self.charge.is_none() && !(dynamic && self.resistance.is_some())
    }
}

/// The kind of a stage.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum StageKind {
    /// Real time without inertia: `steps` equal steps over the duration, the electrodes at
    /// their waveforms' values at each step's stage time, materials relax.
    QuasiStatic { steps: usize },
    /// Load steps from the previous state to the targets at the end of the stage.
    Static { steps: usize },
    /// Time integration with nominal step `dt` (s).
    Dynamic {
        dt: f64,
        scheme: Method,
        mass: MassKind,
    },
    /// The natural modes about the state the previous stage left: the `count` modes nearest to
    /// `shift_hz` (Hz) of each circumferential harmonic of `harmonics` (`[0]`: the model's own
    /// modes; n ≥ 1 for axisymmetric models). Takes no time and changes no state.
    Modes {
        count: usize,
        shift_hz: f64,
        harmonics: Vec<u32>,
    },
    /// The frequency response of the probes to a small voltage on electrode `electrode` (plan
    /// index) about the state the previous stage left. Takes no time and changes no state.
    FrequencyResponse {
        electrode: usize,
        frequencies: Vec<f64>,
        method: ResponseMethod,
    },
    /// Arc-length continuation: a static stage whose load factor is an unknown, so that the
    /// path goes on through limit points. Its first step (and largest load step) is 1/`steps`.
    Continuation {
        steps: usize,
        parameter: PathParameter,
        target: PathTarget,
        max_points: usize,
    },
}

/// The load a continuation stage follows (all loads that change in the stage move with the
/// load factor; this one is reported as the path's abscissa and at its limit points).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PathParameter {
    /// The voltage (V) of electrode `electrode` (plan index).
    Voltage { electrode: usize },
    /// The charge (C, whole device) of a charge-controlled electrode.
    Charge { electrode: usize },
    /// The follower pressure (Pa) of `model.pressures[index]`.
    Pressure { index: usize },
    /// The dead loads (tractions, gravity, the weights of attached masses): the fraction of
    /// their full values applied, the load proportionality factor of Riks's method.
    Force,
}

impl PathParameter {
    /// Column name and SI unit of the parameter, e.g. (`voltage_top`, `V`).
    pub fn column(&self, plan: &Plan) -> (String, &'static str) {
        match self {
            PathParameter::Voltage { electrode } => {
                (format!("voltage_{}", plan.electrodes[*electrode].name), "V")
            }
            PathParameter::Charge { electrode } => {
                (format!("charge_{}", plan.electrodes[*electrode].name), "C")
            }
            PathParameter::Pressure { index } => (format!("pressure_{index}"), "Pa"),
            PathParameter::Force => ("dead_load_factor".into(), "-"),
        }
    }
}

/// Where a continuation stage ends.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PathTarget {
    /// At this load factor (1: the stage's targets), landed on exactly.
    Load(f64),
    /// Where the probe named `name` first reaches `value`.
    Probe { name: String, value: f64 },
    /// After `max_points` points.
    Points,
}

impl StageKind {
    /// Nominal number of steps of a stage of this kind lasting `duration`.
    pub fn nominal_steps(&self, duration: f64) -> usize {
        match self {
            StageKind::Static { steps }
            | StageKind::QuasiStatic { steps }
            | StageKind::Continuation { steps, .. } => *steps,
            StageKind::Dynamic { dt, .. } => (duration / dt - 1e-9).ceil().max(1.0) as usize,
            StageKind::Modes { .. } | StageKind::FrequencyResponse { .. } => 0,
        }
    }

    /// Whether the stage is a small-signal analysis about the current state (no steps, no time).
    pub fn is_linearised(&self) -> bool {
        matches!(
            self,
            StageKind::Modes { .. } | StageKind::FrequencyResponse { .. }
        )
    }
}

/// A stage of the plan.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Stage {
    pub name: String,
    pub kind: StageKind,
    /// Duration (s): pseudo-time of a static stage.
    pub duration: f64,
    /// Whether the electrodes follow their waveforms (else they are held at 0 V).
    pub electrodes_on: bool,
    /// The electrodes whose voltage this stage takes from a control (`[[controls]]`) instead
    /// of their waveform: the electrode's name and the table's knots (stage time in s, V).
    #[serde(default)]
    pub controls: Vec<(String, Vec<(f64, f64)>)>,
    /// A static or quasi-static stage of an axisymmetric model: the test of its states against
    /// circumferential harmonics (`None`: harmonic 0 only, the stage's own).
    #[serde(default)]
    pub stability: Option<HarmonicStability>,
}

/// The test of a stage's converged states against the circumferential harmonics 1…`harmonics`
/// with the electrodes held ([`crate::time::harmonic::harmonic_inertia`]); harmonic 0 is the
/// stage's own test of its tangent's inertia.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HarmonicStability {
    pub harmonics: u32,
    /// End the run at the last stable state (else report the loss and go on).
    pub stop: bool,
}

impl Stage {
    /// The waveform an electrode or circuit source with waveform `w` follows in this stage, in
    /// stage time (0 at the stage's start, as Abaqus' step time): `w`, or 0 V when the stage has
    /// its electrodes off.
    /// The waveform electrode `e` follows in this stage: its control's table when the stage
    /// controls it (and has its electrodes on), else [`Stage::waveform`] of its own.
    pub fn electrode_waveform(&self, e: &Electrode) -> crate::waveform::Waveform {
        match self.controls.iter().find(|(name, _)| *name == e.name) {
            Some((_, knots)) if self.electrodes_on => crate::waveform::Waveform::table(knots),
            _ => self.waveform(&e.voltage),
        }
    }

    /// The charge (C, whole device) of a charge-controlled electrode `e` in this stage: its
    /// control's table, or its waveform; `None` for the other electrodes.
    pub fn electrode_charge(&self, e: &Electrode) -> Option<crate::waveform::Waveform> {
        let w = e.charge.as_ref()?;
        Some(
            match self.controls.iter().find(|(name, _)| *name == e.name) {
                Some((_, knots)) => crate::waveform::Waveform::table(knots),
                None => w.clone(),
            },
        )
    }

    pub fn waveform(&self, w: &crate::waveform::Waveform) -> crate::waveform::Waveform {
        if self.electrodes_on {
            w.clone()
        } else {
            crate::waveform::Waveform::constant(0.0)
        }
    }
}

/// Output settings.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct OutputPlan {
    pub fields_every: usize,
    pub plots: bool,
    pub plot_format: String,
    /// How the arrays of the field files are written.
    pub fields_format: FieldFormat,
    /// The revolved 3-D view written beside every field file of an axisymmetric model (`None`:
    /// not written; always `None` for a 3-D model).
    pub revolve: Option<Revolve>,
}

/// How the meridian section of an axisymmetric model is swept about its axis for the revolved
/// view (`output.revolve_sector`, `output.revolve_wedges`). Output only: the solution never
/// reads it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Revolve {
    /// The swept angle in degrees, in (0, 360]; 360 closes the ring.
    pub sector_deg: f64,
    /// The wedges the sector is divided into (at least 1, each at most 120°).
    pub wedges: usize,
}

/// The encoding of the field files' arrays (`output.vtu_format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum FieldFormat {
    /// base64 of the raw values.
    #[default]
    Binary,
    /// base64 of zlib-compressed blocks.
    Compressed,
    /// Text.
    Ascii,
}

/// Everything needed to run a scenario.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Plan {
    pub name: String,
    /// As data without its materials ([`crate::problem::model::data`]): whoever reads a plan
    /// sets them.
    #[serde(with = "crate::problem::model::data")]
    pub model: Model,
    /// Displacement conditions (fixed for the whole run).
    pub supports: Vec<crate::problem::dofs::Dirichlet>,
    pub electrodes: Vec<Electrode>,
    pub stages: Vec<Stage>,
    pub probes: Vec<(String, Probe)>,
    pub output: OutputPlan,
    /// Mass density (kg/m³) of each material, in `model.materials` order.
    pub densities: Vec<f64>,
    /// Kelvin–Voigt viscosity (Pa·s) of each material.
    pub viscosities: Vec<f64>,
    /// Problems that do not stop the run (e.g. Drucker instability of a fit), for the summary.
    pub warnings: Vec<String>,
    /// Rigid regions with their attached masses (ties and weights are in `model`).
    pub rigid: Vec<Rigid>,
    /// Names of the materials, in `model.materials` order.
    pub material_names: Vec<String>,
    /// The resolved parameters of each material (a preset's values included), one line each.
    pub material_parameters: Vec<Vec<String>>,
    /// The pre-stretch phase that runs before the first stage, if any.
    pub prestretch: Option<Prestretch>,
    /// Copies of the meshed part that make the physical device (4 for a quarter disc or stack): global
    /// probes (charge, capacitance, reaction, energies) are multiplied by it.
    pub symmetry_factor: f64,
    /// Dielectric strength (V/m) of each material, if given.
    pub breakdown: Vec<Option<f64>>,
    /// Stop at the first step whose true field exceeds a material's strength.
    pub stop_at_breakdown: bool,
    /// The linear solver of every stage.
    pub solver: SolverSettings,
    /// Newton's settings for every nonlinear solve of the run: the stages, the pre-stretch and
    /// the small-signal base states.
    pub newton: crate::solve::newton::NewtonSettings,
    /// The step control of the static stages and the pre-stretch (its `steps` set per stage).
    pub step_control: crate::solve::stepping::StepControl,
    /// Per pressure of `model.pressures`, per stage: whether it acts in the stage (a static stage
    /// ramps it on or off, later stages hold it).
    pub pressure_stages: Vec<Vec<bool>>,
    /// Per pressure: the volume (m³, meshed part) it holds under volume control in the stages it
    /// acts in (its fraction of `value` is then an unknown), or `None` (pressure control).
    pub pressure_volumes: Vec<Option<f64>>,
    /// On a rank's part of a plan divided between MPI ranks ([`crate::job::part::messages`]):
    /// the whole problem and the other ranks. `None`: the plan is the whole problem.
    #[serde(skip)]
    pub part: Option<std::sync::Arc<super::rank::PlanPart>>,
}

impl Plan {
    /// The part of every cell when `ranks` processes share them: METIS's partition balancing
    /// both the cells and the unknowns of their nodes
    /// ([`partition_cells`](crate::mesh::partition::partition_cells)); the same on every process.
    /// A node's unknowns here leave out what no stage solves for node by node: the supports, the
    /// potential of an electrode (prescribed, or one unknown for all its nodes) and the
    /// displacements of a rigid region (a few unknowns for all its nodes).
    pub fn partition(&self, ranks: usize) -> Vec<usize> {
        use crate::problem::dofs::{constrained_flags, FIELDS, PHI};
        let mesh = &self.model.mesh;
        let mut conditions = self.model.dirichlet.clone();
        conditions.extend(self.supports.iter().cloned());
        conditions.extend(self.model.axisymmetric_supports());
        let mut held = constrained_flags(mesh.n_nodes(), &conditions);
        for e in &self.electrodes {
            e.nodes.iter().for_each(|&n| held[n * FIELDS + PHI] = true);
        }
        for r in &self.rigid {
            for &n in &r.nodes {
                (0..FIELDS)
                    .filter(|&f| f != PHI)
                    .for_each(|f| held[n * FIELDS + f] = true);
            }
        }
        let unknowns: Vec<usize> = held
            .chunks(FIELDS)
            .map(|h| h.iter().filter(|&&held| !held).count())
            .collect();
        crate::mesh::partition::partition_cells(mesh, ranks, Some(&unknowns))
    }

    /// Shares the cells of the model between `ranks` processes, of which this is `rank`: a
    /// METIS partition of the cells ([`Plan::partition`], the same on every process), of which
    /// this process assembles its part; `sum` adds a
    /// vector over the processes (every process receiving the same bits). Every system built
    /// from the model afterwards assembles only this process's cells, and the model holds the
    /// reference geometry of those cells only. Returns the number of cells of each process.
    pub fn share_cells(
        &mut self,
        rank: usize,
        ranks: usize,
        sum: crate::algebra::exchange::SumOverProcesses,
    ) -> Vec<usize> {
        let part = self.partition(ranks);
        let mut counts = vec![0; ranks];
        for &p in &part {
            counts[p] += 1;
        }
        self.model.hold_geometry_of(|c| part[c] == rank);
        self.model.share = Some(std::sync::Arc::new(crate::problem::assembly::CellShare {
            part,
            rank,
            size: ranks,
            sum,
        }));
        counts
    }

    /// The fraction of each pressure at the end of stage `si` when the stage ends at its load
    /// factor 1: 1 where it acts.
    pub fn pressure_targets(&self, si: usize) -> Vec<f64> {
        self.pressure_stages
            .iter()
            .map(|on| if on[si] { 1.0 } else { 0.0 })
            .collect()
    }
}

impl Plan {
    /// Fingerprint of the plan (FNV-1a, 64 bit): its name, node coordinates, connectivity, cell
    /// materials and stage kinds/durations. A resume whose rebuilt plan differs (e.g. a changed
    /// mesh file) is refused.
    pub fn fingerprint(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut write = |bytes: &[u8]| {
            for &b in bytes {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        write(self.name.as_bytes());
        let m = &self.model.mesh;
        for x in &m.nodes {
            for c in x {
                write(&c.to_bits().to_le_bytes());
            }
        }
        for &c in &m.connectivity {
            write(&(c as u64).to_le_bytes());
        }
        for &c in &self.model.cell_material {
            write(&(c as u64).to_le_bytes());
        }
        for s in &self.stages {
            write(s.name.as_bytes());
            write(&s.duration.to_bits().to_le_bytes());
            write(&(s.kind.nominal_steps(s.duration) as u64).to_le_bytes());
        }
        h
    }

    /// Hash (FNV-1a, 64 bit) of everything that decides the computed physics: the model (mesh,
    /// loads, supports, ties, pressures, circuits), the materials' resolved parameters, densities
    /// and viscosities, rigid regions, pre-stretch, electrodes with their drives, and the stages.
    /// Output settings, probes and solver choices are left out. Two runs with equal hashes
    /// solve the same problem; `lumped --compare` uses it to tell an edited scenario.
    pub fn model_hash(&self) -> u64 {
        /// FNV-1a over the bytes written into it.
        struct Fnv(u64);
        impl std::io::Write for Fnv {
            fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
                for &b in bytes {
                    self.0 ^= b as u64;
                    self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
                }
                Ok(bytes.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        fn model_data<S: serde::Serializer>(m: &&Model, s: S) -> Result<S::Ok, S::Error> {
            crate::problem::model::data::serialize(m, s)
        }
        #[derive(serde::Serialize)]
        struct Physics<'a> {
            #[serde(serialize_with = "model_data")]
            model: &'a Model,
            supports: &'a [crate::problem::dofs::Dirichlet],
            electrodes: &'a [Electrode],
            stages: &'a [Stage],
            densities: &'a [f64],
            viscosities: &'a [f64],
            rigid: &'a [Rigid],
            material_parameters: &'a [Vec<String>],
            prestretch: &'a Option<Prestretch>,
            symmetry_factor: f64,
            pressure_stages: &'a [Vec<bool>],
            pressure_volumes: &'a [Option<f64>],
        }
        let physics = Physics {
            model: &self.model,
            supports: &self.supports,
            electrodes: &self.electrodes,
            stages: &self.stages,
            densities: &self.densities,
            viscosities: &self.viscosities,
            rigid: &self.rigid,
            material_parameters: &self.material_parameters,
            prestretch: &self.prestretch,
            symmetry_factor: self.symmetry_factor,
            pressure_stages: &self.pressure_stages,
            pressure_volumes: &self.pressure_volumes,
        };
        let mut h = Fnv(0xcbf2_9ce4_8422_2325);
        // writing into the hash cannot fail; a serialisation error would leave a partial hash,
        // which is still deterministic for the plan
        let _ = postcard::to_io(&physics, &mut h);
        h.0
    }
}

/// An equibiaxial in-plane pre-stretch of the body, imposed on a set (the rim).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Prestretch {
    pub stretch: f64,
    /// Load steps of the ramp: the fallback of an instantaneous pre-stretch (when the homogeneous
    /// guess does not converge), the steps of a timed one.
    pub steps: usize,
    /// Real time of the stretch (s); 0 is instantaneous.
    pub duration: f64,
    /// Real time the stretch is held before the first stage (s), in `hold_steps` equal steps.
    pub hold: f64,
    pub hold_steps: usize,
}

impl Prestretch {
    /// Whether the phase runs in real time (its steps then relax materials with internal
    /// variables, and the first stage starts at `duration + hold`).
    pub fn timed(&self) -> bool {
        self.duration > 0.0 || self.hold > 0.0
    }
}

impl Plan {
    /// The time (s) of the run's clock at which stage `index` starts: a timed pre-stretch's
    /// `duration + hold`, then the durations of the stages before it.
    pub fn stage_start(&self, index: usize) -> f64 {
        let pre = self
            .prestretch
            .filter(Prestretch::timed)
            .map_or(0.0, |p| p.duration + p.hold);
        pre + self.stages[..index].iter().map(|s| s.duration).sum::<f64>()
    }
}

/// A rigid region of the plan.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Rigid {
    pub set: String,
    pub nodes: Vec<usize>,
    /// Attached mass carried by the mesh (kg; the physical mass divided by the symmetry factor).
    pub mass: f64,
    /// The acceleration of gravity on it (m/s²): its weight, mass · gravity, is a dead load at
    /// its first node.
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Rotary inertia (kg·m²) about a diameter through the attachment node `nodes[0]`: the
    /// region tilts in the modes of harmonic 1 of an axisymmetric model; `None`: no rotation.
    #[serde(default)]
    pub rotary_inertia: Option<f64>,
}

/// How a frequency response is computed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ResponseMethod {
    /// One complex sparse solve of the full linearised system per frequency (exact).
    Direct,
    /// The lowest `count` modes with a static correction (the reduced model's response): fast
    /// for many frequencies, accurate below the highest kept mode.
    Modal { count: usize },
}
