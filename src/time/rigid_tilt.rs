//! Natural modes of a 3-D model whose rigid regions rotate as well as translate: a pad given a
//! rotary inertia rocks. The time-domain stages tie a rigid region's translations only; for the
//! modes about a loaded state, each such region's nodes follow the linearised rigid motion
//! u_a = t + θ × (x_a − x_c), with six unknowns (t, θ), about the point x_c on the region's
//! central axis (the mean of its nodes' x and y) at the height of its attachment node, where the
//! axisymmetric model tilts it and where its attached mass sits. The tangent and mass of the
//! model with the region's ties removed are transformed, K_r = Tᵀ K T and M_r = Tᵀ M T; the
//! attached mass m is the kinetic mass of t, and the rotary inertia I about a diameter that of
//! θ_x and θ_y (2I, a thin disc's polar moment, of θ_z). The axisymmetric model's harmonic 1
//! with the same m and I ([`crate::time::harmonic`]) finds the same rocking mode.

use crate::algebra::system::NonlinearSystem;
use crate::problem::dofs::{Field, CONSTRAINED, FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;
use crate::time::mass::NodalMass;
use crate::time::modal::{modes_of, Mode, ModeSettings};
use crate::time::reduction::{
    add_projected_mass, direct_solver, equation_map, paired_csr, PairedRows,
};
use std::collections::BTreeMap;

/// A rigid region that rotates: its attachment node, attached mass (kg) and rotary inertia
/// about a diameter (kg·m²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBody {
    pub node: usize,
    pub mass: f64,
    pub inertia: f64,
}

/// The modes of the 3-D `model` (its Dirichlet conditions hold the supports and the electrode
/// voltages) about `state`, with the mass `mass` (the body's, with the attached masses of the
/// regions that do not rotate), the regions of `bodies` rotating (module docs). Each region is
/// the translation tie of its attachment node; none of its nodes may be held.
pub fn modes_with_tilts(
    model: &Model,
    state: &[f64],
    mass: &NodalMass,
    settings: &ModeSettings,
    bodies: &[RigidBody],
) -> Result<Vec<Mode>, String> {
    if model.is_axisymmetric() {
        return Err(
            "rotating rigid regions: a 3-D model (an axisymmetric one tilts its pads in \
                    harmonic 1)"
                .into(),
        );
    }
    // the regions: the nodes of the translation ties of each attachment node
    let mut untied = model.clone();
    let mut regions: Vec<(Vec<usize>, RigidBody)> = Vec::new();
    for tilt in bodies {
        let nodes = model
            .ties
            .iter()
            .find(|t| t.field == Field::Ux && t.nodes.contains(&tilt.node))
            .map(|t| t.nodes.clone())
            .ok_or_else(|| format!("node {} is in no rigid region", tilt.node))?;
        untied.ties.retain(|t| {
            !(matches!(t.field, Field::Ux | Field::Uy | Field::Uz) && t.nodes.contains(&tilt.node))
        });
        regions.push((nodes, *tilt));
    }
    let mut problem = StaticProblem::new(&untied, Some(state.to_vec()));
    problem.set_drive(crate::problem::drive::Drive::held(&untied));
    problem.assemble_every_cell();
    let n = problem.n();
    let mut k = problem.new_matrix();
    let mut r = vec![0.0; n];
    problem.evaluate(&mut r, Some(&mut k))?;
    let dofs = &problem.dofs;
    // each dof's combination of the reduced unknowns: the other equations first, then six per
    // region
    let mut in_region = vec![None; model.mesh.n_nodes()];
    for (i, (nodes, _)) in regions.iter().enumerate() {
        for &a in nodes {
            in_region[a] = Some(i);
        }
    }
    let mut reduced_of_eq = vec![usize::MAX; n];
    let mut field = Vec::new();
    for (d, &e) in dofs.eq.iter().enumerate() {
        let a = d / FIELDS;
        if e == CONSTRAINED || (in_region[a].is_some() && d % FIELDS != PHI) {
            continue;
        }
        if reduced_of_eq[e] == usize::MAX {
            reduced_of_eq[e] = field.len();
            field.push(d % FIELDS);
        }
    }
    let first_region = field.len();
    field.extend(std::iter::repeat_n(0, 6 * regions.len()));
    let position = |a: usize| -> [f64; 3] {
        let x = model.mesh.nodes[a];
        [0, 1, 2].map(|i| x[i] + state[a * FIELDS + i])
    };
    // the centre of each region's rotation: on its axis, at its attachment node's height
    let centres: Vec<[f64; 3]> = regions
        .iter()
        .map(|(nodes, body)| {
            let mean =
                |i: usize| nodes.iter().map(|&a| position(a)[i]).sum::<f64>() / nodes.len() as f64;
            [mean(0), mean(1), position(body.node)[2]]
        })
        .collect();
    let mut combination: Vec<Vec<(usize, f64)>> = vec![Vec::new(); dofs.eq.len()];
    for (d, c) in combination.iter_mut().enumerate() {
        let (a, s) = (d / FIELDS, d % FIELDS);
        match in_region[a] {
            Some(i) if s != PHI => {
                if dofs.eq[d] == CONSTRAINED {
                    return Err(format!(
                        "the rigid region of node {} is held (node {a}): it cannot rotate",
                        regions[i].1.node
                    ));
                }
                let xa = position(a);
                let xc = centres[i];
                let rr = [xa[0] - xc[0], xa[1] - xc[1], xa[2] - xc[2]];
                let base = first_region + 6 * i;
                // u = t + θ × r
                let rot = match s {
                    0 => [(4, rr[2]), (5, -rr[1])],
                    1 => [(5, rr[0]), (3, -rr[2])],
                    _ => [(3, rr[1]), (4, -rr[0])],
                };
                c.push((base + s, 1.0));
                c.extend(rot.iter().map(|&(j, v)| (base + j, v)));
            }
            _ if dofs.eq[d] != CONSTRAINED => c.push((reduced_of_eq[dofs.eq[d]], 1.0)),
            _ => {}
        }
    }
    // the equations' combinations (a dof of each equation stands for it)
    let mut of_eq: Vec<&[(usize, f64)]> = vec![&[]; n];
    for (d, &e) in dofs.eq.iter().enumerate() {
        if e != CONSTRAINED && of_eq[e].is_empty() {
            of_eq[e] = &combination[d];
        }
    }
    let n_red = field.len();
    let mut rows: PairedRows = vec![BTreeMap::new(); n_red];
    for (e1, row) in of_eq.iter().enumerate() {
        for p in k.row_ptr[e1]..k.row_ptr[e1 + 1] {
            let (e2, v) = (k.col_idx[p] as usize, k.values[p]);
            for &(r1, c1) in *row {
                for &(r2, c2) in of_eq[e2] {
                    rows[r1].entry(r2).or_insert((0.0, 0.0)).0 += c1 * c2 * v;
                }
            }
        }
    }
    add_projected_mass(&mut rows, mass, &combination, 1.0);
    for (i, (_, tilt)) in regions.iter().enumerate() {
        let base = first_region + 6 * i;
        for (j, inertia) in [
            (0, tilt.mass),
            (1, tilt.mass),
            (2, tilt.mass),
            (3, tilt.inertia),
            (4, tilt.inertia),
            (5, 2.0 * tilt.inertia),
        ] {
            rows[base + j].entry(base + j).or_insert((0.0, 0.0)).1 += inertia;
        }
    }
    let (kmat, mmat) = paired_csr(&rows);
    let reduced = equation_map(&field);
    let found = modes_of(
        &kmat,
        &mmat,
        &reduced,
        direct_solver(),
        &mut |x, y| mmat.mul_vec(x, y),
        settings,
    )?;
    let scale = dofs.scale;
    Ok(found
        .into_iter()
        .map(|m| {
            let shape = combination
                .iter()
                .enumerate()
                .map(|(d, c)| {
                    c.iter()
                        .map(|&(r, v)| v * m.shape[r * FIELDS + field[r]])
                        .sum::<f64>()
                        * scale[d % FIELDS]
                })
                .collect();
            Mode { shape, ..m }
        })
        .collect())
}
