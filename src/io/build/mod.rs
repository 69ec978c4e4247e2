//! Validation of a parsed [`Scenario`] and construction of what the analysis runs: the model, the
//! electrodes with their waveforms, the stages and the probes. Every error names the file, the key
//! and what was expected (type, range, unit).
//!
//! One file per concern: [`mesh`] (generators, Gmsh files, element kind, formulation),
//! [`materials`] (models, presets, regions, density, viscosity, breakdown), [`parameters`]
//! (the key paths of material parameters), [`loads`]
//! (constraints, tractions, gravity, rigid regions, pre-stretch), [`electrodes`] (electrodes and
//! their waveforms), [`stages`], [`probes`] and [`solver`]. [`build`] calls them in a fixed order,
//! so that a scenario with several errors always reports the same one first.

mod controller;
mod controls;
mod electrodes;
mod loads;
mod materials;
mod mesh;
mod parameters;
mod probes;
mod solver;
mod stages;

use super::scenario::{closest, InputError, OutputSpec, Scenario};
pub use crate::job::plan::{Electrode, OutputPlan, Plan, Prestretch, Rigid, Stage, StageKind};
use crate::mesh::{ElementKind, Mesh};
pub use materials::override_parameters;
pub use parameters::{material_parameter, parameter, Parameter, ParameterKey};
pub use stages::log_range;
use std::path::Path;

/// Fewest time steps per period of a periodic voltage before a warning.
pub const MIN_STEPS_PER_PERIOD: f64 = 20.0;

/// Largest number of cells a generated mesh may have (memory guard: ~5 GB of tangent).
pub const MAX_CELLS: u64 = 2_000_000;

/// Largest number of cells a mesh of a distributed solve may have, before it is generated:
/// PETSc's 32-bit indices number at most 2³¹ − 1 rows, four per node (a hex8 mesh has about as
/// many nodes as cells; the rows themselves are checked once the nodes are known).
pub const MAX_DISTRIBUTED_CELLS: u64 = 400_000_000;

/// Validates a scenario and builds its plan. `file` names the source in messages; `base_dir` is
/// where relative file names point.
/// The waveform of a number or waveform table at `key` of scenario `file` (CSV tables read
/// from `base_dir`), checked as an electrode's voltage is.
pub fn waveform(
    file: &str,
    key: &str,
    v: &crate::io::scenario::VoltageSpec,
    base_dir: Option<&Path>,
) -> Result<crate::waveform::Waveform, InputError> {
    electrodes::build_waveform(&Ctx::plain(file), key, v, base_dir)
}

pub fn build(s: &Scenario, file: &str, base_dir: Option<&Path>) -> Result<Plan, InputError> {
    build_with(s, file, base_dir, true)
}

/// As [`build`]; `hold_geometry`: whether the model holds every cell's reference geometry, or
/// computes it when asked (a plan that rank 0 only cuts into the ranks' parts, each of which
/// computes its own cells' geometry).
pub fn build_with(
    s: &Scenario,
    file: &str,
    base_dir: Option<&Path>,
    hold_geometry: bool,
) -> Result<Plan, InputError> {
    let ctx = Ctx {
        file,
        distributed: s.solver.as_ref().and_then(|x| x.kind.as_deref()) == Some("petsc"),
        hold_geometry,
    };
    check_name(&ctx, &s.name)?;
    let (mesh, mut warnings) = mesh::build_mesh(&ctx, s, base_dir)?;
    let mut materials = materials::build_materials(&ctx, s, &mesh, &mut warnings)?;
    let material_parameters = std::mem::take(&mut materials.parameters);
    let mut model = mesh::build_model(&ctx, s, mesh, materials)?;
    let symmetry_factor = mesh::symmetry_factor(&s.mesh);
    let loads = loads::build_loads(&ctx, s, &mut model, symmetry_factor)?;
    let (breakdown, stop_at_breakdown) = materials::build_breakdown(&ctx, s)?;
    let mut electrodes = electrodes::build_electrodes(&ctx, s, &model.mesh, base_dir)?;
    let mut supports = loads.supports;
    supports.extend(electrodes::ground_without_electrodes(
        &electrodes,
        &model.mesh,
    ));
    let mut stages = stages::build_stages(&ctx, s, &electrodes)?;
    controls::build_controls(&ctx, s, &mut stages, &electrodes)?;
    electrodes::charge_electrodes(&mut electrodes, &stages, &mut model, symmetry_factor);
    stages::check_internal_variables(&ctx, &stages, &model)?;
    if let Some(e) = electrodes.iter().find(|e| e.charge.is_some()) {
        if let Some((i, _)) = stages.iter().enumerate().find(|(_, st)| {
            matches!(
                st.kind,
                crate::job::plan::StageKind::Dynamic {
                    scheme: crate::time::stage::Method::Trapezoidal,
                    ..
                }
            )
        }) {
            return Err(ctx.err(
                format!("stages.{i}.integrator"),
                format!(
                    "electrode `{}` is charge-controlled: use the `midpoint` or `newmark` \
                     integrator (the explicit `trapezoidal` one does not hold a charge yet)",
                    e.name
                ),
            ));
        }
        if let Some((i, _)) = stages.iter().enumerate().find(|(_, st)| {
            matches!(
                st.kind,
                crate::job::plan::StageKind::Modes { .. }
                    | crate::job::plan::StageKind::FrequencyResponse { .. }
            )
        }) {
            return Err(ctx.err(
                format!("stages.{i}.kind"),
                format!(
                    "electrode `{}` is charge-controlled: small-signal stages hold every \
                     electrode at its voltage, which would not keep its charge",
                    e.name
                ),
            ));
        }
    }
    if !model.is_axisymmetric() {
        if let Some((i, _)) = stages.iter().enumerate().find(|(_, st)| {
            matches!(&st.kind, crate::job::plan::StageKind::Modes { harmonics, .. }
                if harmonics.iter().any(|&n| n > 0))
        }) {
            return Err(ctx.err(
                format!("stages.{i}.harmonic"),
                "circumferential harmonics n ≥ 1 are modes of an axisymmetric model \
                 (`mesh.geometry = \"axisymmetric\"`); a 3-D model finds every mode with \
                 `harmonic = 0`"
                    .to_string(),
            ));
        }
    }
    if !model.circuits.is_empty() {
        if let Some((i, _)) = stages.iter().enumerate().find(|(_, st)| {
            matches!(
                st.kind,
                crate::job::plan::StageKind::Dynamic {
                    scheme: crate::time::stage::Method::Trapezoidal,
                    ..
                }
            )
        }) {
            return Err(ctx.err(
                format!("stages.{i}.integrator"),
                "circuit-driven electrodes need the `midpoint` or `newmark` integrator: the \
                 explicit `trapezoidal` one does not integrate the circuit",
            ));
        }
    }
    let pressure_stages = loads::pressure_stages(&ctx, s, &stages)?;
    let pressure_volumes = loads::pressure_volumes(&ctx, s, symmetry_factor)?;
    for (on, volume) in pressure_stages.iter().zip(&pressure_volumes) {
        if volume.is_none() {
            continue;
        }
        if let Some((i, _)) = stages.iter().enumerate().find(|(i, st)| {
            on[*i] && matches!(st.kind, crate::job::plan::StageKind::Continuation { .. })
        }) {
            return Err(ctx.err(
                format!("stages.{i}.kind"),
                "a volume-controlled pressure acts in static and quasi-static stages (its volume \
                 already passes the limit points a continuation would follow); leave this stage \
                 out of its `stages`",
            ));
        }
    }
    for on in &pressure_stages {
        if let Some((i, _)) = stages.iter().enumerate().find(|(i, st)| {
            on[*i]
                && !matches!(
                    st.kind,
                    crate::job::plan::StageKind::Static { .. }
                        | crate::job::plan::StageKind::QuasiStatic { .. }
                        | crate::job::plan::StageKind::Continuation { .. }
                )
        }) {
            return Err(ctx.err(
                format!("stages.{i}.kind"),
                "pressure loads act in static, quasi-static and continuation stages only: dynamic \
                 and small-signal stages do not include their follower stiffness yet (list the \
                 stages a pressure acts in with its `stages` key)",
            ));
        }
    }
    let probes = probes::build_probes(&ctx, s, &model, &electrodes)?;
    controller::build_controllers(&ctx, s, &mut electrodes, &stages, &probes, base_dir)?;
    let output = build_output(&ctx, &s.output, model.is_axisymmetric())?;
    let (newton, step_control) = solver::build_newton(&ctx, s)?;
    warnings.extend(stages::aliasing_warnings(&stages, &electrodes));
    Ok(Plan {
        name: s.name.clone(),
        model,
        supports,
        electrodes,
        stages,
        probes,
        output,
        densities: materials::densities(s),
        viscosities: materials::viscosities(s),
        warnings,
        rigid: loads.rigid,
        material_names: s.materials.keys().cloned().collect(),
        material_parameters,
        prestretch: loads.prestretch,
        symmetry_factor,
        breakdown,
        stop_at_breakdown,
        solver: solver::build_solver(&ctx, s)?,
        newton,
        step_control,
        pressure_stages,
        pressure_volumes,
        part: None,
    })
}

/// The materials of a scenario's plan (in `Plan::material_names` order) without its mesh: what
/// a rank that receives its part of a plan builds for itself (materials are code, not data).
pub fn materials(
    s: &Scenario,
    file: &str,
) -> Result<Vec<std::sync::Arc<dyn crate::material::Material>>, InputError> {
    let ctx = Ctx::plain(file);
    Ok(materials::material_list(&ctx, s, &mut Vec::new())?.materials)
}

/// The linear solver settings of a scenario without its mesh (with PETSc's, a collective check
/// of its options on every rank: see [`crate::solve::petsc::check_options`]).
pub fn solver_settings(
    s: &Scenario,
    file: &str,
) -> Result<crate::solve::linear::SolverSettings, InputError> {
    solver::build_solver(&Ctx::plain(file), s)
}

/// `name`: it names the output directory.
fn check_name(ctx: &Ctx, name: &str) -> Result<(), InputError> {
    // the name is a directory under `deasim-out/`: one plain path component
    if name.trim().is_empty()
        || name.contains(['/', '\\', '\0'])
        || name == "."
        || name == ".."
        || name.starts_with('-')
        || name.len() > 100
    {
        return Err(ctx.err(
            "name",
            format!(
                "`{}` is not a plain directory name: expected a non-empty name of at most 100 \
                 characters, not `.` or `..`, without `/` or `\\` and not starting with `-`",
                name.escape_debug()
            ),
        ));
    }
    Ok(())
}

/// `[output]` → the output settings; `axisymmetric` allows the keys of the revolved view.
fn build_output(ctx: &Ctx, o: &OutputSpec, axisymmetric: bool) -> Result<OutputPlan, InputError> {
    if !["png", "svg"].contains(&o.plot_format.as_str()) {
        return Err(ctx.err(
            "output.plot_format",
            format!("expected `png` or `svg`; got `{}`", o.plot_format),
        ));
    }
    use crate::job::plan::FieldFormat;
    let fields_format = match o.vtu_format.as_deref().unwrap_or("binary") {
        "binary" => FieldFormat::Binary,
        "compressed" => FieldFormat::Compressed,
        "ascii" => FieldFormat::Ascii,
        other => {
            return Err(ctx.err(
                "output.vtu_format",
                format!("expected `binary`, `compressed` or `ascii`; got `{other}`"),
            ))
        }
    };
    Ok(OutputPlan {
        fields_every: o.fields_every.min(usize::MAX as u64) as usize,
        plots: o.plots,
        plot_format: o.plot_format.clone(),
        fields_format,
        revolve: build_revolve(ctx, o, axisymmetric)?,
    })
}

/// Largest number of wedges of the revolved view (0.5° each over a full turn).
pub const MAX_REVOLVE_WEDGES: u64 = 720;

/// Largest angle of one wedge of the revolved view (degrees): a straight chord across a wider
/// angle would flatten the ring.
pub const MAX_WEDGE_DEG: f64 = 120.0;

/// The revolved view of an axisymmetric model (`output.revolve*`): on by default, 270° (the cut
/// shows the meridian section) in one wedge per 10°. The keys are refused for a 3-D model.
fn build_revolve(
    ctx: &Ctx,
    o: &OutputSpec,
    axisymmetric: bool,
) -> Result<Option<crate::job::plan::Revolve>, InputError> {
    if !axisymmetric {
        let given = [
            ("output.revolve", o.revolve.is_some()),
            ("output.revolve_sector", o.revolve_sector.is_some()),
            ("output.revolve_wedges", o.revolve_wedges.is_some()),
        ];
        if let Some((key, _)) = given.iter().find(|(_, g)| *g) {
            return Err(ctx.err(
                *key,
                "the revolved view is for axisymmetric models (`mesh.geometry = \"axisymmetric\"`); \
                 a 3-D model's field files already show the whole body: remove the key",
            ));
        }
        return Ok(None);
    }
    let sector = o.revolve_sector.unwrap_or(270.0);
    if !(sector.is_finite() && sector > 0.0 && sector <= 360.0) {
        return Err(ctx.err(
            "output.revolve_sector",
            format!(
                "must be an angle in degrees with 0 < angle ≤ 360; got {}",
                crate::units::Short(sector)
            ),
        ));
    }
    let fewest = (sector / MAX_WEDGE_DEG).ceil().max(1.0) as u64;
    let wedges = match o.revolve_wedges {
        None => ((sector / 10.0).ceil() as u64).clamp(fewest, MAX_REVOLVE_WEDGES),
        Some(w) if w > MAX_REVOLVE_WEDGES => {
            return Err(ctx.err(
                "output.revolve_wedges",
                format!("must be at most {MAX_REVOLVE_WEDGES}; got {w}"),
            ))
        }
        Some(w) if w < fewest => {
            return Err(ctx.err(
                "output.revolve_wedges",
                format!(
                    "must be at least {fewest} for a sector of {}° (one wedge spans at most \
                     {MAX_WEDGE_DEG}°); got {w}",
                    crate::units::Short(sector)
                ),
            ))
        }
        Some(w) => w,
    };
    Ok(o.revolve
        .unwrap_or(true)
        .then_some(crate::job::plan::Revolve {
            sector_deg: sector,
            wedges: wedges as usize,
        }))
}

/// What every concern builder shares: the file name of the messages, and the common checks.
struct Ctx<'a> {
    file: &'a str,
    /// Whether the scenario's solver is distributed (`[solver] kind = "petsc"`): its mesh is
    /// then bounded by PETSc's indices and rank 0's memory, not by a serial factorisation.
    distributed: bool,
    /// Whether the model holds every cell's reference geometry ([`build_with`]).
    hold_geometry: bool,
}

impl<'a> Ctx<'a> {
    /// The context of checks that do not depend on the mesh's size (one process, geometry held).
    const fn plain(file: &'a str) -> Self {
        Ctx {
            file,
            distributed: false,
            hold_geometry: true,
        }
    }

    /// The most cells a mesh may have: [`MAX_CELLS`] for one process, whose direct solver
    /// factors the whole tangent; [`MAX_DISTRIBUTED_CELLS`] for a distributed solver.
    fn max_cells(&self) -> u64 {
        if self.distributed {
            MAX_DISTRIBUTED_CELLS
        } else {
            MAX_CELLS
        }
    }

    /// Refuses a mesh too large to solve: its estimated memory exceeds what is available (the
    /// serial solve's, [`crate::io::memory::check`]; for a distributed solver what rank 0 holds
    /// while it builds the whole plan and cuts the ranks' parts,
    /// [`crate::io::memory::check_set_up`]), or, distributed, its rows (four per node) exceed
    /// PETSc's 32-bit indices.
    fn check_size(&self, nodes: u64, cells: u64, kind: ElementKind) -> Result<(), String> {
        if !self.distributed {
            return crate::io::memory::check(nodes, cells, kind);
        }
        let rows = 4 * nodes;
        if rows > i32::MAX as u64 {
            return Err(format!(
                "{nodes} nodes make {rows} rows, more than PETSc's 32-bit indices number \
                 ({}); use fewer divisions",
                i32::MAX
            ));
        }
        crate::io::memory::check_set_up(nodes, cells, self.hold_geometry)
    }

    fn err(&self, key: impl Into<String>, msg: impl Into<String>) -> InputError {
        InputError::at_key(self.file, key, msg)
    }

    fn positive(&self, key: &str, v: Option<f64>, what: &str) -> Result<f64, InputError> {
        match v {
            None => Err(self.err(key, format!("missing: expected {what} (a positive number)"))),
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            Some(x) => Err(self.err(
                key,
                format!(
                    "must be a positive finite number ({what}); got {}",
                    crate::units::Short(x)
                ),
            )),
        }
    }

    fn finite(&self, key: &str, v: f64, what: &str) -> Result<f64, InputError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(
                key,
                format!(
                    "must be a finite number ({what}); got {}",
                    crate::units::Short(v)
                ),
            ))
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

/// Scenarios for the unit tests of the concern builders: a small valid scenario whose sections
/// can be replaced or added to.
#[cfg(test)]
mod testing {
    use super::{build, Ctx, Plan};
    use crate::io::scenario::{parse, InputError, Scenario};

    /// The file name of the test scenarios.
    pub(super) const FILE: &str = "test.toml";

    /// The context of the concern builders.
    pub(super) const CTX: Ctx<'static> = Ctx::plain(FILE);

    /// A valid scenario by section: a 10 × 10 × 1 mm hex8 box of 2 × 2 × 1 cells (18 nodes, 9 on
    /// each face z0 and z1), one neo-Hooke material, z0 held and grounded, 1 kV on z1, one static
    /// stage of 2 steps.
    const BASE: [(&str, &str); 6] = [
        ("name", "name = \"t\""),
        (
            "mesh",
            "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [2, 2, 1]",
        ),
        (
            "materials",
            "[materials.gel]\nmodel = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\npermittivity = 4.7",
        ),
        (
            "constraints",
            "[[constraints]]\nset = \"z0\"\nfix = [\"x\", \"y\", \"z\"]",
        ),
        (
            "electrodes",
            "[electrodes.top]\nset = \"z1\"\nvoltage = 1000.0\n\
             [electrodes.bottom]\nset = \"z0\"\nvoltage = 0.0",
        ),
        ("stages", "[[stages]]\nkind = \"static\"\nsteps = 2"),
    ];

    /// The text of the base scenario with the sections named in `with` replaced (an empty text
    /// removes the section); sections not in the base (`probes`, `loads`, …) are appended.
    pub(super) fn text(with: &[(&str, &str)]) -> String {
        let pick = |name: &str, base: &'static str| {
            with.iter()
                .find(|(n, _)| *n == name)
                .map_or(base.to_string(), |(_, t)| t.to_string())
        };
        let mut sections: Vec<String> = BASE.iter().map(|(n, t)| pick(n, t)).collect();
        for (n, t) in with {
            if !BASE.iter().any(|(b, _)| b == n) {
                sections.push(t.to_string());
            }
        }
        sections.join("\n") + "\n"
    }

    /// The parsed scenario of [`text`].
    pub(super) fn scenario(with: &[(&str, &str)]) -> Scenario {
        let text = text(with);
        parse(&text, FILE, &[]).unwrap_or_else(|e| panic!("{e}\n{text}"))
    }

    /// The plan of [`text`], which must build.
    pub(super) fn plan(with: &[(&str, &str)]) -> Plan {
        build(&scenario(with), FILE, None).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The error of [`text`], which must not build.
    pub(super) fn error(with: &[(&str, &str)]) -> InputError {
        build(&scenario(with), FILE, None).expect_err("the scenario must be rejected")
    }

    /// Asserts that `e` names the file and `key`, and says `expected`.
    pub(super) fn assert_names(e: &InputError, key: &str, expected: &str) {
        let msg = e.to_string();
        assert_eq!(e.file, FILE, "{msg}");
        assert_eq!(e.key.as_deref(), Some(key), "{msg}");
        assert!(msg.starts_with(&format!("{FILE}: key `{key}`: ")), "{msg}");
        assert!(msg.contains(expected), "`{expected}` not in: {msg}");
    }

    /// Asserts that the scenario of [`text`] is rejected at `key` with a message saying `expected`.
    pub(super) fn assert_rejected(with: &[(&str, &str)], key: &str, expected: &str) {
        assert_names(&error(with), key, expected);
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{assert_names, assert_rejected, plan, text, CTX};
    use crate::problem::dofs::Field;

    #[test]
    fn the_base_scenario_builds_with_the_defaults() {
        let p = plan(&[]);
        assert_eq!(p.name, "t");
        assert_eq!(p.model.mesh.n_cells(), 4);
        // three components held on z0, no ground: there are electrodes
        assert_eq!(p.supports.len(), 3);
        assert_eq!(p.electrodes.len(), 2);
        assert_eq!(p.stages.len(), 1);
        assert_eq!(p.output.fields_every, 1);
        assert!(p.output.plots);
        assert_eq!(p.output.plot_format, "png");
        assert_eq!(p.symmetry_factor, 1.0);
        assert_eq!(p.material_names, ["gel"]);
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    }

    #[test]
    fn output_settings_are_taken_over() {
        let p = plan(&[(
            "output",
            "[output]\nfields_every = 5\nplots = false\nplot_format = \"svg\"",
        )]);
        assert_eq!(p.output.fields_every, 5);
        assert!(!p.output.plots);
        assert_eq!(p.output.plot_format, "svg");
    }

    #[test]
    fn without_electrodes_the_potential_is_held_at_zero_everywhere() {
        let p = plan(&[("electrodes", "")]);
        assert!(p.electrodes.is_empty());
        let ground = p.supports.last().unwrap();
        assert_eq!(ground.field, Field::Phi);
        assert_eq!(ground.value, 0.0);
        assert_eq!(ground.nodes.len(), p.model.mesh.n_nodes());
        assert_eq!(p.supports.len(), 4);
    }

    #[test]
    fn ctx_accepts_positive_and_finite_numbers_and_known_sets() {
        assert_eq!(CTX.positive("a.b", Some(2.5), "length in m").unwrap(), 2.5);
        assert_eq!(CTX.finite("a.b", -3.0, "offset").unwrap(), -3.0);
        let p = plan(&[]);
        assert_eq!(CTX.set_nodes(&p.model.mesh, "k", "z1").unwrap().len(), 9);
    }

    #[test]
    fn a_name_with_a_slash_is_rejected() {
        let with = [("name", "name = \"a/b\"")];
        assert_rejected(&with, "name", "without `/`");
        assert_rejected(&[("name", "name = \"..\"")], "name", "not `.` or `..`");
        assert_rejected(&[("name", "name = \"  \"")], "name", "non-empty name");
    }

    /// The sections of a small axisymmetric film (a 2 × 1 quad4 rectangle) and `output`.
    fn axisymmetric(output: &str) -> Vec<(&'static str, String)> {
        vec![
            (
                "mesh",
                "[mesh]\ngeometry = \"axisymmetric\"\ngenerator = \"rectangle\"\nradius = 0.01\n\
                 thickness = 0.001\nradial = 2\nlayers = 1"
                    .to_string(),
            ),
            (
                "constraints",
                "[[constraints]]\nset = \"bottom\"\nfix = [\"z\"]".to_string(),
            ),
            (
                "electrodes",
                "[electrodes.top]\nset = \"top\"\nvoltage = 1000.0\n\
                 [electrodes.bottom]\nset = \"bottom\"\nvoltage = 0.0"
                    .to_string(),
            ),
            ("output", output.to_string()),
        ]
    }

    fn revolve_of(output: &str) -> Option<crate::job::plan::Revolve> {
        let sections = axisymmetric(output);
        let with: Vec<(&str, &str)> = sections.iter().map(|(k, v)| (*k, v.as_str())).collect();
        plan(&with).output.revolve
    }

    #[test]
    fn the_revolved_view_defaults_to_270_degrees_in_10_degree_wedges() {
        use crate::job::plan::Revolve;
        let r = |sector_deg, wedges| Some(Revolve { sector_deg, wedges });
        assert_eq!(revolve_of(""), r(270.0, 27));
        assert_eq!(revolve_of("[output]\nrevolve_sector = 360"), r(360.0, 36));
        assert_eq!(revolve_of("[output]\nrevolve_sector = 45.0"), r(45.0, 5));
        assert_eq!(revolve_of("[output]\nrevolve_sector = 0.5"), r(0.5, 1));
        assert_eq!(
            revolve_of("[output]\nrevolve_sector = 360\nrevolve_wedges = 3"),
            r(360.0, 3)
        );
        assert_eq!(revolve_of("[output]\nrevolve = false"), None);
        // a 3-D model has none
        assert_eq!(plan(&[]).output.revolve, None);
    }

    #[test]
    fn revolved_view_keys_are_refused_for_3d_models_and_out_of_range() {
        for (line, key) in [
            ("revolve = true", "output.revolve"),
            ("revolve = false", "output.revolve"),
            ("revolve_sector = 90", "output.revolve_sector"),
            ("revolve_wedges = 4", "output.revolve_wedges"),
        ] {
            assert_rejected(
                &[("output", &format!("[output]\n{line}"))],
                key,
                "the revolved view is for axisymmetric models",
            );
        }
        let rejected = |output: &str, key: &str, expected: &str| {
            let sections = axisymmetric(output);
            let with: Vec<(&str, &str)> = sections.iter().map(|(k, v)| (*k, v.as_str())).collect();
            assert_rejected(&with, key, expected);
        };
        for sector in ["0", "-90", "361", "nan", "inf"] {
            rejected(
                &format!("[output]\nrevolve_sector = {sector}"),
                "output.revolve_sector",
                "0 < angle ≤ 360",
            );
        }
        rejected(
            "[output]\nrevolve_wedges = 0",
            "output.revolve_wedges",
            "must be at least 3 for a sector of 270°",
        );
        rejected(
            "[output]\nrevolve_sector = 360\nrevolve_wedges = 2",
            "output.revolve_wedges",
            "must be at least 3 for a sector of 360°",
        );
        rejected(
            "[output]\nrevolve_sector = 90\nrevolve_wedges = 0",
            "output.revolve_wedges",
            "must be at least 1",
        );
        rejected(
            "[output]\nrevolve_wedges = 721",
            "output.revolve_wedges",
            "must be at most 720; got 721",
        );
    }

    #[test]
    fn vtu_format_is_binary_compressed_or_ascii() {
        use crate::job::plan::FieldFormat;
        assert_eq!(plan(&[]).output.fields_format, FieldFormat::Binary);
        for (name, format) in [
            ("ascii", FieldFormat::Ascii),
            ("compressed", FieldFormat::Compressed),
        ] {
            let p = plan(&[("output", &format!("[output]\nvtu_format = \"{name}\""))]);
            assert_eq!(p.output.fields_format, format);
        }
        assert_rejected(
            &[("output", "[output]\nvtu_format = \"hdf5\"")],
            "output.vtu_format",
            "expected `binary`, `compressed` or `ascii`; got `hdf5`",
        );
    }

    #[test]
    fn an_unknown_plot_format_is_rejected() {
        assert_rejected(
            &[("output", "[output]\nplot_format = \"jpg\"")],
            "output.plot_format",
            "expected `png` or `svg`; got `jpg`",
        );
    }

    #[test]
    fn ctx_rejects_missing_non_positive_and_non_finite_numbers() {
        let e = CTX
            .positive("mesh.radius", None, "outer radius in m")
            .unwrap_err();
        assert_names(&e, "mesh.radius", "missing: expected outer radius in m");
        let e = CTX.positive("x", Some(0.0), "length in m").unwrap_err();
        assert_names(
            &e,
            "x",
            "must be a positive finite number (length in m); got 0",
        );
        let e = CTX.finite("y", f64::NAN, "offset in V").unwrap_err();
        assert_names(&e, "y", "must be a finite number (offset in V); got NaN");
    }

    #[test]
    fn ctx_rejects_an_unknown_set_with_a_suggestion() {
        let p = plan(&[]);
        let e = CTX
            .set_nodes(&p.model.mesh, "probes.a.set", "z2")
            .unwrap_err();
        assert_names(
            &e,
            "probes.a.set",
            "unknown set `z2` (the mesh has: all, x0, x1",
        );
        assert!(e.message.ends_with("did you mean `z0`?"), "{e}");
    }

    #[test]
    fn the_first_error_in_build_order_is_reported() {
        // a bad mesh and a bad stage: the mesh is checked first
        let with = [
            (
                "mesh",
                "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [0, 2, 1]",
            ),
            ("stages", "[[stages]]\nkind = \"statik\""),
        ];
        assert_rejected(&with, "mesh.divisions", "at least 1");
        assert!(text(&with).contains("statik"));
    }
}
