//! `[materials.<name>]` and `[regions]`: material models and presets with their parameters, the
//! material of every cell, density, viscosity and dielectric strength.

use super::Ctx;
use crate::io::scenario::{closest, InputError, MaterialSpec, Scenario};
use crate::material::registry::{self, MaterialParams};
use crate::material::Material;
use crate::mesh::Mesh;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The materials of a model.
pub(super) struct Materials {
    /// In name order.
    pub materials: Vec<Arc<dyn Material>>,
    /// The index in `materials` of each cell's material.
    pub cell_material: Vec<usize>,
    /// The resolved parameters of each material, one line each ([`registry::describe`]).
    pub parameters: Vec<Vec<String>>,
}

/// The materials and the material of every cell; the warnings of the material checks go to
/// `warnings`.
pub(super) fn build_materials(
    ctx: &Ctx,
    s: &Scenario,
    mesh: &Mesh,
    warnings: &mut Vec<String>,
) -> Result<Materials, InputError> {
    let mut materials = material_list(ctx, s, warnings)?;
    let index: BTreeMap<&str, usize> = s
        .materials
        .keys()
        .enumerate()
        .map(|(i, name)| (name.as_str(), i))
        .collect();
    materials.cell_material = cell_materials(ctx, s, mesh, &index)?;
    Ok(materials)
}

/// The materials in name order, with the resolved parameters of each, without the material of
/// each cell (`cell_material` empty: needs no mesh); the warnings of the material checks go to
/// `warnings`.
pub(super) fn material_list(
    ctx: &Ctx,
    s: &Scenario,
    warnings: &mut Vec<String>,
) -> Result<Materials, InputError> {
    if s.materials.is_empty() {
        return Err(ctx.err("materials", "at least one material is needed"));
    }
    let mut mats: Vec<Arc<dyn Material>> = Vec::new();
    let mut parameters = Vec::new();
    for (name, m) in &s.materials {
        let (mat, described) = build_material(ctx, name, m, warnings)?;
        mats.push(mat);
        parameters.push(described);
    }
    Ok(Materials {
        materials: mats,
        cell_material: Vec::new(),
        parameters,
    })
}

/// Dielectric strength (V/m) of each material, if given, and whether to stop at breakdown.
pub(super) fn build_breakdown(
    ctx: &Ctx,
    s: &Scenario,
) -> Result<(Vec<Option<f64>>, bool), InputError> {
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
    Ok((breakdown, stop_at_breakdown))
}

/// Mass density (kg/m³) of each material, 0 when not given.
pub(super) fn densities(s: &Scenario) -> Vec<f64> {
    s.materials
        .values()
        .map(|m| m.density.unwrap_or(0.0))
        .collect()
}

/// Kelvin–Voigt viscosity (Pa·s) of each material, 0 when not given.
pub(super) fn viscosities(s: &Scenario) -> Vec<f64> {
    s.materials
        .values()
        .map(|m| m.viscosity.unwrap_or(0.0))
        .collect()
}

/// The material of every cell: from `regions` (cell set → material), or the one material.
fn cell_materials(
    ctx: &Ctx,
    s: &Scenario,
    mesh: &Mesh,
    index: &BTreeMap<&str, usize>,
) -> Result<Vec<usize>, InputError> {
    let mut cell_material = vec![usize::MAX; mesh.n_cells()];
    if s.regions.is_empty() {
        if index.len() > 1 {
            return Err(ctx.err(
                "regions",
                "several materials: `regions` must say which cell set has which material",
            ));
        }
        cell_material.iter_mut().for_each(|c| *c = 0);
        return Ok(cell_material);
    }
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
    Ok(cell_material)
}

/// The material `name`: its model and parameters (a preset's, overridden by those given).
pub(super) fn build_material(
    ctx: &Ctx,
    name: &str,
    m: &MaterialSpec,
    warnings: &mut Vec<String>,
) -> Result<(Arc<dyn Material>, Vec<String>), InputError> {
    let key = |k: &str| format!("materials.{name}.{k}");
    let (model, mut p) = model_and_preset(ctx, name, m)?;
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
    override_parameters(m, &mut p);
    for (k, v, unit) in [
        ("density", m.density, "kg/m³"),
        ("viscosity", m.viscosity, "Pa·s"),
    ] {
        if let Some(x) = v {
            if !(x.is_finite() && x >= 0.0) {
                return Err(ctx.err(
                    key(k),
                    format!(
                        "must be a finite number ≥ 0 in {unit}; got {}",
                        crate::units::Short(x)
                    ),
                ));
            }
        }
    }
    let (mat, w) = registry::build(&model, &p).map_err(|e| ctx.err(key(&e.key), e.message))?;
    warnings.extend(w.into_iter().map(|w| format!("material `{name}`: {w}")));
    Ok((mat, registry::describe(&model, &p)))
}

/// The model name and the parameters of the preset (defaults without a preset).
fn model_and_preset(
    ctx: &Ctx,
    name: &str,
    m: &MaterialSpec,
) -> Result<(String, MaterialParams), InputError> {
    let key = |k: &str| format!("materials.{name}.{k}");
    let Some(preset) = &m.preset else {
        let model = m.model.clone().ok_or_else(|| {
            ctx.err(
                key("model"),
                format!(
                    "missing: expected a model ({}) or a `preset`",
                    registry::MODELS.join(", ")
                ),
            )
        })?;
        return Ok((model, MaterialParams::default()));
    };
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
    Ok((model.to_string(), params))
}

/// Parameters given in a material table `m` override those of `p` (a preset's): what a scenario
/// and a calibration spec both read.
pub fn override_parameters(m: &MaterialSpec, p: &mut MaterialParams) {
    if let Some(b) = &m.branches {
        p.branches = b.iter().map(|b| (b.mu, b.tau)).collect();
    }
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
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_rejected, plan};

    /// Two materials on the two halves of the box (x < 5 mm: `soft`).
    const TWO: &str = "[materials.soft]\nmodel = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\n\
                       permittivity = 4.7\ndensity = 1000.0\nviscosity = 5.0\n\
                       [materials.stiff]\nmodel = \"neo-hooke\"\nmu = 4e5\nlambda = 4e7\n\
                       permittivity = 3.0\nbreakdown_field = 8e7\nstop_at_breakdown = true";

    fn material(body: &str) -> String {
        format!("[materials.gel]\n{body}")
    }

    #[test]
    fn a_model_with_its_parameters() {
        let p = plan(&[]);
        assert_eq!(p.model.materials.len(), 1);
        assert_eq!(p.model.materials[0].shear_modulus(), 1e5);
        assert!(p.model.cell_material.iter().all(|&m| m == 0));
        assert_eq!(p.densities, [0.0]);
        assert_eq!(p.viscosities, [0.0]);
        assert_eq!(p.breakdown, [None]);
        assert!(!p.stop_at_breakdown);
    }

    #[test]
    fn a_preset_with_an_overridden_parameter() {
        let preset = plan(&[("materials", &material("preset = \"vhb4910-gent\""))]);
        let overridden = plan(&[(
            "materials",
            &material("preset = \"vhb4910-gent\"\nmodel = \"gent\"\nmu = [123456.0]"),
        )]);
        let mu = preset.model.materials[0].shear_modulus();
        assert!(mu > 0.0 && mu != 123456.0, "{mu}");
        assert_eq!(overridden.model.materials[0].shear_modulus(), 123456.0);
        // the rest of the preset is kept
        assert_eq!(
            preset.model.materials[0].permittivity(),
            overridden.model.materials[0].permittivity()
        );
    }

    #[test]
    fn regions_give_every_cell_its_material_and_properties_follow_name_order() {
        // the base `all` cell set, then `stiff` over it: every cell stiff
        let p = plan(&[
            ("materials", TWO),
            ("regions", "[regions]\nall = \"stiff\""),
        ]);
        assert_eq!(p.material_names, ["soft", "stiff"]);
        assert_eq!(p.model.materials[1].shear_modulus(), 4e5);
        assert!(p.model.cell_material.iter().all(|&m| m == 1));
        assert_eq!(p.densities, [1000.0, 0.0]);
        assert_eq!(p.viscosities, [5.0, 0.0]);
        assert_eq!(p.breakdown, [None, Some(8e7)]);
        assert!(p.stop_at_breakdown);
    }

    #[test]
    fn unknown_models_and_presets_are_rejected() {
        assert_rejected(
            &[("materials", &material("model = \"neo-hook\"\nmu = 1e5"))],
            "materials.gel.model",
            "unknown material model `neo-hook` (known: neo-hooke,",
        );
        assert_rejected(
            &[("materials", &material("preset = \"vhb\""))],
            "materials.gel.preset",
            "unknown preset `vhb` (known: vhb4910-yeoh,",
        );
        assert_rejected(
            &[(
                "materials",
                &material("preset = \"vhb4910-gent\"\nmodel = \"yeoh\""),
            )],
            "materials.gel.model",
            "preset `vhb4910-gent` is a `gent` material; got model `yeoh`",
        );
        assert_rejected(
            &[("materials", &material("mu = 1e5"))],
            "materials.gel.model",
            "missing: expected a model (neo-hooke,",
        );
    }

    #[test]
    fn bad_parameters_density_and_viscosity_are_rejected() {
        let body = "model = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\npermittivity = 4.7\n";
        assert_rejected(
            &[("materials", &material(&format!("{body}density = -1.0")))],
            "materials.gel.density",
            "must be a finite number ≥ 0 in kg/m³; got -1",
        );
        assert_rejected(
            &[("materials", &material(&format!("{body}viscosity = inf")))],
            "materials.gel.viscosity",
            "must be a finite number ≥ 0 in Pa·s; got inf",
        );
        assert_rejected(
            &[("materials", &material(&format!("{body}c10 = 1.0")))],
            "materials.gel.c10",
            "not a parameter of model `neo-hooke`",
        );
        assert_rejected(
            &[(
                "materials",
                &material(&format!("{body}breakdown_field = 0.0")),
            )],
            "materials.gel.breakdown_field",
            "must be a positive finite number (dielectric strength in V/m); got 0",
        );
        assert_rejected(
            &[(
                "materials",
                &material(&format!("{body}stop_at_breakdown = true")),
            )],
            "materials.gel.stop_at_breakdown",
            "needs `breakdown_field` (V/m) on the same material",
        );
    }

    #[test]
    fn bad_regions_are_rejected() {
        assert_rejected(
            &[("materials", TWO)],
            "regions",
            "several materials: `regions` must say which cell set has which material",
        );
        assert_rejected(
            &[("materials", TWO), ("regions", "[regions]\nall = \"stif\"")],
            "regions.all",
            "unknown material `stif`; did you mean `stiff`?",
        );
        assert_rejected(
            &[
                ("materials", TWO),
                ("regions", "[regions]\nbody = \"soft\""),
            ],
            "regions.body",
            "unknown cell set `body` (cell sets: all)",
        );
    }

    #[test]
    fn an_empty_materials_table_is_rejected() {
        assert_rejected(
            &[("materials", "[materials]")],
            "materials",
            "at least one material is needed",
        );
    }
}
