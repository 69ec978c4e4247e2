//! The axisymmetric (meridian) cells and kernel: patch test, exact hoop stretch, invariance under
//! an axial translation, the cell tangent against finite differences, and the homogeneous film
//! (a disc with full electrodes) against the closed form of `deasim::analytic::Film`, with its
//! pull-in voltage.
//!
//! The film is solved by a small dense Newton over the assembled kernel (constrained dofs
//! eliminated), independent of the sparse 3-D machinery (`deasim::cli::validate::axisymmetric`,
//! shared with `deasim validate`).

use deasim::cli::validate::axisymmetric::{
    dense_newton, film_disc, film_material, meridian_mesh, set_voltage, try_assemble,
    MeridianMesh as Mesh,
};
use deasim::element::{AxisymmetricKernel, CellHistory, CellInput, CellKernel};
use deasim::fem::axisymmetric::MeridianKind;
use deasim::material::{ElectroNeoHooke, Material};
use deasim::problem::examples::{film_closed_form, FILM_SIZE};
use nalgebra::{DMatrix, DVector};

fn material() -> ElectroNeoHooke {
    film_material()
}

/// A meridian mesh (`validate::axisymmetric::meridian_mesh`), which must be valid.
fn mesh(kind: MeridianKind, r1: f64, r2: f64, h: f64, nr: usize, nz: usize, perturb: f64) -> Mesh {
    meridian_mesh(kind, r1, r2, h, nr, nz, perturb).expect("valid cells")
}

fn assemble(m: &Mesh, mat: &dyn Material, x: &[f64]) -> (f64, DVector<f64>, DMatrix<f64>) {
    try_assemble(m, mat, x).expect("admissible state")
}

/// The homogeneous state u_r = (λ − 1)R, u_z = (t − 1)Z, Φ = e·Z + φ₀.
fn homogeneous(m: &Mesh, lambda: f64, t: f64, e: f64, phi0: f64) -> Vec<f64> {
    m.nodes
        .iter()
        .flat_map(|p| {
            [
                (lambda - 1.0) * p[0],
                (t - 1.0) * p[1],
                0.0,
                e * p[1] + phi0,
            ]
        })
        .collect()
}

/// Patch test: a homogeneous state with equal radial and hoop stretch, any axial stretch and a
/// potential linear in Z has a homogeneous, divergence-free stress (P_RR = P_ΘΘ), so every
/// unknown of an interior node has zero residual and the energy is Ψ times the ring volume, on
/// distorted meshes of every kind. The quadrature integrates these terms exactly (bilinear or
/// affine maps; see the rule of each kind), so the bound is rounding: 1e-9 of the nodal force
/// scale |P|·(cell volume)/(cell size), and 1e-12 relative for the energy.
#[test]
fn patch_test_homogeneous_state_is_exact_for_every_kind() {
    let mat = material();
    let (lambda, t, e) = (1.13, 0.84, 2.0e7);
    let (f, e0) = (
        deasim::material::Mat3::from_diagonal(&nalgebra::Vector3::new(lambda, t, lambda)),
        nalgebra::Vector3::new(0.0, -e, 0.0),
    );
    let s = mat
        .stress_at(&f, &e0, deasim::material::PointHistory::NONE)
        .unwrap();
    for kind in MeridianKind::ALL {
        for r1 in [0.0, 2e-3] {
            let (r2, h) = (10e-3, 1e-3);
            let m = mesh(kind, r1, r2, h, 3, 2, 0.15);
            let x = homogeneous(&m, lambda, t, -e, 5.0);
            let (energy, r, _) = assemble(&m, &mat, &x);
            let vol = std::f64::consts::PI * (r2 * r2 - r1 * r1) * h;
            assert!(
                (energy - s.energy * vol).abs() < 1e-12 * (s.energy * vol).abs(),
                "{kind:?}: energy {energy} vs {}",
                s.energy * vol
            );
            let scale = s.p.norm() * vol / 6.0 / (h / 2.0);
            let dscale = s.d0.norm() * vol / 6.0 / (h / 2.0);
            let mut worst: f64 = 0.0;
            for (a, p) in m.nodes.iter().enumerate() {
                let interior =
                    p[1] > 1e-12 && p[1] < h - 1e-12 && p[0] > r1 + 1e-12 && p[0] < r2 - 1e-12;
                if interior {
                    worst = worst.max(r[4 * a].abs() / scale);
                    worst = worst.max(r[4 * a + 1].abs() / scale);
                    worst = worst.max(r[4 * a + 3].abs() / dscale);
                }
                assert_eq!(r[4 * a + 2], 0.0, "slot 2 has no residual");
            }
            eprintln!("{kind:?}, R₁ = {r1}: interior residual / force scale = {worst:.2e}");
            assert!(worst < 1e-9, "{kind:?}: {worst:e}");
        }
    }
}

/// u_r = c·R gives the hoop stretch 1 + c exactly at every quadrature point, and an axial rigid
/// translation changes neither F, E₀ nor the energy (to rounding, 1e-14 relative).
#[test]
fn hoop_stretch_is_exact_and_axial_translation_changes_nothing() {
    let mat = material();
    for kind in MeridianKind::ALL {
        let m = mesh(kind, 0.0, 5e-3, 1e-3, 2, 2, 0.1);
        let c = 0.07;
        let mut x = homogeneous(&m, 1.0 + c, 1.0, 1e6, 0.0);
        // a non-homogeneous state on top of it
        for (a, p) in m.nodes.iter().enumerate() {
            x[4 * a + 1] += 1e-5 * (p[0] * 300.0).sin();
        }
        for g in &m.geom {
            let nl = 4 * g.n_nodes;
            let cell = &m.cells[m.geom.iter().position(|h| std::ptr::eq(h, g)).unwrap()];
            let local: Vec<f64> = cell
                .iter()
                .flat_map(|&a| x[4 * a..4 * a + 4].to_vec())
                .collect();
            let mut shifted = local.clone();
            for a in 0..g.n_nodes {
                shifted[4 * a + 1] += 3e-4;
            }
            let mut out = vec![Default::default(); g.n_qp];
            let mut out2 = vec![Default::default(); g.n_qp];
            let input = |l| CellInput {
                geom: g,
                mat: &mat,
                hist: CellHistory::NONE,
                local: l,
            };
            AxisymmetricKernel
                .point_deformations(&input(&local), &mut out)
                .unwrap();
            AxisymmetricKernel
                .point_deformations(&input(&shifted), &mut out2)
                .unwrap();
            for ((f, e0), (f2, e02)) in out.iter().zip(&out2) {
                let f: &deasim::material::Mat3 = f;
                assert!(
                    (f[(2, 2)] - (1.0 + c)).abs() < 1e-14,
                    "{kind:?}: {}",
                    f[(2, 2)]
                );
                assert!((f - f2).norm() < 1e-14 && (e0 - e02).norm() < 1e-14 * e0.norm());
            }
            let e1 = AxisymmetricKernel.energy(&input(&local)).unwrap();
            let e2 = AxisymmetricKernel.energy(&input(&shifted)).unwrap();
            assert!((e1 - e2).abs() <= 1e-14 * e1.abs(), "{kind:?}");
            let _ = nl;
        }
    }
}

/// The full coupled cell tangent against central differences of the residual, and the residual
/// against central differences of the energy, on a distorted cell of each kind at a
/// non-homogeneous state. Steps 1e-7 of the displacement scale and 1e-7 of the potential scale;
/// the truncation error O(h²) and rounding (1e-16/h of the entries) both stay below 1e-6
/// relative to the largest entry.
#[test]
fn cell_tangent_and_residual_match_finite_differences() {
    let mat = material();
    for kind in MeridianKind::ALL {
        let m = mesh(kind, 1e-3, 4e-3, 2e-3, 2, 1, 0.2);
        let g = &m.geom[1];
        let cell = &m.cells[1];
        let n = g.n_nodes;
        let nl = 4 * n;
        let mut local = vec![0.0; nl];
        for (la, &a) in cell.iter().enumerate() {
            let p = m.nodes[a];
            local[4 * la] = 0.05 * p[0] + 1e-5 * (p[1] * 900.0).cos();
            local[4 * la + 1] = -0.1 * p[1] + 2e-5 * (p[0] * 700.0).sin();
            local[4 * la + 3] = 3e4 * p[1] / 2e-3 + 2e3 * (p[0] * 500.0).sin();
        }
        let eval = |l: &[f64]| {
            let mut r = vec![0.0; nl];
            let mut k = vec![0.0; nl * nl];
            let input = CellInput {
                geom: g,
                mat: &mat,
                hist: CellHistory::NONE,
                local: l,
            };
            let e = AxisymmetricKernel
                .residual_tangent(&input, &mut r, Some(&mut k))
                .unwrap();
            (e, r, k)
        };
        let (_, r0, k0) = eval(&local);
        let kmax = k0.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let rmax = r0.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let mut worst_k: f64 = 0.0;
        let mut worst_r: f64 = 0.0;
        for j in 0..nl {
            if j % 4 == 2 {
                continue;
            }
            let h = if j % 4 == 3 { 1e-7 * 3e4 } else { 1e-7 * 4e-3 };
            let (mut p, mut q) = (local.clone(), local.clone());
            p[j] += h;
            q[j] -= h;
            let (ep, rp, _) = eval(&p);
            let (eq, rq, _) = eval(&q);
            for i in 0..nl {
                let fd = (rp[i] - rq[i]) / (2.0 * h);
                // scale the Φ rows/columns to comparable magnitudes
                worst_k = worst_k.max((fd - k0[i * nl + j]).abs() / kmax.max(1e-300));
            }
            worst_r = worst_r.max(((ep - eq) / (2.0 * h) - r0[j]).abs() / rmax);
        }
        // symmetry
        let mut asym: f64 = 0.0;
        for i in 0..nl {
            for j in 0..nl {
                asym = asym.max((k0[i * nl + j] - k0[j * nl + i]).abs() / kmax);
            }
        }
        eprintln!("{kind:?}: tangent FD error {worst_k:.2e}, residual FD error {worst_r:.2e}, asymmetry {asym:.1e}");
        assert!(worst_k < 1e-6, "{kind:?}: tangent {worst_k:e}");
        assert!(worst_r < 1e-6, "{kind:?}: residual {worst_r:e}");
        assert!(asym < 1e-12, "{kind:?}: asymmetry {asym:e}");
    }
}

/// The disc of radius 10 mm and thickness 1 mm (the 3-D film's thickness) with full electrodes
/// (`validate::axisymmetric::film_disc`): the homogeneous closed form at every step of a 15-step
/// ramp to 30 kV, for every kind, to 1e-10 in the stretches (Newton converged to 1e-13 of the
/// first residual; the closed form is solved to rounding).
fn film_setup(kind: MeridianKind) -> (Mesh, Vec<bool>) {
    film_disc(kind).expect("valid disc")
}

#[test]
fn film_disc_matches_the_closed_form_for_every_kind() {
    let mat = material();
    let reference = film_closed_form();
    let h = FILM_SIZE[2];
    for kind in MeridianKind::ALL {
        let (m, fixed) = film_setup(kind);
        let mut x = vec![0.0; 4 * m.nodes.len()];
        let mut worst: f64 = 0.0;
        let started = std::time::Instant::now();
        for step in 1..=15 {
            let v = 30e3 * step as f64 / 15.0;
            set_voltage(&m, &mut x, v);
            assert!(
                dense_newton(&m, &mat, &mut x, &fixed),
                "{kind:?}: step {step}"
            );
            let s = reference.state(v / h).expect("below pull-in");
            for (a, p) in m.nodes.iter().enumerate() {
                if p[0] > 0.0 {
                    worst = worst.max((x[4 * a] / p[0] + 1.0 - s.lambda).abs());
                }
                if p[1] > 0.0 {
                    worst = worst.max((x[4 * a + 1] / p[1] + 1.0 - s.t).abs());
                }
                let phi = v * p[1] / h;
                assert!(
                    (x[4 * a + 3] - phi).abs() <= 1e-9 * v,
                    "{kind:?}: Φ at node {a}"
                );
            }
        }
        eprintln!(
            "{kind:?}: max |Δλ|, |Δt| over 15 steps = {worst:.2e} ({:.2} s)",
            started.elapsed().as_secs_f64()
        );
        assert!(worst < 1e-10, "{kind:?}: {worst:e}");
    }
}

/// Pull-in: the disc has an equilibrium at 0.999 of the closed-form critical voltage (reached by
/// a ramp) and none at 1.001 of it (Newton from the last state does not converge: the
/// homogeneous branch has no state there and the disc, with the homogeneous solution unique on
/// this branch, follows it).
#[test]
fn film_disc_pulls_in_at_the_closed_form_voltage() {
    let mat = material();
    let h = FILM_SIZE[2];
    let (e_c, s_c) = film_closed_form().pull_in();
    let v_c = e_c * h;
    for kind in [MeridianKind::Quad4, MeridianKind::Tri6] {
        let (m, fixed) = film_setup(kind);
        let mut x = vec![0.0; 4 * m.nodes.len()];
        for step in 1..=20 {
            let v = 0.999 * v_c * step as f64 / 20.0;
            set_voltage(&m, &mut x, v);
            assert!(dense_newton(&m, &mat, &mut x, &fixed), "{kind:?}: {v} V");
        }
        let a = m.nodes.iter().position(|p| p[0] > 0.0).unwrap();
        let lambda = 1.0 + x[4 * a] / m.nodes[a][0];
        eprintln!(
            "{kind:?}: at 0.999 V_c = {:.1} V, λ = {lambda:.4} (λ_c = {:.4})",
            0.999 * v_c,
            s_c.lambda
        );
        let mut beyond = x.clone();
        set_voltage(&m, &mut beyond, 1.001 * v_c);
        assert!(
            !dense_newton(&m, &mat, &mut beyond, &fixed),
            "{kind:?}: an equilibrium beyond pull-in"
        );
    }
}
