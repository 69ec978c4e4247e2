//! Validation of a parsed [`Scenario`] and construction of what the analysis runs: the model, the
//! electrodes with their waveforms, the stages and the probes. Every error names the file, the key
//! and what was expected (type, range, unit).

use super::scenario::{closest, InputError, MaterialSpec, Scenario, VoltageSpec, WaveformSpec};
use crate::element::mean_dilatation::Formulation;
pub use crate::job::plan::{Electrode, OutputPlan, Plan, Prestretch, Rigid, Stage, StageKind};
use crate::job::probes::{NodalQuantity, Probe, ProbeKind};
use crate::material::registry::{self, MaterialParams};
use crate::material::Material;
use crate::mesh::disc::{disc_mesh, DiscSpec};
use crate::mesh::stack::{stack_mesh, StackSpec};
use crate::mesh::{generate::box_mesh, ElementKind, Mesh};
use crate::problem::dofs::Field;
use crate::problem::model::Model;
use crate::solve::linear::{Ordering, SolverKind, SolverSettings};
use crate::time::mass::MassKind;
use crate::time::stage::Method;
use crate::waveform::{FourierBase, Shape, Waveform};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Fewest time steps per period of a periodic voltage before a warning.
pub const MIN_STEPS_PER_PERIOD: f64 = 20.0;

/// Largest number of cells a generated mesh may have (memory guard: ~5 GB of tangent).
pub const MAX_CELLS: u64 = 2_000_000;

struct Ctx<'a> {
    file: &'a str,
}

impl Ctx<'_> {
    fn err(&self, key: impl Into<String>, msg: impl Into<String>) -> InputError {
        InputError::at_key(self.file, key, msg)
    }

    fn positive(&self, key: &str, v: Option<f64>, what: &str) -> Result<f64, InputError> {
        match v {
            None => Err(self.err(key, format!("missing: expected {what} (a positive number)"))),
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            Some(x) => Err(self.err(
                key,
                format!("must be a positive finite number ({what}); got {x}"),
            )),
        }
    }

    fn finite(&self, key: &str, v: f64, what: &str) -> Result<f64, InputError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(key, format!("must be a finite number ({what}); got {v}")))
        }
    }

    fn set_nodes(&self, mesh: &Mesh, key: &str, name: &str) -> Result<Vec<usize>, InputError> {
        match mesh.set_nodes(name) {
            Some(n) if !n.is_empty() => Ok(n),
            Some(_) => Err(self.err(key, format!("set `{name}` is empty"))),
            None => {
                let names = mesh.set_names();
                let hint = closest(name, names.iter().map(|s| s.as_str()))
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                Err(self.err(
                    key,
                    format!(
                        "unknown set `{name}` (the mesh has: {}){hint}",
                        names.join(", ")
                    ),
                ))
            }
        }
    }
}

/// The element kinds by scenario name.
const ELEMENTS: [(&str, ElementKind); 3] = [
    ("hex8", ElementKind::Hex8),
    ("tet4", ElementKind::Tet4),
    ("tet10", ElementKind::Tet10),
];

fn element_kind(ctx: &Ctx, name: &str) -> Result<ElementKind, InputError> {
    ELEMENTS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, k)| *k)
        .ok_or_else(|| {
            let hint = closest(name, ELEMENTS.map(|e| e.0))
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            ctx.err(
                "mesh.element",
                format!("unknown element `{name}`: expected `hex8`, `tet4` or `tet10`{hint}"),
            )
        })
}

/// The mesh of a scenario, and warnings about it (cells the Gmsh import reoriented).
fn build_mesh(
    ctx: &Ctx,
    s: &Scenario,
    base_dir: Option<&Path>,
) -> Result<(Mesh, Vec<String>), InputError> {
    let m = &s.mesh;
    if let Some(file) = &m.file {
        return build_file_mesh(ctx, m, file, base_dir);
    }
    if m.scale.is_some() {
        return Err(ctx.err("mesh.scale", "applies to meshes read from a `file` only"));
    }
    let generator = m.generator.as_deref().ok_or_else(|| {
        ctx.err(
            "mesh.generator",
            "missing: expected `box`, `disc` or `stack` (or a `file`)",
        )
    })?;
    if !["box", "disc", "stack"].contains(&generator) {
        let hint = closest(generator, ["box", "disc", "stack"])
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
        return Err(ctx.err(
            "mesh.generator",
            format!("unknown generator `{generator}`: expected `box`, `disc` or `stack`{hint}"),
        ));
    }
    reject_foreign_keys(ctx, m, generator)?;
    let kind = element_kind(ctx, m.element.as_deref().unwrap_or("hex8"))?;
    if generator == "disc" {
        return Ok((build_disc(ctx, m, kind)?, Vec::new()));
    }
    if generator == "stack" {
        return Ok((build_stack(ctx, m, kind)?, Vec::new()));
    }
    let size = m
        .size
        .ok_or_else(|| ctx.err("mesh.size", "missing: expected [lx, ly, lz] in m"))?;
    for (i, v) in size.iter().enumerate() {
        ctx.positive(&format!("mesh.size.{i}"), Some(*v), "edge length in m")?;
    }
    let div = m.divisions.ok_or_else(|| {
        ctx.err(
            "mesh.divisions",
            "missing: expected [nx, ny, nz], cells per direction",
        )
    })?;
    if div.contains(&0) {
        return Err(ctx.err("mesh.divisions", "every entry must be at least 1"));
    }
    let per_hex = if kind == ElementKind::Hex8 { 1 } else { 6 };
    let cells = div
        .iter()
        .try_fold(per_hex as u64, |acc, &d| acc.checked_mul(d));
    match cells {
        Some(c) if c <= MAX_CELLS => {
            // before generating it: the nodes of the box
            let per_div = if kind == ElementKind::Tet10 { 2 } else { 1 };
            let nodes: u64 = div.iter().map(|&d| per_div * d + 1).product();
            super::memory::check(nodes, c, kind).map_err(|e| ctx.err("mesh.divisions", e))?;
        }
        _ => {
            return Err(ctx.err(
                "mesh.divisions",
                format!(
                "{div:?} gives more than {MAX_CELLS} cells: too large for this machine's memory"
            ),
            ))
        }
    }
    Ok((
        box_mesh(
            size,
            [div[0] as usize, div[1] as usize, div[2] as usize],
            kind,
        ),
        Vec::new(),
    ))
}

/// Keys of the `stack` generator (the other generators reject them).
const STACK_KEYS: [&str; 6] = [
    "side",
    "films",
    "film_thickness",
    "border",
    "layers_per_film",
    "active_cells",
];

/// Rejects a stack key given to `box` or `disc`, and a `box` or `disc` key given to `stack`.
fn reject_foreign_keys(
    ctx: &Ctx,
    m: &super::scenario::MeshSpec,
    generator: &str,
) -> Result<(), InputError> {
    let given = [
        ("size", m.size.is_some()),
        ("divisions", m.divisions.is_some()),
        ("radius", m.radius.is_some()),
        ("thickness", m.thickness.is_some()),
        ("pad_radius", m.pad_radius.is_some()),
        ("electrode_radius", m.electrode_radius.is_some()),
        ("radial", m.radial.is_some()),
        ("layers", m.layers.is_some()),
        ("side", m.side.is_some()),
        ("films", m.films.is_some()),
        ("film_thickness", m.film_thickness.is_some()),
        ("border", m.border.is_some()),
        ("layers_per_film", m.layers_per_film.is_some()),
        ("active_cells", m.active_cells.is_some()),
    ];
    for (key, is_given) in given {
        let stack_key = STACK_KEYS.contains(&key);
        if is_given && stack_key != (generator == "stack") {
            let owner = if stack_key {
                "`stack`"
            } else {
                "`box` or `disc`"
            };
            return Err(ctx.err(
                format!("mesh.{key}"),
                format!("applies to the {owner} generator, not to `generator = \"{generator}\"`"),
            ));
        }
    }
    Ok(())
}

/// `mesh.file`: a Gmsh mesh, its path relative to the scenario file.
fn build_file_mesh(
    ctx: &Ctx,
    m: &super::scenario::MeshSpec,
    file: &str,
    base_dir: Option<&Path>,
) -> Result<(Mesh, Vec<String>), InputError> {
    let generator_keys = [
        ("generator", m.generator.is_some()),
        ("size", m.size.is_some()),
        ("divisions", m.divisions.is_some()),
        ("radius", m.radius.is_some()),
        ("thickness", m.thickness.is_some()),
        ("pad_radius", m.pad_radius.is_some()),
        ("electrode_radius", m.electrode_radius.is_some()),
        ("radial", m.radial.is_some()),
        ("layers", m.layers.is_some()),
        ("quarter", m.quarter.is_some()),
        ("grading", m.grading.is_some()),
        ("side", m.side.is_some()),
        ("films", m.films.is_some()),
        ("film_thickness", m.film_thickness.is_some()),
        ("border", m.border.is_some()),
        ("layers_per_film", m.layers_per_film.is_some()),
        ("active_cells", m.active_cells.is_some()),
    ];
    if let Some((k, _)) = generator_keys.iter().find(|(_, given)| *given) {
        return Err(ctx.err(
            format!("mesh.{k}"),
            format!(
                "applies to the mesh generators, not to a mesh read from `mesh.file = \"{file}\"`"
            ),
        ));
    }
    let scale = match m.scale {
        None => 1.0,
        Some(v) => ctx.positive("mesh.scale", Some(v), "factor from file units to m")?,
    };
    let path = base_dir
        .map(|d| d.join(file))
        .unwrap_or_else(|| file.into());
    let g = crate::mesh::gmsh::read_msh(&path, scale)
        .map_err(|e| ctx.err("mesh.file", e.to_string()))?;
    if let Some(name) = &m.element {
        let want = element_kind(ctx, name)?;
        if want != g.mesh.kind {
            return Err(ctx.err(
                "mesh.element",
                format!(
                    "`{name}` given, but `{}` holds {} cells",
                    path.display(),
                    g.mesh.kind.name()
                ),
            ));
        }
    }
    if g.mesh.n_cells() as u64 > MAX_CELLS {
        return Err(ctx.err(
            "mesh.file",
            format!(
                "{} cells: too large for this machine's memory",
                g.mesh.n_cells()
            ),
        ));
    }
    let mut warnings = Vec::new();
    if g.reoriented > 0 {
        warnings.push(format!(
            "{}: {} inverted cells were reordered to a positive orientation",
            path.display(),
            g.reoriented
        ));
    }
    Ok((g.mesh, warnings))
}

/// The `disc` generator: a circular membrane (O-grid) with sets `rim`, `top`, `bottom`, `pad`,
/// `electrode_top`, `electrode_bottom` (and `symmetry_x`, `symmetry_y` for a quarter).
fn build_disc(
    ctx: &Ctx,
    m: &super::scenario::MeshSpec,
    kind: ElementKind,
) -> Result<Mesh, InputError> {
    let radius = ctx.positive("mesh.radius", m.radius, "outer radius in m")?;
    let thickness = ctx.positive("mesh.thickness", m.thickness, "thickness in m")?;
    let pad_radius = ctx.positive("mesh.pad_radius", m.pad_radius, "pad radius in m")?;
    let electrode_radius = ctx.positive(
        "mesh.electrode_radius",
        m.electrode_radius,
        "electrode radius in m",
    )?;
    let radial = m.radial.unwrap_or(8);
    let layers = m.layers.unwrap_or(1);
    if !(2..=2000).contains(&radial) {
        return Err(ctx.err(
            "mesh.radial",
            format!("must be between 2 and 2000; got {radial}"),
        ));
    }
    if !(1..=200).contains(&layers) {
        return Err(ctx.err(
            "mesh.layers",
            format!("must be between 1 and 200; got {layers}"),
        ));
    }
    let spec = DiscSpec {
        radius,
        thickness,
        pad_radius,
        electrode_radius,
        radial: radial as usize,
        layers: layers as usize,
        quarter: m.quarter.unwrap_or(true),
        grading: m.grading.unwrap_or(1.0),
        kind,
    };
    let layout = spec.layout().map_err(|e| ctx.err("mesh", e))?;
    check_cell_count(ctx, "mesh.radial", layout.hexahedra, kind)?;
    disc_mesh(&spec).map_err(|e| ctx.err("mesh", e))
}

/// Refuses a generated mesh of more than [`MAX_CELLS`] cells (`hexahedra` of the layout, six
/// tetrahedra each for tet meshes), naming `key`, the parameter that sets the size.
fn check_cell_count(
    ctx: &Ctx,
    key: &str,
    hexahedra: usize,
    kind: ElementKind,
) -> Result<(), InputError> {
    let cells = hexahedra as u64 * if kind == ElementKind::Hex8 { 1 } else { 6 };
    if cells > MAX_CELLS {
        return Err(ctx.err(
            key,
            format!("{cells} cells: too large for this machine's memory"),
        ));
    }
    Ok(())
}

/// The `stack` generator: `films` films with electrodes `electrode_0` … `electrode_N` on every
/// interface, a passive `border`, cells graded toward the electrode edges (see
/// [`crate::mesh::stack`]).
fn build_stack(
    ctx: &Ctx,
    m: &super::scenario::MeshSpec,
    kind: ElementKind,
) -> Result<Mesh, InputError> {
    let side = match m.side.as_ref().map(|s| s.to_vec()) {
        None => {
            return Err(ctx.err(
                "mesh.side",
                "missing: expected the side length in m, or [lx, ly]",
            ))
        }
        Some(v) if v.len() == 1 => [v[0], v[0]],
        Some(v) if v.len() == 2 => [v[0], v[1]],
        Some(v) => {
            return Err(ctx.err(
                "mesh.side",
                format!(
                    "expected one side length or [lx, ly] in m; got {} values",
                    v.len()
                ),
            ))
        }
    };
    for (i, v) in side.iter().enumerate() {
        ctx.positive(&format!("mesh.side.{i}"), Some(*v), "side length in m")?;
    }
    let film_thickness = ctx.positive(
        "mesh.film_thickness",
        m.film_thickness,
        "film thickness in m",
    )?;
    let films = m
        .films
        .ok_or_else(|| ctx.err("mesh.films", "missing: expected the number of films (≥ 1)"))?;
    let border = m.border.ok_or_else(|| {
        ctx.err(
            "mesh.border",
            "missing: expected the passive border width in m",
        )
    })?;
    let half = 0.5 * side[0].min(side[1]);
    if !(border.is_finite() && border >= 0.0 && border < half) {
        return Err(ctx.err(
            "mesh.border",
            format!("must lie in [0, {half}) m (half the shorter side); got {border}"),
        ));
    }
    for (key, value, range) in [
        ("films", films, 1..=1000),
        ("layers_per_film", m.layers_per_film.unwrap_or(2), 1..=100),
        ("active_cells", m.active_cells.unwrap_or(8), 1..=2000),
    ] {
        if !range.contains(&value) {
            return Err(ctx.err(
                format!("mesh.{key}"),
                format!(
                    "must be between {} and {}; got {value}",
                    range.start(),
                    range.end()
                ),
            ));
        }
    }
    let grading = m.grading.unwrap_or(1.0);
    if !(grading.is_finite() && (1.0..=1e3).contains(&grading)) {
        return Err(ctx.err(
            "mesh.grading",
            format!("expected a size ratio between 1 and 1000; got {grading}"),
        ));
    }
    let spec = StackSpec {
        side,
        films: films as usize,
        film_thickness,
        border,
        layers_per_film: m.layers_per_film.unwrap_or(2) as usize,
        active_cells: m.active_cells.unwrap_or(8) as usize,
        grading,
        quarter: m.quarter.unwrap_or(true),
        kind,
    };
    let layout = spec.layout().map_err(|e| ctx.err("mesh", e))?;
    check_cell_count(ctx, "mesh.active_cells", layout.hexahedra, kind)?;
    stack_mesh(&spec).map_err(|e| ctx.err("mesh", e))
}

fn build_material(
    ctx: &Ctx,
    name: &str,
    m: &MaterialSpec,
    warnings: &mut Vec<String>,
) -> Result<Arc<dyn Material>, InputError> {
    let key = |k: &str| format!("materials.{name}.{k}");
    let (model, mut p) = match &m.preset {
        Some(preset) => {
            let (model, params) = registry::preset(preset).ok_or_else(|| {
                let hint = closest(preset, registry::PRESETS.iter().copied())
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                ctx.err(
                    key("preset"),
                    format!(
                        "unknown preset `{preset}` (known: {}){hint}",
                        registry::PRESETS.join(", ")
                    ),
                )
            })?;
            if let Some(given) = &m.model {
                if given != model {
                    return Err(ctx.err(
                        key("model"),
                        format!("preset `{preset}` is a `{model}` material; got model `{given}`"),
                    ));
                }
            }
            (model.to_string(), params)
        }
        None => {
            let model = m.model.clone().ok_or_else(|| {
                ctx.err(
                    key("model"),
                    format!(
                        "missing: expected a model ({}) or a `preset`",
                        registry::MODELS.join(", ")
                    ),
                )
            })?;
            (model, MaterialParams::default())
        }
    };
    if !registry::MODELS.contains(&model.as_str()) {
        let hint = closest(&model, registry::MODELS.iter().copied())
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
        return Err(ctx.err(
            key("model"),
            format!(
                "unknown material model `{model}` (known: {}){hint}",
                registry::MODELS.join(", ")
            ),
        ));
    }
    // parameters given in the scenario override the preset's
    if let Some(mu) = &m.mu {
        p.mu = mu.to_vec();
    }
    if let Some(a) = &m.alpha {
        p.alpha = a.clone();
    }
    for (slot, value) in [
        (&mut p.lambda, m.lambda),
        (&mut p.kappa, m.kappa),
        (&mut p.c10, m.c10),
        (&mut p.c20, m.c20),
        (&mut p.c30, m.c30),
        (&mut p.c01, m.c01),
        (&mut p.d1, m.d1),
        (&mut p.d2, m.d2),
        (&mut p.d3, m.d3),
        (&mut p.jm, m.jm),
        (&mut p.lambda_m, m.lambda_m),
        (&mut p.permittivity, m.permittivity),
        (&mut p.c1, m.c1),
        (&mut p.c2, m.c2),
    ] {
        if value.is_some() {
            *slot = value;
        }
    }
    for (k, v) in [
        ("density", m.density, "kg/m³"),
        ("viscosity", m.viscosity, "Pa·s"),
    ]
    .map(|(k, v, u)| (k, (v, u)))
    {
        if let (Some(x), unit) = v {
            if !(x.is_finite() && x >= 0.0) {
                return Err(ctx.err(
                    key(k),
                    format!("must be a finite number ≥ 0 in {unit}; got {x}"),
                ));
            }
        }
    }
    let (mat, w) = registry::build(&model, &p).map_err(|e| ctx.err(key(&e.key), e.message))?;
    warnings.extend(w.into_iter().map(|w| format!("material `{name}`: {w}")));
    Ok(mat)
}

fn build_waveform(
    ctx: &Ctx,
    key: &str,
    v: &VoltageSpec,
    base_dir: Option<&Path>,
) -> Result<Waveform, InputError> {
    let w: &WaveformSpec = match v {
        VoltageSpec::Constant(x) => {
            return Ok(Waveform::constant(ctx.finite(key, *x, "voltage in V")?))
        }
        VoltageSpec::Waveform(w) => w,
    };
    let k = |s: &str| format!("{key}.{s}");
    ctx.finite(&k("amplitude"), w.amplitude, "amplitude in V")?;
    ctx.finite(&k("offset"), w.offset, "offset in V")?;
    ctx.finite(&k("phase"), w.phase, "phase in degrees")?;
    let bipolar = match w.polarity.as_deref() {
        None | Some("unipolar") => false,
        Some("bipolar") => true,
        Some(o) => {
            return Err(ctx.err(
                k("polarity"),
                format!("expected `unipolar` or `bipolar`; got `{o}`"),
            ))
        }
    };
    let freq = || ctx.positive(&k("frequency"), w.frequency, "frequency in Hz");
    let shape = match w.waveform.as_str() {
        "constant" => Shape::Constant,
        "ramp" => Shape::Ramp {
            rise_time: w
                .rise_time
                .map(|r| ctx.positive(&k("rise_time"), Some(r), "rise time in s"))
                .transpose()?
                .unwrap_or(0.0),
        },
        "step" => Shape::Step {
            at: ctx.finite(&k("at"), w.at.unwrap_or(0.0), "time in s")?,
            rise_time: w
                .rise_time
                .map(|r| ctx.positive(&k("rise_time"), Some(r), "rise time in s"))
                .transpose()?
                .unwrap_or(0.0),
        },
        "square" => {
            let duty = w.duty.unwrap_or(0.5);
            if !(duty > 0.0 && duty < 1.0) {
                return Err(ctx.err(
                    k("duty"),
                    format!("must lie strictly between 0 and 1; got {duty}"),
                ));
            }
            Shape::Square {
                frequency: freq()?,
                duty,
                bipolar,
            }
        }
        "triangle" => Shape::Triangle {
            frequency: freq()?,
            bipolar,
        },
        "sine" => Shape::Sine {
            frequency: freq()?,
            bipolar,
        },
        "fourier" => {
            let base = match w.base.as_deref() {
                Some("square") => FourierBase::Square,
                Some("triangle") => FourierBase::Triangle,
                Some("sine") => FourierBase::Sine,
                o => {
                    return Err(ctx.err(
                        k("base"),
                        format!("expected `square` or `triangle`; got {o:?}"),
                    ))
                }
            };
            let terms = w.terms.unwrap_or(5);
            if !(1..=10_000).contains(&terms) {
                return Err(ctx.err(
                    k("terms"),
                    format!("must be between 1 and 10000; got {terms}"),
                ));
            }
            Shape::Fourier {
                base,
                frequency: freq()?,
                terms: terms as usize,
                bipolar,
            }
        }
        "table" => {
            let file = w
                .file
                .as_deref()
                .ok_or_else(|| ctx.err(k("file"), "missing: a CSV file of `time,value` rows"))?;
            let path = base_dir
                .map(|d| d.join(file))
                .unwrap_or_else(|| file.into());
            let text = std::fs::read_to_string(&path).map_err(|e| {
                ctx.err(k("file"), format!("cannot read `{}`: {e}", path.display()))
            })?;
            let mut points = Vec::new();
            for (i, line) in text.lines().enumerate() {
                let line = line.trim();
                if line.is_empty() || line.starts_with('#') {
                    continue;
                }
                let mut parts = line.split(',').map(|p| p.trim().parse::<f64>());
                match (parts.next(), parts.next(), parts.next()) {
                    (Some(Ok(t)), Some(Ok(v)), None) if t.is_finite() && v.is_finite() => {
                        points.push((t, v))
                    }
                    _ if i == 0 => {} // header
                    _ => {
                        return Err(ctx.err(
                            k("file"),
                            format!(
                                "{}:{}: expected `time,value` with two finite numbers",
                                path.display(),
                                i + 1
                            ),
                        ))
                    }
                }
            }
            if points.is_empty() || points.windows(2).any(|p| p[1].0 <= p[0].0) {
                return Err(ctx.err(
                    k("file"),
                    format!(
                        "{}: expected at least one row and strictly increasing times",
                        path.display()
                    ),
                ));
            }
            // the table holds volts: amplitude scales it (1 by default when not given)
            return Ok(Waveform {
                shape: Shape::Table { points },
                amplitude: if w.amplitude == 0.0 { 1.0 } else { w.amplitude },
                offset: w.offset,
                phase_deg: 0.0,
            });
        }
        other => {
            let names = [
                "constant", "ramp", "step", "square", "triangle", "sine", "fourier", "table",
            ];
            let hint = closest(other, names)
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                k("waveform"),
                format!(
                    "unknown waveform `{other}` (known: {}){hint}",
                    names.join(", ")
                ),
            ));
        }
    };
    Ok(Waveform {
        shape,
        amplitude: w.amplitude,
        offset: w.offset,
        phase_deg: w.phase,
    })
}

/// Validates a scenario and builds its plan. `file` names the source in messages; `base_dir` is
/// where relative file names point.
pub fn build(s: &Scenario, file: &str, base_dir: Option<&Path>) -> Result<Plan, InputError> {
    let ctx = Ctx { file };
    // the name is a directory under `deasim-out/`: one plain path component
    if s.name.trim().is_empty()
        || s.name.contains(['/', '\\', '\0'])
        || s.name == "."
        || s.name == ".."
        || s.name.starts_with('-')
        || s.name.len() > 100
    {
        return Err(ctx.err(
            "name",
            format!(
                "`{}` is not a plain directory name: expected a non-empty name of at most 100 \
                 characters, not `.` or `..`, without `/` or `\\` and not starting with `-`",
                s.name.escape_debug()
            ),
        ));
    }
    let (mesh, mut warnings) = build_mesh(&ctx, s, base_dir)?;
    super::memory::check(mesh.n_nodes() as u64, mesh.n_cells() as u64, mesh.kind)
        .map_err(|e| ctx.err("mesh", e))?;
    if s.materials.is_empty() {
        return Err(ctx.err("materials", "at least one material is needed"));
    }
    let mut mats: Vec<Arc<dyn Material>> = Vec::new();
    let mut index: BTreeMap<&str, usize> = BTreeMap::new();
    for (name, m) in &s.materials {
        index.insert(name, mats.len());
        mats.push(build_material(&ctx, name, m, &mut warnings)?);
    }
    let n_cells = mesh.n_cells();
    let mut cell_material = vec![usize::MAX; n_cells];
    if s.regions.is_empty() {
        if mats.len() > 1 {
            return Err(ctx.err(
                "regions",
                "several materials: `regions` must say which cell set has which material",
            ));
        }
        cell_material.iter_mut().for_each(|c| *c = 0);
    } else {
        for (set, mat) in &s.regions {
            let key = format!("regions.{set}");
            let m = *index.get(mat.as_str()).ok_or_else(|| {
                let hint = closest(mat, index.keys().copied())
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                ctx.err(&key, format!("unknown material `{mat}`{hint}"))
            })?;
            let cells = mesh.cell_sets.get(set).ok_or_else(|| {
                let names: Vec<&str> = mesh.cell_sets.keys().map(|s| s.as_str()).collect();
                ctx.err(
                    &key,
                    format!("unknown cell set `{set}` (cell sets: {})", names.join(", ")),
                )
            })?;
            for &c in cells {
                cell_material[c] = m;
            }
        }
        if let Some(c) = cell_material.iter().position(|&m| m == usize::MAX) {
            return Err(ctx.err(
                "regions",
                format!("cell {c} has no material: the regions must cover the body"),
            ));
        }
    }
    let mut model =
        Model::new(mesh, mats[0].clone()).map_err(|e| ctx.err("mesh", e.to_string()))?;
    model.materials = mats;
    model.cell_material = cell_material;
    if let Some(f) = &s.mesh.formulation {
        model.formulation = Formulation::from_name(f).ok_or_else(|| {
            ctx.err(
                "mesh.formulation",
                format!("unknown formulation `{f}`: expected `standard` or `mean-dilatation`"),
            )
        })?;
        if model.formulation == Formulation::MeanDilatation && model.mesh.kind == ElementKind::Tet10
        {
            return Err(ctx.err(
                "mesh.formulation",
                "`mean-dilatation` is the locking-free hex8 (Q1/P0); tet10 is used with the \
                 `standard` formulation",
            ));
        }
    }
    for (i, t) in s.tractions.iter().enumerate() {
        for (c, v) in t.value.iter().enumerate() {
            ctx.finite(&format!("tractions.{i}.value.{c}"), *v, "traction in Pa")?;
        }
        model
            .add_traction(&t.set, t.value)
            .map_err(|e| ctx.err(format!("tractions.{i}.set"), e.to_string()))?;
    }

    let mut supports = Vec::new();
    for (i, c) in s.constraints.iter().enumerate() {
        let key = format!("constraints.{i}");
        let nodes = ctx.set_nodes(&model.mesh, &format!("{key}.set"), &c.set)?;
        ctx.finite(&format!("{key}.value"), c.value, "displacement in m")?;
        if c.fix.is_empty() {
            return Err(ctx.err(
                format!("{key}.fix"),
                "expected a list of components among \"x\", \"y\", \"z\"",
            ));
        }
        for comp in &c.fix {
            let field = match comp.as_str() {
                "x" => Field::Ux,
                "y" => Field::Uy,
                "z" => Field::Uz,
                o => {
                    return Err(ctx.err(
                        format!("{key}.fix"),
                        format!("unknown component `{o}`: expected \"x\", \"y\" or \"z\""),
                    ))
                }
            };
            supports.push(crate::problem::dofs::Dirichlet {
                nodes: nodes.clone(),
                field,
                value: c.value,
            });
        }
    }

    if let Some(p) = &s.prestretch {
        let l = ctx.positive("prestretch.stretch", Some(p.stretch), "in-plane stretch")?;
        if !(0.1..=20.0).contains(&l) {
            return Err(ctx.err(
                "prestretch.stretch",
                format!("expected a stretch between 0.1 and 20; got {l}"),
            ));
        }
        let nodes = ctx.set_nodes(&model.mesh, "prestretch.set", &p.set)?;
        for n in nodes {
            let x = model.mesh.nodes[n];
            for (field, value) in [(Field::Ux, (l - 1.0) * x[0]), (Field::Uy, (l - 1.0) * x[1])] {
                supports.push(crate::problem::dofs::Dirichlet {
                    nodes: vec![n],
                    field,
                    value,
                });
            }
        }
    }
    let symmetry_factor = if matches!(s.mesh.generator.as_deref(), Some("disc" | "stack"))
        && s.mesh.quarter != Some(false)
    {
        4.0
    } else {
        1.0
    };
    let rigid = build_loads(&ctx, s, &mut model, &supports, symmetry_factor)?;
    let prestretch = match &s.prestretch {
        Some(p) => {
            let n = p.steps.unwrap_or(4);
            if !(1..=100_000).contains(&n) {
                return Err(ctx.err(
                    "prestretch.steps",
                    format!("must be between 1 and 100000; got {n}"),
                ));
            }
            Some(Prestretch {
                stretch: p.stretch,
                steps: n as usize,
            })
        }
        None => None,
    };
    let mut breakdown = Vec::new();
    let mut stop_at_breakdown = false;
    for (name, m) in &s.materials {
        breakdown.push(match m.breakdown_field {
            Some(e) => Some(ctx.positive(
                &format!("materials.{name}.breakdown_field"),
                Some(e),
                "dielectric strength in V/m",
            )?),
            None => None,
        });
        if m.stop_at_breakdown == Some(true) {
            if m.breakdown_field.is_none() {
                return Err(ctx.err(
                    format!("materials.{name}.stop_at_breakdown"),
                    "needs `breakdown_field` (V/m) on the same material",
                ));
            }
            stop_at_breakdown = true;
        }
    }
    let mut electrodes = Vec::new();
    for (name, e) in &s.electrodes {
        let key = format!("electrodes.{name}");
        let nodes = ctx.set_nodes(&model.mesh, &format!("{key}.set"), &e.set)?;
        let voltage = build_waveform(&ctx, &format!("{key}.voltage"), &e.voltage, base_dir)?;
        electrodes.push(Electrode {
            name: name.clone(),
            nodes,
            voltage,
        });
    }
    for (i, a) in electrodes.iter().enumerate() {
        for b in &electrodes[i + 1..] {
            if a.nodes.iter().any(|n| b.nodes.binary_search(n).is_ok()) {
                return Err(ctx.err(
                    format!("electrodes.{}.set", b.name),
                    format!(
                        "electrodes `{}` and `{}` share nodes: they would short-circuit",
                        a.name, b.name
                    ),
                ));
            }
        }
    }

    if electrodes.is_empty() {
        // no electrode: a purely mechanical problem; the potential would be defined only up to a
        // constant (a singular tangent), so it is held at 0 everywhere
        supports.push(crate::problem::dofs::Dirichlet {
            nodes: (0..model.mesh.n_nodes()).collect(),
            field: Field::Phi,
            value: 0.0,
        });
    }
    if s.stages.is_empty() {
        return Err(ctx.err("stages", "at least one stage is needed"));
    }
    let mut stages = Vec::new();
    for (i, st) in s.stages.iter().enumerate() {
        let key = format!("stages.{i}");
        let name = st.name.clone().unwrap_or_else(|| format!("stage{i}"));
        let duration = match st.duration {
            Some(d) => ctx.positive(&format!("{key}.duration"), Some(d), "duration in s")?,
            None => 1.0,
        };
        let kind = match st.kind.as_str() {
            "static" => {
                let steps = st.steps.unwrap_or(1);
                if !(1..=1_000_000).contains(&steps) {
                    return Err(ctx.err(
                        format!("{key}.steps"),
                        format!("must be between 1 and 1000000; got {steps}"),
                    ));
                }
                for (k, v) in [
                    ("dt", st.dt.is_some()),
                    ("integrator", st.integrator.is_some()),
                    ("mass", st.mass.is_some()),
                ] {
                    if v {
                        return Err(ctx.err(format!("{key}.{k}"), "applies to dynamic stages only"));
                    }
                }
                StageKind::Static {
                    steps: steps as usize,
                }
            }
            "dynamic" => {
                let duration = st.duration.ok_or_else(|| {
                    ctx.err(
                        format!("{key}.duration"),
                        "missing: dynamic stages need a duration in s",
                    )
                })?;
                let dt = ctx.positive(&format!("{key}.dt"), st.dt, "time step in s")?;
                if dt > duration {
                    return Err(ctx.err(
                        format!("{key}.dt"),
                        format!("the time step {dt} s exceeds the stage duration {duration} s"),
                    ));
                }
                if duration / dt > 1e7 {
                    return Err(ctx.err(
                        format!("{key}.dt"),
                        format!("{duration} s in steps of {dt} s is more than 10⁷ steps"),
                    ));
                }
                if st.steps.is_some() {
                    return Err(ctx.err(
                        format!("{key}.steps"),
                        "applies to static stages only (dynamic stages use `dt`)",
                    ));
                }
                let scheme = match st.integrator.as_deref().unwrap_or("midpoint") {
                    "midpoint" => Method::Midpoint,
                    "trapezoidal" => Method::Trapezoidal,
                    "newmark" => Method::Newmark {
                        beta: 0.25,
                        gamma: 0.5,
                    },
                    o => {
                        let hint = closest(o, ["midpoint", "newmark", "trapezoidal"])
                            .map(|c| format!("; did you mean `{c}`?"))
                            .unwrap_or_default();
                        return Err(ctx.err(
                            format!("{key}.integrator"),
                            format!(
                                "unknown integrator `{o}`: expected `midpoint`, `newmark` or `trapezoidal`{hint}"
                            ),
                        ));
                    }
                };
                for (mname, m) in &s.materials {
                    if !m.density.is_some_and(|d| d > 0.0) {
                        return Err(ctx.err(
                            format!("materials.{mname}.density"),
                            format!(
                                "dynamic stage `{name}` needs a positive mass density in kg/m³"
                            ),
                        ));
                    }
                }
                let mass = match st.mass.as_deref().unwrap_or("consistent") {
                    "consistent" => MassKind::Consistent,
                    "lumped" => MassKind::Lumped,
                    o => {
                        return Err(ctx.err(
                            format!("{key}.mass"),
                            format!("expected `consistent` or `lumped`; got `{o}`"),
                        ))
                    }
                };
                StageKind::Dynamic { dt, scheme, mass }
            }
            o => {
                let hint = closest(o, ["static", "dynamic"])
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                return Err(ctx.err(
                    format!("{key}.kind"),
                    format!("unknown stage kind `{o}`: expected `static` or `dynamic`{hint}"),
                ));
            }
        };
        if stages.iter().any(|s: &Stage| s.name == name) {
            return Err(ctx.err(
                format!("{key}.name"),
                format!("two stages are named `{name}`"),
            ));
        }
        stages.push(Stage {
            name,
            kind,
            duration,
            electrodes_on: st.electrodes_on.unwrap_or(true),
        });
    }

    let mut probes = Vec::new();
    for (name, p) in &s.probes {
        let key = format!("probes.{name}");
        probes.push((
            name.clone(),
            build_probe(&ctx, &key, p, &model, &electrodes)?,
        ));
    }
    let densities = s
        .materials
        .values()
        .map(|m| m.density.unwrap_or(0.0))
        .collect();
    let viscosities = s
        .materials
        .values()
        .map(|m| m.viscosity.unwrap_or(0.0))
        .collect();
    let o = &s.output;
    if !["png", "svg"].contains(&o.plot_format.as_str()) {
        return Err(ctx.err(
            "output.plot_format",
            format!("expected `png` or `svg`; got `{}`", o.plot_format),
        ));
    }
    // a time step that cannot resolve a periodic voltage aliases it (the midpoint rule samples
    // the signal at t + Δt/2): say so rather than report a response to a signal never seen
    for st in &stages {
        let StageKind::Dynamic { dt, .. } = st.kind else {
            continue;
        };
        if !st.electrodes_on {
            continue;
        }
        for e in &electrodes {
            if let Some(f) = e.voltage.frequency() {
                let per_period = 1.0 / (f * dt);
                if per_period < MIN_STEPS_PER_PERIOD {
                    warnings.push(format!(
                        "stage `{}`: dt = {dt:e} s gives only {per_period:.1} steps per period of \
                         the {f} Hz voltage of electrode `{}` (at least {MIN_STEPS_PER_PERIOD} \
                         are needed to resolve it; the response is aliased)",
                        st.name, e.name
                    ));
                }
            }
        }
    }
    Ok(Plan {
        name: s.name.clone(),
        model,
        supports,
        electrodes,
        stages,
        probes,
        output: OutputPlan {
            fields_every: o.fields_every.min(usize::MAX as u64) as usize,
            plots: o.plots,
            plot_format: o.plot_format.clone(),
        },
        densities,
        viscosities,
        warnings,
        rigid,
        material_names: s.materials.keys().cloned().collect(),
        prestretch,
        symmetry_factor,
        breakdown,
        stop_at_breakdown,
        solver: build_solver(&ctx, s)?,
    })
}

/// `[solver]` → the solver settings.
fn build_solver(ctx: &Ctx, s: &Scenario) -> Result<SolverSettings, InputError> {
    let mut out = SolverSettings::default();
    let Some(spec) = &s.solver else {
        return Ok(out);
    };
    if let Some(k) = &spec.kind {
        out.kind = SolverKind::from_name(k).ok_or_else(|| {
            ctx.err(
                "solver.kind",
                format!(
                    "unknown solver `{k}`; expected one of: {}",
                    SolverKind::NAMES.join(", ")
                ),
            )
        })?;
    }
    if let Some(o) = &spec.ordering {
        out.ordering = Ordering::from_name(o).ok_or_else(|| {
            ctx.err(
                "solver.ordering",
                format!(
                    "unknown ordering `{o}`; expected one of: {}",
                    Ordering::NAMES.join(", ")
                ),
            )
        })?;
    }
    Ok(out)
}

/// Gravity (body forces ρg and the weights of the attached masses) and rigid regions (ties of the
/// three translations), written into the model.
fn build_loads(
    ctx: &Ctx,
    s: &Scenario,
    model: &mut Model,
    supports: &[crate::problem::dofs::Dirichlet],
    symmetry_factor: f64,
) -> Result<Vec<Rigid>, InputError> {
    let Some(loads) = &s.loads else {
        return Ok(Vec::new());
    };
    let g = match loads.gravity {
        Some(g) => {
            for (i, v) in g.iter().enumerate() {
                ctx.finite(&format!("loads.gravity.{i}"), *v, "acceleration in m/s²")?;
            }
            if g.iter().map(|v| v * v).sum::<f64>().sqrt() > 1e4 {
                return Err(ctx.err(
                    "loads.gravity",
                    format!("expected an acceleration in m/s² (e.g. [0, 0, -9.81]); got {g:?}"),
                ));
            }
            g
        }
        None => [0.0; 3],
    };
    model.body_force = s
        .materials
        .values()
        .map(|m| {
            let rho = m.density.unwrap_or(0.0);
            g.map(|a| rho * a)
        })
        .collect();
    let mut rigid = Vec::new();
    for (i, r) in loads.rigid.iter().enumerate() {
        let key = format!("loads.rigid.{i}");
        let mut nodes = ctx.set_nodes(&model.mesh, &format!("{key}.set"), &r.set)?;
        nodes.sort_unstable();
        nodes.dedup();
        if !(r.mass.is_finite() && r.mass >= 0.0) {
            return Err(ctx.err(
                format!("{key}.mass"),
                format!("expected a mass in kg ≥ 0; got {}", r.mass),
            ));
        }
        for (j, other) in rigid.iter().enumerate() {
            let o: &Rigid = other;
            if nodes.iter().any(|n| o.nodes.binary_search(n).is_ok()) {
                return Err(ctx.err(
                    format!("{key}.set"),
                    format!(
                        "overlaps rigid region {j} (`{}`): merge them into one set",
                        o.set
                    ),
                ));
            }
        }
        for c in supports {
            if c.value != 0.0 && c.nodes.iter().any(|n| nodes.binary_search(n).is_ok()) {
                return Err(ctx.err(
                    format!("{key}.set"),
                    format!(
                        "`{}` contains nodes with a prescribed non-zero displacement (a constraint or the pre-stretch): a rigid region can only be held or free",
                        r.set
                    ),
                ));
            }
        }
        for field in [Field::Ux, Field::Uy, Field::Uz] {
            model.ties.push(crate::problem::dofs::Tie {
                nodes: nodes.clone(),
                field,
            });
        }
        if !(r.damping.is_finite() && r.damping >= 0.0) {
            return Err(ctx.err(
                format!("{key}.damping"),
                format!(
                    "expected a damping coefficient in N·s/m ≥ 0; got {}",
                    r.damping
                ),
            ));
        }
        if r.damping > 0.0 {
            if let Some(j) = s
                .stages
                .iter()
                .position(|st| st.integrator.as_deref() == Some("trapezoidal"))
            {
                return Err(ctx.err(
                    format!("{key}.damping"),
                    format!(
                        "a damped rigid region needs the `midpoint` or `newmark` integrator; \
                         stage {j} uses `trapezoidal`"
                    ),
                ));
            }
            model
                .point_dampers
                .push((nodes[0], r.damping / symmetry_factor));
        }
        let mass = r.mass / symmetry_factor;
        if mass > 0.0 && g != [0.0; 3] {
            model.point_forces.push((nodes[0], g.map(|a| mass * a)));
        }
        rigid.push(Rigid {
            set: r.set.clone(),
            nodes,
            mass,
        });
    }
    Ok(rigid)
}

fn build_probe(
    ctx: &Ctx,
    key: &str,
    p: &super::scenario::ProbeSpec,
    model: &Model,
    electrodes: &[Electrode],
) -> Result<Probe, InputError> {
    let need = |v: &Option<String>, what: &str| {
        v.clone().ok_or_else(|| {
            ctx.err(
                format!("{key}.{what}"),
                format!("missing: `{}` probes need `{what}`", p.kind),
            )
        })
    };
    let nodal = |q: &str| -> Result<NodalQuantity, InputError> {
        Ok(match q {
            "ux" => NodalQuantity::Component(0),
            "uy" => NodalQuantity::Component(1),
            "uz" => NodalQuantity::Component(2),
            "u" => NodalQuantity::Magnitude,
            "phi" => NodalQuantity::Potential,
            o => {
                let names = ["ux", "uy", "uz", "u", "phi"];
                let hint = closest(o, names)
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                return Err(ctx.err(
                    format!("{key}.quantity"),
                    format!(
                        "unknown nodal quantity `{o}` (known: {}){hint}",
                        names.join(", ")
                    ),
                ));
            }
        })
    };
    let electrode = |name: &str| -> Result<usize, InputError> {
        electrodes
            .iter()
            .position(|e| e.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> = electrodes.iter().map(|e| e.name.as_str()).collect();
                ctx.err(
                    format!("{key}.electrode"),
                    format!(
                        "unknown electrode `{name}` (electrodes: {})",
                        names.join(", ")
                    ),
                )
            })
    };
    let kind = match p.kind.as_str() {
        "mean" | "max" | "min" => {
            let q = nodal(&need(&p.quantity, "quantity")?)?;
            let nodes = ctx.set_nodes(&model.mesh, &format!("{key}.set"), &need(&p.set, "set")?)?;
            match p.kind.as_str() {
                "mean" => ProbeKind::Mean(q, nodes),
                "max" => ProbeKind::Max(q, nodes),
                _ => ProbeKind::Min(q, nodes),
            }
        }
        "point" => {
            let q = nodal(&need(&p.quantity, "quantity")?)?;
            let at = p.at.ok_or_else(|| {
                ctx.err(
                    format!("{key}.at"),
                    "missing: `point` probes need `at = [x, y, z]` in m",
                )
            })?;
            if at.iter().any(|v| !v.is_finite()) {
                return Err(ctx.err(format!("{key}.at"), "coordinates must be finite (m)"));
            }
            ProbeKind::Point(q, model.mesh.nearest_node(at))
        }
        "charge" => ProbeKind::Charge(electrode(&need(&p.electrode, "electrode")?)?),
        "capacitance" => ProbeKind::Capacitance(electrode(&need(&p.electrode, "electrode")?)?),
        "reaction" => {
            let c = match need(&p.quantity, "quantity")?.as_str() {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                o => {
                    return Err(ctx.err(
                        format!("{key}.quantity"),
                        format!("reaction component must be \"x\", \"y\" or \"z\"; got `{o}`"),
                    ))
                }
            };
            ProbeKind::Reaction(
                c,
                ctx.set_nodes(&model.mesh, &format!("{key}.set"), &need(&p.set, "set")?)?,
            )
        }
        "energy" => match need(&p.quantity, "quantity")?.as_str() {
            "stored" => ProbeKind::StoredEnergy,
            "electric" => ProbeKind::ElectricEnergy,
            o => {
                return Err(ctx.err(
                    format!("{key}.quantity"),
                    format!("energy must be `stored` or `electric`; got `{o}`"),
                ))
            }
        },
        "center_deflection" => ProbeKind::Deflection(ctx.set_nodes(
            &model.mesh,
            &format!("{key}.set"),
            p.set.as_deref().unwrap_or("pad"),
        )?),
        "max_electric_field" => ProbeKind::MaxElectricField,
        o => {
            let names = [
                "mean",
                "max",
                "min",
                "point",
                "charge",
                "capacitance",
                "reaction",
                "energy",
                "center_deflection",
                "max_electric_field",
            ];
            let hint = closest(o, names)
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                format!("{key}.kind"),
                format!(
                    "unknown probe kind `{o}` (known: {}){hint}",
                    names.join(", ")
                ),
            ));
        }
    };
    let scale = ctx.finite(&format!("{key}.scale"), p.scale.unwrap_or(1.0), "factor")?;
    let offset = ctx.finite(&format!("{key}.offset"), p.offset.unwrap_or(0.0), "offset")?;
    Ok(Probe {
        kind,
        scale,
        offset,
    })
}
