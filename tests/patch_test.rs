//! Patch tests: a linear field prescribed on the boundary of a distorted mesh is reproduced exactly
//! inside (the interpolation is linearly complete and the homogeneous state has constant P and D₀,
//! so every interior node is in equilibrium). Mechanical patch test (Φ = 0), and the coupled one with
//! a uniform field as well. Tolerance 1e-9 of the boundary values (Newton tolerance).
//! Hex8, tet4 and tet10 (straight-sided: distorted corners, mid-edge nodes at the midpoints).
//! Also: zero voltage and no load gives exactly zero displacement.

mod common;

use common::{distort, Rng};
use deasim::job::statics::solve_static;
use deasim::material::{ElectroNeoHooke, EPSILON_0};
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::{Dirichlet, Field};
use deasim::problem::examples::film;
use deasim::problem::model::Model;
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use std::sync::Arc;

fn patch(kind: ElementKind, with_field: bool) {
    let mut rng = Rng::new(11);
    let h = 1e-3;
    // tet10: the corners are distorted and the mid-edge nodes added afterwards (straight-sided
    // cells: with curved ones the 4-point rule does not integrate ∫∇N_a dV exactly)
    let base = if kind == ElementKind::Tet10 {
        ElementKind::Tet4
    } else {
        kind
    };
    let mut mesh = box_mesh([3.0 * h, 3.0 * h, 3.0 * h], [3, 3, 3], base);
    // distort only interior nodes so the boundary stays a box
    let boundary: Vec<bool> = (0..mesh.n_nodes())
        .map(|n| {
            ["x0", "x1", "y0", "y1", "z0", "z1"]
                .iter()
                .any(|s| mesh.node_sets[*s].contains(&n))
        })
        .collect();
    let original = mesh.nodes.clone();
    distort(&mut mesh, h, 0.25, &mut rng);
    for (n, b) in boundary.iter().enumerate() {
        if *b {
            mesh.nodes[n] = original[n];
        }
    }
    if kind == ElementKind::Tet10 {
        mesh = deasim::mesh::quadratic::to_tet10(&mesh);
    }
    assert_eq!(mesh.kind, kind);
    let boundary: Vec<bool> = (0..mesh.n_nodes())
        .map(|n| {
            ["x0", "x1", "y0", "y1", "z0", "z1"]
                .iter()
                .any(|s| mesh.node_sets[*s].contains(&n))
        })
        .collect();
    let mat = ElectroNeoHooke::new(1e5, 1e6, 4.7);
    let mut model = Model::new(mesh, Arc::new(mat)).unwrap();
    let grad = [[0.05, 0.02, -0.01], [0.01, -0.03, 0.02], [0.00, 0.04, 0.06]];
    let e_field = if with_field {
        [2e6, -1e6, 5e6]
    } else {
        [0.0; 3]
    }; // V/m, Φ = −E·X
    for n in 0..model.mesh.n_nodes() {
        if !boundary[n] {
            continue;
        }
        let x = model.mesh.nodes[n];
        for (i, field) in [Field::Ux, Field::Uy, Field::Uz].into_iter().enumerate() {
            let v = grad[i][0] * x[0] + grad[i][1] * x[1] + grad[i][2] * x[2];
            model.dirichlet.push(Dirichlet {
                nodes: vec![n],
                field,
                value: v,
            });
        }
        let phi = -(e_field[0] * x[0] + e_field[1] * x[1] + e_field[2] * x[2]);
        model.dirichlet.push(Dirichlet {
            nodes: vec![n],
            field: Field::Phi,
            value: phi,
        });
    }
    let out = solve_static(
        &model,
        None,
        &StepControl {
            steps: 2,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    out.result.expect("patch converges");
    let mut worst = 0.0f64;
    for n in 0..model.mesh.n_nodes() {
        let x = model.mesh.nodes[n];
        for i in 0..3 {
            let v = grad[i][0] * x[0] + grad[i][1] * x[1] + grad[i][2] * x[2];
            worst = worst.max((out.state[n * 4 + i] - v).abs() / (0.1 * h));
        }
        let phi = -(e_field[0] * x[0] + e_field[1] * x[1] + e_field[2] * x[2]);
        worst = worst.max((out.state[n * 4 + 3] - phi).abs() / (1e7 * h));
    }
    eprintln!("{kind:?} field={with_field}: worst relative deviation {worst:.2e}");
    assert!(worst < 1e-9, "{kind:?}: {worst:e}");
    let _ = EPSILON_0;
}

#[test]
fn mechanical_patch_test() {
    patch(ElementKind::Hex8, false);
    patch(ElementKind::Tet4, false);
    patch(ElementKind::Tet10, false);
}

#[test]
fn coupled_patch_test() {
    patch(ElementKind::Hex8, true);
    patch(ElementKind::Tet4, true);
    patch(ElementKind::Tet10, true);
}

#[test]
fn zero_voltage_gives_zero_displacement() {
    let model = film([3, 3, 2], ElementKind::Hex8, 0.0).unwrap();
    let out = solve_static(
        &model,
        None,
        &StepControl {
            steps: 3,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, step| {
            assert_eq!(
                step.newton.iterations, 0,
                "the zero state is already in equilibrium"
            );
        },
    );
    out.result.unwrap();
    assert!(out.state.iter().all(|&v| v == 0.0));
}
