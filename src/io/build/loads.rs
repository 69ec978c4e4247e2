//! `[[constraints]]`, `[[tractions]]`, `[loads]` (gravity, rigid regions) and `[prestretch]`: the
//! supports of the plan and the loads written into the model.

use super::{Ctx, Prestretch, Rigid};
use crate::io::scenario::{InputError, RigidSpec, Scenario};
use crate::mesh::Mesh;
use crate::problem::dofs::{Dirichlet, Field, Tie};
use crate::problem::model::Model;

/// The supports, rigid regions and pre-stretch of a scenario.
pub(super) struct Loads {
    /// The constraints, then the pre-stretch of the rim.
    pub supports: Vec<Dirichlet>,
    pub rigid: Vec<Rigid>,
    pub prestretch: Option<Prestretch>,
}

/// Tractions, gravity and rigid regions go into `model`; the supports, rigid regions and
/// pre-stretch are returned. `symmetry_factor` divides the attached masses and dampers.
pub(super) fn build_loads(
    ctx: &Ctx,
    s: &Scenario,
    model: &mut Model,
    symmetry_factor: f64,
) -> Result<Loads, InputError> {
    build_tractions(ctx, s, model)?;
    build_pressures(ctx, s, model)?;
    // an axisymmetric model holds its hoop slot and the axis's radial displacement
    let mut supports = model.axisymmetric_supports();
    supports.extend(build_constraints(ctx, s, &model.mesh)?);
    supports.extend(prestretch_supports(ctx, s, model)?);
    let rigid = match &s.loads {
        None => Vec::new(),
        Some(loads) => {
            let g = build_gravity(ctx, s, loads.gravity, model)?;
            build_rigid(ctx, s, model, &supports, g, symmetry_factor)?
        }
    };
    let prestretch = build_prestretch(ctx, s)?;
    Ok(Loads {
        supports,
        rigid,
        prestretch,
    })
}

/// A vector of the scenario in the model's slots: (x, y, z) in 3-D; in an axisymmetric model
/// the cylindrical components (r, θ, z) go to the slots (r, z, ·), and θ must be 0 (the model
/// carries no torsion).
pub(super) fn model_vector(
    ctx: &Ctx,
    key: &str,
    mesh: &Mesh,
    v: [f64; 3],
) -> Result<[f64; 3], InputError> {
    if mesh.kind.meridian().is_none() {
        return Ok(v);
    }
    if v[1] != 0.0 {
        return Err(ctx.err(
            key,
            format!(
                "an axisymmetric model reads vectors as cylindrical components [r, θ, z] and \
                 carries no hoop (θ) component; got {v:?}"
            ),
        ));
    }
    Ok([v[0], v[2], 0.0])
}

/// The displacement slot of a component name: `x`, `y`, `z` in 3-D; `r`, `z` in an
/// axisymmetric model (slots 0 and 1).
pub(super) fn component_field(
    ctx: &Ctx,
    key: &str,
    mesh: &Mesh,
    name: &str,
) -> Result<Field, InputError> {
    let axisymmetric = mesh.kind.meridian().is_some();
    match (axisymmetric, name) {
        (false, "x") => Ok(Field::Ux),
        (false, "y") => Ok(Field::Uy),
        (false, "z") => Ok(Field::Uz),
        (true, "r") => Ok(Field::Ux),
        (true, "z") => Ok(Field::Uy),
        (true, o) => Err(ctx.err(
            key,
            format!(
                "unknown component `{o}`: an axisymmetric model has \"r\" (radial) and \"z\" \
                 (axial)"
            ),
        )),
        (false, o) => Err(ctx.err(
            key,
            format!("unknown component `{o}`: expected \"x\", \"y\" or \"z\""),
        )),
    }
}

/// `[[tractions]]`: dead nominal tractions (Pa) on face sets.
fn build_tractions(ctx: &Ctx, s: &Scenario, model: &mut Model) -> Result<(), InputError> {
    for (i, t) in s.tractions.iter().enumerate() {
        for (c, v) in t.value.iter().enumerate() {
            ctx.finite(&format!("tractions.{i}.value.{c}"), *v, "traction in Pa")?;
        }
        let value = model_vector(ctx, &format!("tractions.{i}.value"), &model.mesh, t.value)?;
        model
            .add_traction(&t.set, value)
            .map_err(|e| ctx.err(format!("tractions.{i}.set"), e.to_string()))?;
    }
    Ok(())
}

/// `[[loads.pressure]]`: follower pressures (Pa) on face sets.
fn build_pressures(ctx: &Ctx, s: &Scenario, model: &mut Model) -> Result<(), InputError> {
    let pressures = s.loads.as_ref().map_or(&[][..], |l| l.pressure.as_slice());
    for (i, p) in pressures.iter().enumerate() {
        // under volume control the unknown is the pressure in Pa: a fraction of 1 Pa
        let value =
            match (p.value, p.volume) {
                (Some(v), None) => {
                    ctx.finite(&format!("loads.pressure.{i}.value"), v, "pressure in Pa")?
                }
                (None, Some(_)) => 1.0,
                (Some(_), Some(_)) => return Err(ctx.err(
                    format!("loads.pressure.{i}.volume"),
                    "give either `value` (the pressure, Pa) or `volume` (the enclosed volume, m³, \
                     with the pressure an unknown), not both",
                )),
                (None, None) => {
                    return Err(ctx.err(
                        format!("loads.pressure.{i}"),
                        "missing: expected `value` (the pressure, Pa) or `volume` (the enclosed \
                     volume, m³, with the pressure an unknown)",
                    ))
                }
            };
        let faces = match model.mesh.face_sets.get(&p.set) {
            Some(f) if !f.is_empty() => f.clone(),
            _ => {
                let mut names: Vec<&str> =
                    model.mesh.face_sets.keys().map(String::as_str).collect();
                names.sort_unstable();
                return Err(ctx.err(
                    format!("loads.pressure.{i}.set"),
                    format!(
                        "`{}` is not a face set of the mesh (face sets: {})",
                        p.set,
                        names.join(", ")
                    ),
                ));
            }
        };
        let faces = crate::problem::pressure::surface(&model.mesh, &faces);
        model
            .pressures
            .push(crate::problem::pressure::Pressure::new(faces, value));
    }
    Ok(())
}

/// `[[constraints]]`: one displacement condition per fixed component.
fn build_constraints(ctx: &Ctx, s: &Scenario, mesh: &Mesh) -> Result<Vec<Dirichlet>, InputError> {
    let mut supports = Vec::new();
    for (i, c) in s.constraints.iter().enumerate() {
        let key = format!("constraints.{i}");
        let nodes = ctx.set_nodes(mesh, &format!("{key}.set"), &c.set)?;
        ctx.finite(&format!("{key}.value"), c.value, "displacement in m")?;
        if c.fix.is_empty() {
            return Err(ctx.err(
                format!("{key}.fix"),
                "expected a list of components among \"x\", \"y\", \"z\"",
            ));
        }
        for comp in &c.fix {
            let field = component_field(ctx, &format!("{key}.fix"), mesh, comp)?;
            supports.push(Dirichlet {
                nodes: nodes.clone(),
                field,
                value: c.value,
            });
        }
    }
    Ok(supports)
}

/// `[prestretch]` `stretch`, `set` and `clamp`: the in-plane displacements (λ − 1) x, (λ − 1) y
/// of every node of the set; with `clamp = "face"` also the axial displacement (λₜ − 1) z, λₜ the
/// thickness stretch of the first material's homogeneous equibiaxial state.
fn prestretch_supports(
    ctx: &Ctx,
    s: &Scenario,
    model: &Model,
) -> Result<Vec<Dirichlet>, InputError> {
    let Some(p) = &s.prestretch else {
        return Ok(Vec::new());
    };
    let mesh = &model.mesh;
    let face = match p.clamp.as_deref() {
        None | Some("in-plane") => false,
        Some("face") => true,
        Some(other) => {
            return Err(ctx.err(
                "prestretch.clamp",
                format!("expected \"in-plane\" or \"face\"; got \"{other}\""),
            ))
        }
    };
    let l = ctx.positive("prestretch.stretch", Some(p.stretch), "in-plane stretch")?;
    if !(0.1..=20.0).contains(&l) {
        return Err(ctx.err(
            "prestretch.stretch",
            format!(
                "expected a stretch between 0.1 and 20; got {}",
                crate::units::Short(l)
            ),
        ));
    }
    let mut supports = Vec::new();
    // in-plane: x and y in 3-D; the radius in an axisymmetric model (whose axis is the y slot)
    let meridian = mesh.kind.meridian().is_some();
    let components = if meridian { 1 } else { 2 };
    let (axial_field, axial) = if meridian {
        (Field::Uy, 1)
    } else {
        (Field::Uz, 2)
    };
    let thickness = match model.materials.first() {
        Some(m) if face => crate::material::homogeneous::equibiaxial_thickness(m.as_ref(), l),
        _ => 1.0,
    };
    for n in ctx.set_nodes(mesh, "prestretch.set", &p.set)? {
        let x = mesh.nodes[n];
        for (field, value) in [(Field::Ux, (l - 1.0) * x[0]), (Field::Uy, (l - 1.0) * x[1])]
            .into_iter()
            .take(components)
        {
            supports.push(Dirichlet {
                nodes: vec![n],
                field,
                value,
            });
        }
        if face {
            supports.push(Dirichlet {
                nodes: vec![n],
                field: axial_field,
                value: (thickness - 1.0) * x[axial],
            });
        }
    }
    Ok(supports)
}

/// `[prestretch]` `steps`: the pre-stretch phase of the plan.
fn build_prestretch(ctx: &Ctx, s: &Scenario) -> Result<Option<Prestretch>, InputError> {
    let Some(p) = &s.prestretch else {
        return Ok(None);
    };
    let n = p.steps.unwrap_or(4);
    if !(1..=100_000).contains(&n) {
        return Err(ctx.err(
            "prestretch.steps",
            format!("must be between 1 and 100000; got {n}"),
        ));
    }
    let time = |key: &str, v: Option<f64>| -> Result<f64, InputError> {
        match v {
            None => Ok(0.0),
            Some(x) if x.is_finite() && x >= 0.0 => Ok(x),
            Some(x) => Err(ctx.err(
                format!("prestretch.{key}"),
                format!(
                    "must be a non-negative time in s; got {}",
                    crate::units::Short(x)
                ),
            )),
        }
    };
    let duration = time("duration", p.duration)?;
    let hold = time("hold", p.hold)?;
    let hold_steps = p.hold_steps.unwrap_or(20);
    if !(1..=1_000_000).contains(&hold_steps) {
        return Err(ctx.err(
            "prestretch.hold_steps",
            format!("must be between 1 and 1000000; got {hold_steps}"),
        ));
    }
    Ok(Some(Prestretch {
        stretch: p.stretch,
        steps: n as usize,
        duration,
        hold,
        hold_steps: hold_steps as usize,
    }))
}

/// `loads.gravity` (m/s², zero when not given): the body forces ρg of the materials go into
/// `model`.
fn build_gravity(
    ctx: &Ctx,
    s: &Scenario,
    gravity: Option<[f64; 3]>,
    model: &mut Model,
) -> Result<[f64; 3], InputError> {
    let g = match gravity {
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
            if model.is_axisymmetric() && g[0] != 0.0 {
                return Err(ctx.err(
                    "loads.gravity",
                    format!(
                        "an axisymmetric model's gravity acts along its axis: [0, 0, g_z]; got \
                         {g:?}"
                    ),
                ));
            }
            model_vector(ctx, "loads.gravity", &model.mesh, g)?
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
    Ok(g)
}

/// `[[loads.rigid]]`: ties of the three translations, and the damper and weight (under gravity
/// `g`) of the attached mass, written into the model.
fn build_rigid(
    ctx: &Ctx,
    s: &Scenario,
    model: &mut Model,
    supports: &[Dirichlet],
    g: [f64; 3],
    symmetry_factor: f64,
) -> Result<Vec<Rigid>, InputError> {
    let mut rigid: Vec<Rigid> = Vec::new();
    for (i, r) in s.loads.iter().flat_map(|l| &l.rigid).enumerate() {
        let key = format!("loads.rigid.{i}");
        let nodes = rigid_nodes(ctx, &key, r, &model.mesh, &rigid, supports)?;
        check_damping(ctx, s, &key, r)?;
        // the translations; an axisymmetric body can only move along its axis: the tie of the
        // radial slot is held as a whole by the axis node the region must contain
        if model.is_axisymmetric() && !nodes.iter().any(|&n| model.mesh.nodes[n][0] == 0.0) {
            return Err(ctx.err(
                format!("{key}.set"),
                format!(
                    "`{}` has no node on the axis: a rigid region of an axisymmetric model is a \
                     central body (a pad) that moves along the axis",
                    r.set
                ),
            ));
        }
        let fields: &[Field] = if model.is_axisymmetric() {
            &[Field::Ux, Field::Uy]
        } else {
            &[Field::Ux, Field::Uy, Field::Uz]
        };
        for &field in fields {
            model.ties.push(Tie {
                nodes: nodes.clone(),
                field,
                held: false,
            });
        }
        if r.damping > 0.0 {
            model
                .point_dampers
                .push((nodes[0], r.damping / symmetry_factor));
        }
        let mass = r.mass / symmetry_factor;
        if mass > 0.0 && g != [0.0; 3] {
            model.point_forces.push((nodes[0], g.map(|a| mass * a)));
        }
        let rotary_inertia = match r.rotary_inertia {
            None => None,
            Some(i) if !model.is_axisymmetric() && symmetry_factor != 1.0 => {
                return Err(ctx.err(
                    format!("{key}.rotary_inertia"),
                    format!(
                        "a rigid region rotates in the modes of a whole 3-D model only: the \
                         symmetry planes of a part hold its tilt (mesh the whole device, \
                         `quarter = false`, or use an axisymmetric model's harmonic 1); got {i}"
                    ),
                ))
            }
            Some(i) if i.is_finite() && i > 0.0 => Some(i / symmetry_factor),
            Some(i) => {
                return Err(ctx.err(
                    format!("{key}.rotary_inertia"),
                    format!("expected a rotary inertia in kg·m² > 0; got {i}"),
                ))
            }
        };
        rigid.push(Rigid {
            set: r.set.clone(),
            nodes,
            mass,
            gravity: g,
            rotary_inertia,
        });
    }
    Ok(rigid)
}

/// The sorted nodes of the rigid region `r`: a set that overlaps no earlier region and carries
/// no prescribed non-zero displacement, with a mass ≥ 0.
fn rigid_nodes(
    ctx: &Ctx,
    key: &str,
    r: &RigidSpec,
    mesh: &Mesh,
    earlier: &[Rigid],
    supports: &[Dirichlet],
) -> Result<Vec<usize>, InputError> {
    let mut nodes = ctx.set_nodes(mesh, &format!("{key}.set"), &r.set)?;
    nodes.sort_unstable();
    nodes.dedup();
    if !(r.mass.is_finite() && r.mass >= 0.0) {
        return Err(ctx.err(
            format!("{key}.mass"),
            format!("expected a mass in kg ≥ 0; got {}", r.mass),
        ));
    }
    for (j, o) in earlier.iter().enumerate() {
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
    Ok(nodes)
}

/// The damping of a rigid region: ≥ 0, and when positive, no stage may use the trapezoidal rule.
fn check_damping(ctx: &Ctx, s: &Scenario, key: &str, r: &RigidSpec) -> Result<(), InputError> {
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
    }
    Ok(())
}

/// Per `[[loads.pressure]]`: the volume (m³, of the meshed part: the whole device's divided by
/// `symmetry_factor`) it holds under volume control, checked positive; at most one of them.
pub(super) fn pressure_volumes(
    ctx: &Ctx,
    s: &Scenario,
    symmetry_factor: f64,
) -> Result<Vec<Option<f64>>, InputError> {
    let pressures = s.loads.as_ref().map_or(&[][..], |l| l.pressure.as_slice());
    let mut out = Vec::new();
    for (i, p) in pressures.iter().enumerate() {
        let key = format!("loads.pressure.{i}.volume");
        let v = match p.volume {
            Some(v) => {
                Some(ctx.positive(&key, Some(v), "enclosed volume in m³")? / symmetry_factor)
            }
            None => None,
        };
        if v.is_some() && out.iter().any(Option::is_some) {
            return Err(ctx.err(
                key,
                "only one pressure can be volume-controlled (the others give a `value`)",
            ));
        }
        out.push(v);
    }
    Ok(out)
}

/// Per `[[loads.pressure]]`, per stage: whether it acts there (`stages`, default every stage).
pub(super) fn pressure_stages(
    ctx: &Ctx,
    s: &Scenario,
    stages: &[crate::job::plan::Stage],
) -> Result<Vec<Vec<bool>>, InputError> {
    let pressures = s.loads.as_ref().map_or(&[][..], |l| l.pressure.as_slice());
    let mut out = Vec::new();
    for (i, p) in pressures.iter().enumerate() {
        let Some(names) = &p.stages else {
            out.push(vec![true; stages.len()]);
            continue;
        };
        let mut on = vec![false; stages.len()];
        for name in names {
            match stages.iter().position(|st| &st.name == name) {
                Some(k) => on[k] = true,
                None => {
                    let known: Vec<&str> = stages.iter().map(|st| st.name.as_str()).collect();
                    return Err(ctx.err(
                        format!("loads.pressure.{i}.stages"),
                        format!("no stage is named `{name}` (stages: {})", known.join(", ")),
                    ));
                }
            }
        }
        out.push(on);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_rejected, plan};
    use super::*;

    const DENSE: &str = "[materials.gel]\nmodel = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\n\
                         permittivity = 4.7\ndensity = 1000.0";

    #[test]
    fn constraints_hold_one_component_each() {
        let p = plan(&[(
            "constraints",
            "[[constraints]]\nset = \"z0\"\nfix = [\"x\", \"z\"]\n\
             [[constraints]]\nset = \"x1\"\nfix = [\"x\"]\nvalue = 1e-4",
        )]);
        let fields: Vec<(Field, usize, f64)> = p
            .supports
            .iter()
            .map(|d| (d.field, d.nodes.len(), d.value))
            .collect();
        assert_eq!(
            fields,
            [
                (Field::Ux, 9, 0.0),
                (Field::Uz, 9, 0.0),
                (Field::Ux, 6, 1e-4)
            ]
        );
    }

    #[test]
    fn tractions_and_the_prestretch_are_applied() {
        let p = plan(&[
            (
                "tractions",
                "[[tractions]]\nset = \"z1\"\nvalue = [0.0, 0.0, -10.0]",
            ),
            (
                "prestretch",
                "[prestretch]\nstretch = 1.5\nset = \"x1\"\nsteps = 7",
            ),
        ]);
        assert_eq!(p.model.tractions.len(), 1);
        assert_eq!(p.model.tractions[0].faces.len(), 4);
        assert_eq!(p.model.tractions[0].value, [0.0, 0.0, -10.0]);
        assert_eq!(
            p.prestretch,
            Some(Prestretch {
                stretch: 1.5,
                steps: 7,
                duration: 0.0,
                hold: 0.0,
                hold_steps: 20,
            })
        );
        // 3 constraints, then ux and uy of the 6 nodes of x1 (x = 10 mm): ux = 0.5 x
        assert_eq!(p.supports.len(), 3 + 12);
        let ux = &p.supports[3];
        assert_eq!((ux.field, ux.nodes.len()), (Field::Ux, 1));
        assert!((ux.value - 0.005).abs() < 1e-15, "{}", ux.value);
        assert_eq!(p.supports[4].field, Field::Uy);
    }

    #[test]
    fn gravity_and_a_rigid_region_with_its_mass_and_damper() {
        let p = plan(&[
            ("materials", DENSE),
            (
                "loads",
                "[loads]\ngravity = [0.0, 0.0, -10.0]\n\
                 [[loads.rigid]]\nset = \"z1\"\nmass = 0.02\ndamping = 3.0",
            ),
        ]);
        assert_eq!(p.model.body_force, [[0.0, 0.0, -10_000.0]]);
        assert_eq!(p.rigid.len(), 1);
        assert_eq!((p.rigid[0].set.as_str(), p.rigid[0].mass), ("z1", 0.02));
        assert_eq!(p.rigid[0].nodes.len(), 9);
        assert!(p.rigid[0].nodes.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(p.model.ties.len(), 3);
        assert_eq!(p.model.point_dampers, [(p.rigid[0].nodes[0], 3.0)]);
        assert_eq!(
            p.model.point_forces,
            [(p.rigid[0].nodes[0], [0.0, 0.0, 0.02 * -10.0])]
        );
    }

    #[test]
    fn without_loads_the_model_has_no_body_force() {
        let p = plan(&[("materials", DENSE)]);
        assert!(p.model.body_force.is_empty());
        assert!(p.rigid.is_empty() && p.model.ties.is_empty());
        assert_eq!(p.prestretch, None);
    }

    #[test]
    fn bad_constraints_are_rejected() {
        assert_rejected(
            &[(
                "constraints",
                "[[constraints]]\nset = \"z3\"\nfix = [\"x\"]",
            )],
            "constraints.0.set",
            "unknown set `z3` (the mesh has: all,",
        );
        assert_rejected(
            &[(
                "constraints",
                "[[constraints]]\nset = \"z0\"\nfix = [\"x\", \"w\"]",
            )],
            "constraints.0.fix",
            "unknown component `w`: expected \"x\", \"y\" or \"z\"",
        );
        assert_rejected(
            &[("constraints", "[[constraints]]\nset = \"z0\"\nfix = []")],
            "constraints.0.fix",
            "expected a list of components",
        );
        assert_rejected(
            &[(
                "constraints",
                "[[constraints]]\nset = \"z0\"\nfix = [\"x\"]\nvalue = nan",
            )],
            "constraints.0.value",
            "must be a finite number (displacement in m); got NaN",
        );
    }

    #[test]
    fn bad_tractions_and_gravity_are_rejected() {
        assert_rejected(
            &[(
                "tractions",
                "[[tractions]]\nset = \"z1\"\nvalue = [0.0, 0.0, inf]",
            )],
            "tractions.0.value.2",
            "must be a finite number (traction in Pa); got inf",
        );
        assert_rejected(
            &[(
                "tractions",
                "[[tractions]]\nset = \"top\"\nvalue = [0.0, 0.0, 1.0]",
            )],
            "tractions.0.set",
            "unknown set 'top'",
        );
        assert_rejected(
            &[("loads", "[loads]\ngravity = [0.0, 0.0, -9.81e4]")],
            "loads.gravity",
            "expected an acceleration in m/s² (e.g. [0, 0, -9.81])",
        );
    }

    #[test]
    fn bad_rigid_regions_are_rejected() {
        assert_rejected(
            &[("loads", "[[loads.rigid]]\nset = \"z1\"\nmass = -1.0")],
            "loads.rigid.0.mass",
            "expected a mass in kg ≥ 0; got -1",
        );
        assert_rejected(
            &[(
                "loads",
                "[[loads.rigid]]\nset = \"z1\"\n[[loads.rigid]]\nset = \"x1\"",
            )],
            "loads.rigid.1.set",
            "overlaps rigid region 0 (`z1`): merge them into one set",
        );
        assert_rejected(
            &[
                (
                    "constraints",
                    "[[constraints]]\nset = \"x1\"\nfix = [\"x\"]\nvalue = 1e-4",
                ),
                ("loads", "[[loads.rigid]]\nset = \"z1\""),
            ],
            "loads.rigid.0.set",
            "`z1` contains nodes with a prescribed non-zero displacement",
        );
        assert_rejected(
            &[
                ("materials", DENSE),
                (
                    "stages",
                    "[[stages]]\nkind = \"dynamic\"\nduration = 0.1\ndt = 0.01\n\
                     integrator = \"trapezoidal\"",
                ),
                ("loads", "[[loads.rigid]]\nset = \"z1\"\ndamping = 1.0"),
            ],
            "loads.rigid.0.damping",
            "needs the `midpoint` or `newmark` integrator; stage 0 uses `trapezoidal`",
        );
    }

    #[test]
    fn a_bad_prestretch_is_rejected() {
        assert_rejected(
            &[("prestretch", "[prestretch]\nstretch = 30.0\nset = \"x1\"")],
            "prestretch.stretch",
            "expected a stretch between 0.1 and 20; got 30",
        );
        assert_rejected(
            &[("prestretch", "[prestretch]\nstretch = 1.5\nset = \"rim\"")],
            "prestretch.set",
            "unknown set `rim`",
        );
        assert_rejected(
            &[(
                "prestretch",
                "[prestretch]\nstretch = 1.5\nset = \"x1\"\nsteps = 0",
            )],
            "prestretch.steps",
            "must be between 1 and 100000; got 0",
        );
    }
}
