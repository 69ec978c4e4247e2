//! Natural modes of circumferential harmonic n ≥ 1 of an axisymmetric model: the modes of the
//! revolved 3-D body whose displacements vary as (u_r cos nΘ, u_z cos nΘ, u_θ sin nΘ) and whose
//! potential as Φ cos nΘ, about an axisymmetric equilibrium, with the electrodes held at their
//! voltages (δΦ = 0 on them). The tangent is [`crate::element::harmonic`]'s, the mass the model's
//! consistent mass on the three displacement slots; both carry the Θ-integral ½ of harmonics
//! n ≥ 1, so the modal mass of a shape is its kinetic mass in the 3-D body. The potential is
//! condensed by the same shift-invert Lanczos as [`crate::time::modal`].
//!
//! **Conditions of harmonic n** (the slot 2 of a meridian node holds u_θ here; the axisymmetric
//! model's own hold of it is dropped):
//! - a node held in both u_r and u_z by a support (a clamp) is held in u_θ too; a node held in one
//!   component keeps the others;
//! - on the axis (R = 0) the fields must be single-valued and smooth: for n = 1 a lateral
//!   translation only, u_z = Φ = 0 and u_θ = −u_r (u_r cos Θ e_r − u_r sin Θ e_θ = u_r e_x);
//!   for n ≥ 2 every unknown is 0. An axis node held along the axis is held in place;
//! - a rigid region (whose translations the model ties) keeps, for n = 1, its lateral
//!   translation t (u_r = t, u_θ = −t, u_z = 0 at each of its nodes) with its attached mass, and
//!   is held for n ≥ 2. Rigid regions carry no rotation (in 3-D too); one given a rotary inertia
//!   I ([`Tilt`]) also tilts by α about the diameter through its attachment node at height z_c:
//!   δx = α e_y × (x − z_c e_z) adds u_r = α(z − z_c), u_θ = −α(z − z_c), u_z = −α r (current r,
//!   z), with the kinetic mass I of α;
//! - a potential tied over an electrode (uniform on it) has no harmonic n ≥ 1: held.
//!
//! Harmonic 0 is the model's own axisymmetric analysis ([`crate::time::modal::modes`]).

use crate::algebra::csr::CsrMatrix;
use crate::element::harmonic::{harmonic_factor, harmonic_tangent};
use crate::element::CellHistory;
use crate::problem::dofs::{DofMap, Field, FIELDS, PHI};
use crate::problem::model::Model;
use crate::solve::linear::Inertia;
use crate::time::mass::NodalMass;
use crate::time::modal::{modes_of, Mode, ModeSettings};
use crate::time::reduction::{
    add_projected_mass, direct_solver, equation_map, paired_csr, PairedRows,
};
use std::collections::BTreeMap;

/// A rigid region that tilts in harmonic 1: its attachment node (its first) and its rotary
/// inertia (kg·m²) about a diameter through that node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    pub node: usize,
    pub inertia: f64,
}

/// The equations of harmonic `n`: each dof's combination Σ coef · unknown (empty: held), the
/// number of unknowns and the rotary inertias of the tilt unknowns.
struct HarmonicDofs {
    dof: Vec<Vec<(usize, f64)>>,
    count: usize,
    inertias: Vec<(usize, f64)>,
}

/// How a dof of the harmonic problem is set: held at 0, or `coef` times equation `eq`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Link {
    Held,
    Free,
    /// coef times the unknown of another dof (its leader, numbered first).
    To(usize, f64),
}

/// The equations of every dof of harmonic `n` ≥ 1 of `model` about `state` (module docs).
fn harmonic_dofs(model: &Model, state: &[f64], n: u32, tilts: &[Tilt]) -> HarmonicDofs {
    let mesh = &model.mesh;
    let nn = mesh.n_nodes();
    let mut held = vec![false; nn * FIELDS];
    for d in &model.dirichlet {
        // slot 2 is held by the axisymmetric model only: it is u_θ here
        if d.field == Field::Uz {
            continue;
        }
        for &a in &d.nodes {
            held[a * FIELDS + d.field.index()] = true;
        }
    }
    let on_axis = |a: usize| mesh.nodes[a][0] == 0.0;
    let mut link = vec![Link::Free; nn * FIELDS];
    // the tilting regions' nodes and attachment nodes
    let mut tilting: Vec<(Vec<usize>, Tilt)> = Vec::new();
    for a in 0..nn {
        let d = a * FIELDS;
        if on_axis(a) {
            // held[d] is the axis condition of harmonic 0, not a support
            let fixed = held[d + 1];
            link[d + 1] = Link::Held;
            link[d + PHI] = Link::Held;
            if n == 1 && !fixed {
                link[d + 2] = Link::To(d, -1.0);
            } else {
                link[d] = Link::Held;
                link[d + 2] = Link::Held;
            }
        } else {
            for s in [0, 1, PHI] {
                if held[d + s] {
                    link[d + s] = Link::Held;
                }
            }
            if held[d] && held[d + 1] {
                link[d + 2] = Link::Held;
            }
        }
    }
    for t in &model.ties {
        match t.field {
            Field::Phi => t
                .nodes
                .iter()
                .for_each(|&a| link[a * FIELDS + PHI] = Link::Held),
            // a rigid region: ties of (u_r, u_z); the u_r tie stands for the region
            Field::Ux => {
                let Some(&first) = t.nodes.iter().min() else {
                    continue;
                };
                let lead = first * FIELDS;
                let free =
                    n == 1 && !t.held && t.nodes.iter().all(|&a| on_axis(a) || !held[a * FIELDS]);
                if free {
                    if let Some(tilt) = tilts.iter().find(|x| x.node == first) {
                        tilting.push((t.nodes.clone(), *tilt));
                    }
                }
                for &a in &t.nodes {
                    let d = a * FIELDS;
                    link[d + 1] = Link::Held;
                    if free {
                        link[d] = if d == lead {
                            Link::Free
                        } else {
                            Link::To(lead, 1.0)
                        };
                        link[d + 2] = Link::To(lead, -1.0);
                    } else {
                        link[d] = Link::Held;
                        link[d + 2] = Link::Held;
                    }
                }
            }
            _ => {}
        }
    }
    let scale = model.potential_scale();
    let mut dof = vec![Vec::new(); nn * FIELDS];
    let mut count = 0;
    for d in 0..nn * FIELDS {
        if link[d] == Link::Free {
            dof[d].push((count, if d % FIELDS == PHI { scale } else { 1.0 }));
            count += 1;
        }
    }
    for d in 0..nn * FIELDS {
        if let Link::To(lead, c) = link[d] {
            dof[d] = dof[lead].iter().map(|&(e, cl)| (e, c * cl)).collect();
        }
    }
    let mut inertias = Vec::new();
    for (nodes, tilt) in tilting {
        let alpha = count;
        count += 1;
        inertias.push((alpha, tilt.inertia));
        let zc = mesh.nodes[tilt.node][1] + state[tilt.node * FIELDS + 1];
        for a in nodes {
            let d = a * FIELDS;
            let r = mesh.nodes[a][0] + state[d];
            let dz = mesh.nodes[a][1] + state[d + 1] - zc;
            dof[d].push((alpha, dz));
            dof[d + 2].push((alpha, -dz));
            dof[d + 1].push((alpha, -r));
        }
    }
    HarmonicDofs {
        dof,
        count,
        inertias,
    }
}

/// The harmonic problem of `n` ≥ 1: its tangent K_n and mass M_n over the harmonic unknowns, the
/// equation map that [`modes_of`] reads, each dof's combination of unknowns and the field of each
/// unknown.
struct HarmonicSystem {
    k: CsrMatrix,
    m: CsrMatrix,
    dofs: DofMap,
    eq: Vec<Vec<(usize, f64)>>,
    field: Vec<usize>,
}

/// Why harmonic `n` of `model` cannot be formed, if it cannot.
fn check_harmonic(model: &Model, n: u32) -> Result<(), String> {
    if !model.is_axisymmetric() {
        return Err(format!(
            "harmonic {n}: circumferential harmonics are modes of an axisymmetric model (`mesh.geometry = \"axisymmetric\"`); a 3-D model finds every mode with harmonic 0"
        ));
    }
    if n == 0 {
        return Err("harmonic 0 is the axisymmetric analysis itself".into());
    }
    if !model.pressures.is_empty() {
        return Err(format!(
            "harmonic {n}: the load stiffness of follower pressures has no harmonic form yet; harmonic 0 only"
        ));
    }
    if model.materials.iter().any(|m| m.state_size() > 0) {
        return Err(format!(
            "harmonic {n}: a material with internal variables: linearise about its relaxed state"
        ));
    }
    Ok(())
}

/// Assembles harmonic `n` of `model` about `state` (module docs); the mass when `mass` is given
/// (else M_n is zero on K_n's pattern).
fn harmonic_system(
    model: &Model,
    state: &[f64],
    mass: Option<&NodalMass>,
    n: u32,
    tilts: &[Tilt],
) -> Result<HarmonicSystem, String> {
    check_harmonic(model, n)?;
    let HarmonicDofs {
        dof: eq,
        count: n_eq,
        inertias,
    } = harmonic_dofs(model, state, n, tilts);
    // rows of (K, M) entries
    let mut rows: PairedRows = vec![BTreeMap::new(); n_eq];
    let mut k = vec![0.0; crate::element::MAX_LOCAL * crate::element::MAX_LOCAL];
    let formulation = model.formulation;
    model.for_each_cell(state, |c, g, mat, local| {
        harmonic_tangent(formulation, g, mat, CellHistory::NONE, local, n, &mut k)
            .map_err(|e| format!("harmonic {n}: cell {c}: {}", e.error))?;
        let cell = model.mesh.cell(c);
        let nl = cell.len() * FIELDS;
        for (i, &(ai, si)) in cell
            .iter()
            .flat_map(|a| (0..FIELDS).map(move |s| (a, s)))
            .collect::<Vec<_>>()
            .iter()
            .enumerate()
        {
            for &(ei, ci) in &eq[ai * FIELDS + si] {
                for (j, &b) in cell.iter().enumerate() {
                    for s in 0..FIELDS {
                        for &(ej, cj) in &eq[b * FIELDS + s] {
                            rows[ei].entry(ej).or_insert((0.0, 0.0)).0 +=
                                ci * cj * k[i * nl + j * FIELDS + s];
                        }
                    }
                }
            }
        }
        Ok::<(), String>(())
    })?;
    let factor = harmonic_factor(n);
    if let Some(mass) = mass {
        add_projected_mass(&mut rows, mass, &eq, factor);
        // a tilt's kinetic mass is its rotary inertia (a rigid body's ½Iα̇², not a ring's)
        for &(e, inertia) in &inertias {
            rows[e].entry(e).or_insert((0.0, 0.0)).1 += inertia;
        }
    }
    let (kmat, mmat) = paired_csr(&rows);
    // the equations as the nodes of a map of their own: equation e is dof (e, its field)
    // a tilt is a displacement unknown
    let mut field = vec![0; n_eq];
    for (d, e) in eq.iter().enumerate() {
        if let [(e, _)] = e.as_slice() {
            field[*e] = d % FIELDS;
        }
    }
    let dofs = equation_map(&field);
    Ok(HarmonicSystem {
        k: kmat,
        m: mmat,
        dofs,
        eq,
        field,
    })
}

/// The stability of the axisymmetric equilibrium `state` of `model` against perturbations of
/// harmonic `n` ≥ 1 with the electrodes held (module docs): the inertia of K_n and the number of
/// negative pivots of a stable state, its free potential unknowns (K_n is negative definite in
/// the potential and, at a stable state, positive definite in the displacements once the
/// potential is condensed; Sylvester's law of inertia). Rigid regions translate but do not tilt.
pub fn harmonic_inertia(model: &Model, state: &[f64], n: u32) -> Result<(Inertia, usize), String> {
    let sys = harmonic_system(model, state, None, n, &[])?;
    let mut lin = direct_solver();
    let inertia = lin
        .factor(&sys.k)
        .map_err(|e| format!("harmonic {n}: {e}"))?
        .ok_or_else(|| format!("harmonic {n}: the direct solver gave no inertia"))?;
    Ok((inertia, sys.dofs.n_free_phi))
}

/// The natural modes of harmonic `n` ≥ 1 of the axisymmetric `model` (its Dirichlet conditions
/// hold the supports and the electrode voltages) about the axisymmetric equilibrium `state`,
/// with the model's mass `mass` (module docs). The shapes hold (u_r, u_z, u_θ, Φ) per node, the
/// amplitudes of cos nΘ, cos nΘ, sin nΘ and cos nΘ; unit modal mass in the 3-D body. The rigid
/// regions of `tilts` tilt in harmonic 1.
pub fn harmonic_modes(
    model: &Model,
    state: &[f64],
    mass: &NodalMass,
    settings: &ModeSettings,
    n: u32,
    tilts: &[Tilt],
) -> Result<Vec<Mode>, String> {
    let HarmonicSystem {
        k: kmat,
        m: mmat,
        dofs,
        eq,
        field,
    } = harmonic_system(model, state, Some(mass), n, tilts)?;
    let found = modes_of(
        &kmat,
        &mmat,
        &dofs,
        direct_solver(),
        &mut |x, y| mmat.mul_vec(x, y),
        settings,
    )
    .map_err(|e| format!("harmonic {n}: {e}"))?;
    Ok(found
        .into_iter()
        .map(|m| {
            let mut shape = vec![0.0; eq.len()];
            for (d, e) in eq.iter().enumerate() {
                shape[d] = e
                    .iter()
                    .map(|&(e, c)| c * m.shape[e * FIELDS + field[e]])
                    .sum();
            }
            Mode {
                shape,
                harmonic: n,
                ..m
            }
        })
        .collect())
}
