//! `[probes.<name>]`: the recorded quantities.

use super::{Ctx, Electrode};
use crate::io::scenario::{closest, InputError, ProbeSpec, Scenario};
use crate::job::probes::{NodalQuantity, Probe, ProbeFace, ProbeKind};
use crate::problem::model::Model;

/// The probe kinds by scenario name.
const KINDS: [&str; 17] = [
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
    "current",
    "power",
    "source_energy",
    "resistor_loss",
    "area_strain",
    "volume",
    "pressure",
];

/// The nodal quantities by scenario name.
const NODAL: [&str; 5] = ["ux", "uy", "uz", "u", "phi"];

/// The probes in name order, with their names.
pub(super) fn build_probes(
    ctx: &Ctx,
    s: &Scenario,
    model: &Model,
    electrodes: &[Electrode],
) -> Result<Vec<(String, Probe)>, InputError> {
    let mut probes = Vec::new();
    for (name, p) in &s.probes {
        let key = format!("probes.{name}");
        probes.push((
            name.clone(),
            build_probe(ctx, &key, p, s, model, electrodes)?,
        ));
    }
    Ok(probes)
}

/// The probe at `key`: its kind, `scale`, `offset`, unit and description.
fn build_probe(
    ctx: &Ctx,
    key: &str,
    p: &ProbeSpec,
    s: &Scenario,
    model: &Model,
    electrodes: &[Electrode],
) -> Result<Probe, InputError> {
    let kind = probe_kind(ctx, key, p, s, model, electrodes)?;
    let scale = ctx.finite(&format!("{key}.scale"), p.scale.unwrap_or(1.0), "factor")?;
    let offset = ctx.finite(&format!("{key}.offset"), p.offset.unwrap_or(0.0), "offset")?;
    let unit = match &p.unit {
        Some(u) => {
            let bad = u.is_empty()
                || u.chars().count() > 16
                || u.chars().any(|c| c.is_control() || "[]\"".contains(c));
            if bad {
                return Err(ctx.err(
                    format!("{key}.unit"),
                    format!(
                        "expected a short unit such as `-`, `mm` or `kPa` (1 to 16 characters, \
                         no brackets or quotes); got `{}`",
                        u.escape_debug()
                    ),
                ));
            }
            u.clone()
        }
        // a scaled quantity has a unit only the user knows
        None if scale == 1.0 => kind.unit().to_string(),
        None => String::new(),
    };
    Ok(Probe {
        kind,
        scale,
        offset,
        unit,
        description: describe(p, scale, offset),
    })
}

/// What a probe measures, in words: `1 + 1000 × mean uz over z1`.
fn describe(p: &ProbeSpec, scale: f64, offset: f64) -> String {
    let q = p.quantity.as_deref().unwrap_or("?");
    let set = p.set.as_deref().unwrap_or("?");
    let electrode = p.electrode.as_deref().unwrap_or("?");
    let base = match p.kind.as_str() {
        "mean" | "max" | "min" => format!("{} {q} over {set}", p.kind),
        "point" => {
            let at = p.at.unwrap_or([f64::NAN; 3]);
            format!("{q} at ({}, {}, {}) m", at[0], at[1], at[2])
        }
        "charge" | "capacitance" | "current" | "power" => {
            format!("{} of electrode {electrode}", p.kind)
        }
        "source_energy" => format!("energy delivered by the source of electrode {electrode}"),
        "resistor_loss" => format!("energy lost in the resistance of electrode {electrode}"),
        "reaction" => format!("reaction force {q} on {set}"),
        "energy" => format!("{q} energy"),
        "center_deflection" => format!(
            "downward deflection of {}",
            p.set.as_deref().unwrap_or("pad")
        ),
        "max_electric_field" => "largest true electric field".to_string(),
        "volume" => format!("volume enclosed by {set}"),
        "pressure" => format!("pressure on {set}"),
        "area_strain" => match &p.electrode {
            Some(e) => format!("area strain of electrode {e}"),
            None => format!("area strain of {set}"),
        },
        other => other.to_string(),
    };
    match (offset != 0.0, scale != 1.0) {
        (false, false) => base,
        (false, true) => format!("{scale} × {base}"),
        (true, false) => format!("{offset} + {base}"),
        (true, true) => format!("{offset} + {scale} × {base}"),
    }
}

/// The weights of a `mean` over the set `name` with nodes `nodes`: each node's share ∫Nₐ dA of
/// the reference area when the set has faces (a node set of the same name included), else 1.
fn area_weights(mesh: &crate::mesh::Mesh, name: &str, nodes: &[usize]) -> Vec<f64> {
    let Some(faces) = mesh.face_sets.get(name) else {
        return vec![1.0; nodes.len()];
    };
    let mut by_node = std::collections::BTreeMap::new();
    for &f in faces {
        let (local, w) = crate::problem::loads::face_node_areas(mesh, f);
        let cell = mesh.cell(f.cell);
        for (i, &l) in local.iter().enumerate() {
            *by_node.entry(cell[l]).or_insert(0.0) += w[i];
        }
    }
    let weights: Vec<f64> = nodes
        .iter()
        .map(|n| by_node.get(n).copied().unwrap_or(0.0))
        .collect();
    if weights.iter().sum::<f64>() > 0.0 {
        weights
    } else {
        vec![1.0; nodes.len()]
    }
}

/// What the probe measures, by `kind`.
fn probe_kind(
    ctx: &Ctx,
    key: &str,
    p: &ProbeSpec,
    s: &Scenario,
    model: &Model,
    electrodes: &[Electrode],
) -> Result<ProbeKind, InputError> {
    let need = |v: &Option<String>, what: &str| need(ctx, key, p, v, what);
    let set = |name: &str| ctx.set_nodes(&model.mesh, &format!("{key}.set"), name);
    let electrode = |name: &str| electrode_index(ctx, key, electrodes, name);
    let axisymmetric = model.is_axisymmetric();
    Ok(match p.kind.as_str() {
        "mean" | "max" | "min" => {
            let q = nodal(ctx, key, &need(&p.quantity, "quantity")?, axisymmetric)?;
            let name = need(&p.set, "set")?;
            let nodes = set(&name)?;
            match p.kind.as_str() {
                "mean" => {
                    let weights = area_weights(&model.mesh, &name, &nodes);
                    ProbeKind::Mean(q, nodes, weights)
                }
                "max" => ProbeKind::Max(q, nodes),
                _ => ProbeKind::Min(q, nodes),
            }
        }
        "point" => {
            let q = nodal(ctx, key, &need(&p.quantity, "quantity")?, axisymmetric)?;
            let at = p.at.ok_or_else(|| {
                ctx.err(
                    format!("{key}.at"),
                    "missing: `point` probes need `at = [x, y, z]` in m",
                )
            })?;
            if at.iter().any(|v| !v.is_finite()) {
                return Err(ctx.err(format!("{key}.at"), "coordinates must be finite (m)"));
            }
            // an axisymmetric model's point is [r, 0, z] (cylindrical coordinates)
            let at = super::loads::model_vector(ctx, &format!("{key}.at"), &model.mesh, at)?;
            let node = model.mesh.nearest_node(at);
            let (lo, hi) = model.mesh.extents();
            let diagonal = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt();
            let outside = (0..3)
                .map(|c| (lo[c] - at[c]).max(at[c] - hi[c]).max(0.0).powi(2))
                .sum::<f64>()
                .sqrt();
            if outside > 0.01 * diagonal {
                let x = model.mesh.nodes[node];
                let distance = (0..3).map(|c| (x[c] - at[c]).powi(2)).sum::<f64>().sqrt();
                return Err(ctx.err(
                    format!("{key}.at"),
                    format!(
                        "[{}, {}, {}] m lies {outside:.3e} m outside the mesh, which spans \
                         x {:.4e}…{:.4e}, y {:.4e}…{:.4e}, z {:.4e}…{:.4e} m (the nearest node \
                         is {distance:.3e} m away); coordinates are in m, not mm",
                        at[0], at[1], at[2], lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
                    ),
                ));
            }
            ProbeKind::Point(q, node)
        }
        "charge" => ProbeKind::Charge(electrode(&need(&p.electrode, "electrode")?)?),
        "capacitance" => ProbeKind::Capacitance(electrode(&need(&p.electrode, "electrode")?)?),
        "current" => ProbeKind::Current(electrode(&need(&p.electrode, "electrode")?)?),
        "power" => ProbeKind::Power(electrode(&need(&p.electrode, "electrode")?)?),
        "source_energy" | "resistor_loss" => {
            let e = electrode(&need(&p.electrode, "electrode")?)?;
            if electrodes[e].resistance.is_none() {
                return Err(ctx.err(
                    format!("{key}.electrode"),
                    format!(
                        "`{}` is not driven through a circuit: `{}` needs an electrode with \
                         `circuit = {{ source = …, resistance = … }}`",
                        electrodes[e].name, p.kind
                    ),
                ));
            }
            if p.kind == "source_energy" {
                ProbeKind::SourceEnergy(e)
            } else {
                ProbeKind::ResistorLoss(e)
            }
        }
        "reaction" => {
            let c = reaction_component(ctx, key, &need(&p.quantity, "quantity")?, axisymmetric)?;
            ProbeKind::Reaction(c, set(&need(&p.set, "set")?)?)
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
        "center_deflection" => ProbeKind::Deflection(
            set(p.set.as_deref().unwrap_or("pad"))?,
            if axisymmetric { 1 } else { 2 },
        ),
        "max_electric_field" => ProbeKind::MaxElectricField,
        "pressure" => {
            let name = need(&p.set, "set")?;
            let pressures = s.loads.as_ref().map_or(&[][..], |l| l.pressure.as_slice());
            match pressures.iter().position(|q| q.set == name) {
                Some(i) => ProbeKind::Pressure(i),
                None => {
                    return Err(ctx.err(
                        format!("{key}.set"),
                        format!("no `[[loads.pressure]]` acts on `{name}`"),
                    ))
                }
            }
        }
        "volume" => {
            let name = need(&p.set, "set")?;
            let key = format!("{key}.set");
            // the same face-set check as the area strain's
            surface(ctx, &key, &model.mesh, &name)?;
            let faces = model.mesh.face_sets[&name].clone();
            ProbeKind::Volume(crate::problem::pressure::surface(&model.mesh, &faces))
        }
        "area_strain" => {
            let (set_key, name) = match (&p.electrode, &p.set) {
                (Some(e), None) => {
                    electrode(e)?;
                    (format!("{key}.electrode"), s.electrodes[e].set.clone())
                }
                (None, Some(set)) => (format!("{key}.set"), set.clone()),
                _ => {
                    return Err(ctx.err(
                        key.to_string(),
                        "`area_strain` probes need either `electrode` or `set` (a face set)",
                    ))
                }
            };
            ProbeKind::AreaStrain(surface(ctx, &set_key, &model.mesh, &name)?)
        }
        o => {
            let hint = closest(o, KINDS)
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                format!("{key}.kind"),
                format!(
                    "unknown probe kind `{o}` (known: {}){hint}",
                    KINDS.join(", ")
                ),
            ));
        }
    })
}

/// The faces of the face set `name` with their nodes and positions.
fn surface(
    ctx: &Ctx,
    key: &str,
    mesh: &crate::mesh::Mesh,
    name: &str,
) -> Result<Vec<ProbeFace>, InputError> {
    let faces = match mesh.face_sets.get(name) {
        Some(f) if !f.is_empty() => f,
        _ => {
            let mut names: Vec<&str> = mesh.face_sets.keys().map(String::as_str).collect();
            names.sort_unstable();
            return Err(ctx.err(
                key.to_string(),
                format!(
                    "`{name}` is not a face set of the mesh (face sets: {}); this probe needs \
                     the faces of a surface",
                    names.join(", ")
                ),
            ));
        }
    };
    let ring = mesh.kind.meridian().is_some();
    Ok(faces
        .iter()
        .map(|f| {
            let cell = mesh.cell(f.cell);
            let nodes: Vec<usize> = mesh.kind.faces()[f.face].iter().map(|&l| cell[l]).collect();
            let positions = nodes.iter().map(|&n| mesh.nodes[n]).collect();
            ProbeFace {
                cell: f.cell,
                nodes,
                positions,
                ring,
            }
        })
        .collect())
}

/// The value of `what` (`quantity`, `set`, `electrode`), which probes of this kind need.
fn need(
    ctx: &Ctx,
    key: &str,
    p: &ProbeSpec,
    v: &Option<String>,
    what: &str,
) -> Result<String, InputError> {
    v.clone().ok_or_else(|| {
        ctx.err(
            format!("{key}.{what}"),
            format!("missing: `{}` probes need `{what}`", p.kind),
        )
    })
}

/// A nodal quantity of [`NODAL`]; an axisymmetric model has `ur` and `uz` (slots 0 and 1)
/// instead of `ux`, `uy`, `uz`.
fn nodal(ctx: &Ctx, key: &str, q: &str, axisymmetric: bool) -> Result<NodalQuantity, InputError> {
    if axisymmetric {
        return match q {
            "ur" => Ok(NodalQuantity::Component(0)),
            "uz" => Ok(NodalQuantity::Component(1)),
            "u" => Ok(NodalQuantity::Magnitude),
            "phi" => Ok(NodalQuantity::Potential),
            o => Err(ctx.err(
                format!("{key}.quantity"),
                format!(
                    "unknown nodal quantity `{o}` of an axisymmetric model (known: ur, uz, u, \
                     phi)"
                ),
            )),
        };
    }
    Ok(match q {
        "ux" => NodalQuantity::Component(0),
        "uy" => NodalQuantity::Component(1),
        "uz" => NodalQuantity::Component(2),
        "u" => NodalQuantity::Magnitude,
        "phi" => NodalQuantity::Potential,
        o => {
            let hint = closest(o, NODAL)
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                format!("{key}.quantity"),
                format!(
                    "unknown nodal quantity `{o}` (known: {}){hint}",
                    NODAL.join(", ")
                ),
            ));
        }
    })
}

/// The component (0, 1, 2) of a reaction probe: `x`, `y` or `z`; `r` or `z` (slots 0, 1) in
/// an axisymmetric model.
fn reaction_component(
    ctx: &Ctx,
    key: &str,
    q: &str,
    axisymmetric: bool,
) -> Result<usize, InputError> {
    if axisymmetric {
        return match q {
            "r" => Ok(0),
            "z" => Ok(1),
            o => Err(ctx.err(
                format!("{key}.quantity"),
                format!(
                    "reaction component of an axisymmetric model must be \"r\" or \"z\"; got `{o}`"
                ),
            )),
        };
    }
    match q {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        o => Err(ctx.err(
            format!("{key}.quantity"),
            format!("reaction component must be \"x\", \"y\" or \"z\"; got `{o}`"),
        )),
    }
}

/// The index of the electrode `name`.
fn electrode_index(
    ctx: &Ctx,
    key: &str,
    electrodes: &[Electrode],
    name: &str,
) -> Result<usize, InputError> {
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
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_rejected, plan};
    use super::*;

    fn probes(text: &str) -> Vec<(String, Probe)> {
        plan(&[("probes", text)]).probes
    }

    /// `mean` over a face set is the surface mean ∫q dA / A of the interpolated quantity: on tet10
    /// (quadratic faces) a quadratic field uz = x² averages to L²/3 exactly, where the arithmetic
    /// mean of the nodal values does not.
    #[test]
    fn mean_over_a_face_set_is_the_area_weighted_mean() {
        let plan = plan(&[
            (
                "mesh",
                "[mesh]\ngenerator = \"box\"\nsize = [0.01, 0.01, 0.001]\ndivisions = [3, 2, 1]\n\
                 element = \"tet10\"",
            ),
            (
                "probes",
                "[probes.a]\nkind = \"mean\"\nquantity = \"uz\"\nset = \"z1\"",
            ),
        ]);
        let mesh = &plan.model.mesh;
        let mut state = vec![0.0; mesh.n_nodes() * 4];
        for (n, x) in mesh.nodes.iter().enumerate() {
            state[n * 4 + 2] = x[0] * x[0];
        }
        let probe = &plan.probes[0].1;
        let ProbeKind::Mean(_, nodes, _) = &probe.kind else {
            panic!("{:?}", probe.kind)
        };
        let arithmetic = nodes.iter().map(|&n| state[n * 4 + 2]).sum::<f64>() / nodes.len() as f64;
        let input = crate::job::probes::ProbeInput {
            state: &state,
            reactions: &state,
            electrodes: &[],
            stored: 0.0,
            electric: 0.0,
            reference: &state,
            max_field: 0.0,
            symmetry: 1.0,
            previous: (&[], 0.0),
            circuit_energy: &[],
            pressures: &[],
            charges: &[],
        };
        let mean = probe.evaluate(&input);
        let exact = 0.01f64 * 0.01 / 3.0;
        assert!((mean - exact).abs() < 1e-12 * exact, "{mean} vs {exact}");
        assert!((arithmetic - exact).abs() > 1e-3 * exact, "{arithmetic}");
    }

    #[test]
    fn nodal_probes_over_sets_and_at_points() {
        let p = probes(
            "[probes.a]\nkind = \"mean\"\nquantity = \"uz\"\nset = \"z1\"\nscale = 1000.0\n\
             [probes.b]\nkind = \"point\"\nquantity = \"phi\"\nat = [0.0, 0.0, 0.001]\n\
             [probes.c]\nkind = \"min\"\nquantity = \"u\"\nset = \"x0\"\noffset = 1.0",
        );
        assert_eq!(p.len(), 3);
        let ProbeKind::Mean(q, nodes, weights) = &p[0].1.kind else {
            panic!("{:?}", p[0].1.kind)
        };
        assert_eq!((*q, nodes.len()), (NodalQuantity::Component(2), 9));
        // the top face's area shares: corners ¼, edges ½, the centre 1 of a cell's area
        let area: f64 = weights.iter().sum();
        assert!((area - 1e-4).abs() < 1e-18, "{area}");
        assert_eq!((p[0].1.scale, p[0].1.offset), (1000.0, 0.0));
        let ProbeKind::Point(NodalQuantity::Potential, node) = p[1].1.kind else {
            panic!("{:?}", p[1].1.kind)
        };
        let mesh = plan(&[]).model.mesh;
        assert_eq!(mesh.nodes[node], [0.0, 0.0, 0.001]);
        assert!(matches!(
            p[2].1.kind,
            ProbeKind::Min(NodalQuantity::Magnitude, _)
        ));
        assert_eq!((p[2].1.scale, p[2].1.offset), (1.0, 1.0));
    }

    #[test]
    fn electrode_probes_refer_to_the_electrode_index() {
        // electrodes in name order: bottom (0), top (1)
        let p = probes(
            "[probes.q]\nkind = \"charge\"\nelectrode = \"top\"\n\
             [probes.c]\nkind = \"capacitance\"\nelectrode = \"bottom\"",
        );
        let kinds: Vec<(&str, &ProbeKind)> = p.iter().map(|(n, p)| (n.as_str(), &p.kind)).collect();
        assert_eq!(
            kinds,
            [
                ("c", &ProbeKind::Capacitance(0)),
                ("q", &ProbeKind::Charge(1))
            ]
        );
    }

    #[test]
    fn global_probes() {
        let p = probes(
            "[probes.e]\nkind = \"energy\"\nquantity = \"electric\"\n\
             [probes.f]\nkind = \"max_electric_field\"\n\
             [probes.r]\nkind = \"reaction\"\nquantity = \"y\"\nset = \"z0\"\n\
             [probes.s]\nkind = \"center_deflection\"\nset = \"z1\"",
        );
        assert_eq!(p[0].1.kind, ProbeKind::ElectricEnergy);
        assert_eq!(p[1].1.kind, ProbeKind::MaxElectricField);
        assert!(matches!(&p[2].1.kind, ProbeKind::Reaction(1, n) if n.len() == 9));
        assert!(matches!(&p[3].1.kind, ProbeKind::Deflection(n, 2) if n.len() == 9));
    }

    #[test]
    fn unknown_kinds_and_quantities_are_rejected() {
        assert_rejected(
            &[("probes", "[probes.a]\nkind = \"maximum\"")],
            "probes.a.kind",
            "unknown probe kind `maximum` (known: mean, max, min,",
        );
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"max\"\nquantity = \"uw\"\nset = \"z1\"",
            )],
            "probes.a.quantity",
            "unknown nodal quantity `uw` (known: ux, uy, uz, u, phi); did you mean",
        );
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"reaction\"\nquantity = \"w\"\nset = \"z0\"",
            )],
            "probes.a.quantity",
            "reaction component must be \"x\", \"y\" or \"z\"; got `w`",
        );
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"energy\"\nquantity = \"kinetic\"",
            )],
            "probes.a.quantity",
            "energy must be `stored` or `electric`; got `kinetic`",
        );
    }

    #[test]
    fn missing_keys_are_rejected() {
        assert_rejected(
            &[("probes", "[probes.a]\nkind = \"mean\"\nquantity = \"ux\"")],
            "probes.a.set",
            "missing: `mean` probes need `set`",
        );
        assert_rejected(
            &[("probes", "[probes.a]\nkind = \"point\"\nquantity = \"ux\"")],
            "probes.a.at",
            "missing: `point` probes need `at = [x, y, z]` in m",
        );
        assert_rejected(
            &[("probes", "[probes.a]\nkind = \"charge\"")],
            "probes.a.electrode",
            "missing: `charge` probes need `electrode`",
        );
        // `center_deflection` defaults to the `pad` set, which a box has not
        assert_rejected(
            &[("probes", "[probes.a]\nkind = \"center_deflection\"")],
            "probes.a.set",
            "unknown set `pad`",
        );
    }

    #[test]
    fn bad_references_and_numbers_are_rejected() {
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"capacitance\"\nelectrode = \"hv\"",
            )],
            "probes.a.electrode",
            "unknown electrode `hv` (electrodes: bottom, top)",
        );
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"point\"\nquantity = \"ux\"\nat = [0.0, nan, 0.0]",
            )],
            "probes.a.at",
            "coordinates must be finite (m)",
        );
        assert_rejected(
            &[(
                "probes",
                "[probes.a]\nkind = \"max_electric_field\"\nscale = inf",
            )],
            "probes.a.scale",
            "must be a finite number (factor); got inf",
        );
    }
}
