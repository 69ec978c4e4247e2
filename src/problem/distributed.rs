//! One rank's equations among those of the whole problem, for models built on a rank's part of
//! the mesh ([`crate::mesh::distribute::LocalMesh`]).
//!
//! A rank's model numbers its own free unknowns; a distributed vector or matrix numbers the
//! whole problem's. [`LocalEquations`] connects the two: the global number of each of the rank's
//! equations in a numbering where each rank owns one contiguous block (PETSc's ownership
//! ranges), and which of them the rank owns. An equation is owned by the owner of its lowest
//! node, the rule of the shared assembly's term equations, so a tied equation (a rigid pad's
//! translation, a charge-controlled electrode's potential) whose nodes lie on several ranks is
//! one row of one rank and a ghost of the others.
//!
//! What is summed over the ranks: the cell terms at the nodes they share. What a rank's model
//! must not hold twice: the terms that are not cell terms (point forces and charges, dashpots,
//! circuits) at a node another rank holds too; they belong to the owner of their equation.

use crate::mesh::distribute::{LocalMesh, Numbering};
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS};

/// The owner of each equation of `dofs`: the owner of its lowest node (`node_owner` per node).
pub fn equation_owners(dofs: &DofMap, node_owner: &[usize]) -> Vec<usize> {
    let mut lowest = vec![usize::MAX; dofs.n_free];
    for (d, &e) in dofs.eq.iter().enumerate() {
        if e != CONSTRAINED {
            lowest[e] = lowest[e].min(d / FIELDS);
        }
    }
    lowest.iter().map(|&n| node_owner[n]).collect()
}

/// A rank's equations in the whole problem's numbering.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalEquations {
    /// The global number of each of the rank's equations (in the contiguous numbering).
    pub global: Vec<usize>,
    /// Whether the rank owns each of its equations.
    pub owned: Vec<bool>,
    /// The first global number of each rank, and the number of equations at the end.
    pub start: Vec<usize>,
}

impl LocalEquations {
    /// The equations of the model on `local` (numbered by `local_dofs`) in the whole problem
    /// (numbered by `whole`, its equations renumbered by `numbering`, whose blocks say which
    /// rank owns each: see [`equation_owners`] and [`Numbering::contiguous`]). Fails
    /// when the two disagree: a dof free in one and held in the other, or two dofs of one local
    /// equation that are two equations of the whole problem (a tie or support that the rank's
    /// part of the sets does not reproduce).
    pub fn new(
        whole: &DofMap,
        numbering: &Numbering,
        local: &LocalMesh,
        local_dofs: &DofMap,
    ) -> Result<Self, String> {
        let mut global = vec![usize::MAX; local_dofs.n_free];
        for (d, &e) in local_dofs.eq.iter().enumerate() {
            let (node, field) = (local.nodes[d / FIELDS], d % FIELDS);
            let g = whole.eq[node * FIELDS + field];
            match (e == CONSTRAINED, g == CONSTRAINED) {
                (true, true) => continue,
                (false, false) => {}
                (held, _) => {
                    return Err(format!(
                        "rank {}: field {field} of node {node} is {} on this rank but {} in the \
                         whole problem",
                        local.rank,
                        if held { "held" } else { "free" },
                        if held { "free" } else { "held" },
                    ))
                }
            }
            let g = numbering.number[g];
            if global[e] == usize::MAX {
                global[e] = g;
            } else if global[e] != g {
                return Err(format!(
                    "rank {}: field {field} of node {node} shares a local equation with another \
                     node whose equation in the whole problem is another one",
                    local.rank
                ));
            }
        }
        let owned = global
            .iter()
            .map(|&g| {
                let r = numbering.start.partition_point(|&s| s <= g) - 1;
                r == local.rank
            })
            .collect();
        Ok(LocalEquations {
            global,
            owned,
            start: numbering.start.clone(),
        })
    }

    /// The number of equations this rank owns.
    pub fn n_owned(&self) -> usize {
        self.owned.iter().filter(|&&o| o).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::partition::partition_cells;
    use crate::mesh::{ElementKind, Mesh};
    use crate::problem::assembly::node_processes;
    use crate::problem::dofs::{Field, Tie};
    use crate::problem::examples::{film_on, wavy_state, FILM_SIZE};
    use crate::problem::model::Model;
    use crate::problem::statics::StaticProblem;
    use crate::problem::system::NonlinearSystem;

    /// The film on `mesh`, with its top face's displacement tied in z when `tied` (as a rigid
    /// pad holds it), so that one equation spans the ranks.
    fn film(mesh: Mesh, tied: bool) -> Model {
        let mut model = film_on(mesh, 1000.0).unwrap();
        if tied {
            let nodes = model.mesh.set_nodes("z1").unwrap();
            model.ties.push(Tie {
                nodes,
                field: Field::Uz,
            });
        }
        model
    }

    /// Residual and dense tangent of `model` at `state` over its free unknowns.
    fn evaluate(model: &Model, state: Vec<f64>) -> (DofMap, Vec<f64>, Vec<Vec<f64>>) {
        let mut p = StaticProblem::new(model, Some(state));
        let mut k = p.new_matrix();
        let mut r = vec![0.0; p.n()];
        p.evaluate(&mut r, Some(&mut k)).unwrap();
        let mut dense = vec![vec![0.0; k.n]; k.n];
        for i in 0..k.n {
            for q in k.row_ptr[i]..k.row_ptr[i + 1] {
                dense[i][k.col_idx[q] as usize] += k.values[q];
            }
        }
        (p.dofs.clone(), r, dense)
    }

    /// The models that the ranks build on their parts of the mesh add up, at their global
    /// equations, to the whole model's residual and tangent; each equation is owned by one rank,
    /// and a rank's owned equations are its block of the contiguous numbering.
    #[test]
    fn the_ranks_models_add_up_to_the_whole_problem() {
        for tied in [false, true] {
            let mesh = box_mesh(FILM_SIZE, [6, 6, 3], ElementKind::Hex8);
            let whole_model = film(mesh.clone(), tied);
            let state = wavy_state(&whole_model, 0.0, 1e-5, 1000.0);
            let (dofs, r, k) = evaluate(&whole_model, state.clone());
            for ranks in [2, 3] {
                let part = partition_cells(&mesh, ranks, None);
                let node_owner = node_processes(&mesh, &dofs, &part, ranks);
                let owner = equation_owners(&dofs, &node_owner);
                let numbering = Numbering::contiguous(&owner, ranks);
                let n = dofs.n_free;
                let (mut r_sum, mut k_sum) = (vec![0.0; n], vec![vec![0.0; n]; n]);
                let mut owned_by = vec![0; n];
                for rank in 0..ranks {
                    let local = LocalMesh::of_rank(&mesh, &part, &node_owner, rank, ranks).unwrap();
                    let model = film(local.mesh.clone(), tied);
                    let (local_dofs, rl, kl) = evaluate(&model, local.gather_nodes(&state, FIELDS));
                    let eqs = LocalEquations::new(&dofs, &numbering, &local, &local_dofs).unwrap();
                    for (e, &g) in eqs.global.iter().enumerate() {
                        r_sum[g] += rl[e];
                        for (f, &h) in eqs.global.iter().enumerate() {
                            k_sum[g][h] += kl[e][f];
                        }
                        if eqs.owned[e] {
                            owned_by[g] += 1;
                            assert!((eqs.start[rank]..eqs.start[rank + 1]).contains(&g));
                        }
                    }
                    assert_eq!(eqs.n_owned(), eqs.start[rank + 1] - eqs.start[rank]);
                }
                assert!(
                    owned_by.iter().all(|&c| c == 1),
                    "{ranks} ranks: owned once"
                );
                let rs = r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                let ks = k.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
                for e in 0..n {
                    let g = numbering.number[e];
                    assert!(
                        (r_sum[g] - r[e]).abs() <= 1e-13 * rs,
                        "tied {tied}, {ranks} ranks, equation {e}: {} against {}",
                        r_sum[g],
                        r[e]
                    );
                    for f in 0..n {
                        let h = numbering.number[f];
                        assert!((k_sum[g][h] - k[e][f]).abs() <= 1e-13 * ks);
                    }
                }
            }
        }
    }

    /// A rank whose part of a tie is held while the whole tie is free (a support that the
    /// rank's sets reproduce differently) is refused, naming the node.
    #[test]
    fn a_rank_that_holds_what_the_whole_frees_is_refused() {
        let mesh = box_mesh(FILM_SIZE, [2, 1, 1], ElementKind::Hex8);
        let whole = film(mesh.clone(), false);
        let (dofs, _, _) = evaluate(&whole, vec![0.0; mesh.n_nodes() * FIELDS]);
        let part = vec![0, 1];
        let node_owner = node_processes(&mesh, &dofs, &part, 2);
        let owner = equation_owners(&dofs, &node_owner);
        let numbering = Numbering::contiguous(&owner, 2);
        let local = LocalMesh::of_rank(&mesh, &part, &node_owner, 1, 2).unwrap();
        let mut model = film(local.mesh.clone(), false);
        model.fix("z1", Field::Ux, 0.0).unwrap();
        let (local_dofs, _, _) = evaluate(&model, vec![0.0; local.nodes.len() * FIELDS]);
        let err = LocalEquations::new(&dofs, &numbering, &local, &local_dofs).unwrap_err();
        assert!(err.contains("held on this rank but free"), "{err}");
    }
}
