//! Small-signal analyses about a converged state of a run: the natural modes and the frequency
//! response of the probes to a small harmonic voltage on one electrode about its DC bias. The
//! supports stay and every electrode is held at the voltage it has in the state (a DC bias
//! softens the structure); the mass is the consistent one with the rigid regions' masses.
//! Materials with Maxwell branches are linearised about their relaxed state at the same loads:
//! the modes are those of the long-term stiffness, the frequency response carries each branch's
//! complex modulus. Used by the `modes` and `frequency-response` stages and by the commands of
//! the same purpose.

use super::plan::Plan;
use super::plan::ResponseMethod;
use super::probes::{ProbeInput, ProbeKind};
use super::state::FrequencyResponse;
use super::statics::solve_static_with;
use crate::problem::dofs::{Dirichlet, Field, FIELDS, PHI};
use crate::problem::model::Model;
use crate::solve::stepping::StepControl;
use crate::time::frequency::{linearise, relaxed_model, Linearisation};
use crate::time::harmonic::{harmonic_modes, Tilt};
use crate::time::mass::{MassKind, NodalMass};
use crate::time::modal::{modes, Mode, ModeSettings};
use crate::time::reduced::{Outputs, ReducedModel};
use crate::time::rigid_tilt::{modes_with_tilts, RigidBody};

/// The model with the plan's supports and every electrode held at its voltage in `state`, the
/// electrode `drive.0` at `drive.1` V instead when given; the dead loads at full value.
pub fn held_model(plan: &Plan, state: &[f64], drive: Option<(usize, f64)>) -> Model {
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    for (i, e) in plan.electrodes.iter().enumerate() {
        let value = match drive {
            Some((d, v)) if d == i => v,
            _ => state[e.nodes[0] * FIELDS + PHI],
        };
        model.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value,
        });
    }
    model
}

/// The consistent mass of the body with the rigid regions' attached masses.
pub fn device_mass(plan: &Plan, model: &Model) -> NodalMass {
    let mut mass = NodalMass::new(model, &plan.densities, MassKind::Consistent);
    for r in &plan.rigid {
        if r.mass > 0.0 {
            mass.add_point_mass(r.nodes[0], r.mass);
        }
    }
    mass
}

/// Why a plan cannot be linearised (no mass, internal variables without a relaxed limit), if it
/// cannot.
pub fn check_linearisable(plan: &Plan) -> Result<(), String> {
    if plan.densities.iter().all(|&d| d <= 0.0) && plan.rigid.iter().all(|r| r.mass <= 0.0) {
        return Err("the scenario has no mass: give `materials.<m>.density` (kg/m³)".into());
    }
    if plan
        .model
        .materials
        .iter()
        .any(|m| m.state_size() > 0 && m.relaxed().is_none())
    {
        return Err(
            "a material with internal variables has no relaxed limit to linearise about".into(),
        );
    }
    Ok(())
}

/// Whether a material of the plan has Maxwell branches.
pub fn has_branches(plan: &Plan) -> bool {
    plan.model
        .materials
        .iter()
        .any(|m| !m.maxwell_branches().is_empty())
}

/// The base of a linearisation: the held model and its equilibrium. With Maxwell branches, the
/// relaxed equilibrium at the same loads and voltages (the long-time state), solved from `state`
/// with the relaxed materials; else `state` itself.
pub fn base_state(plan: &Plan, state: &[f64]) -> Result<(Model, Vec<f64>), String> {
    let model = held_model(plan, state, None);
    if !has_branches(plan) {
        return Ok((model, state.to_vec()));
    }
    let relaxed = relaxed_model(&model);
    let out = solve_static_with(
        &relaxed,
        &plan.solver,
        Some(state.to_vec()),
        crate::problem::drive::Drive::held(&relaxed),
        &StepControl {
            steps: 1,
            ..plan.step_control.clone()
        },
        &plan.newton,
        |_, _| {},
    );
    out.result
        .map_err(|f| format!("the relaxed state was not reached: {}", f.reason))?;
    Ok((model, out.state))
}

/// The natural modes about `state` (`FIELDS` values per node); with Maxwell branches, of the
/// relaxed (long-term) stiffness about the relaxed state.
pub fn modes_at(plan: &Plan, state: &[f64], settings: &ModeSettings) -> Result<Vec<Mode>, String> {
    check_linearisable(plan)?;
    let (model, base) = base_state(plan, state)?;
    let relaxed = relaxed_model(&model);
    // the rigid regions given a rotary inertia tilt (harmonic 1) or rotate (a 3-D model)
    let bodies: Vec<RigidBody> = plan
        .rigid
        .iter()
        .filter_map(|r| {
            r.rotary_inertia.map(|inertia| RigidBody {
                node: r.nodes[0],
                mass: r.mass,
                inertia,
            })
        })
        .collect();
    if !bodies.is_empty() && !relaxed.is_axisymmetric() && settings.harmonic == 0 {
        // the rotating regions carry their masses themselves, at their centres
        let mut mass = NodalMass::new(&relaxed, &plan.densities, MassKind::Consistent);
        for r in plan.rigid.iter().filter(|r| r.rotary_inertia.is_none()) {
            if r.mass > 0.0 {
                mass.add_point_mass(r.nodes[0], r.mass);
            }
        }
        return modes_with_tilts(&relaxed, &base, &mass, settings, &bodies);
    }
    let mass = device_mass(plan, &relaxed);
    if settings.harmonic > 0 {
        let tilts: Vec<Tilt> = bodies
            .iter()
            .map(|b| Tilt {
                node: b.node,
                inertia: b.inertia,
            })
            .collect();
        return harmonic_modes(&relaxed, &base, &mass, settings, settings.harmonic, &tilts);
    }
    modes(&relaxed, &base, &mass, &plan.solver, settings)
}

/// [`modes_at`] of each circumferential harmonic of `harmonics` (axisymmetric models; `[0]` for
/// the model's own modes), in that order, each harmonic's lowest (or nearest the shift) first.
pub fn modes_of_harmonics(
    plan: &Plan,
    state: &[f64],
    settings: &ModeSettings,
    harmonics: &[u32],
) -> Result<Vec<Mode>, String> {
    let mut out = Vec::new();
    for &n in harmonics {
        out.extend(modes_at(
            plan,
            state,
            &ModeSettings {
                harmonic: n,
                ..*settings
            },
        )?);
    }
    Ok(out)
}

/// The probes that have a linearisation (not the energies and the largest field), plan indices.
pub fn linear_probes(plan: &Plan) -> Vec<usize> {
    (0..plan.probes.len())
        .filter(|&i| {
            !matches!(
                plan.probes[i].1.kind,
                ProbeKind::MaxElectricField
                    | ProbeKind::StoredEnergy
                    | ProbeKind::ElectricEnergy
                    | ProbeKind::Current(_)
                    | ProbeKind::Power(_)
            )
        })
        .collect()
}

/// The linearisable probes of a plan about a state of `model`.
pub struct ProbeMap<'a> {
    pub plan: &'a Plan,
    pub model: &'a Model,
    pub state: &'a [f64],
    /// The state deflections are measured from.
    pub reference: &'a [f64],
    /// Plan indices of the probes.
    pub probes: Vec<usize>,
}

impl ProbeMap<'_> {
    /// The probes' values (offsets removed) at a state.
    pub fn values(&self, s: &[f64]) -> Result<Vec<f64>, String> {
        let plan = self.plan;
        let reactions = crate::problem::statics::nodal_reactions(self.model, s)?;
        let electrodes: Vec<(&[usize], f64)> = plan
            .electrodes
            .iter()
            .map(|e| (e.nodes.as_slice(), s[e.nodes[0] * FIELDS + PHI]))
            .collect();
        let charges = crate::job::probes::electrode_charges(&electrodes, &reactions, &[]);
        let input = ProbeInput {
            charges: &charges,
            state: s,
            reactions: &reactions,
            electrodes: &electrodes,
            stored: 0.0,
            electric: 0.0,
            reference: self.reference,
            max_field: f64::NAN,
            symmetry: plan.symmetry_factor,
            previous: (&[], 0.0),
            circuit_energy: &[],
            pressures: &[],
        };
        Ok(self
            .probes
            .iter()
            .map(|&i| plan.probes[i].1.evaluate(&input) - plan.probes[i].1.offset)
            .collect())
    }

    /// The probes' first-order change along the perturbation `dq` (`FIELDS` values per node), by
    /// a central difference of step h·dq, h = min(1, 10 nm / largest displacement of dq): small
    /// against any device, large against round-off (the probes are smooth in the state).
    pub fn gradient(&self, dq: &[f64]) -> Result<Vec<f64>, String> {
        let largest = dq
            .iter()
            .enumerate()
            .filter(|(d, _)| d % FIELDS != PHI)
            .map(|(_, v)| v.abs())
            .fold(0.0, f64::max);
        let h = if largest > 0.0 {
            (1e-8 / largest).min(1.0)
        } else {
            1.0
        };
        let plus: Vec<f64> = self.state.iter().zip(dq).map(|(s, d)| s + h * d).collect();
        let minus: Vec<f64> = self.state.iter().zip(dq).map(|(s, d)| s - h * d).collect();
        let (p, m) = (self.values(&plus)?, self.values(&minus)?);
        Ok(p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect())
    }

    /// Names of the probes.
    pub fn names(&self) -> Vec<String> {
        self.probes
            .iter()
            .map(|&i| self.plan.probes[i].0.clone())
            .collect()
    }
}

/// The frequency response about `state` (an equilibrium with every electrode at its voltage in
/// it) to a small voltage on electrode `driven`; `reference` is the state deflection probes are
/// measured from.
pub fn frequency_response_at(
    plan: &Plan,
    state: &[f64],
    reference: &[f64],
    driven: usize,
    frequencies: &[f64],
    method: ResponseMethod,
) -> Result<FrequencyResponse, String> {
    check_linearisable(plan)?;
    if has_branches(plan) && matches!(method, ResponseMethod::Modal { .. }) {
        return Err(
            "the modal method has no complex modulus for Maxwell branches; use `direct`".into(),
        );
    }
    let (model, base) = base_state(plan, state)?;
    let state = base.as_slice();
    let relaxed = relaxed_model(&model);
    let mass = device_mass(plan, &model);
    let electrode = &plan.electrodes[driven];
    let bias = state[electrode.nodes[0] * FIELDS + PHI];
    // in a distributed run each process's part, solved by the distributed solver (the direct
    // method in real form)
    let solver = plan.solver.distributed_direct();
    let mut lin = linearise(
        &model,
        state,
        &mass,
        &plan.viscosities,
        &electrode.nodes,
        solver,
    )?;
    let map = ProbeMap {
        plan,
        model: &relaxed,
        state,
        reference,
        probes: linear_probes(plan),
    };
    let values = response_values(&mut lin, &map, frequencies, method, &electrode.name, bias)?;
    let warning = (!lin.drives_motion()).then(|| zero_bias_warning(&electrode.name, bias));
    Ok(FrequencyResponse {
        electrode: electrode.name.clone(),
        bias,
        frequencies: frequencies.to_vec(),
        probes: map.names().into_iter().zip(values).collect(),
        method,
        solved_by: match method {
            ResponseMethod::Direct => lin.solved_by(),
            ResponseMethod::Modal { count } => format!(
                "the reduced model of {count} modes and the static correction{}",
                if lin.is_part() {
                    ", projected from each process's own cells' part"
                } else {
                    ""
                }
            ),
        },
        warning,
    })
}

/// The warning of a drive about zero bias.
/// Which modes a model cannot represent because of its symmetry, in a sentence for the user
/// (`None` for a full 3-D model). An axisymmetric model finds only the modes of circumferential
/// harmonic 0; a model of a part of a device (a quarter or half disc, an octant or half sphere,
/// held on its planes of symmetry) finds only the modes symmetric about those planes.
pub fn mode_symmetry_note(plan: &Plan) -> Option<String> {
    let f = plan.symmetry_factor;
    if plan.model.is_axisymmetric() {
        let mut note =
            "an axisymmetric model finds the modes of one circumferential harmonic at a time \
                        (`harmonic`, default 0: the axisymmetric modes); lateral motion of a pad \
                        (n = 1) and modes with n nodal diameters need `harmonic = n`"
                .to_string();
        if f > 1.0 {
            note.push_str("; nor modes antisymmetric about its plane of symmetry");
        }
        return Some(note);
    }
    let planes = match f {
        f if f > 6.0 => "its three planes of symmetry",
        f if f > 3.0 => "its two planes of symmetry (x = 0, y = 0)",
        f if f > 1.0 => "its plane of symmetry",
        _ => return None,
    };
    Some(format!(
        "the model is 1/{f} of the device and represents only the modes symmetric about \
         {planes}: modes antisymmetric about one of them (rocking of a pad, most modes with \
         nodal diameters) are not found"
    ))
}

pub fn zero_bias_warning(electrode: &str, bias: f64) -> String {
    format!(
        "`{electrode}` is at {bias} V: the electrostatic force is ∝ 2 V_dc ṽ, so at zero bias a \
         small voltage moves nothing to first order (only the charge follows); give a DC bias"
    )
}

/// The probes' complex responses per volt, probe by probe, by `method`.
pub fn response_values(
    lin: &mut Linearisation,
    map: &ProbeMap,
    frequencies: &[f64],
    method: ResponseMethod,
    electrode: &str,
    bias: f64,
) -> Result<Vec<Vec<(f64, f64)>>, String> {
    let mut out = vec![Vec::with_capacity(frequencies.len()); map.probes.len()];
    match method {
        ResponseMethod::Direct => {
            let omegas: Vec<f64> = frequencies
                .iter()
                .map(|f| 2.0 * std::f64::consts::PI * f)
                .collect();
            let gradients =
                lin.responses(&omegas, |xr, xi| Ok((map.gradient(xr)?, map.gradient(xi)?)))?;
            for (gr, gi) in gradients {
                for (j, o) in out.iter_mut().enumerate() {
                    o.push((gr[j], gi[j]));
                }
            }
        }
        ResponseMethod::Modal { count } => {
            let gradient = |dq: &[f64]| map.gradient(dq);
            let outputs = Outputs {
                names: map.names(),
                offsets: vec![0.0; map.probes.len()],
                gradient: &gradient,
            };
            let rom = ReducedModel::build(lin, count, &map.plan.solver, &outputs, electrode, bias)?;
            for &f in frequencies {
                let y = rom.response(2.0 * std::f64::consts::PI * f);
                for (o, v) in out.iter_mut().zip(y) {
                    o.push(v);
                }
            }
        }
    }
    Ok(out)
}
