//! The ranks' parts of a model add up to the whole model, on the examples.
//!
//! A distributed run divides the cells between its ranks by a METIS partition; each rank cuts
//! its part of the mesh out as a mesh of its own (`LocalMesh`) and its part of the model
//! (`Model::part`). What the ranks assemble must then sum, at the global equations, to what one
//! process assembles: every cell term once, every support and tie on every rank that holds its
//! nodes, every point force and charge (the attached masses' weights, a charge-controlled
//! electrode's charge, and a point force and a charge added at every node) once. Reference: the whole model's
//! residual and tangent at the same state, at the scenario's end conditions; tolerance 1e-12 of
//! the largest entry (sums in another order, round-off only).

use deasim::algebra::csr::CsrMatrix;
use deasim::algebra::exchange::LocalEquations;
use deasim::algebra::system::{LoadedSystem, NonlinearSystem};
use deasim::io::build::build;
use deasim::io::examples::example;
use deasim::io::scenario::parse;
use deasim::mesh::distribute::{LocalMesh, Numbering};
use deasim::mesh::partition::partition_cells;
use deasim::problem::assembly::node_processes;
use deasim::problem::distributed::equation_owners;
use deasim::problem::dofs::{Dirichlet, Field, FIELDS};
use deasim::problem::model::Model;
use deasim::problem::statics::StaticProblem;

/// The model of example `name` (with the `--set` overrides `set`) with its supports and its
/// voltage electrodes at 1 kV.
fn example_model(name: &str, set: &[&str]) -> Model {
    let text = example(name).expect("an example");
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    let plan = build(&parse(text, name, &set).unwrap(), name, None).unwrap();
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    for e in plan.electrodes.iter().filter(|e| e.charge.is_none()) {
        model.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value: 1e3,
        });
    }
    model
}

/// `model` with a point force and a free charge at every node beside its own loads, a
/// thousandth of the largest residual entry at `state` (so that the nodes the ranks share carry
/// loads well above the tolerance: each must be applied once).
fn with_point_forces(mut model: Model, state: &[f64]) -> Model {
    let (_, r, _) = evaluate(&model, state.to_vec());
    let f = 1e-3 * r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let extra: Vec<(usize, [f64; 3])> = (0..model.mesh.n_nodes())
        .map(|n| (n, [f, -f * (n as f64).sin(), 0.5 * f]))
        .collect();
    model.point_forces.extend(extra);
    // and a free charge on every node's potential, of the same size in the scaled residual
    let q = f / model.potential_scale();
    let charges: Vec<(usize, f64)> = (0..model.mesh.n_nodes())
        .map(|n| (n, q * (n as f64).cos()))
        .collect();
    model.point_charges.extend(charges);
    model
}

/// A small smooth state: displacements of a micrometre, potentials of a few hundred volts.
fn wavy(model: &Model) -> Vec<f64> {
    (0..model.mesh.n_nodes() * FIELDS)
        .map(|d| {
            let x = model.mesh.nodes[d / FIELDS];
            let w = (3e2 * x[0] + 5e2 * x[1] + 7e2 * x[2] + d as f64).sin();
            if d % FIELDS == 3 {
                300.0 * w
            } else {
                1e-6 * w
            }
        })
        .collect()
}

/// Residual and tangent of `model` at `state`, its dead loads and prescribed values at full.
fn evaluate(model: &Model, state: Vec<f64>) -> (StaticProblem<'_>, Vec<f64>, CsrMatrix) {
    let mut p = StaticProblem::new(model, Some(state));
    p.set_load(1.0);
    let mut k = p.new_matrix();
    let mut r = vec![0.0; p.n()];
    p.evaluate(&mut r, Some(&mut k)).unwrap();
    (p, r, k)
}

fn parts_add_up(name: &str, set: &[&str]) -> Model {
    let whole = example_model(name, set);
    let state = wavy(&whole);
    let whole = with_point_forces(whole, &state);
    let (problem, r, k) = evaluate(&whole, state.clone());
    let dofs = problem.dofs.clone();
    let mesh = &whole.mesh;
    let r_scale = r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let k_scale = k.values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    assert!(r_scale > 0.0 && k_scale > 0.0);
    for ranks in [2, 3] {
        let part = partition_cells(mesh, ranks, None);
        let node_owner = node_processes(mesh, &dofs, &part, ranks);
        let numbering = Numbering::contiguous(&equation_owners(&dofs, &node_owner), ranks);
        let mut whole_eq = vec![0; dofs.n_free];
        for (e, &g) in numbering.number.iter().enumerate() {
            whole_eq[g] = e;
        }
        let mut r_sum = vec![0.0; dofs.n_free];
        let mut k_sum = vec![0.0; k.nnz()];
        for rank in 0..ranks {
            let local = LocalMesh::of_rank(mesh, &part, &node_owner, rank, ranks).unwrap();
            let model = whole.part(&local).unwrap();
            let (p, rl, kl) = evaluate(&model, local.gather_nodes(&state, FIELDS));
            let eqs = LocalEquations::new(&dofs, &numbering, &local, &p.dofs).unwrap();
            let at: Vec<usize> = eqs.global.iter().map(|&g| whole_eq[g]).collect();
            for (e, &i) in at.iter().enumerate() {
                r_sum[i] += rl[e];
                for q in kl.row_ptr[e]..kl.row_ptr[e + 1] {
                    let j = at[kl.col_idx[q] as usize];
                    let pos = k.position(i, j).unwrap_or_else(|| {
                        panic!("{name}, rank {rank}: entry ({i}, {j}) not in the whole pattern")
                    });
                    k_sum[pos] += kl.values[q];
                }
            }
        }
        for (e, (a, b)) in r_sum.iter().zip(&r).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12 * r_scale,
                "{name}, {ranks} ranks, equation {e}: {a:e} against {b:e}"
            );
        }
        for (a, b) in k_sum.iter().zip(&k.values) {
            assert!(
                (a - b).abs() <= 1e-12 * k_scale,
                "{name}, {ranks} ranks: tangent {a:e} against {b:e}"
            );
        }
    }
    whole
}

#[test]
fn the_films_parts_add_up_to_the_whole() {
    let film = parts_add_up("film", &[]);
    assert!(film.ties.is_empty());
}

/// Rigid pad (tied translations, held in y on the symmetry plane: held as a whole on every
/// rank), with the attached mass's weight as point forces.
#[test]
fn the_3d_diaphragms_parts_add_up_to_the_whole() {
    let diaphragm = parts_add_up("diaphragm-3d", &[]);
    assert!(!diaphragm.ties.is_empty() && !diaphragm.point_forces.is_empty());
}

/// Several electrodes through the layers.
#[test]
fn the_stacks_parts_add_up_to_the_whole() {
    parts_add_up("stack", &[]);
}

/// A charge-controlled electrode: its potential one tied unknown across the ranks, its charge
/// a point charge on the rank that owns that unknown (the example's one cell refined, so that
/// the ranks have cells).
#[test]
fn the_charged_films_parts_add_up_to_the_whole() {
    let film = parts_add_up("film-charge", &["mesh.divisions=[4,4,2]"]);
    assert!(!film.ties.is_empty() && !film.point_charges.is_empty());
}

/// A follower pressure on the film's top: each face acts on the rank of its cell, so the parts'
/// residuals and tangents (the pressure's load and its follower stiffness) add up to the whole.
#[test]
fn a_pressed_films_parts_add_up_to_the_whole() {
    let pressure = "loads.pressure=[{set=\"z1\",value=2e5}]";
    let film = parts_add_up("film", &[pressure]);
    assert_eq!(film.pressures.len(), 1);
    // the pressure's share of the residual is far above the comparison's tolerance
    let state = wavy(&film);
    let (_, pressed, _) = evaluate(&film, state.clone());
    let mut bare = film.clone();
    bare.pressures.clear();
    let (_, r, _) = evaluate(&bare, state);
    let scale = r.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let load = pressed
        .iter()
        .zip(&r)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(load > 1e-3 * scale, "{load:e} of {scale:e}");
}
