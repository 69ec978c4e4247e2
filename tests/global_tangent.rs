//! The assembled tangent is the derivative of the assembled residual.
//!
//! On a distorted mesh (nodes moved by up to 20 % of the cell size) with a random state
//! (displacement gradients ~0.1, fields ~0.3√(μ/ε)) and the Vu coupling terms switched on, every
//! column of the global tangent is compared with a central difference of the global residual, for
//! hex8, tet4 and tet10. Tolerance 1e-6 relative to the largest tangent entry: the central difference error
//! is O(h²) ≈ 1e-8 of the entries here, round-off ≈ 1e-16/h ≈ 1e-9.

mod common;

use common::{distort, tangent_fd_error, Rng};
use deasim::material::{ElectroNeoHooke, EPSILON_0};
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::{Field, Tie};
use deasim::problem::model::Model;
use deasim::problem::statics::StaticProblem;
use deasim::solve::newton::NonlinearSystem;
use std::sync::Arc;

fn check(kind: ElementKind) {
    let mut rng = Rng::new(7);
    let h = 1e-3;
    let mut mesh = box_mesh([2.0 * h, 2.0 * h, h], [2, 2, 1], kind);
    // mid-edge nodes lie h/2 apart: tet10 takes a smaller distortion to keep its cells valid
    let amount = if kind == ElementKind::Tet10 {
        0.05
    } else {
        0.2
    };
    distort(&mut mesh, h, amount, &mut rng);
    let (mu, lambda, eps_r) = (1e5, 4e5, 4.7);
    let eps = eps_r * EPSILON_0;
    let mat = ElectroNeoHooke::new(mu, lambda, eps_r).with_coupling(0.3 * eps, 0.2 * eps);
    let model = Model::new(mesh, Arc::new(mat)).unwrap();
    let mut p = StaticProblem::new(&model, None);
    let e_scale = (mu / eps).sqrt();
    for (i, v) in p.state.iter_mut().enumerate() {
        *v = if i % 4 == 3 {
            0.3 * e_scale * h * rng.next()
        } else {
            0.1 * h * rng.next()
        };
    }
    let n = p.n();
    assert_eq!(
        n,
        model.mesh.n_nodes() * 4,
        "no conditions: every dof is free"
    );
    // the scaled unknowns are lengths (m): step 1e-7 of the cell size
    let worst = tangent_fd_error(&mut p, 1e-7 * h);
    eprintln!("{kind:?}: {n} dofs, max |K - K_fd| / max|K| = {worst:.2e}");
    assert!(worst < 1e-6, "{kind:?}: {worst:e}");
}

#[test]
fn global_tangent_matches_finite_differences_hex8() {
    check(ElementKind::Hex8);
}

#[test]
fn global_tangent_matches_finite_differences_tet4() {
    check(ElementKind::Tet4);
}

/// Tet10 with every node moved by up to 5 % of h, mid-edge nodes included (curved cells).
#[test]
fn global_tangent_matches_finite_differences_tet10() {
    check(ElementKind::Tet10);
}

/// Tied dofs (a rigid region's translations): the assembled residual and tangent are Pᵀr and
/// PᵀKP of the untied system, P the map from the shared equations to the dofs; 1e-12 relative.
#[test]
fn tied_system_is_the_reduced_untied_one() {
    let mut rng = Rng::new(11);
    let h = 1e-3;
    let mut mesh = box_mesh([3.0 * h, 3.0 * h, h], [3, 3, 2], ElementKind::Hex8);
    distort(&mut mesh, h, 0.1, &mut rng);
    let mat = ElectroNeoHooke::new(1e5, 4e5, 4.7);
    let mut model = Model::new(mesh, Arc::new(mat)).unwrap();
    let tied_nodes = model.mesh.set_nodes("z1").unwrap();
    let n_nodes = model.mesh.n_nodes();
    let mut state = vec![0.0; n_nodes * 4];
    for v in state.iter_mut() {
        *v = 0.05 * h * rng.next();
    }
    let untied = {
        let mut p = StaticProblem::new(&model, Some(state.clone()));
        let mut k = p.new_matrix();
        let mut r = vec![0.0; p.n()];
        p.evaluate(&mut r, Some(&mut k)).unwrap();
        (p.dofs.clone(), r, k)
    };
    model.ties = [Field::Ux, Field::Uy, Field::Uz]
        .into_iter()
        .map(|field| Tie {
            nodes: tied_nodes.clone(),
            field,
            held: false,
        })
        .collect();
    let mut p = StaticProblem::new(&model, Some(state));
    let mut k = p.new_matrix();
    let mut r = vec![0.0; p.n()];
    p.evaluate(&mut r, Some(&mut k)).unwrap();
    assert_eq!(p.n(), untied.0.n_free - 3 * (tied_nodes.len() - 1));
    // reduce the untied system: equation of every dof in both numberings
    let (ud, ur, uk) = untied;
    let mut r_red = vec![0.0; p.n()];
    let mut k_red = vec![vec![0.0; p.n()]; p.n()];
    for d in 0..n_nodes * 4 {
        let (eu, et) = (ud.eq[d], p.dofs.eq[d]);
        if eu == usize::MAX {
            continue;
        }
        r_red[et] += ur[eu];
        for d2 in 0..n_nodes * 4 {
            let (eu2, et2) = (ud.eq[d2], p.dofs.eq[d2]);
            if eu2 == usize::MAX {
                continue;
            }
            if let Some(pos) = uk.position(eu, eu2) {
                k_red[et][et2] += uk.values[pos];
            }
        }
    }
    let kmax = uk.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rmax = ur.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut err: f64 = 0.0;
    for i in 0..p.n() {
        err = err.max((r[i] - r_red[i]).abs() / rmax);
        for j in 0..p.n() {
            let kij = k.position(i, j).map(|pos| k.values[pos]).unwrap_or(0.0);
            err = err.max((kij - k_red[i][j]).abs() / kmax);
        }
    }
    println!("tied vs reduced untied system: {err:.2e}");
    assert!(err < 1e-12, "{err}");
}
