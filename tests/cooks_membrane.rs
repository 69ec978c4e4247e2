//! Near incompressibility and surface tractions: the mean-dilatation element and Cook's membrane.
//!
//! * The assembled mean-dilatation tangent is the derivative of the assembled residual (distorted
//!   hex8 mesh, random state, electro-mechanical coupling on, a traction acting), and symmetric.
//! * Patch test with the mean-dilatation element: homogeneous states are reproduced.
//! * Cook's membrane, the benchmark of the deal.II code gallery "Quasi-static finite-strain
//!   compressible elasticity" (J.-P. Pelteret and A. McBride, 2016, doi:10.5281/zenodo.1228964;
//!   the geometry is Cook's 1974 tapered panel): a plate with corners (0,0), (48,44), (48,60),
//!   (0,44) mm, 1 mm thick, clamped at x = 0, a uniform shear traction of
//!   1 N / (16 mm × 1 mm) = 62.5 kPa in +y on x = 48 mm, split neo-Hooke
//!   Ψ = μ/2 (Ī₁ − 3) + κ/4 (J² − 1 − 2 ln J), μ = 422.5 kPa, κ = 2μ(1+ν)/(3(1−2ν)). The quantity
//!   is the vertical displacement of the top right corner (48, 60) mm (mean of the two nodes
//!   through the thickness). The gallery's table for Q1 elements at ν = 0.3 (n cells per edge) is
//!   1: 5.15, 2: 8.72, 4: 12.02, 8: 13.61, 16: 14.13, 32: 14.28 mm; Q2 converges to 14.33 mm.
//!
//! **Which problem the gallery's table solves.** The gallery describes the 3-D problem as plane
//! strain (u_z = 0), but its program marks the ±z faces by testing the *x* coordinate of the face
//! centre, which never matches, so u_z stays free except on the clamped edge: its table is for a
//! free-thickness (plane-stress-like) 1 mm plate. We reproduce that table to its last digit with
//! u_z free (`Thickness::Free`); with u_z = 0 (`Thickness::PlaneStrain`, what the gallery intended
//! and what the brief of this work asked for) Q1 gives values 3–4 % lower (e.g. 8.40 instead of
//! 8.72 mm at n = 2) and converges to ≈ 13.8 mm, not 14.33. The free-thickness state at 1 N is an
//! unstable equilibrium in 3-D: the thin plate buckles sideways (lateral-torsional buckling, a
//! deep cantilever of 1 mm thickness, estimated P_cr ≈ 4.01·√(EI·GJ)/L² ≈ 0.01 N), which our
//! Newton detects as a negative pivot (at 0.36 N with n = 4, 0.04 N with n = 16); deal.II's Newton
//! does not check stability and stays on the symmetric branch, so does ours with
//! `check_stability: false`. The plane-strain problem is stable and is the one used for the
//! nearly incompressible study (locking is a plane-strain phenomenon).
//!
//! Every test runs in a few seconds in a release build; the n = 64 reference is an ignored test.

mod common;

use common::{distort, tangent_fd_error, Rng};
use deasim::cli::validate::cook::{tip, GALLERY_Q1, GALLERY_Q2, MD_4999_N64};
use deasim::job::statics::solve_static;
use deasim::material::{ElectroNeoHooke, EPSILON_0};
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::{Dirichlet, Field};
use deasim::problem::examples::Thickness;
use deasim::problem::model::{Formulation, Model};
use deasim::problem::statics::StaticProblem;
use deasim::solve::newton::{NewtonSettings, NonlinearSystem};
use deasim::solve::stepping::{LoadedSystem, StepControl};
use std::sync::Arc;
use std::time::Instant;

/// Central differences of the assembled residual against the assembled mean-dilatation tangent,
/// column by column, as in `tests/global_tangent.rs`: tolerance 1e-6 of the largest entry (the
/// difference error is O(h²) ≈ 1e-8, round-off ≈ 1e-9). Symmetry to 1e-12.
#[test]
fn mean_dilatation_global_tangent_matches_finite_differences() {
    let mut rng = Rng::new(7);
    let h = 1e-3;
    let mut mesh = box_mesh([2.0 * h, 2.0 * h, h], [2, 2, 1], ElementKind::Hex8);
    distort(&mut mesh, h, 0.2, &mut rng);
    let (mu, lambda, eps_r) = (1e5, 4e6, 4.7);
    let eps = eps_r * EPSILON_0;
    let mat = ElectroNeoHooke::new(mu, lambda, eps_r).with_coupling(0.3 * eps, 0.2 * eps);
    let mut model = Model::new(mesh, Arc::new(mat)).unwrap();
    model.formulation = Formulation::MeanDilatation;
    model.add_traction("x1", [1e4, -2e4, 3e4]).unwrap();
    let mut p = StaticProblem::new(&model, None);
    p.set_load(1.0);
    let e_scale = (mu / eps).sqrt();
    for (i, v) in p.state.iter_mut().enumerate() {
        *v = if i % 4 == 3 {
            0.3 * e_scale * h * rng.next()
        } else {
            0.1 * h * rng.next()
        };
    }
    let n = p.n();
    let step = 1e-7 * h;
    let worst = tangent_fd_error(&mut p, step);
    eprintln!("mean-dilatation hex8: {n} dofs, max |K - K_fd| / max|K| = {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
    let mut r = vec![0.0; n];
    let mut e = vec![0.0; n];
    // the residual is the gradient of the energy: Π(x + h e_j) − Π(x − h e_j) ≈ 2h r_j
    // (checked on the displacement unknowns of the first nodes; tractions excluded from Π here,
    // so compare against the residual of the unloaded problem)
    p.set_load(0.0);
    p.evaluate(&mut r, None).unwrap();
    let rmax = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut worst_r = 0.0f64;
    for j in 0..12 {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        let s = p.snapshot();
        p.increment(&e, step);
        let ep = p.energies().unwrap();
        p.restore(&s);
        p.increment(&e, -step);
        let em = p.energies().unwrap();
        p.restore(&s);
        // Ψ = mechanical − electric
        let fd = ((ep.0 - ep.1) - (em.0 - em.1)) / (2.0 * step);
        worst_r = worst_r.max((fd - r[j]).abs() / rmax);
    }
    eprintln!("mean-dilatation hex8: max |r - dΠ/dx| / max|r| = {worst_r:.2e}");
    assert!(worst_r < 1e-6, "{worst_r:e}");
}

/// A linear displacement and potential prescribed on the boundary of a distorted 3×3×3 mesh is
/// reproduced inside by the mean-dilatation element (homogeneous F: F̄ = F at every point), with and
/// without a field, on a nearly incompressible material (κ/μ = 5000). Tolerance 1e-9 of the
/// boundary values (Newton tolerance).
#[test]
fn mean_dilatation_patch_test() {
    for with_field in [false, true] {
        let mut rng = Rng::new(11);
        let h = 1e-3;
        let mut mesh = box_mesh([3.0 * h, 3.0 * h, 3.0 * h], [3, 3, 3], ElementKind::Hex8);
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
        let mat = ElectroNeoHooke::new(1e5, 5e8, 4.7);
        let mut model = Model::new(mesh, Arc::new(mat)).unwrap();
        model.formulation = Formulation::MeanDilatation;
        let grad = [[0.05, 0.02, -0.01], [0.01, -0.03, 0.02], [0.00, 0.04, 0.06]];
        let e_field = if with_field {
            [2e6, -1e6, 5e6]
        } else {
            [0.0; 3]
        };
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
        eprintln!("mean-dilatation patch, field={with_field}: worst deviation {worst:.2e}");
        assert!(worst < 1e-9, "{worst:e}");
    }
}

/// Vertical displacement (mm) of the corner (48, 60) mm after ramping the traction in 5 steps
/// (`deasim::cli::validate::cook::tip`; Newton converges in ≤ 5 iterations per step at ν = 0.3;
/// the ramp cuts back by itself when a step is too large at ν = 0.4999).
fn cook_tip(n: usize, nu: f64, formulation: Formulation, thickness: Thickness) -> f64 {
    tip(n, nu, formulation, thickness).unwrap_or_else(|e| panic!("{e}"))
}

/// Richardson extrapolation of three values on meshes refined by 2, with the observed order.
fn richardson(coarse: f64, mid: f64, fine: f64) -> (f64, f64) {
    let p = ((mid - coarse) / (fine - mid)).log2();
    (fine + (fine - mid) / (2f64.powf(p) - 1.0), p)
}

/// ν = 0.3, standard hex8, the gallery's boundary conditions (u_z free): its Q1 table within 0.1 %
/// at n = 1 … 32, monotone convergence towards the Q2 value 14.33 mm.
///
/// Why 0.1 % (tighter than the 1.5 % first asked for): this is the same trilinear element, fully
/// integrated (2×2×2 Gauss points), on the same mapped mesh with the same energy and load, so the
/// discrete solutions coincide and the only difference is the table's rounding to 0.01 mm
/// (≤ 0.06 % at n ≥ 2; 0.1 % at n = 1). Measured: 5.154, 8.724, 12.024, 13.608, 14.129, 14.278 mm.
/// The mean-dilatation element converges to the same Q2 value from closer (n = 32: within 0.2 %).
#[test]
fn cook_membrane_reproduces_gallery_table() {
    let t0 = Instant::now();
    let mut last = 0.0;
    for (n, expected) in GALLERY_Q1 {
        let tip = cook_tip(n, 0.3, Formulation::Standard, Thickness::Free);
        let err = (tip - expected) / expected;
        eprintln!(
            "ν = 0.3, u_z free, standard, n = {n:2}: {tip:.3} mm (gallery {expected}, {:+.3} %)",
            100.0 * err
        );
        assert!(err.abs() < 1e-3, "n = {n}: {tip} vs {expected}");
        assert!(
            tip > last && tip < GALLERY_Q2,
            "monotone convergence from below"
        );
        last = tip;
    }
    let mut last_md = 0.0;
    for n in [2, 4, 8, 16, 32] {
        let tip = cook_tip(n, 0.3, Formulation::MeanDilatation, Thickness::Free);
        eprintln!("ν = 0.3, u_z free, mean-dilatation, n = {n:2}: {tip:.3} mm");
        assert!(tip > last_md && tip < GALLERY_Q2);
        last_md = tip;
    }
    assert!((GALLERY_Q2 - last_md) / GALLERY_Q2 < 0.002, "{last_md}");
    eprintln!("gallery table: {:.1} s", t0.elapsed().as_secs_f64());
}

/// ν = 0.3 in plane strain (u_z = 0): both formulations converge monotonically from below, to the
/// same limit (their n = 32 values and their Richardson extrapolations agree within 0.5 %), which
/// lies ≈ 4 % below the gallery's free-thickness value (a plane-strain plate is stiffer).
#[test]
fn cook_membrane_plane_strain_compressible() {
    let t0 = Instant::now();
    let mut limits = Vec::new();
    for formulation in [Formulation::Standard, Formulation::MeanDilatation] {
        let tips: Vec<f64> = [4, 8, 16, 32]
            .iter()
            .map(|&n| {
                let tip = cook_tip(n, 0.3, formulation, Thickness::PlaneStrain);
                eprintln!("ν = 0.3, plane strain, {formulation:?}, n = {n:2}: {tip:.3} mm");
                tip
            })
            .collect();
        for w in tips.windows(2) {
            assert!(w[1] > w[0], "{tips:?}");
        }
        let (limit, p) = richardson(tips[1], tips[2], tips[3]);
        eprintln!("  Richardson (8, 16, 32): {limit:.3} mm, observed order {p:.2}");
        limits.push((tips[3], limit));
    }
    let (std32, std_lim) = limits[0];
    let (md32, md_lim) = limits[1];
    assert!((std32 - md32).abs() / md32 < 0.005);
    assert!((std_lim - md_lim).abs() / md_lim < 0.005);
    assert!(md_lim < 0.98 * GALLERY_Q2 && md_lim > 0.94 * GALLERY_Q2);
    eprintln!("plane strain ν = 0.3: {:.1} s", t0.elapsed().as_secs_f64());
}

/// ν = 0.4999 (κ/μ ≈ 5000) in plane strain: the standard hex8 locks — at n = 8 its tip deflection
/// is below half of the converged value (measured 4.20 mm, 37 %) — while the mean-dilatation
/// element converges under refinement (n = 4, 8, 16, 32) with shrinking differences to the
/// reference: the same element on a much finer mesh, n = 64 (a finer mesh, not an independent
/// method; the constant is checked by the ignored test below). n = 32 is within 1 % of it, and so
/// is the Richardson extrapolation of n = 8, 16, 32.
#[test]
fn cook_membrane_nearly_incompressible_locking_and_mean_dilatation() {
    let nu = 0.4999;
    let t0 = Instant::now();
    let reference = MD_4999_N64;
    for n in [4, 8, 16] {
        let tip = cook_tip(n, nu, Formulation::Standard, Thickness::PlaneStrain);
        eprintln!(
            "ν = {nu}, plane strain, standard, n = {n:2}: {tip:.3} mm ({:.0} % of the reference)",
            100.0 * tip / reference
        );
        if n == 8 {
            assert!(tip < 0.5 * reference, "plain hex8 should lock: {tip}");
        }
    }
    let mut tips = Vec::new();
    for n in [4, 8, 16, 32] {
        let tip = cook_tip(n, nu, Formulation::MeanDilatation, Thickness::PlaneStrain);
        eprintln!(
            "ν = {nu}, plane strain, mean-dilatation, n = {n:2}: {tip:.3} mm ({:+.2} % of the reference)",
            100.0 * (tip - reference) / reference
        );
        tips.push(tip);
    }
    for w in tips.windows(3) {
        assert!(w[2] > w[1] && (w[2] - w[1]) < (w[1] - w[0]), "{tips:?}");
    }
    assert!((tips[3] - reference).abs() / reference < 0.01);
    let (limit, p) = richardson(tips[1], tips[2], tips[3]);
    eprintln!("  Richardson (8, 16, 32): {limit:.3} mm, observed order {p:.2}; reference n = 64: {reference}");
    assert!((limit - reference).abs() / reference < 0.01);
    eprintln!("ν = {nu}: {:.1} s", t0.elapsed().as_secs_f64());
}

/// The n = 64 reference of the nearly incompressible study (about 35 s in a release build).
#[test]
#[ignore]
fn cook_membrane_nearly_incompressible_fine_reference() {
    let tip = cook_tip(
        64,
        0.4999,
        Formulation::MeanDilatation,
        Thickness::PlaneStrain,
    );
    eprintln!("ν = 0.4999, plane strain, mean-dilatation, n = 64: {tip:.4} mm");
    assert!((tip - MD_4999_N64).abs() < 1e-3, "{tip}");
}
