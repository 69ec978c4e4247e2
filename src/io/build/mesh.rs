//! `[mesh]`: the generators (`box`, `disc`, `stack`, `sphere`) and Gmsh files, the element kind, the
//! formulation, the keys of one generator given to another, and the cell-count guard.

use super::materials::Materials;
use super::Ctx;
use crate::element::mean_dilatation::Formulation;
use crate::io::scenario::{closest, InputError, MeshSpec, Scenario};
use crate::mesh::disc::{disc_mesh, DiscSpec};
use crate::mesh::meridian::disc_meridian;
use crate::mesh::stack::{stack_mesh, StackSpec};
use crate::mesh::{generate::box_mesh, ElementKind, MeridianKind, Mesh};
use crate::problem::model::Model;
use std::path::Path;

/// The element kinds by scenario name.
const ELEMENTS: [(&str, ElementKind); 3] = [
    ("hex8", ElementKind::Hex8),
    ("tet4", ElementKind::Tet4),
    ("tet10", ElementKind::Tet10),
];

/// The meridian element kinds of axisymmetric models by scenario name.
const MERIDIAN_ELEMENTS: [(&str, MeridianKind); 5] = [
    ("quad4", MeridianKind::Quad4),
    ("quad8", MeridianKind::Quad8),
    ("quad9", MeridianKind::Quad9),
    ("tri3", MeridianKind::Tri3),
    ("tri6", MeridianKind::Tri6),
];

/// The generators by scenario name.
const GENERATORS: [&str; 5] = ["box", "disc", "stack", "sphere", "rectangle"];

/// The generators of axisymmetric models.
const MERIDIAN_GENERATORS: [&str; 3] = ["disc", "rectangle", "sphere"];

/// The size keys of each generator (the others reject them).
const GENERATOR_KEYS: [(&str, &[&str]); 5] = [
    ("box", &["size", "divisions"]),
    (
        "disc",
        &[
            "radius",
            "thickness",
            "pad_radius",
            "electrode_radius",
            "radial",
            "layers",
        ],
    ),
    (
        "stack",
        &[
            "side",
            "films",
            "film_thickness",
            "border",
            "layers_per_film",
            "active_cells",
        ],
    ),
    ("sphere", &["radius", "thickness", "radial", "layers"]),
    (
        "rectangle",
        &["radius", "inner_radius", "thickness", "radial", "layers"],
    ),
];

/// Whether `mesh.geometry` asks for an axisymmetric model (`3d` when not given).
pub(super) fn is_axisymmetric(ctx: &Ctx, m: &MeshSpec) -> Result<bool, InputError> {
    match m.geometry.as_deref() {
        None | Some("3d" | "3-d" | "3D") => Ok(false),
        Some("axisymmetric") => Ok(true),
        Some(o) => Err(ctx.err(
            "mesh.geometry",
            format!("unknown geometry `{o}`: expected `3d` or `axisymmetric`"),
        )),
    }
}

/// The mesh of a scenario, and warnings about it (cells the Gmsh import reoriented); refused when
/// it would not fit in memory.
pub(super) fn build_mesh(
    ctx: &Ctx,
    s: &Scenario,
    base_dir: Option<&Path>,
) -> Result<(Mesh, Vec<String>), InputError> {
    let (mesh, mut warnings) = mesh_of(ctx, &s.mesh, base_dir)?;
    ctx.check_size(mesh.n_nodes() as u64, mesh.n_cells() as u64, mesh.kind)
        .map_err(|e| ctx.err("mesh", e))?;
    if s.mesh.file.is_none() {
        warnings.extend(generated_size_warning(&s.mesh, &mesh));
    }
    Ok((mesh, warnings))
}

/// A generated mesh more than 1 m across: a dielectric elastomer device is millimetres to
/// centimetres, so its lengths were most likely typed in mm where metres are read (as a Gmsh
/// file's size warning says).
fn generated_size_warning(m: &MeshSpec, mesh: &Mesh) -> Option<String> {
    let (lo, hi) = mesh.extents();
    let size = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max);
    if size.is_nan() || size <= 1.0 {
        return None;
    }
    let generator = m.generator.as_deref().unwrap_or("box");
    let key = match generator {
        "box" => "mesh.size",
        "stack" => "mesh.side",
        _ => "mesh.radius",
    };
    Some(format!(
        "`{key}`: the generated `{generator}` mesh is {} m across (lengths are read in m); if \
         they were typed in mm, give them in m (10 mm = 0.01)",
        crate::units::Short(size)
    ))
}

/// The model of the mesh with its materials, and the formulation of `mesh.formulation`.
pub(super) fn build_model(
    ctx: &Ctx,
    s: &Scenario,
    mesh: Mesh,
    materials: Materials,
) -> Result<Model, InputError> {
    let mut model = Model::with_geometry(mesh, materials.materials[0].clone(), ctx.hold_geometry)
        .map_err(|e| ctx.err("mesh", e.to_string()))?;
    model.materials = materials.materials;
    model.cell_material = materials.cell_material;
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
    Ok(model)
}

/// Copies of the meshed part that make the physical device: 4 for a quarter disc or stack, 8 for
/// the octant of a sphere.
pub(super) fn symmetry_factor(m: &MeshSpec) -> f64 {
    if m.geometry.as_deref() == Some("axisymmetric") {
        // the meridian cells carry whole rings; the sphere is its upper half
        return if m.generator.as_deref() == Some("sphere") {
            2.0
        } else {
            1.0
        };
    }
    match m.generator.as_deref() {
        Some("disc" | "stack") if m.quarter != Some(false) => 4.0,
        Some("sphere") => 8.0,
        _ => 1.0,
    }
}

fn element_kind(ctx: &Ctx, name: &str, axisymmetric: bool) -> Result<ElementKind, InputError> {
    if axisymmetric {
        return MERIDIAN_ELEMENTS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, k)| ElementKind::Meridian(*k))
            .ok_or_else(|| {
                ctx.err(
                    "mesh.element",
                    format!(
                        "unknown element `{name}` for `geometry = \"axisymmetric\"`: expected \
                         `quad4`, `quad8`, `quad9`, `tri3` or `tri6` (cells of the meridian plane)"
                    ),
                )
            });
    }
    if MERIDIAN_ELEMENTS.iter().any(|(n, _)| *n == name) {
        return Err(ctx.err(
            "mesh.element",
            format!(
                "`{name}` is a cell of the meridian plane: give `geometry = \"axisymmetric\"`, or \
                 a 3-D element (`hex8`, `tet4`, `tet10`)"
            ),
        ));
    }
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

/// The mesh read from `mesh.file` or made by `mesh.generator`.
fn mesh_of(
    ctx: &Ctx,
    m: &MeshSpec,
    base_dir: Option<&Path>,
) -> Result<(Mesh, Vec<String>), InputError> {
    if let Some(file) = &m.file {
        return build_file_mesh(ctx, m, file, base_dir);
    }
    if m.scale.is_some() {
        return Err(ctx.err("mesh.scale", "applies to meshes read from a `file` only"));
    }
    let generator = generator(ctx, m)?;
    reject_foreign_keys(ctx, m, generator)?;
    let axisymmetric = is_axisymmetric(ctx, m)?;
    let default_kind = if axisymmetric { "quad8" } else { "hex8" };
    let kind = element_kind(
        ctx,
        m.element.as_deref().unwrap_or(default_kind),
        axisymmetric,
    )?;
    if axisymmetric != MERIDIAN_GENERATORS.contains(&generator)
        && (axisymmetric || generator == "rectangle")
    {
        let hint = if axisymmetric {
            "axisymmetric models use `disc`, `rectangle` or `sphere`"
        } else {
            "`rectangle` makes meridian cells: give `geometry = \"axisymmetric\"`"
        };
        return Err(ctx.err(
            "mesh.generator",
            format!(
                "`{generator}` with `geometry` = {}: {hint}",
                if axisymmetric { "axisymmetric" } else { "3d" }
            ),
        ));
    }
    let mesh = match generator {
        "rectangle" => build_rectangle(ctx, m, kind)?,
        "sphere" if axisymmetric => build_meridian_sphere(ctx, m, kind)?,
        "disc" => build_disc(ctx, m, kind)?,
        "stack" => build_stack(ctx, m, kind)?,
        "sphere" => build_sphere(ctx, m, kind)?,
        _ => build_box(ctx, m, kind)?,
    };
    Ok((mesh, Vec::new()))
}

/// `mesh.generator`, one of [`GENERATORS`].
fn generator<'a>(ctx: &Ctx, m: &'a MeshSpec) -> Result<&'a str, InputError> {
    let generator = m.generator.as_deref().ok_or_else(|| {
        ctx.err(
            "mesh.generator",
            "missing: expected `box`, `disc` or `stack` (or a `file`)",
        )
    })?;
    if !GENERATORS.contains(&generator) {
        let hint = closest(generator, GENERATORS)
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
        return Err(ctx.err(
            "mesh.generator",
            format!(
                "unknown generator `{generator}`: expected `box`, `disc`, `stack` or \
                     `sphere`{hint}"
            ),
        ));
    }
    Ok(generator)
}

/// The `box` generator: `size` = [lx, ly, lz] in m, `divisions` = [nx, ny, nz] cells.
fn build_box(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
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
        Some(c) if c <= ctx.max_cells() => {
            // before generating it: the nodes of the box
            let per_div = if kind == ElementKind::Tet10 { 2 } else { 1 };
            let nodes: u64 = div.iter().map(|&d| per_div * d + 1).product();
            ctx.check_size(nodes, c, kind)
                .map_err(|e| ctx.err("mesh.divisions", e))?;
        }
        _ => {
            return Err(ctx.err(
                "mesh.divisions",
                format!(
                    "{div:?} gives more than {} cells: too large for this machine's memory",
                    ctx.max_cells()
                ),
            ))
        }
    }
    Ok(box_mesh(
        size,
        [div[0] as usize, div[1] as usize, div[2] as usize],
        kind,
    ))
}

/// Rejects a size key of another generator (`size` given to `disc`, `films` to `sphere`, …).
fn reject_foreign_keys(ctx: &Ctx, m: &MeshSpec, generator: &str) -> Result<(), InputError> {
    let given = [
        ("size", m.size.is_some()),
        ("divisions", m.divisions.is_some()),
        ("radius", m.radius.is_some()),
        ("inner_radius", m.inner_radius.is_some()),
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
    let owners = |key: &str| -> Vec<&str> {
        GENERATOR_KEYS
            .iter()
            .filter(|(_, keys)| keys.contains(&key))
            .map(|(g, _)| *g)
            .collect()
    };
    for (key, is_given) in given {
        let owned_by = owners(key);
        if is_given && !owned_by.contains(&generator) {
            let list: Vec<String> = owned_by.iter().map(|g| format!("`{g}`")).collect();
            let list = match list.split_last() {
                Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
                _ => list.join(""),
            };
            return Err(ctx.err(
                format!("mesh.{key}"),
                format!(
                    "applies to the {} generator, not to `generator = \"{generator}\"`",
                    list
                ),
            ));
        }
    }
    Ok(())
}

/// Rejects a generator key given with `mesh.file`.
fn reject_generator_keys(ctx: &Ctx, m: &MeshSpec, file: &str) -> Result<(), InputError> {
    let generator_keys = [
        ("generator", m.generator.is_some()),
        ("inner_radius", m.inner_radius.is_some()),
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
    Ok(())
}

/// `mesh.file`: a Gmsh mesh (the meridian mesh of an axisymmetric model with `geometry =
/// "axisymmetric"`), its path relative to the scenario file.
fn build_file_mesh(
    ctx: &Ctx,
    m: &MeshSpec,
    file: &str,
    base_dir: Option<&Path>,
) -> Result<(Mesh, Vec<String>), InputError> {
    reject_generator_keys(ctx, m, file)?;
    let scale = match m.scale {
        None => 1.0,
        Some(v) => ctx.positive("mesh.scale", Some(v), "factor from file units to m")?,
    };
    let path = base_dir
        .map(|d| d.join(file))
        .unwrap_or_else(|| file.into());
    let axisymmetric = is_axisymmetric(ctx, m)?;
    let g = read_file_mesh(&path, scale, axisymmetric).map_err(|e| ctx.err("mesh.file", e))?;
    if let Some(name) = &m.element {
        let want = element_kind(ctx, name, axisymmetric)?;
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
    if g.mesh.n_cells() as u64 > ctx.max_cells() {
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
    let (lo, hi) = g.mesh.extents();
    let size = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max);
    if m.scale.is_none() && size > 1.0 {
        warnings.push(format!(
            "{}: the mesh is {size:.4} m across (read in m); if it was drawn in mm, give \
             `mesh.scale = 1e-3`",
            path.display()
        ));
    }
    Ok((g.mesh, warnings))
}

/// A Gmsh file as a 3-D mesh, or as a meridian mesh for an axisymmetric model; when it does not
/// read so but reads the other way, the message says which `mesh.geometry` it needs.
fn read_file_mesh(
    path: &Path,
    scale: f64,
    axisymmetric: bool,
) -> Result<crate::mesh::gmsh::GmshMesh, String> {
    use crate::mesh::gmsh::{read_msh, read_msh_meridian};
    let read = |meridian: bool| {
        if meridian {
            read_msh_meridian(path, scale)
        } else {
            read_msh(path, scale)
        }
    };
    read(axisymmetric).map_err(|e| match read(!axisymmetric) {
        Ok(other) if axisymmetric => format!(
            "`{}` holds a 3-D mesh ({} cells), not the meridian of an axisymmetric model (2-D \
             cells in the x–y plane, x = R ≥ 0, y = Z): remove `geometry = \"axisymmetric\"` \
             to read it as a 3-D model",
            path.display(),
            other.mesh.kind.name()
        ),
        Ok(other) => format!(
            "`{}` holds a 2-D mesh ({} cells), not a 3-D one: give `geometry = \"axisymmetric\"` \
             to read it as the meridian of an axisymmetric model (x = R ≥ 0, y = Z)",
            path.display(),
            other.mesh.kind.name()
        ),
        Err(_) => e.to_string(),
    })
}

/// The `disc` generator: a circular membrane (O-grid) with sets `rim`, `top`, `bottom`, `pad`,
/// `electrode_top`, `electrode_bottom` (and `symmetry_x`, `symmetry_y` for a quarter).
fn build_disc(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
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
    match kind {
        ElementKind::Meridian(m) => disc_meridian(&spec, m),
        _ => disc_mesh(&spec),
    }
    .map_err(|e| ctx.err("mesh", e))
}

/// The `sphere` generator: the octant (x, y, z ≥ 0) of a spherical shell of inner radius `radius`
/// and wall `thickness`, `radial` cells along each edge of its three patches and `layers` through
/// the wall; sets `inner`, `outer` and the symmetry planes `x0`, `y0`, `z0`.
fn build_sphere(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
    let radius = ctx.positive("mesh.radius", m.radius, "inner radius in m")?;
    let thickness = ctx.positive("mesh.thickness", m.thickness, "wall thickness in m")?;
    if kind != ElementKind::Hex8 {
        return Err(ctx.err(
            "mesh.element",
            "the `sphere` generator makes hex8 cells; give `element = \"hex8\"` (with \
             `formulation = \"mean-dilatation\"` for a nearly incompressible wall)",
        ));
    }
    let radial = m.radial.unwrap_or(6);
    let layers = m.layers.unwrap_or(2);
    if !(1..=1000).contains(&radial) {
        return Err(ctx.err(
            "mesh.radial",
            format!("must be between 1 and 1000; got {radial}"),
        ));
    }
    if !(1..=200).contains(&layers) {
        return Err(ctx.err(
            "mesh.layers",
            format!("must be between 1 and 200; got {layers}"),
        ));
    }
    check_cell_count(
        ctx,
        "mesh.radial",
        (3 * radial * radial * layers) as usize,
        kind,
    )?;
    Ok(crate::mesh::sphere::sphere_octant(
        radius,
        radius + thickness,
        radial as usize,
        layers as usize,
    ))
}

/// The `rectangle` generator (axisymmetric): R ∈ [inner_radius, radius], Z ∈ [0, thickness]
/// with `radial × layers` equal cells; sets `inner` (and `axis` when inner_radius = 0), `outer`,
/// `bottom`, `top`.
fn build_rectangle(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
    let radius = ctx.positive("mesh.radius", m.radius, "outer radius in m")?;
    let thickness = ctx.positive("mesh.thickness", m.thickness, "height in m")?;
    let inner = m.inner_radius.unwrap_or(0.0);
    if !(inner.is_finite() && (0.0..radius).contains(&inner)) {
        return Err(ctx.err(
            "mesh.inner_radius",
            format!("expected 0 ≤ inner_radius < radius ({radius} m); got {inner}"),
        ));
    }
    let (radial, layers) = meridian_divisions(ctx, m, 8, 1)?;
    let ElementKind::Meridian(k) = kind else {
        return Err(ctx.err("mesh.element", "expected a meridian element"));
    };
    crate::mesh::meridian::rectangle_mesh(inner, radius, thickness, radial, layers, k)
        .map_err(|e| ctx.err("mesh", e))
}

/// The `sphere` generator (axisymmetric): the upper half of a spherical shell of inner radius
/// `radius` and wall `thickness`, `radial` cells along the quarter meridian and `layers`
/// through the wall; sets `inner`, `outer`, `equator` (Z = 0) and `axis`.
fn build_meridian_sphere(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
    let radius = ctx.positive("mesh.radius", m.radius, "inner radius in m")?;
    let thickness = ctx.positive("mesh.thickness", m.thickness, "wall thickness in m")?;
    let (radial, layers) = meridian_divisions(ctx, m, 16, 2)?;
    let ElementKind::Meridian(k) = kind else {
        return Err(ctx.err("mesh.element", "expected a meridian element"));
    };
    crate::mesh::meridian::sphere_meridian(radius, radius + thickness, radial, layers, k)
        .map_err(|e| ctx.err("mesh", e))
}

/// `mesh.radial` and `mesh.layers` of a meridian generator, with their defaults.
fn meridian_divisions(
    ctx: &Ctx,
    m: &MeshSpec,
    radial: u64,
    layers: u64,
) -> Result<(usize, usize), InputError> {
    let radial = m.radial.unwrap_or(radial);
    let layers = m.layers.unwrap_or(layers);
    if !(1..=100_000).contains(&radial) {
        return Err(ctx.err(
            "mesh.radial",
            format!("must be between 1 and 100000; got {radial}"),
        ));
    }
    if !(1..=10_000).contains(&layers) {
        return Err(ctx.err(
            "mesh.layers",
            format!("must be between 1 and 10000; got {layers}"),
        ));
    }
    if radial * layers > ctx.max_cells() {
        return Err(ctx.err(
            "mesh.radial",
            format!(
                "{} cells: too large for this machine's memory",
                radial * layers
            ),
        ));
    }
    Ok((radial as usize, layers as usize))
}

/// Refuses a generated mesh of more cells than `ctx.max_cells()` allows (`hexahedra` of the layout, six
/// tetrahedra each for tet meshes), naming `key`, the parameter that sets the size.
fn check_cell_count(
    ctx: &Ctx,
    key: &str,
    hexahedra: usize,
    kind: ElementKind,
) -> Result<(), InputError> {
    let cells = hexahedra as u64
        * if matches!(kind, ElementKind::Hex8 | ElementKind::Meridian(_)) {
            1
        } else {
            6
        };
    if cells > ctx.max_cells() {
        return Err(ctx.err(
            key,
            format!("{cells} cells: too large for this machine's memory"),
        ));
    }
    Ok(())
}

/// `mesh.side` of the `stack` generator: one side length or [lx, ly] in m.
fn stack_side(ctx: &Ctx, m: &MeshSpec) -> Result<[f64; 2], InputError> {
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
    Ok(side)
}

/// The `stack` generator: `films` films with electrodes `electrode_0` … `electrode_N` on every
/// interface, a passive `border`, cells graded toward the electrode edges (see
/// [`crate::mesh::stack`]).
fn build_stack(ctx: &Ctx, m: &MeshSpec, kind: ElementKind) -> Result<Mesh, InputError> {
    let side = stack_side(ctx, m)?;
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
            format!(
                "must lie in [0, {half}) m (half the shorter side); got {}",
                crate::units::Short(border)
            ),
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
            format!(
                "expected a size ratio between 1 and 1000; got {}",
                crate::units::Short(grading)
            ),
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

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_names, assert_rejected, plan, scenario, CTX, FILE};
    use super::*;

    const DISC: &str = "[mesh]\ngenerator = \"disc\"\nradius = 17.5e-3\nthickness = 1e-3\n\
                        pad_radius = 3.75e-3\nelectrode_radius = 7.5e-3\nradial = 6\nlayers = 1";
    const SPHERE: &str =
        "[mesh]\ngenerator = \"sphere\"\nradius = 0.01\nthickness = 0.5e-3\nradial = 3\nlayers = 2";
    const STACK: &str = "[mesh]\ngenerator = \"stack\"\nside = 4e-3\nfilms = 2\n\
                         film_thickness = 50e-6\nborder = 0.4e-3\nlayers_per_film = 2\n\
                         active_cells = 2";

    /// A distributed solver lifts the serial cell limit (set by the direct factorisation of the
    /// whole tangent on one process) to PETSc's: a mesh of 3·10⁶ cells is refused for one
    /// process and accepted for a distributed run; 10⁹ cells are refused for both.
    #[test]
    fn a_distributed_solver_lifts_the_serial_cell_limit() {
        let distributed = Ctx {
            distributed: true,
            ..CTX
        };
        let e = check_cell_count(&CTX, "mesh.radial", 3_000_000, ElementKind::Hex8).unwrap_err();
        assert!(e.to_string().contains("3000000 cells: too large"), "{e}");
        check_cell_count(&distributed, "mesh.radial", 3_000_000, ElementKind::Hex8).unwrap();
        for ctx in [&CTX, &distributed] {
            assert!(
                check_cell_count(ctx, "mesh.radial", 1_000_000_000, ElementKind::Hex8).is_err()
            );
        }
    }

    fn box_mesh_of(extra: &str) -> String {
        format!(
            "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [2, 2, 1]\n{extra}"
        )
    }

    fn mesh(section: &str) -> Result<(Mesh, Vec<String>), InputError> {
        build_mesh(&CTX, &scenario(&[("mesh", section)]), None)
    }

    fn gmsh_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gmsh")
    }

    /// The error of the `[mesh]` table `mesh` on the Gmsh test files.
    fn gmsh_mesh_error(mesh: &str) -> InputError {
        build_mesh(&CTX, &scenario(&[("mesh", mesh)]), Some(&gmsh_dir())).unwrap_err()
    }

    #[test]
    fn box_meshes_of_every_element_kind() {
        let p = plan(&[]);
        assert_eq!(p.model.mesh.kind, ElementKind::Hex8);
        assert_eq!((p.model.mesh.n_cells(), p.model.mesh.n_nodes()), (4, 18));
        let (m, _) = mesh(&box_mesh_of("element = \"tet4\"")).unwrap();
        assert_eq!(
            (m.kind, m.n_cells(), m.n_nodes()),
            (ElementKind::Tet4, 24, 18)
        );
        let (m, _) = mesh(&box_mesh_of("element = \"tet10\"")).unwrap();
        assert_eq!((m.kind, m.n_nodes()), (ElementKind::Tet10, 5 * 5 * 3));
    }

    #[test]
    fn disc_and_stack_generators_with_their_sets_and_symmetry() {
        let s = scenario(&[("mesh", DISC)]);
        let (m, _) = build_mesh(&CTX, &s, None).unwrap();
        for set in ["rim", "pad", "electrode_top", "symmetry_x"] {
            assert!(m.set_nodes(set).is_some_and(|n| !n.is_empty()), "{set}");
        }
        assert_eq!(symmetry_factor(&s.mesh), 4.0);
        let whole = format!("{DISC}\nquarter = false");
        assert_eq!(symmetry_factor(&scenario(&[("mesh", &whole)]).mesh), 1.0);
        let (m, _) = mesh(STACK).unwrap();
        for set in ["electrode_0", "electrode_1", "electrode_2", "high_voltage"] {
            assert!(m.set_nodes(set).is_some_and(|n| !n.is_empty()), "{set}");
        }
        assert!(m.set_nodes("electrode_3").is_none());
        let s = scenario(&[("mesh", SPHERE)]);
        let (m, _) = build_mesh(&CTX, &s, None).unwrap();
        assert_eq!(m.n_cells(), 3 * 3 * 3 * 2);
        for set in ["inner", "outer", "x0", "y0", "z0"] {
            assert!(m.set_nodes(set).is_some_and(|n| !n.is_empty()), "{set}");
        }
        // inner radius `radius`, outer `radius + thickness`
        let r = |n: usize| m.nodes[n].iter().map(|c| c * c).sum::<f64>().sqrt();
        assert!(m
            .set_nodes("inner")
            .unwrap()
            .iter()
            .all(|&n| (r(n) - 0.01).abs() < 1e-12));
        assert!(m
            .set_nodes("outer")
            .unwrap()
            .iter()
            .all(|&n| (r(n) - 0.0105).abs() < 1e-12));
        assert_eq!(symmetry_factor(&s.mesh), 8.0);
        let e = mesh(&format!("{SPHERE}\nelement = \"tet4\"")).unwrap_err();
        assert_names(
            &e,
            "mesh.element",
            "the `sphere` generator makes hex8 cells",
        );
        let e = mesh(&SPHERE.replace("radius = 0.01", "")).unwrap_err();
        assert_names(&e, "mesh.radius", "inner radius in m");
    }

    #[test]
    fn the_formulation_is_set_on_the_model() {
        let p = plan(&[("mesh", &box_mesh_of("formulation = \"mean-dilatation\""))]);
        assert_eq!(p.model.formulation, Formulation::MeanDilatation);
        let p = plan(&[]);
        assert_eq!(p.model.formulation, Formulation::Standard);
    }

    #[test]
    fn gmsh_files_are_read_relative_to_the_base_directory_and_scaled() {
        let s = scenario(&[(
            "mesh",
            "[mesh]\nfile = \"film-hex8-msh22.msh\"\nscale = 1e-3\nelement = \"hex8\"",
        )]);
        let (m, warnings) = build_mesh(&CTX, &s, Some(&gmsh_dir())).unwrap();
        assert_eq!(m.kind, ElementKind::Hex8);
        assert!(warnings.is_empty(), "{warnings:?}");
        // drawn in mm: 10 x 10 x 1 mm after scaling
        let zmax = m.nodes.iter().map(|x| x[2]).fold(f64::MIN, f64::max);
        assert!((zmax - 1e-3).abs() < 1e-12, "{zmax}");
        // without the scale it would be a 10 m device: said, with the way out
        let s = scenario(&[("mesh", "[mesh]\nfile = \"film-hex8-msh22.msh\"")]);
        let (_, warnings) = build_mesh(&CTX, &s, Some(&gmsh_dir())).unwrap();
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("m across") && w.contains("mesh.scale = 1e-3")),
            "{warnings:?}"
        );
    }

    #[test]
    fn unknown_or_missing_generators_are_rejected() {
        let e = mesh("[mesh]\ngenerator = \"bx\"").unwrap_err();
        assert_names(&e, "mesh.generator", "unknown generator `bx`");
        assert!(e.message.ends_with("did you mean `box`?"), "{e}");
        let e = mesh("[mesh]\nsize = [1.0, 1.0, 1.0]").unwrap_err();
        assert_names(
            &e,
            "mesh.generator",
            "missing: expected `box`, `disc` or `stack`",
        );
        let e = mesh(&box_mesh_of("scale = 2.0")).unwrap_err();
        assert_names(
            &e,
            "mesh.scale",
            "applies to meshes read from a `file` only",
        );
    }

    #[test]
    fn bad_box_sizes_and_divisions_are_rejected() {
        let bad_size =
            "[mesh]\ngenerator = \"box\"\nsize = [0.01, -1.0, 0.001]\ndivisions = [2, 2, 1]";
        assert_rejected(
            &[("mesh", bad_size)],
            "mesh.size.1",
            "must be a positive finite number (edge length in m); got -1",
        );
        let zero = "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [2, 0, 1]";
        assert_rejected(
            &[("mesh", zero)],
            "mesh.divisions",
            "every entry must be at least 1",
        );
        let huge =
            "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [2000, 2000, 1]";
        assert_rejected(
            &[("mesh", huge)],
            "mesh.divisions",
            "gives more than 2000000 cells: too large",
        );
        let missing = "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]";
        assert_rejected(
            &[("mesh", missing)],
            "mesh.divisions",
            "missing: expected [nx, ny, nz]",
        );
    }

    #[test]
    fn keys_of_another_generator_are_rejected() {
        let e = mesh(&box_mesh_of("films = 2")).unwrap_err();
        assert_names(
            &e,
            "mesh.films",
            "applies to the `stack` generator, not to `generator = \"box\"`",
        );
        let e = mesh(&format!("{STACK}\nradius = 1.0")).unwrap_err();
        assert_names(
            &e,
            "mesh.radius",
            "applies to the `disc`, `sphere` or `rectangle` generator, not to `generator = \"stack\"`",
        );
        let e = mesh(&box_mesh_of("radius = 1.0")).unwrap_err();
        assert_names(&e, "mesh.radius", "not to `generator = \"box\"`");
        let e = mesh(&format!("{SPHERE}\npad_radius = 1.0")).unwrap_err();
        assert_names(
            &e,
            "mesh.pad_radius",
            "applies to the `disc` generator, not to `generator = \"sphere\"`",
        );
        let e = gmsh_mesh_error("[mesh]\nfile = \"film-hex8-msh22.msh\"\nradial = 4");
        assert_names(
            &e,
            "mesh.radial",
            "applies to the mesh generators, not to a mesh read",
        );
    }

    #[test]
    fn bad_element_kinds_and_formulations_are_rejected() {
        let e = mesh(&box_mesh_of("element = \"hex9\"")).unwrap_err();
        assert_names(
            &e,
            "mesh.element",
            "unknown element `hex9`: expected `hex8`, `tet4`",
        );
        assert!(e.message.ends_with("did you mean `hex8`?"), "{e}");
        let both = box_mesh_of("element = \"tet10\"\nformulation = \"mean-dilatation\"");
        assert_rejected(
            &[("mesh", &both)],
            "mesh.formulation",
            "tet10 is used with the",
        );
        let unknown = box_mesh_of("formulation = \"b-bar\"");
        assert_rejected(
            &[("mesh", &unknown)],
            "mesh.formulation",
            "unknown formulation `b-bar`",
        );
        let e = gmsh_mesh_error("[mesh]\nfile = \"film-hex8-msh22.msh\"\nelement = \"tet4\"");
        assert_names(&e, "mesh.element", "`tet4` given, but");
        assert!(e.message.ends_with("holds hex8 cells"), "{e}");
    }

    #[test]
    fn bad_disc_and_stack_parameters_are_rejected() {
        let e = mesh(&DISC.replace("radial = 6", "radial = 1")).unwrap_err();
        assert_names(&e, "mesh.radial", "must be between 2 and 2000; got 1");
        let e = mesh(&DISC.replace("thickness = 1e-3", "thickness = nan")).unwrap_err();
        assert_names(
            &e,
            "mesh.thickness",
            "positive finite number (thickness in m)",
        );
        let e = mesh(&STACK.replace("border = 0.4e-3", "border = 3e-3")).unwrap_err();
        assert_names(
            &e,
            "mesh.border",
            "must lie in [0, 0.002) m (half the shorter side)",
        );
        let e = mesh(&STACK.replace("side = 4e-3", "side = [1e-3, 2e-3, 3e-3]")).unwrap_err();
        assert_names(
            &e,
            "mesh.side",
            "expected one side length or [lx, ly] in m; got 3 values",
        );
        let e = mesh(&STACK.replace("films = 2", "films = 0")).unwrap_err();
        assert_names(&e, "mesh.films", "must be between 1 and 1000; got 0");
    }

    #[test]
    fn a_missing_gmsh_file_is_rejected() {
        let e = gmsh_mesh_error("[mesh]\nfile = \"no-such-file.msh\"");
        assert_names(&e, "mesh.file", "no-such-file.msh");
        let e = gmsh_mesh_error("[mesh]\nfile = \"film-hex8-msh22.msh\"\nscale = 0.0");
        assert_names(&e, "mesh.scale", "factor from file units to m");
    }

    /// An axisymmetric scenario on a Gmsh meridian file (R ∈ [0, 2], Z ∈ [0, 1] mm in 4 × 2 quad8
    /// cells): the model has the file's cells and sets, the axis nodes held radially, the
    /// electrodes on the physical curves.
    #[test]
    fn axisymmetric_scenario_on_a_gmsh_meridian_file() {
        let dir = gmsh_dir();
        let s = scenario(&[
            (
                "mesh",
                "[mesh]\ngeometry = \"axisymmetric\"\nfile = \"meridian-quad8-msh22.msh\"\n\
                 scale = 1e-3\nelement = \"quad8\"",
            ),
            (
                "constraints",
                "[[constraints]]\nset = \"bottom\"\nfix = [\"z\"]",
            ),
            (
                "electrodes",
                "[electrodes.top]\nset = \"top\"\nvoltage = 1000.0\n\
                 [electrodes.bottom]\nset = \"bottom\"\nvoltage = 0.0",
            ),
        ]);
        let p = crate::io::build::build(&s, FILE, Some(&dir));
        let wrong = scenario(&[(
            "mesh",
            "[mesh]\ngeometry = \"axisymmetric\"\nfile = \"meridian-quad8-msh22.msh\"\n\
             element = \"tri6\"",
        )]);
        let e = build_mesh(&CTX, &wrong, Some(&dir));
        let p = p.unwrap_or_else(|e| panic!("{e}"));
        let m = &p.model.mesh;
        assert_eq!(m.kind, ElementKind::Meridian(MeridianKind::Quad8));
        assert_eq!((m.n_cells(), m.n_nodes()), (8, 37));
        assert!(p.model.is_axisymmetric());
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
        let axis = m.node_sets["axis"].clone();
        assert_eq!(axis.len(), 5);
        assert!(axis.iter().all(|&n| m.nodes[n][0] == 0.0));
        // the axis nodes are held radially (slot 0) by the model's own supports
        assert!(p
            .supports
            .iter()
            .any(|d| d.field == crate::problem::dofs::Field::Ux && d.nodes == axis));
        let top = &p.electrodes.iter().find(|e| e.name == "top").unwrap().nodes;
        assert_eq!(top.len(), 9);
        assert!(top.iter().all(|&n| (m.nodes[n][1] - 1e-3).abs() < 1e-15));
        let e = e.unwrap_err();
        assert_names(&e, "mesh.element", "`tri6` given, but");
        assert!(e.message.ends_with("holds quad8 cells"), "{e}");
    }

    /// A 2-D file in a 3-D scenario, a 3-D file in an axisymmetric one: the error says which
    /// `geometry` reads it.
    #[test]
    fn gmsh_files_of_the_other_geometry_are_rejected() {
        let e = gmsh_mesh_error("[mesh]\nfile = \"meridian-tri6-msh41.msh\"");
        assert_names(&e, "mesh.file", "holds a 2-D mesh (tri6 cells)");
        assert!(
            e.message.contains("give `geometry = \"axisymmetric\"`"),
            "{e}"
        );
        let e =
            gmsh_mesh_error("[mesh]\ngeometry = \"axisymmetric\"\nfile = \"film-tet4-msh22.msh\"");
        assert_names(&e, "mesh.file", "holds a 3-D mesh (tet4 cells)");
        assert!(
            e.message.contains("remove `geometry = \"axisymmetric\"`"),
            "{e}"
        );
        // a file neither way reads: the reader's own message
        let e = gmsh_mesh_error("[mesh]\ngeometry = \"axisymmetric\"\nfile = \"no-such-file.msh\"");
        assert_names(&e, "mesh.file", "no-such-file.msh: cannot read");
    }
}
