//! The calibration spec (TOML) and the measured curves (CSV) it names: parsed, checked and turned
//! into a [`Problem`] — the material, the parameters to fit with their bounds and scales, and the
//! experiments with their protocols and data. Every error names the file, the key or the line,
//! and what was expected.

use crate::io::scenario::{closest, InputError, MaterialSpec};
use crate::material::homogeneous::Mode;
use crate::material::registry::{self, MaterialParams};
use crate::material::Material;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The spec file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecFile {
    /// The material table: the keys of a scenario's `materials.<m>` table.
    pub material: MaterialSpec,
    #[serde(default)]
    pub parameters: Vec<ParameterSpec>,
    #[serde(default)]
    pub experiments: Vec<ExperimentSpec>,
    #[serde(default)]
    pub fit: FitSpec,
    /// Device-level objectives (a finite element run in the loop): refused for now.
    #[serde(default)]
    pub objective: Option<toml::Value>,
}

/// One fitted parameter.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    /// `material.<key>`: `material.mu`, `material.branches.0.tau`, …
    pub path: String,
    pub lower: f64,
    pub upper: f64,
    /// `linear` (default) or `log`: the variable the fit steps in.
    #[serde(default)]
    pub scale: Option<String>,
}

/// One measured test.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentSpec {
    pub name: String,
    /// `uniaxial`, `equibiaxial`, `pure-shear` (ramps), `cyclic`, `relaxation` (`creep` is not
    /// calibrated yet).
    pub test: String,
    /// Deformation of cyclic and relaxation tests (default `uniaxial`).
    #[serde(default)]
    pub mode: Option<String>,
    /// Largest (ramps, cycles) or held (relaxation) stretch (default 2.5).
    #[serde(default)]
    pub stretch: Option<f64>,
    /// Stretch rate (1/s) of ramps and cycles.
    #[serde(default)]
    pub rate: Option<f64>,
    /// Held stress of a creep test (Pa).
    #[serde(default)]
    pub stress: Option<f64>,
    /// Time (s) to reach the held stretch (default 0.1).
    #[serde(default)]
    pub ramp_time: Option<f64>,
    /// Hold time (s) of a relaxation test (default 60).
    #[serde(default)]
    pub hold: Option<f64>,
    /// Load–unload cycles (default 1).
    #[serde(default)]
    pub cycles: Option<usize>,
    /// Time steps per segment: ramp, hold, half cycle (default 200).
    #[serde(default)]
    pub steps: Option<usize>,
    /// CSV file, relative to the spec.
    pub data: String,
    /// Weight of the experiment's residuals (default 1).
    #[serde(default)]
    pub weight: Option<f64>,
}

/// Options of the fit.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct FitSpec {
    /// Iterations of the least-squares solver per start (default 200).
    pub max_iterations: Option<usize>,
    /// Relative reduction of the sum of squares below which the fit stops (default 1e-12).
    pub ftol: Option<f64>,
    /// Relative step in the scaled variables below which the fit stops (default 1e-10).
    pub xtol: Option<f64>,
    /// Largest scaled projected gradient at which the fit stops (default 1e-10).
    pub gtol: Option<f64>,
    /// Number of starts: the first from the material's values, the others spread over the box
    /// (default 1).
    pub starts: Option<usize>,
}

/// A parameter's variable in the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// z = θ.
    Linear,
    /// z = ln θ.
    Log,
}

/// A fitted parameter, checked.
#[derive(Debug, Clone)]
pub struct FitParameter {
    /// `material.<key>` as given.
    pub path: String,
    /// Index in the material's θ.
    pub index: usize,
    pub initial: f64,
    pub lower: f64,
    pub upper: f64,
    pub scale: Scale,
}

impl FitParameter {
    /// θ → z.
    pub fn to_z(&self, theta: f64) -> f64 {
        match self.scale {
            Scale::Linear => theta,
            Scale::Log => theta.ln(),
        }
    }
    /// z → θ, kept inside the bounds (exp ∘ ln may round past one).
    pub fn to_theta(&self, z: f64) -> f64 {
        match self.scale {
            Scale::Linear => z,
            Scale::Log => z.exp(),
        }
        .clamp(self.lower, self.upper)
    }
    /// dθ/dz at θ.
    pub fn dtheta_dz(&self, theta: f64) -> f64 {
        match self.scale {
            Scale::Linear => 1.0,
            Scale::Log => theta,
        }
    }
}

/// The loading of an experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Protocol {
    /// λ = 1 + rate·t up to `stretch` (no unloading).
    Ramp { stretch: f64, rate: f64 },
    /// Triangles 1 → `stretch` → 1, `cycles` times, at `rate`.
    Cyclic {
        stretch: f64,
        rate: f64,
        cycles: usize,
    },
    /// λ rises linearly to `stretch` in `ramp_time`, then is held for `hold`.
    Relaxation {
        stretch: f64,
        ramp_time: f64,
        hold: f64,
    },
}

impl Protocol {
    /// The prescribed stretch at time t.
    pub fn stretch_at(&self, t: f64) -> f64 {
        match *self {
            Protocol::Ramp { stretch, rate } => {
                let s = (stretch - 1.0).signum();
                1.0 + s * rate * t
            }
            Protocol::Cyclic { stretch, rate, .. } => {
                let half = (stretch - 1.0).abs() / rate;
                let p = (t / half) % 2.0;
                let p = if p <= 1.0 { p } else { 2.0 - p };
                1.0 + (stretch - 1.0) * p
            }
            Protocol::Relaxation {
                stretch, ramp_time, ..
            } => 1.0 + (stretch - 1.0) * (t / ramp_time).min(1.0),
        }
    }

    /// The step end times with `steps` steps per segment, and the segments' end indices into
    /// the path (index 0 = the initial state at t = 0): a ramp has one segment, a cycle two per
    /// cycle (loading, unloading), a relaxation test two (ramp, hold).
    pub fn times(&self, steps: usize) -> (Vec<f64>, Vec<usize>) {
        let mut times = Vec::new();
        let mut ends = Vec::new();
        let mut segment = |times: &mut Vec<f64>, a: f64, b: f64| {
            times.extend((1..=steps).map(|i| a + (b - a) * i as f64 / steps as f64));
            ends.push(times.len());
        };
        match *self {
            Protocol::Ramp { stretch, rate } => {
                segment(&mut times, 0.0, (stretch - 1.0).abs() / rate);
            }
            Protocol::Cyclic {
                stretch,
                rate,
                cycles,
            } => {
                let half = (stretch - 1.0).abs() / rate;
                for k in 0..2 * cycles {
                    segment(&mut times, k as f64 * half, (k + 1) as f64 * half);
                }
            }
            Protocol::Relaxation {
                ramp_time, hold, ..
            } => {
                segment(&mut times, 0.0, ramp_time);
                if hold > 0.0 {
                    segment(&mut times, ramp_time, ramp_time + hold);
                }
            }
        }
        (times, ends)
    }
}

/// Measured points of an experiment.
#[derive(Debug, Clone, Default)]
pub struct Data {
    pub stretch: Vec<f64>,
    /// Nominal stress (Pa).
    pub stress: Vec<f64>,
    /// Time (s), when the file has the column.
    pub time: Option<Vec<f64>>,
    /// 1-based line of each point in the file.
    pub lines: Vec<usize>,
}

/// An experiment, checked: its protocol, steps and data.
#[derive(Debug, Clone)]
pub struct Experiment {
    pub name: String,
    /// The `test` key.
    pub test: String,
    pub mode: Mode,
    pub protocol: Protocol,
    pub steps: usize,
    pub weight: f64,
    pub data_path: PathBuf,
    pub data: Data,
}

/// Options of the least-squares fit, defaults filled in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    pub max_iterations: usize,
    pub ftol: f64,
    pub xtol: f64,
    pub gtol: f64,
    pub starts: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_iterations: 200,
            ftol: 1e-12,
            xtol: 1e-10,
            gtol: 1e-10,
            starts: 1,
        }
    }
}

/// A material-point calibration problem, checked.
#[derive(Debug, Clone)]
pub struct Problem {
    /// The spec file (for messages).
    pub file: String,
    /// The registry model name and the material's parameter set as given.
    pub model: String,
    pub params: MaterialParams,
    /// The material built from them.
    pub material: Arc<dyn Material>,
    pub parameters: Vec<FitParameter>,
    pub experiments: Vec<Experiment>,
    pub options: FitOptions,
}

/// The message of a material-point spec that holds device-level objectives.
pub const DEVICE_OBJECTIVES: &str =
    "`[[objective]]` terms belong to a device calibration, a scenario with `[[parameters]]` and \
     `[[objective]]` (`deasim calibrate SCENARIO.toml`, `Simulation::calibrate_device`); a \
     material-point spec with `[[experiments]]` cannot hold them";

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |s| s.chars().count()) + 1;
    (line, col)
}

/// Whether `text` (a TOML document) holds device-level objectives: the one thing the material
/// level refuses before anything else.
pub fn has_objectives(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("objective"))
}

/// Whether `text` (a TOML document) is a scenario to calibrate at device level: objectives and
/// no material-point experiments.
pub fn is_device(text: &str) -> bool {
    toml::from_str::<toml::Table>(text)
        .is_ok_and(|t| t.contains_key("objective") && !t.contains_key("experiments"))
}

/// Parses the spec at `path` and reads its data. `Err(None)`-free: every error is an
/// [`InputError`] naming the file and the key (or the CSV file and line).
pub fn read(path: &Path) -> Result<Problem, InputError> {
    read_with(path, &[])
}

/// [`read`] with `--set KEY=VALUE` overrides applied to the spec's table before it is checked
/// (the same syntax as a scenario's: `material.mu=2e4`, `experiments.0.weight=2`).
pub fn read_with(path: &Path, overrides: &[String]) -> Result<Problem, InputError> {
    let file = path.display().to_string();
    let mut text = std::fs::read_to_string(path).map_err(|e| InputError {
        file: file.clone(),
        position: None,
        key: None,
        message: format!("cannot read the calibration spec: {e}"),
    })?;
    if !overrides.is_empty() {
        let mut table: toml::Table = toml::from_str(&text).map_err(|e| InputError {
            file: file.clone(),
            position: e.span().map(|s| line_col(&text, s.start)),
            key: None,
            message: format!("invalid TOML: {}", e.message().trim()),
        })?;
        for o in overrides {
            crate::io::scenario::apply_override(&mut table, o).map_err(|(key, message)| {
                InputError {
                    file: "--set".into(),
                    position: None,
                    key: Some(key),
                    message,
                }
            })?;
        }
        text = toml::to_string(&table).map_err(|e| InputError {
            file: file.clone(),
            position: None,
            key: None,
            message: format!("the overridden spec cannot be written back: {e}"),
        })?;
    }
    let base = path.parent().unwrap_or(Path::new("."));
    parse(&text, &file, base)
}

/// Parses a spec's text; `file` names it in messages, `base` is the directory its data paths are
/// relative to.
pub fn parse(text: &str, file: &str, base: &Path) -> Result<Problem, InputError> {
    let err = |key: &str, message: String| InputError::at_key(file, key, message);
    let de = toml::Deserializer::parse(text).map_err(|e| InputError {
        file: file.into(),
        position: e.span().map(|s| line_col(text, s.start)),
        key: None,
        message: format!("invalid TOML: {}", e.message().trim()),
    })?;
    let spec: SpecFile = serde_path_to_error::deserialize(de).map_err(|e| {
        let key = e.path().to_string().replace('[', ".").replace(']', "");
        let inner = e.into_inner();
        InputError {
            file: file.into(),
            position: inner.span().map(|s| line_col(text, s.start)),
            key: (key != "." && !key.is_empty()).then_some(key),
            message: inner
                .message()
                .replace("struct MaterialSpec", "a material table"),
        }
    })?;
    if spec.objective.is_some() {
        return Err(err("objective", DEVICE_OBJECTIVES.into()));
    }
    let (model, params) = material_params(&spec.material).map_err(|(k, m)| err(&k, m))?;
    let (material, _) = registry::build(&model, &params)
        .map_err(|e| err(&format!("material.{}", e.key), e.message))?;
    let theta = material.parameters().ok_or_else(|| {
        err(
            "material.model",
            "this material has no parameter vector".into(),
        )
    })?;
    if spec.parameters.is_empty() {
        return Err(err(
            "parameters",
            "no parameter to fit: give at least one `[[parameters]]` with `path = \"material.<key>\"`"
                .into(),
        ));
    }
    let mut parameters: Vec<FitParameter> = Vec::new();
    for (i, p) in spec.parameters.iter().enumerate() {
        let key = |k: &str| format!("parameters.{i}.{k}");
        let name = p.path.strip_prefix("material.").ok_or_else(|| {
            err(
                &key("path"),
                format!(
                    "expected `material.<key>` (e.g. `material.mu`); got `{}`",
                    p.path
                ),
            )
        })?;
        let index = theta.index(name).ok_or_else(|| {
            let hint = closest(name, theta.names.iter().map(|s| s.as_str()))
                .map(|c| format!("; did you mean `material.{c}`?"))
                .unwrap_or_default();
            err(
                &key("path"),
                format!(
                    "`{}` is not a differentiable parameter of this `{model}` material (it has: \
                     {}){hint}",
                    p.path,
                    theta.names.join(", ")
                ),
            )
        })?;
        if parameters.iter().any(|q| q.index == index) {
            return Err(err(&key("path"), format!("`{}` is given twice", p.path)));
        }
        let scale = match p.scale.as_deref() {
            None | Some("linear") => Scale::Linear,
            Some("log") => Scale::Log,
            Some(o) => {
                return Err(err(
                    &key("scale"),
                    format!("expected `linear` or `log`; got `{o}`"),
                ))
            }
        };
        if !(p.lower.is_finite() && p.upper.is_finite() && p.lower < p.upper) {
            return Err(err(
                &key("upper"),
                format!(
                    "`{}`: expected finite bounds with lower < upper; got [{}, {}]",
                    p.path, p.lower, p.upper
                ),
            ));
        }
        if scale == Scale::Log && p.lower <= 0.0 {
            return Err(err(
                &key("lower"),
                format!(
                    "`{}`: a log-scaled parameter needs a positive lower bound; got {}",
                    p.path, p.lower
                ),
            ));
        }
        let initial = theta.values[index];
        if !(p.lower..=p.upper).contains(&initial) {
            return Err(err(
                &key("path"),
                format!(
                    "`{}`: the starting value {initial} (from [material]) lies outside its bounds \
                     [{}, {}]",
                    p.path, p.lower, p.upper
                ),
            ));
        }
        parameters.push(FitParameter {
            path: p.path.clone(),
            index,
            initial,
            lower: p.lower,
            upper: p.upper,
            scale,
        });
    }
    if spec.experiments.is_empty() {
        return Err(err(
            "experiments",
            "no experiment: give at least one `[[experiments]]` with its test and data".into(),
        ));
    }
    let mut experiments = Vec::new();
    for (i, e) in spec.experiments.iter().enumerate() {
        experiments.push(experiment(file, i, e, base)?);
    }
    let n_data: usize = experiments.iter().map(|e| e.data.stress.len()).sum();
    if n_data <= parameters.len() {
        return Err(err(
            "experiments",
            format!(
                "{n_data} data points for {} parameters: a fit needs more points than parameters",
                parameters.len()
            ),
        ));
    }
    let d = FitOptions::default();
    let f = &spec.fit;
    let options = FitOptions {
        max_iterations: f.max_iterations.unwrap_or(d.max_iterations),
        ftol: f.ftol.unwrap_or(d.ftol),
        xtol: f.xtol.unwrap_or(d.xtol),
        gtol: f.gtol.unwrap_or(d.gtol),
        starts: f.starts.unwrap_or(d.starts),
    };
    for (k, v) in [
        ("fit.ftol", options.ftol),
        ("fit.xtol", options.xtol),
        ("fit.gtol", options.gtol),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(err(k, format!("expected a number ≥ 0; got {v}")));
        }
    }
    if !(1..=100_000).contains(&options.max_iterations) {
        return Err(err(
            "fit.max_iterations",
            format!("expected 1 to 100000; got {}", options.max_iterations),
        ));
    }
    if !(1..=1000).contains(&options.starts) {
        return Err(err(
            "fit.starts",
            format!("expected 1 to 1000; got {}", options.starts),
        ));
    }
    Ok(Problem {
        file: file.into(),
        model,
        params,
        material,
        parameters,
        experiments,
        options,
    })
}

/// The model name and parameters of a material table: a preset's overridden by those given (as
/// a scenario's materials).
pub fn material_params(m: &MaterialSpec) -> Result<(String, MaterialParams), (String, String)> {
    let (model, mut p) = match &m.preset {
        None => {
            let model = m.model.clone().ok_or_else(|| {
                (
                    "material.model".to_string(),
                    format!(
                        "missing: expected a model ({}) or a `preset`",
                        registry::MODELS.join(", ")
                    ),
                )
            })?;
            (model, MaterialParams::default())
        }
        Some(preset) => {
            let (model, p) = registry::preset(preset).ok_or_else(|| {
                (
                    "material.preset".to_string(),
                    format!(
                        "unknown preset `{preset}` (known: {})",
                        registry::PRESETS.join(", ")
                    ),
                )
            })?;
            if let Some(given) = &m.model {
                if given != model {
                    return Err((
                        "material.model".into(),
                        format!("preset `{preset}` is a `{model}` material; got model `{given}`"),
                    ));
                }
            }
            (model.to_string(), p)
        }
    };
    if !registry::MODELS.contains(&model.as_str()) {
        return Err((
            "material.model".into(),
            format!(
                "unknown material model `{model}` (known: {})",
                registry::MODELS.join(", ")
            ),
        ));
    }
    for (k, v) in [
        ("density", m.density),
        ("viscosity", m.viscosity),
        ("breakdown_field", m.breakdown_field),
    ] {
        if v.is_some() {
            return Err((
                format!("material.{k}"),
                "not part of a material-point calibration (the point has no inertia, no \
                 Kelvin–Voigt viscosity and no field); remove it"
                    .into(),
            ));
        }
    }
    crate::io::build::override_parameters(m, &mut p);
    Ok((model, p))
}

/// Checks experiment `i` and reads its data.
fn experiment(
    file: &str,
    i: usize,
    e: &ExperimentSpec,
    base: &Path,
) -> Result<Experiment, InputError> {
    let key = |k: &str| format!("experiments.{i}.{k}");
    let err = |k: &str, message: String| InputError::at_key(file, key(k), message);
    let positive = |k: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(err(k, format!("expected a positive number; got {v}")))
        }
    };
    let mode_name = match e.test.as_str() {
        "uniaxial" | "equibiaxial" | "pure-shear" => e.test.as_str(),
        _ => e.mode.as_deref().unwrap_or("uniaxial"),
    };
    let mode = match mode_name {
        "uniaxial" => Mode::Uniaxial,
        "equibiaxial" => Mode::Equibiaxial,
        "pure-shear" => Mode::PureShear,
        o => {
            return Err(err(
                "mode",
                format!("expected `uniaxial`, `equibiaxial` or `pure-shear`; got `{o}`"),
            ))
        }
    };
    let stretch = positive("stretch", e.stretch.unwrap_or(2.5))?;
    if (stretch - 1.0).abs() < 1e-12 {
        return Err(err(
            "stretch",
            "1 is the undeformed state; give the stretch to reach".into(),
        ));
    }
    let rate = || -> Result<f64, InputError> {
        let r = e
            .rate
            .ok_or_else(|| err("rate", "missing: the stretch rate in 1/s".into()))?;
        positive("rate", r)
    };
    let cycles = e.cycles.unwrap_or(1);
    if !(1..=1000).contains(&cycles) {
        return Err(err("cycles", format!("expected 1 to 1000; got {cycles}")));
    }
    let protocol = match e.test.as_str() {
        "uniaxial" | "equibiaxial" | "pure-shear" => Protocol::Ramp {
            stretch,
            rate: rate()?,
        },
        "cyclic" => Protocol::Cyclic {
            stretch,
            rate: rate()?,
            cycles,
        },
        "relaxation" => Protocol::Relaxation {
            stretch,
            ramp_time: positive("ramp_time", e.ramp_time.unwrap_or(0.1))?,
            hold: {
                let h = e.hold.unwrap_or(60.0);
                if !(h.is_finite() && h >= 0.0) {
                    return Err(err("hold", format!("expected a time ≥ 0 in s; got {h}")));
                }
                h
            },
        },
        "creep" => {
            return Err(err(
                "test",
                "creep experiments (stress control) cannot be calibrated yet; use cyclic, \
                 relaxation or ramp data"
                    .into(),
            ))
        }
        o => {
            return Err(err(
                "test",
                format!(
                    "expected `uniaxial`, `equibiaxial`, `pure-shear`, `cyclic` or `relaxation`; \
                     got `{o}`"
                ),
            ))
        }
    };
    if e.stress.is_some() {
        return Err(err(
            "stress",
            "only a creep test holds a stress; this test prescribes the stretch".into(),
        ));
    }
    let steps = e.steps.unwrap_or(200);
    if !(1..=1_000_000).contains(&steps) {
        return Err(err("steps", format!("expected 1 to 1000000; got {steps}")));
    }
    let weight = e.weight.unwrap_or(1.0);
    if !(weight.is_finite() && weight > 0.0) {
        return Err(err(
            "weight",
            format!("expected a positive number; got {weight}"),
        ));
    }
    let data_path = base.join(&e.data);
    let text = std::fs::read_to_string(&data_path).map_err(|x| {
        err(
            "data",
            format!("cannot read `{}`: {x}", data_path.display()),
        )
    })?;
    let timed = matches!(protocol, Protocol::Relaxation { .. });
    let data = read_csv(&text, &data_path.display().to_string(), timed)?;
    Ok(Experiment {
        name: e.name.clone(),
        test: e.test.clone(),
        mode,
        protocol,
        steps,
        weight,
        data_path,
        data,
    })
}

/// Reads a measured curve: a header naming `stretch`, `nominal_stress_pa` (or
/// `nominal_stress_kpa`) and, for timed protocols (`needs_time`), `time_s`; lines starting with
/// `#` and blank lines are skipped; times must increase.
pub fn read_csv(text: &str, file: &str, needs_time: bool) -> Result<Data, InputError> {
    let at = |line: usize, message: String| InputError {
        file: file.into(),
        position: Some((line, 1)),
        key: None,
        message,
    };
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hline, header) = rows.next().ok_or_else(|| {
        at(
            1,
            "empty file: expected a header `stretch,nominal_stress_pa`".into(),
        )
    })?;
    let names: Vec<&str> = header.split(',').map(|s| s.trim()).collect();
    let col = |n: &str| names.iter().position(|c| *c == n);
    let stretch = col("stretch").ok_or_else(|| {
        at(
            hline,
            format!("no column `stretch` in the header `{header}`"),
        )
    })?;
    let (stress, factor) = match (col("nominal_stress_pa"), col("nominal_stress_kpa")) {
        (Some(c), _) => (c, 1.0),
        (None, Some(c)) => (c, 1e3),
        _ => {
            return Err(at(
                hline,
                format!(
                "no column `nominal_stress_pa` (or `nominal_stress_kpa`) in the header `{header}`"
            ),
            ))
        }
    };
    let time = col("time_s");
    if needs_time && time.is_none() {
        return Err(at(
            hline,
            format!("no column `time_s` in the header `{header}`: this test is compared in time"),
        ));
    }
    let mut data = Data {
        time: time.map(|_| Vec::new()),
        ..Default::default()
    };
    for (line, row) in rows {
        let cells: Vec<&str> = row.split(',').map(|s| s.trim()).collect();
        if cells.len() != names.len() {
            return Err(at(
                line,
                format!("{} values for {} columns", cells.len(), names.len()),
            ));
        }
        let num = |c: usize| -> Result<f64, InputError> {
            let v: f64 = cells[c].parse().map_err(|_| {
                at(
                    line,
                    format!("column `{}`: `{}` is not a number", names[c], cells[c]),
                )
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(at(
                    line,
                    format!("column `{}`: {v} is not a finite number", names[c]),
                ))
            }
        };
        let l = num(stretch)?;
        if l <= 0.0 {
            return Err(at(
                line,
                format!("column `stretch`: must be positive; got {l}"),
            ));
        }
        data.stretch.push(l);
        data.stress.push(num(stress)? * factor);
        if let (Some(c), Some(t)) = (time, data.time.as_mut()) {
            let v = num(c)?;
            if let Some(&prev) = t.last() {
                if v <= prev {
                    return Err(at(
                        line,
                        format!("column `time_s`: times must increase; got {v} after {prev}"),
                    ));
                }
            }
            if v < 0.0 {
                return Err(at(line, format!("column `time_s`: must be ≥ 0; got {v}")));
            }
            t.push(v);
        }
        data.lines.push(line);
    }
    if data.stress.is_empty() {
        return Err(at(hline, "no data rows below the header".into()));
    }
    Ok(data)
}

/// A registry model's name and the material built.
pub type NamedMaterial = (String, Arc<dyn Material>);

/// The material of a TOML file's `[material]` table (a calibration's `fitted.toml`, or a spec),
/// if the file has one; `None` when it has none (e.g. a scenario).
pub fn material_table(text: &str, file: &str) -> Option<Result<NamedMaterial, InputError>> {
    let table: toml::Table = toml::from_str(text).ok()?;
    let value = table.get("material")?.clone();
    Some((|| {
        let spec: MaterialSpec = serde_path_to_error::deserialize(value).map_err(|e| {
            let key = e.path().to_string().replace('[', ".").replace(']', "");
            InputError::at_key(
                file,
                format!("material.{key}"),
                e.into_inner().message().to_string(),
            )
        })?;
        let (model, params) =
            material_params(&spec).map_err(|(k, m)| InputError::at_key(file, k, m))?;
        let (mat, _) = registry::build(&model, &params)
            .map_err(|e| InputError::at_key(file, format!("material.{}", e.key), e.message))?;
        Ok((model, mat))
    })())
}
