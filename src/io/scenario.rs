//! The scenario file: TOML schema, parsing with positioned errors, and `--set` overrides.
//!
//! Parsing happens in two steps. The text is read into a TOML table (syntax errors carry line and
//! column); `--set path=value` overrides are applied to that table; the table is then deserialised
//! into [`Scenario`] with unknown keys rejected (the closest valid key is suggested). Semantic checks
//! (ranges, units, names of sets and materials) live in [`crate::io::build`].
//! Every key, its unit and default is documented in `docs/scenario.md`.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// A problem with the input, located as precisely as the input allows.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    /// The scenario file (or `<embedded NAME>`, `--set`).
    pub file: String,
    /// 1-based line and column, where known.
    pub position: Option<(usize, usize)>,
    /// Dotted key path, where known.
    pub key: Option<String>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some((l, c)) = self.position {
            write!(f, ":{l}:{c}")?;
        }
        if let Some(k) = &self.key {
            write!(f, ": key `{k}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for InputError {}

impl InputError {
    /// An error about a key, without a position.
    pub fn at_key(file: &str, key: impl Into<String>, message: impl Into<String>) -> Self {
        InputError {
            file: file.to_string(),
            position: None,
            key: Some(key.into()),
            message: message.into(),
        }
    }
}

/// A whole scenario.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name of the scenario; names the default output directory.
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub mesh: MeshSpec,
    /// Materials by name.
    pub materials: BTreeMap<String, MaterialSpec>,
    /// Cell set → material name. May be omitted when there is one material: it fills the body.
    #[serde(default)]
    pub regions: BTreeMap<String, String>,
    /// Displacement conditions.
    #[serde(default)]
    pub constraints: Vec<ConstraintSpec>,
    /// Electrodes by name.
    #[serde(default)]
    pub electrodes: BTreeMap<String, ElectrodeSpec>,
    /// The analysis stages, run in order.
    pub stages: Vec<StageSpec>,
    /// Recorded quantities by name.
    #[serde(default)]
    pub probes: BTreeMap<String, ProbeSpec>,
    #[serde(default)]
    pub output: OutputSpec,
    /// An equibiaxial in-plane pre-stretch imposed on a set (the rim) by the first static stage and
    /// held afterwards.
    #[serde(default)]
    pub prestretch: Option<PrestretchSpec>,
    /// Dead surface tractions (nominal, Pa of reference area), ramped with the load factor of
    /// static stages.
    #[serde(default)]
    pub tractions: Vec<TractionSpec>,
    /// Gravity and rigid regions with attached masses.
    #[serde(default)]
    pub loads: Option<LoadsSpec>,
    /// The linear solver.
    #[serde(default)]
    pub solver: Option<SolverSpec>,
    /// The differentiable parameters that `deasim gradient` (and calibration and control)
    /// addresses; a plain run ignores them.
    #[serde(default)]
    pub parameters: Vec<ParameterSpec>,
    /// The terms of the objective J of `deasim gradient`, summed; a plain run ignores them.
    #[serde(default)]
    pub objective: Vec<ObjectiveSpec>,
    /// Controlled drives: an electrode whose voltage in a stage follows a piecewise-linear
    /// table of knot values (the unknowns of `deasim gradient` and `deasim control`).
    #[serde(default)]
    pub controls: Vec<ControlSpec>,
    /// `deasim gradient`'s settings (the memory budget of its tape); a plain run ignores them.
    #[serde(default)]
    pub gradient: Option<GradientSpec>,
}

/// `[gradient]`: `memory`, the bytes the taped states of the forward run may take before its
/// dynamic stages are recomputed from checkpoints.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct GradientSpec {
    pub memory: Option<ByteSize>,
}

/// A size in bytes: a number, or a text with a unit (`"256 MiB"`).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum ByteSize {
    Bytes(f64),
    Text(String),
}

impl ByteSize {
    /// The bytes, or what is wrong: a positive number of bytes, or a number and one of the
    /// units B, kB, MB, GB, TB (powers of 1000) or KiB, MiB, GiB, TiB (powers of 1024).
    pub fn bytes(&self) -> Result<usize, String> {
        let expected = "expected a size in bytes, a number (e.g. 268435456) or a text with a \
                        unit (\"256 MiB\", \"2 GB\"; units B, kB, MB, GB, TB, KiB, MiB, GiB, TiB)";
        let value = match self {
            ByteSize::Bytes(b) => *b,
            ByteSize::Text(t) => {
                let t = t.trim();
                let split = t
                    .find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E')
                    .unwrap_or(t.len());
                let (number, unit) = (t[..split].trim(), t[split..].trim());
                let scale: f64 = match unit {
                    "" | "B" => 1.0,
                    "kB" | "KB" => 1e3,
                    "MB" => 1e6,
                    "GB" => 1e9,
                    "TB" => 1e12,
                    "KiB" => 1024.0,
                    "MiB" => 1024.0 * 1024.0,
                    "GiB" => 1024.0 * 1024.0 * 1024.0,
                    "TiB" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
                    _ => return Err(format!("{expected}; got \"{t}\" (unknown unit `{unit}`)")),
                };
                match number.parse::<f64>() {
                    Ok(v) => v * scale,
                    Err(_) => return Err(format!("{expected}; got \"{t}\"")),
                }
            }
        };
        if !(1.0..1.8e19).contains(&value) {
            let got = match self {
                ByteSize::Bytes(b) => format!("{b}"),
                ByteSize::Text(t) => format!("\"{t}\""),
            };
            return Err(format!("{expected} of at least 1 byte; got {got}"));
        }
        Ok(value as usize)
    }
}

/// `[[controls]]`: the voltage of `electrode` in `stage` as a piecewise-linear table with knots
/// every `interval` s of stage time (0 or absent: the stage's nominal step), starting at the values
/// of the electrode's waveform there (or `values`, one per knot); `lower`, `upper` (V) and
/// `max_rate` (V/s) bound it for an optimiser.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct ControlSpec {
    pub electrode: String,
    #[serde(default)]
    pub stage: Option<String>,
    #[serde(default)]
    pub interval: Option<f64>,
    #[serde(default)]
    pub values: Option<Vec<f64>>,
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    #[serde(default)]
    pub max_rate: Option<f64>,
}

/// `[[parameters]]`: a differentiable scalar of the scenario by its key path (the string `--set`
/// takes), with optional bounds and the scale an optimiser works in.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    pub path: String,
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    /// `linear` (default) or `log`.
    #[serde(default)]
    pub scale: Option<String>,
}

/// `[[objective]]`: one term of J (`kind` says which keys it takes).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct ObjectiveSpec {
    /// `probe-final`, `probe-misfit`, `drive-effort`, `rest` or `field-penalty`.
    pub kind: String,
    #[serde(default)]
    pub probe: Option<String>,
    #[serde(default)]
    pub stage: Option<String>,
    /// The measured history: a CSV file with the header `time,value` (path relative to the
    /// scenario).
    #[serde(default)]
    pub data: Option<String>,
    /// A number (`probe-final`), or a number or waveform table of stage time (`probe-misfit`,
    /// instead of `data`), in the probe's unit.
    #[serde(default)]
    pub target: Option<VoltageSpec>,
    /// Targets and data measured from the probe's value at the stage's start.
    #[serde(default)]
    pub relative: Option<bool>,
    /// Default 1.
    #[serde(default)]
    pub weight: Option<f64>,
    #[serde(default)]
    pub electrode: Option<String>,
    /// `value` or `rate` (drive effort).
    #[serde(default)]
    pub of: Option<String>,
    /// V/m (field penalty).
    #[serde(default)]
    pub limit: Option<f64>,
}

/// `[solver]`: the linear solver of every stage.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// `auto` (default), `direct` or `iterative`, or `petsc` in a build with the `petsc` feature.
    pub kind: Option<String>,
    /// Fill-reducing ordering of the direct solver: `nested-dissection` (default) or `amd`.
    pub ordering: Option<String>,
    /// `auto`: the number of unknowns from which factorisations are reused (default 20 000).
    pub reuse_from: Option<i64>,
    /// `auto`: the precision of reused factorisations, `auto` (default: single in static load
    /// steps, double elsewhere), `double` or `single`.
    pub precision: Option<String>,
    /// PETSc options of the `petsc` solver, e.g. `"-ksp_type minres -pc_type jacobi"`.
    pub petsc_options: Option<String>,
    /// `iterative` (and `auto` once it has switched to it): the relative residual of each
    /// linear solve (default 1e-8).
    pub rtol: Option<f64>,
    /// `iterative`, `auto` wherever it runs FGMRES, and `petsc` with a Krylov method:
    /// `adaptive` (the default, but `fixed` for `petsc`) stops each solve at Newton's forcing term when that is looser than the solver's own tolerance; `fixed` solves
    /// every time to that tolerance.
    pub forcing: Option<String>,
    /// `auto`, `direct`: the largest sparse factor to hold, bytes (default: 80 % of the memory
    /// available). Above it `auto` switches to `iterative` and `direct` stops with an error.
    pub memory_limit: Option<f64>,
    /// `petsc` with a Krylov method: `kept` keeps the preconditioner across Newton iterations
    /// and steps until it grows stale; `renewed` sets it up with every tangent.
    pub preconditioner: Option<String>,
    /// Newton converges at ‖r‖ ≤ `newton_rtol`·‖r₀‖ (default 1e-10), every stage, the
    /// pre-stretch and the small-signal base states.
    pub newton_rtol: Option<f64>,
    /// Newton's largest number of iterations per step (default 25).
    pub newton_max_iterations: Option<i64>,
    /// The largest number of halvings of a Newton step in the line search (default 6).
    pub line_search_halvings: Option<i64>,
    /// Newton's tangents in static stages and the pre-stretch: `lagged` (the default: near the
    /// root an iteration may keep the previous iterate's tangent) or `every-iteration`.
    pub newton_tangent: Option<String>,
    /// The smallest load increment of a static stage, as a fraction of a nominal step (default
    /// 1/4096): below it the stage stops as failed.
    pub min_step_fraction: Option<f64>,
    /// `auto`, `direct`: the matrix of the Newton iterations of implicit dynamic steps,
    /// `symmetric` (the default: the symmetric matrix without the configuration derivative of
    /// the Kelvin–Voigt forces, reused across iterations and steps) or `exact` (the unsymmetric
    /// Jacobian, FGMRES preconditioned by a held factor of its symmetric part).
    pub jacobian: Option<String>,
}

/// Gravity, and rigid regions carrying masses. Both act from the first stage on and are ramped
/// like the tractions by static stages.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadsSpec {
    /// Gravitational acceleration (m/s²), e.g. `[0, 0, -9.81]`; acts on every material with a
    /// density and on the attached masses.
    #[serde(default)]
    pub gravity: Option<[f64; 3]>,
    /// Rigid regions: every node of the set moves by one common translation.
    #[serde(default)]
    pub rigid: Vec<RigidSpec>,
    /// Follower pressures (Pa) on face sets, ramped with the load factor of static stages like
    /// the tractions.
    #[serde(default)]
    pub pressure: Vec<PressureSpec>,
}

/// A rigid region (all three translations shared, rotations suppressed) with an attached mass.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RigidSpec {
    /// The node set (e.g. `pad`).
    pub set: String,
    /// Attached point mass (kg) of the whole physical region; a quarter-disc mesh carries a quarter
    /// of it.
    #[serde(default)]
    pub mass: f64,
    /// Linear damping of the region's motion (N·s/m, whole device): air drag and fixture losses of
    /// the attached mass, a dashpot to ground; dynamic stages only.
    #[serde(default)]
    pub damping: f64,
    /// Rotary inertia (kg·m², whole region) about a diameter through the node the mass is
    /// attached to: an axisymmetric model's region then tilts in the modes of harmonic 1. Without
    /// it a rigid region does not rotate (as in 3-D).
    #[serde(default)]
    pub rotary_inertia: Option<f64>,
}

/// The mesh: a generator with its parameters, or a file.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// `3d` (default) or `axisymmetric`: the cells are then meridian cells of the (R, Z)
    /// half-plane (x = R ≥ 0, y = Z), each standing for the ring it sweeps about the axis.
    #[serde(default)]
    pub geometry: Option<String>,
    /// `box`, `disc`, `stack`, `sphere` (3-D); `disc`, `rectangle`, `sphere` (axisymmetric).
    #[serde(default)]
    pub generator: Option<String>,
    /// A Gmsh `.msh` file (MSH 4.1 ASCII or binary, 2.2 ASCII), relative to the scenario file.
    #[serde(default)]
    pub file: Option<String>,
    /// Factor applied to the coordinates of `file` (1e-3 for a file drawn in mm; default 1).
    #[serde(default)]
    pub scale: Option<f64>,
    /// Edge lengths of the box (m).
    #[serde(default)]
    pub size: Option<[f64; 3]>,
    /// Cells along x, y, z.
    #[serde(default)]
    pub divisions: Option<[u64; 3]>,
    /// `disc`: outer (clamped rim) radius (m); `rectangle`: outer radius (m); `sphere`: inner
    /// radius (m).
    #[serde(default)]
    pub radius: Option<f64>,
    /// `rectangle`: inner radius (m; default 0, a solid cylinder or disc).
    #[serde(default)]
    pub inner_radius: Option<f64>,
    /// `disc`: thickness (m).
    #[serde(default)]
    pub thickness: Option<f64>,
    /// `disc`: radius of the central pad (m).
    #[serde(default)]
    pub pad_radius: Option<f64>,
    /// `disc`: radius of the electrodes (m).
    #[serde(default)]
    pub electrode_radius: Option<f64>,
    /// `disc`: cells across the annulus between pad and rim (default 8).
    #[serde(default)]
    pub radial: Option<u64>,
    /// `disc`: cells through the thickness (default 1).
    #[serde(default)]
    pub layers: Option<u64>,
    /// `disc`, `stack`: a quarter model with symmetry faces (default true) or the full device.
    #[serde(default)]
    pub quarter: Option<bool>,
    /// `disc`: outer/inner radial cell size ratio of the annulus (default 1); `stack`:
    /// largest/smallest in-plane cell size across the active half-width (default 1).
    #[serde(default)]
    pub grading: Option<f64>,
    /// `stack`: in-plane edge length of the square device (m), or `[Lx, Ly]`.
    #[serde(default)]
    pub side: Option<Numbers>,
    /// `stack`: number of elastomer films.
    #[serde(default)]
    pub films: Option<u64>,
    /// `stack`: thickness of one film (m).
    #[serde(default)]
    pub film_thickness: Option<f64>,
    /// `stack`: width of the passive border between the electrode edges and the sides (m).
    #[serde(default)]
    pub border: Option<f64>,
    /// `stack`: cells through each film (default 2).
    #[serde(default)]
    pub layers_per_film: Option<u64>,
    /// `stack`: cells from the centre to the electrode edge along x and y (default 8).
    #[serde(default)]
    pub active_cells: Option<u64>,
    /// Element formulation: `standard` (default) or `mean-dilatation` (locking-free hex8 for
    /// nearly incompressible materials).
    #[serde(default)]
    pub formulation: Option<String>,
    /// `hex8` (default), `tet4` or `tet10` for the generators; for a `file`, the kind the file
    /// must hold (optional).
    #[serde(default)]
    pub element: Option<String>,
}

/// A material: the model (or a preset) and its parameters in SI units.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// `neo-hooke`, `neo-hooke-split`, `yeoh`, `mooney-rivlin`, `gent`, `ogden`, `arruda-boyce`;
    /// may be omitted when `preset` is given.
    #[serde(default)]
    pub model: Option<String>,
    /// A named parameter set (e.g. `vhb4910-yeoh`); parameters given here override it.
    #[serde(default)]
    pub preset: Option<String>,
    /// Shear modulus μ (Pa), or the list of Ogden μₚ (Pa).
    #[serde(default)]
    pub mu: Option<Numbers>,
    /// Lamé constant Λ (Pa) of `neo-hooke`.
    pub lambda: Option<f64>,
    /// Bulk modulus κ (Pa) of the split models.
    pub kappa: Option<f64>,
    /// Yeoh / Mooney–Rivlin coefficients (Pa).
    pub c10: Option<f64>,
    pub c20: Option<f64>,
    pub c30: Option<f64>,
    pub c01: Option<f64>,
    /// Abaqus compressibility coefficients Dᵢ (1/Pa).
    pub d1: Option<f64>,
    pub d2: Option<f64>,
    pub d3: Option<f64>,
    /// Gent locking parameter Jm (–).
    pub jm: Option<f64>,
    /// Arruda–Boyce locking stretch λm (–).
    pub lambda_m: Option<f64>,
    /// Ogden exponents αₚ (–).
    #[serde(default)]
    pub alpha: Option<Vec<f64>>,
    /// Relative permittivity εᵣ (–).
    pub permittivity: Option<f64>,
    /// Vu coupling coefficient c₁ (N/V², i.e. F/m).
    pub c1: Option<f64>,
    /// Vu coupling coefficient c₂ (N/V²).
    pub c2: Option<f64>,
    /// Mass density (kg/m³).
    pub density: Option<f64>,
    /// Kelvin–Voigt viscosity η (Pa·s).
    pub viscosity: Option<f64>,
    /// Dielectric strength (V/m): a true field above it is reported in the summary's warnings.
    pub breakdown_field: Option<f64>,
    /// Stop the run at the first step whose true field exceeds `breakdown_field` (default false).
    pub stop_at_breakdown: Option<bool>,
    /// Neo-Hookean Maxwell branches on the isochoric deformation (replace a preset's).
    #[serde(default)]
    pub branches: Option<Vec<BranchSpec>>,
}

/// One Maxwell branch: shear modulus `mu` (Pa) and relaxation time `tau` (s).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BranchSpec {
    pub mu: f64,
    pub tau: f64,
}

/// One number or a list of numbers.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(untagged)]
pub enum Numbers {
    One(f64),
    Many(Vec<f64>),
}

impl Numbers {
    /// The values as a list.
    pub fn to_vec(&self) -> Vec<f64> {
        match self {
            Numbers::One(x) => vec![*x],
            Numbers::Many(v) => v.clone(),
        }
    }
}

impl<'de> Deserialize<'de> for Numbers {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Numbers;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of numbers")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Numbers, E> {
                Ok(Numbers::One(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Numbers, E> {
                Ok(Numbers::One(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Numbers, E> {
                Ok(Numbers::One(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> Result<Numbers, A::Error> {
                Vec::<f64>::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(Numbers::Many)
            }
        }
        d.deserialize_any(V)
    }
}

/// Pre-stretch: the nodes of `set` are moved to (λx, λy, z) (u = (λ − 1)(x, y, 0)).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PrestretchSpec {
    /// In-plane stretch λ (> 0; 1 = none).
    pub stretch: f64,
    /// The set held at the stretched position (default `rim`).
    #[serde(default = "rim")]
    pub set: String,
    /// Load steps of the pre-stretch (default 4); it runs before the first stage, with the rigid
    /// regions free and without the loads, and its steps are recorded under the first stage's name.
    #[serde(default)]
    pub steps: Option<u64>,
    /// Real time (s) the stretch takes (default 0: instantaneous); with a positive duration or
    /// hold the phase runs in time, so materials with internal variables relax during it.
    #[serde(default)]
    pub duration: Option<f64>,
    /// Time (s) the stretch is held before the first stage (default 0).
    #[serde(default)]
    pub hold: Option<f64>,
    /// Equal steps of the hold (default 20).
    #[serde(default)]
    pub hold_steps: Option<u64>,
    /// How the set is held: `"in-plane"` (default: its in-plane position only, so a rim may thin
    /// and slide axially) or `"face"` (also through the thickness, at the homogeneously
    /// pre-stretched film's position: a frame clamped on the stretched film).
    #[serde(default)]
    pub clamp: Option<String>,
}

fn rim() -> String {
    "rim".into()
}

/// A dead traction on a face set.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TractionSpec {
    /// A face set.
    pub set: String,
    /// Traction vector (Pa, force per reference area).
    pub value: [f64; 3],
}

/// A follower pressure on a face set.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PressureSpec {
    /// A face set.
    pub set: String,
    /// Pressure (Pa): positive pushes the faces along −n, n the body's outward normal (it
    /// inflates a cavity whose walls the faces are, and compresses a solid it surrounds).
    pub value: Option<f64>,
    /// Instead of `value`: the volume (m³, whole device) the faces enclose at the end of every
    /// stage it acts in; the pressure is then an unknown (volume control).
    pub volume: Option<f64>,
    /// The names of the stages in which it acts (default: every stage).
    #[serde(default)]
    pub stages: Option<Vec<String>>,
}

/// Fixed displacement components on a set.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSpec {
    /// The node, face or cell set.
    pub set: String,
    /// Components to prescribe: any of `x`, `y`, `z`.
    pub fix: Vec<String>,
    /// Prescribed displacement of those components (m); 0 by default.
    #[serde(default)]
    pub value: f64,
}

/// An electrode: a set and its voltage.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ElectrodeSpec {
    pub set: String,
    /// Charge control: the total free charge (C, of the whole device) the electrode carries, a
    /// number or a waveform table like `voltage`; its voltage becomes an unknown (0: a floating
    /// electrode). Excludes `voltage`.
    #[serde(default)]
    pub charge: Option<VoltageSpec>,
    /// Volts: a number (constant) or a waveform table. 0 = grounded.
    #[serde(default)]
    pub voltage: VoltageSpec,
    /// Circuit control: the electrode is driven by a `source` (V, a number or a waveform)
    /// through a series `resistance` (Ω, of the whole device). Excludes `voltage` and `charge`.
    #[serde(default)]
    pub circuit: Option<CircuitSpec>,
    /// A feedback controller that sets the voltage in the dynamic and quasi-static stages.
    #[serde(default)]
    pub controller: Option<ControllerSpec>,
}

/// `electrodes.<e>.controller`: a sampled PID loop from a probe to the electrode's voltage, or a
/// state feedback from the probes a design file names.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControllerSpec {
    /// `pid` or `state-feedback`.
    pub kind: String,
    /// The state feedback's design (the `lqr.json` of `deasim reduce --lqr`), relative to the
    /// scenario.
    #[serde(default)]
    pub model: Option<String>,
    /// The probe measured (PID).
    #[serde(default)]
    pub probe: Option<String>,
    /// The set point (probe unit): a number or a waveform table.
    #[serde(default)]
    pub setpoint: Option<VoltageSpec>,
    /// Gains: V per probe unit, per probe unit per s, V·s per probe unit.
    #[serde(default)]
    pub kp: Option<f64>,
    #[serde(default)]
    pub ki: Option<f64>,
    #[serde(default)]
    pub kd: Option<f64>,
    /// The sample period (s).
    #[serde(default)]
    pub sample_time: Option<f64>,
    /// The output limits (V).
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    /// Drive added before the limits (V): a number or a waveform table.
    #[serde(default)]
    pub feedforward: Option<VoltageSpec>,
    /// Standard deviation of the measurement noise (probe unit) and its seed.
    #[serde(default)]
    pub noise: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Time constant of the derivative's filter (s).
    #[serde(default)]
    pub derivative_filter: Option<f64>,
}

/// A source behind a series resistance.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CircuitSpec {
    /// The source voltage (V): a number or a waveform table.
    pub source: VoltageSpec,
    /// The series resistance (Ω) of the whole device.
    pub resistance: f64,
}

/// A voltage: constant or a waveform.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(untagged)]
pub enum VoltageSpec {
    Constant(f64),
    Waveform(Box<WaveformSpec>),
}

impl<'de> Deserialize<'de> for VoltageSpec {
    /// A number, or a waveform table whose errors keep their key path.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = VoltageSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a voltage in V (a number) or a waveform table such as { waveform = \"sine\", amplitude = 3000.0, frequency = 2.0 }")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<VoltageSpec, E> {
                Ok(VoltageSpec::Constant(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<VoltageSpec, E> {
                Ok(VoltageSpec::Constant(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<VoltageSpec, E> {
                Ok(VoltageSpec::Constant(v as f64))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<VoltageSpec, A::Error> {
                WaveformSpec::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(|w| VoltageSpec::Waveform(Box::new(w)))
            }
        }
        d.deserialize_any(V)
    }
}

impl Default for VoltageSpec {
    fn default() -> Self {
        VoltageSpec::Constant(0.0)
    }
}

/// A waveform table.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WaveformSpec {
    /// `constant`, `ramp`, `step`, `square`, `triangle`, `sine`, `fourier`, `table`.
    pub waveform: String,
    /// Peak value (V) above the offset.
    #[serde(default)]
    pub amplitude: f64,
    /// Hz.
    #[serde(default)]
    pub frequency: Option<f64>,
    /// V.
    #[serde(default)]
    pub offset: f64,
    /// Degrees.
    #[serde(default)]
    pub phase: f64,
    /// Fraction of the period a square wave is high.
    #[serde(default)]
    pub duty: Option<f64>,
    /// `unipolar` (0..amplitude, default) or `bipolar` (−amplitude..amplitude).
    #[serde(default)]
    pub polarity: Option<String>,
    /// Odd harmonics kept by `fourier`.
    #[serde(default)]
    pub terms: Option<u64>,
    /// `square` or `triangle`: the signal a `fourier` series approximates.
    #[serde(default)]
    pub base: Option<String>,
    /// Time of a `step` (s).
    #[serde(default)]
    pub at: Option<f64>,
    /// Rise time of `ramp` and `step` (s).
    #[serde(default)]
    pub rise_time: Option<f64>,
    /// The rise of `ramp` and `step`: `linear` (default) or `cosine`.
    #[serde(default)]
    pub rise: Option<String>,
    /// CSV file `time,value` of a `table`, relative to the scenario.
    #[serde(default)]
    pub file: Option<String>,
}

/// One analysis stage.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    /// Name in the history and summary; `stage<i>` by default.
    #[serde(default)]
    pub name: Option<String>,
    /// `static` or `dynamic`.
    pub kind: String,
    /// Load steps of a static stage.
    #[serde(default)]
    pub steps: Option<u64>,
    /// Duration (s): of the simulated time of a dynamic stage; the pseudo-time of a static one
    /// (default 1).
    #[serde(default)]
    pub duration: Option<f64>,
    /// Time step of a dynamic stage (s).
    #[serde(default)]
    pub dt: Option<f64>,
    /// Time integrator of a dynamic stage.
    #[serde(default)]
    pub integrator: Option<String>,
    /// Mass matrix of a dynamic stage: `consistent` (default) or `lumped`.
    #[serde(default)]
    pub mass: Option<String>,
    /// `false`: every electrode is held at 0 V during this stage (e.g. while a mass is hung);
    /// default `true`: the electrodes follow their waveforms, in stage time.
    #[serde(default)]
    pub electrodes_on: Option<bool>,
    /// Number of modes of a `modes` stage (default 6), or of the modal method of a
    /// `frequency-response` stage (default 10).
    #[serde(default)]
    pub count: Option<u64>,
    /// `modes`: the modes nearest to this frequency (Hz, default 0: the lowest).
    #[serde(default)]
    pub shift: Option<f64>,
    /// `modes` of an axisymmetric model: the circumferential harmonic n (default 0), or a list.
    #[serde(default)]
    pub harmonic: Option<Numbers>,
    /// `static`, `quasi-static` and `continuation` stages of an axisymmetric model: test every
    /// converged state against the circumferential harmonics 1…N (wrinkling, buckling out of
    /// the meridian plane).
    #[serde(default)]
    pub stability_harmonics: Option<u64>,
    /// With `stability_harmonics`: `stop` (default) ends the run at the last stable state,
    /// `continue` reports the first loss and goes on along the axisymmetric path.
    #[serde(default)]
    pub after_instability: Option<String>,
    /// `frequency-response`: the electrode that carries the small voltage (default: the first
    /// with a non-zero voltage).
    #[serde(default)]
    pub electrode: Option<String>,
    /// `frequency-response`: the frequencies (Hz), or a log range `from`, `to` with `points`.
    #[serde(default)]
    pub frequencies: Option<Vec<f64>>,
    #[serde(default)]
    pub from: Option<f64>,
    #[serde(default)]
    pub to: Option<f64>,
    #[serde(default)]
    pub points: Option<u64>,
    /// `frequency-response`: `direct` (a solve per frequency, default) or `modal` (`count` modes
    /// with a static correction).
    #[serde(default)]
    pub method: Option<String>,
    /// `continuation`: the load followed, `voltage`, `charge` (of `electrode`) or `pressure`.
    #[serde(default)]
    pub parameter: Option<String>,
    /// `continuation`: where the path ends.
    #[serde(default)]
    pub target: Option<TargetSpec>,
    /// `continuation`: the largest number of points (default 500).
    #[serde(default)]
    pub max_points: Option<u64>,
}

/// The end of a continuation stage: a load factor, a probe value, or a number of points.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// Load factor (1: the stage's end values of the loads).
    #[serde(default)]
    pub load: Option<f64>,
    /// A probe's name, with the `value` it must reach.
    #[serde(default)]
    pub probe: Option<String>,
    #[serde(default)]
    pub value: Option<f64>,
    /// A number of points.
    #[serde(default)]
    pub points: Option<u64>,
}

/// A recorded quantity.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// `mean`, `max`, `min` (of a nodal quantity over a set), `point` (at the node nearest to
    /// `at`), `charge`, `capacitance` (of an electrode), `reaction` (force on a set), `energy`,
    /// `center_deflection` (downward displacement of `set`, default `pad`, from the pre-stretched
    /// state), `max_electric_field` (largest true field), `current`, `power` (of an electrode),
    /// `area_strain` (of an electrode's or a set's faces, from the pre-stretched state).
    pub kind: String,
    /// Nodal quantity: `ux`, `uy`, `uz`, `u` (magnitude), `phi`; energy: `stored`, `electric`,
    /// `kinetic`; reaction: component `x`, `y`, `z`.
    #[serde(default)]
    pub quantity: Option<String>,
    #[serde(default)]
    pub set: Option<String>,
    /// Point (m) of a `point` probe.
    #[serde(default)]
    pub at: Option<[f64; 3]>,
    #[serde(default)]
    pub electrode: Option<String>,
    /// The recorded value is offset + scale · quantity (to report a stretch, a unit change, ...).
    #[serde(default)]
    pub scale: Option<f64>,
    #[serde(default)]
    pub offset: Option<f64>,
    /// Unit of the recorded value in plots (`-` for a ratio); the quantity's SI unit by default,
    /// none when `scale` is given without it.
    #[serde(default)]
    pub unit: Option<String>,
}

/// What to write.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Write fields every N accepted steps (0: only the last state).
    #[serde(default = "one")]
    pub fields_every: u64,
    /// Draw plots of every probe against time.
    #[serde(default = "yes")]
    pub plots: bool,
    /// `png` or `svg`.
    #[serde(default = "png")]
    pub plot_format: String,
    /// Encoding of the `.vtu` field files: `binary` (default) or `ascii`.
    #[serde(default)]
    pub vtu_format: Option<String>,
    /// Axisymmetric models only: also write the revolved 3-D view (default true).
    #[serde(default)]
    pub revolve: Option<bool>,
    /// Axisymmetric models only: the angle the revolved view sweeps, degrees (default 270).
    #[serde(default)]
    pub revolve_sector: Option<f64>,
    /// Axisymmetric models only: wedges of the revolved view (default one per 10°).
    #[serde(default)]
    pub revolve_wedges: Option<u64>,
}

fn one() -> u64 {
    1
}
fn yes() -> bool {
    true
}
fn png() -> String {
    "png".into()
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            fields_every: 1,
            plots: true,
            plot_format: png(),
            vtu_format: None,
            revolve: None,
            revolve_sector: None,
            revolve_wedges: None,
        }
    }
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut end = offset.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let before = &text[..end];
    let line = before.matches('\n').count() + 1;
    let col = before
        .rsplit('\n')
        .next()
        .map(|s| s.chars().count())
        .unwrap_or(0)
        + 1;
    (line, col)
}

/// Levenshtein distance, for suggestions.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != *cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The closest candidate to `word`, when it is close enough to be a plausible typo.
pub fn closest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (distance(word, c), c))
        .filter(|(d, c)| *d <= (c.len().max(word.len()) / 2).max(2))
        .min()
        .map(|(_, c)| c)
}

/// serde's type names in the project's words: "expected u64" → "expected a whole number",
/// "f64" → "a number", "struct MaterialSpec" → "a material table".
fn plain(message: &str) -> String {
    let mut m = message.replace("invalid type: ", "wrong type: got ");
    for (serde, ours) in [
        (
            "struct MaterialSpec",
            "a material table (`model` or `preset` and its parameters)",
        ),
        ("a sequence", "an array"),
        ("a map", "a table"),
        ("a boolean", "true or false"),
        ("sequence", "array"),
    ] {
        m = m.replace(serde, ours);
    }
    // `expected f64`, `expected u64, got …`: the words end at a comma, a space or the end
    let mut out = String::with_capacity(m.len());
    for (i, word) in m.split(' ').enumerate() {
        if i > 0 {
            out.push(' ');
        }
        let (core, tail) = word
            .find([',', ';', ')'])
            .map_or((word, ""), |k| word.split_at(k));
        let ours = match core {
            "f64" | "f32" => "a number",
            "u8" | "u16" | "u32" | "u64" | "usize" => "a whole number ≥ 0",
            "i8" | "i16" | "i32" | "i64" | "isize" => "a whole number",
            "str" | "string" if i > 0 && out.ends_with("expected a ") => "string",
            _ if core.starts_with("struct ") => "a table",
            _ => core,
        };
        // serde writes a float with all its digits (`1e300` as 301 of them): keep it short
        let bare = ours.trim_matches('`');
        let long_number = bare.len() > 16 && bare.parse::<f64>().is_ok();
        let short;
        let ours = if long_number {
            let x: f64 = bare.parse().expect("checked");
            short = ours.replace(bare, &crate::units::Short(x).to_string());
            short.as_str()
        } else {
            ours
        };
        out.push_str(ours);
        out.push_str(tail);
    }
    out.replace("expected a a ", "expected a ")
        .replace("expected a number, got", "expected a number; got")
}

/// Adds "did you mean" to serde's "unknown field `x`, expected one of `a`, `b`" messages.
fn with_suggestion(message: &str) -> String {
    let msg = plain(message.trim());
    let Some(rest) = msg.strip_prefix("unknown field `") else {
        return msg;
    };
    let Some((field, tail)) = rest.split_once('`') else {
        return msg;
    };
    let candidates: Vec<&str> = tail.split('`').skip(1).step_by(2).collect();
    match closest(field, candidates.iter().copied()) {
        Some(c) => format!("{msg}; did you mean `{c}`?"),
        None => msg,
    }
}

/// Largest accepted scenario file (bytes).
pub const MAX_SCENARIO_BYTES: usize = 4 << 20;

/// Parses and deserialises a scenario from its text, applying `--set` overrides first.
/// `file` names the source in messages.
pub fn parse(text: &str, file: &str, overrides: &[String]) -> Result<Scenario, InputError> {
    let err = |position, key: Option<String>, message: String| InputError {
        file: file.to_string(),
        position,
        key,
        message,
    };
    if text.len() > MAX_SCENARIO_BYTES {
        return Err(err(
            None,
            None,
            format!(
                "file too large ({} bytes, at most {MAX_SCENARIO_BYTES})",
                text.len()
            ),
        ));
    }
    if text.trim().is_empty() {
        return Err(err(
            None,
            None,
            "empty scenario: expected TOML with at least `name`, `mesh`, `materials` and `stages`"
                .into(),
        ));
    }
    let mut table: toml::Table = toml::from_str(text).map_err(|e| {
        let pos = e.span().map(|s| line_col(text, s.start));
        err(pos, None, format!("invalid TOML: {}", e.message().trim()))
    })?;
    if table.is_empty() && overrides.is_empty() {
        return Err(err(
            None,
            None,
            "empty scenario: expected TOML with at least `name`, `mesh`, `materials` and `stages`"
                .into(),
        ));
    }
    for o in overrides {
        apply_override(&mut table, o).map_err(|(key, message)| InputError {
            file: "--set".into(),
            position: None,
            key: Some(key),
            message,
        })?;
    }
    if overrides.is_empty() {
        // deserialise from the text so that errors carry positions
        let de = toml::Deserializer::parse(text)
            .map_err(|e| err(None, None, e.message().to_string()))?;
        serde_path_to_error::deserialize::<_, Scenario>(de).map_err(|e| {
            let key = dotted(&e.path().to_string());
            let inner = e.into_inner();
            let pos = inner.span().map(|s| line_col(text, s.start));
            err(
                pos,
                (key != "." && !key.is_empty()).then_some(key),
                with_suggestion(inner.message()),
            )
        })
    } else {
        let value = toml::Value::Table(table);
        serde_path_to_error::deserialize::<_, Scenario>(value).map_err(|e| {
            let key = dotted(&e.path().to_string());
            let inner = e.into_inner();
            err(
                None,
                (key != "." && !key.is_empty()).then_some(key),
                with_suggestion(inner.message()),
            )
        })
    }
}

/// A key path in the one style of `--set` and of every message: `stages.0.steps`, not serde's
/// `stages[0].steps`.
fn dotted(path: &str) -> String {
    path.replace('[', ".").replace(']', "")
}

/// `e` with the `--set` override that gave its key (or a table above or below it) named: the
/// value that is wrong is not in the file.
pub fn blame_override(mut e: InputError, overrides: &[String]) -> InputError {
    let Some(key) = e.key.clone() else {
        return e;
    };
    let hit = overrides.iter().find(|o| {
        let path = o.split_once('=').map_or(o.as_str(), |(p, _)| p).trim();
        path == key || key.starts_with(&format!("{path}.")) || path.starts_with(&format!("{key}."))
    });
    if let Some(o) = hit {
        if e.file != "--set" {
            e.message = format!("{} (the value comes from `--set {o}`)", e.message);
        }
    }
    e
}

/// Parses the value of a `--set` (TOML syntax: numbers, strings, arrays, booleans; a bare word is a
/// string).
fn parse_value(raw: &str) -> Result<toml::Value, String> {
    let doc = format!("v = {raw}");
    match toml::from_str::<toml::Table>(&doc) {
        Ok(mut t) => t.remove("v").ok_or_else(|| "no value".to_string()),
        // a number beyond the range of f64 (e.g. `1e400`) is not a word
        Err(_) if raw.parse::<f64>().is_ok_and(|x| x.is_infinite()) => Err(format!(
            "`{raw}` is beyond the range of a number (about ±1.8e308)"
        )),
        Err(_)
            if !raw.is_empty()
                && raw
                    .chars()
                    .all(|c| c.is_alphanumeric() || "-_.".contains(c)) =>
        {
            Ok(toml::Value::String(raw.to_string()))
        }
        Err(e) => Err(format!(
            "cannot read the value `{raw}`: {}",
            e.message().trim()
        )),
    }
}

/// Applies `path=value` to the table: tables by key, arrays by index. Missing tables are created
/// (an unknown key then fails validation with a suggestion); indexing past an array's end fails.
pub fn apply_override(table: &mut toml::Table, spec: &str) -> Result<(), (String, String)> {
    let Some((path, raw)) = spec.split_once('=') else {
        return Err((spec.to_string(), "expected KEY=VALUE".into()));
    };
    let path = path.trim();
    let value = parse_value(raw.trim()).map_err(|m| (path.to_string(), m))?;
    let parts: Vec<&str> = path.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err((path.to_string(), "empty key in the dotted path".into()));
    }
    if let Some(p) = parts.iter().find(|p| p.contains('[') || p.contains(']')) {
        return Err((
            path.to_string(),
            format!(
                "`{p}` is not a key: a list's element is addressed by its index after a dot, \
                 e.g. `{}`",
                path.replace('[', ".").replace(']', "")
            ),
        ));
    }
    materialise_preset_branches(table, &parts);
    set_in_table(table, &parts, 0, value)
}

/// Before a path `materials.<m>.branches.<i>…` is set on a material that takes its branches
/// from its `preset`: the preset's branches written out as the table's `branches`, so that the
/// path sets one entry of them (a gradient check, a fit or a control moves one branch's value
/// of a preset).
fn materialise_preset_branches(table: &mut toml::Table, parts: &[&str]) {
    let ["materials", name, "branches", _, ..] = parts else {
        return;
    };
    let Some(toml::Value::Table(m)) = table
        .get_mut("materials")
        .and_then(|v| v.as_table_mut())
        .and_then(|t| t.get_mut(*name))
    else {
        return;
    };
    if m.contains_key("branches") {
        return;
    }
    let Some((_, params)) = m
        .get("preset")
        .and_then(|p| p.as_str())
        .and_then(crate::material::registry::preset)
    else {
        return;
    };
    if params.branches.is_empty() {
        return;
    }
    let branches = params
        .branches
        .iter()
        .map(|&(mu, tau)| {
            let mut b = toml::Table::new();
            b.insert("mu".into(), toml::Value::Float(mu));
            b.insert("tau".into(), toml::Value::Float(tau));
            toml::Value::Table(b)
        })
        .collect();
    m.insert("branches".into(), toml::Value::Array(branches));
}

fn set_in_table(
    t: &mut toml::Table,
    parts: &[&str],
    i: usize,
    value: toml::Value,
) -> Result<(), (String, String)> {
    let part = parts[i];
    if i + 1 == parts.len() {
        t.insert(part.to_string(), value);
        return Ok(());
    }
    let next = t
        .entry(part.to_string())
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    set_in_value(next, parts, i + 1, value)
}

fn set_in_value(
    cur: &mut toml::Value,
    parts: &[&str],
    i: usize,
    value: toml::Value,
) -> Result<(), (String, String)> {
    let part = parts[i];
    let so_far = parts[..=i].join(".");
    let parent = parts[..i].join(".");
    match cur {
        toml::Value::Table(t) => set_in_table(t, parts, i, value),
        toml::Value::Array(a) => {
            let idx: usize = part.parse().map_err(|_| {
                (
                    so_far.clone(),
                    format!("`{parent}` is an array: expected an index, got `{part}`"),
                )
            })?;
            let len = a.len();
            let slot = a.get_mut(idx).ok_or_else(|| {
                (
                    so_far.clone(),
                    format!("index {idx} is past the end (the array has {len} entries)"),
                )
            })?;
            if i + 1 == parts.len() {
                *slot = value;
                Ok(())
            } else {
                set_in_value(slot, parts, i + 1, value)
            }
        }
        other => Err((
            so_far,
            format!(
                "`{parent}` is a {}, not a table: it has no key `{part}`",
                other.type_str()
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
name = "t"
[mesh]
generator = "box"
size = [1.0, 1.0, 1.0]
divisions = [1, 1, 1]
[materials.m]
model = "neo-hooke"
mu = 1.0
[[stages]]
kind = "static"
steps = 2
"#;

    /// A branch of a preset's set on its own: the preset's other branches are kept.
    #[test]
    fn a_presets_branch_is_set_on_its_own() {
        let text = MINIMAL.replace(
            "model = \"neo-hooke\"\nmu = 1.0",
            "preset = \"vhb4910-wang2016\"",
        );
        let s = parse(&text, "t.toml", &["materials.m.branches.1.tau=7.5".into()]).unwrap();
        let (_, preset) = crate::material::registry::preset("vhb4910-wang2016").unwrap();
        let branches = s.materials["m"].branches.clone().expect("written out");
        assert_eq!(branches.len(), preset.branches.len());
        for (i, (b, p)) in branches.iter().zip(&preset.branches).enumerate() {
            assert_eq!(b.mu, p.0, "branch {i}");
            assert_eq!(b.tau, if i == 1 { 7.5 } else { p.1 }, "branch {i}");
        }
    }

    #[test]
    fn minimal_parses() {
        let s = parse(MINIMAL, "t.toml", &[]).unwrap();
        assert_eq!(s.stages[0].steps, Some(2));
        assert_eq!(s.mesh.element, None);
    }

    #[test]
    fn unknown_key_is_positioned_and_suggested() {
        let text = MINIMAL.replace("mu = 1.0", "muu = 1.0");
        let e = parse(&text, "t.toml", &[]).unwrap_err();
        assert_eq!(e.position.map(|p| p.0), Some(9), "{e}");
        assert!(e.to_string().contains("did you mean `mu`"), "{e}");
        assert!(
            e.key.as_deref().unwrap_or("").contains("materials.m"),
            "{e}"
        );
    }

    /// serde's type names do not reach the user: whole numbers, numbers and the material table
    /// are said in words.
    #[test]
    fn serde_words_are_translated() {
        let text = MINIMAL.replace("steps = 2", "steps = 2.5");
        let e = parse(&text, "t.toml", &[]).unwrap_err().to_string();
        assert!(e.contains("a whole number") && !e.contains("u64"), "{e}");
        let text = MINIMAL.replace("mu = 1.0", "mu = \"1e400\"");
        let e = parse(&text, "t.toml", &[]).unwrap_err().to_string();
        assert!(e.contains("a number") && !e.contains("f64"), "{e}");
        assert!(!e.contains("invalid type"), "{e}");
        let text = format!(
            "materials = {{ m = 3 }}\n{}",
            MINIMAL.replace("[materials.m]\nmodel = \"neo-hooke\"\nmu = 1.0\n", "")
        );
        let e = parse(&text, "t.toml", &[]).unwrap_err().to_string();
        assert!(!e.contains("MaterialSpec"), "{e}");
        assert!(e.contains("a material table"), "{e}");
        // a float where a whole number belongs is printed short, not with its 301 digits
        let text = MINIMAL.replace("steps = 2", "steps = 1e300");
        let e = parse(&text, "t.toml", &[]).unwrap_err().to_string();
        assert!(e.contains("`1e300`") && !e.contains("0000000000"), "{e}");
    }

    /// `--set stages[0].steps=3` names the key that is not one and the dotted form to use, not
    /// serde's "unknown field `stages[0]`"; `1e400` is said to be beyond a number's range, not a
    /// string of the wrong type.
    #[test]
    fn bracketed_and_overflowing_overrides_are_explained() {
        let e = parse(MINIMAL, "t.toml", &["stages[0].steps=3".to_string()])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`stages[0]` is not a key") && e.contains("`stages.0.steps`"),
            "{e}"
        );
        assert!(!e.contains("unknown field"), "{e}");
        let e = parse(MINIMAL, "t.toml", &["stages.0.steps=1e400".to_string()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("beyond the range of a number"), "{e}");
        assert!(!e.contains("string"), "{e}");
    }

    #[test]
    fn wrong_type_names_key_and_type() {
        let text = MINIMAL.replace("steps = 2", "steps = \"two\"");
        let e = parse(&text, "t.toml", &[]).unwrap_err();
        assert!(
            e.to_string().contains("stages[0].steps") || e.to_string().contains("stages.0.steps"),
            "{e}"
        );
        assert!(
            e.message.contains("a whole number") && !e.message.contains("u64"),
            "{e}"
        );
    }

    #[test]
    fn overrides_change_tables_and_arrays() {
        let s = parse(
            MINIMAL,
            "t.toml",
            &[
                "stages.0.steps=7".into(),
                "mesh.divisions=[2,3,4]".into(),
                "materials.m.viscosity=100".into(),
            ],
        )
        .unwrap();
        assert_eq!(s.stages[0].steps, Some(7));
        assert_eq!(s.mesh.divisions, Some([2, 3, 4]));
        assert_eq!(s.materials["m"].viscosity, Some(100.0));
        let e = parse(MINIMAL, "t.toml", &["materials.m.muu=3".into()]).unwrap_err();
        assert!(e.to_string().contains("did you mean `mu`"), "{e}");
        let e = parse(MINIMAL, "t.toml", &["stages.3.steps=1".into()]).unwrap_err();
        assert!(e.message.contains("past the end"), "{e}");
        let e = parse(MINIMAL, "t.toml", &["name.x=1".into()]).unwrap_err();
        assert!(e.message.contains("not a table"), "{e}");
        let e = parse(MINIMAL, "t.toml", &["nokey".into()]).unwrap_err();
        assert!(e.message.contains("KEY=VALUE"), "{e}");
    }

    #[test]
    fn syntax_errors_and_empty_files() {
        let e = parse("name = \n", "x.toml", &[]).unwrap_err();
        assert!(
            e.position.is_some() && e.message.contains("invalid TOML"),
            "{e}"
        );
        let e = parse("", "x.toml", &[]).unwrap_err();
        assert!(e.message.contains("empty"), "{e}");
        let e = parse("\u{0}\u{1}\u{2}binary", "x.toml", &[]).unwrap_err();
        assert!(e.message.contains("invalid TOML"), "{e}");
    }

    #[test]
    fn suggestions() {
        assert_eq!(
            closest("divsions", ["divisions", "size"]),
            Some("divisions")
        );
        assert_eq!(closest("zzzzzz", ["divisions", "size"]), None);
    }
}
