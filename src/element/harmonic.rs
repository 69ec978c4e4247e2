//! Circumferential harmonics of a meridian cell: the second variation of the energy of the
//! revolved body, Π = ∫ Ψ(F, E₀) dV, about an axisymmetric state (u_r, u_z, Φ)(R, Z), along
//! perturbations of circumferential harmonic n ≥ 0,
//!
//! ```text
//! δu_r = a(R, Z) cos nΘ,  δu_z = b(R, Z) cos nΘ,  δu_θ = c(R, Z) sin nΘ,  δΦ = p(R, Z) cos nΘ,
//! ```
//!
//! with (a, b, c, p) interpolated from the nodal slots (u_r, u_z, u_θ, Φ) = (0, 1, 2, 3). In the
//! cylindrical bases (e_r, e_z, e_θ) of the current and (e_R, e_Z, e_Θ) of the reference
//! configuration, F = I + Grad u has the columns ∂u/∂R, ∂u/∂Z and
//! ((∂u_r/∂Θ − u_θ)/R, (∂u_z/∂Θ)/R, (∂u_θ/∂Θ + u_r)/R), and E₀ = −(∂Φ/∂R, ∂Φ/∂Z, (∂Φ/∂Θ)/R). So
//! δF = cos nΘ δF_c + sin nΘ δF_s with
//!
//! ```text
//! δF_c: rR = a,R  rZ = a,Z  zR = b,R  zZ = b,Z  θΘ = (a + n c)/R        δE_c = −(p,R, p,Z, 0)
//! δF_s: rΘ = −(n a + c)/R  zΘ = −n b/R  θR = c,R  θZ = c,Z               δE_s = (0, 0, n p/R)
//! ```
//!
//! and the second variation is the material's tangent (A, B, G at the axisymmetric state, the
//! same blocks as the 3-D kernel) contracted with these and integrated over Θ:
//! ∫ cos² = ∫ sin² = π and ∫ cos sin = 0 for n ≥ 1, so
//! K_n(x, y) = ½ Σ_q w_q [H_q(δ_c x, δ_c y) + H_q(δ_s x, δ_s y)] with the ring weights w_q (which
//! carry 2π). For n = 0 the hoop displacement is the torsion u_θ = c (no sin factor) and the
//! whole field is independent of Θ: K_0(x, y) = Σ_q w_q H_q(δ_c x + δ_s x, δ_c y + δ_s y), which
//! is the axisymmetric tangent on (u_r, u_z, Φ) and adds the torsional block of u_θ. The mass
//! carries the same factor (½ for n ≥ 1), so K_n φ = ω² M_n φ gives the frequencies of the 3-D
//! body for its modes of harmonic n (Zienkiewicz & Taylor, The Finite Element Method, vol. 1,
//! axisymmetric solids under non-symmetric loads, Fourier expansion).
//!
//! The mean-dilatation kernel's θ̄ becomes the cell's mean dilatation at each angle,
//! θ̄(Θ) = Σ_q w_q J_q(Θ) / Σ_q w_q: its couplings (linear forms of δF) are expanded likewise.

use super::{CellHistory, PointFailure};
use crate::element::mean_dilatation::{md_hessian, Formulation};
use crate::fem::axisymmetric::meridian_kinematics;
use crate::fem::{CellGeometry, FIELDS, MAX_NODES};
use crate::material::{Mat3, Mat9, Mat93, Material};

/// The cos and sin parts (δF row-major, δE₀) of one unknown at one point.
#[derive(Clone, Copy, Default)]
struct Part {
    f: [f64; 9],
    e: [f64; 3],
}

/// The parts [cos, sin] of unknown (node `b`, slot `k`) at point q for harmonic n (module docs);
/// for n = 0 the two are merged into the first (the field does not depend on Θ).
fn parts(geom: &CellGeometry, q: usize, b: usize, k: usize, n: u32) -> [Part; 2] {
    let g = geom.grad[q][b];
    let h = geom.hoop(q)[b];
    let nf = f64::from(n);
    let (mut c, mut s) = (Part::default(), Part::default());
    match k {
        0 => {
            c.f[0] = g[0];
            c.f[1] = g[1];
            c.f[8] = h;
            s.f[2] = -nf * h;
        }
        1 => {
            c.f[3] = g[0];
            c.f[4] = g[1];
            s.f[5] = -nf * h;
        }
        2 => {
            s.f[6] = g[0];
            s.f[7] = g[1];
            s.f[2] = -h;
            c.f[8] = nf * h;
        }
        _ => {
            c.e[0] = -g[0];
            c.e[1] = -g[1];
            s.e[2] = nf * h;
        }
    }
    if n == 0 {
        for i in 0..9 {
            c.f[i] += s.f[i];
        }
        for i in 0..3 {
            c.e[i] += s.e[i];
        }
        s = Part::default();
    }
    [c, s]
}

/// The Θ-integral factor of a product of two harmonic fields over 2π (the ring weights carry
/// 2π): 1 for n = 0, ½ for n ≥ 1.
pub fn harmonic_factor(n: u32) -> f64 {
    if n == 0 {
        1.0
    } else {
        0.5
    }
}

/// The harmonic tangent K_n of a meridian cell (module docs) at the axisymmetric state `local`
/// (four values per node, slot 2 not read), written into `k` (row-major 4n × 4n, node-major
/// unknowns (u_r, u_z, u_θ, Φ)), for the cell kinematics of `formulation`.
pub fn harmonic_tangent(
    formulation: Formulation,
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    n: u32,
    k: &mut [f64],
) -> Result<(), PointFailure> {
    debug_assert!(geom.axisymmetric);
    let nn = geom.n_nodes;
    let nl = nn * FIELDS;
    k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    let mut axi = vec![0.0; nl];
    for a in 0..nn {
        axi[a * FIELDS] = local[a * FIELDS];
        axi[a * FIELDS + 1] = local[a * FIELDS + 1];
        axi[a * FIELDS + 3] = local[a * FIELDS + 3];
    }
    let factor = harmonic_factor(n);
    match formulation {
        Formulation::Standard => {
            let mut points = Vec::with_capacity(geom.n_qp);
            for q in 0..geom.n_qp {
                let mut u = [[0.0; 3]; MAX_NODES];
                let mut phi = [0.0; MAX_NODES];
                for a in 0..nn {
                    u[a] = [axi[a * 4], axi[a * 4 + 1], 0.0];
                    phi[a] = axi[a * 4 + 3];
                }
                let (f, e0) = meridian_kinematics(
                    &geom.grad[q][..nn],
                    &geom.hoop(q)[..nn],
                    &u[..nn],
                    &phi[..nn],
                );
                let t = mat
                    .tangent_at(&f, &e0, hist.at(q))
                    .map_err(|error| PointFailure { qp: q, error })?;
                points.push((geom.weights[q], t.a, t.b, t.g));
            }
            add_points(geom, n, factor, &points, k);
        }
        Formulation::MeanDilatation => {
            let h = md_hessian(geom, mat, hist, &axi)?;
            add_points(geom, n, factor, &h.points, k);
            // the couplings through θ̄(Θ): linear forms of each unknown's parts
            let mut forms = vec![[[0.0; 3]; 2]; nl];
            for (x, form) in forms.iter_mut().enumerate() {
                for q in 0..geom.n_qp {
                    let w = geom.weights[q];
                    for (p, part) in parts(geom, q, x / FIELDS, x % FIELDS, n).iter().enumerate() {
                        for i in 0..9 {
                            form[p][0] += h.m[q][i] * part.f[i];
                            form[p][1] += w * h.b[q][i] * part.f[i];
                        }
                        for i in 0..3 {
                            form[p][2] += w * h.e[q][i] * part.e[i];
                        }
                    }
                }
            }
            for x in 0..nl {
                for y in 0..nl {
                    let mut v = 0.0;
                    for p in 0..2 {
                        let ([mx, bx, ex], [my, by, ey]) = (forms[x][p], forms[y][p]);
                        v += bx * my + mx * by + h.d * mx * my + mx * ey + ex * my;
                    }
                    k[x * nl + y] += factor * v;
                }
            }
        }
    }
    Ok(())
}

/// Adds the per-point part Σ_q w_q factor [H_q(δ_c x, δ_c y) + H_q(δ_s x, δ_s y)] to `k`, with
/// H_q(x, y) = δF_x:A:δF_y + δF_x:B:δE_y + δF_y:B:δE_x + δE_x·G·δE_y.
fn add_points(
    geom: &CellGeometry,
    n: u32,
    factor: f64,
    points: &[(f64, Mat9, Mat93, Mat3)],
    k: &mut [f64],
) {
    let nl = geom.n_nodes * FIELDS;
    let mut pts = vec![[Part::default(); 2]; nl];
    let mut hx = vec![[([0.0; 9], [0.0; 3]); 2]; nl];
    for (q, (w, a, b, g)) in points.iter().enumerate() {
        for x in 0..nl {
            pts[x] = parts(geom, q, x / FIELDS, x % FIELDS, n);
            for p in 0..2 {
                let part = &pts[x][p];
                let (mut hf, mut he) = ([0.0; 9], [0.0; 3]);
                for r in 0..9 {
                    let mut s = 0.0;
                    for c in 0..9 {
                        s += a[(r, c)] * part.f[c];
                    }
                    for c in 0..3 {
                        s += b[(r, c)] * part.e[c];
                    }
                    hf[r] = s;
                }
                for r in 0..3 {
                    let mut s = 0.0;
                    for c in 0..9 {
                        s += b[(c, r)] * part.f[c];
                    }
                    for c in 0..3 {
                        s += g[(r, c)] * part.e[c];
                    }
                    he[r] = s;
                }
                hx[x][p] = (hf, he);
            }
        }
        let wf = w * factor;
        for x in 0..nl {
            for y in 0..nl {
                let mut v = 0.0;
                for p in 0..2 {
                    let (hf, he) = &hx[x][p];
                    let py = &pts[y][p];
                    for i in 0..9 {
                        v += hf[i] * py.f[i];
                    }
                    for i in 0..3 {
                        v += he[i] * py.e[i];
                    }
                }
                k[x * nl + y] += wf * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::CellInput;
    use crate::fem::axisymmetric::{
        meridian_geometry, meridian_quadrature, meridian_shape_functions, MeridianKind,
    };
    use crate::material::{ElectroNeoHooke, Vec3, EPSILON_0};

    fn material() -> ElectroNeoHooke {
        ElectroNeoHooke::new(1e5, 2e6, 4.7)
    }

    /// A distorted cell of `kind` starting at R = `r0` (m), and a deformed axisymmetric state
    /// on it (u_r = 0 on the axis, slot 2 zero).
    fn cell(kind: MeridianKind, r0: f64) -> (Vec<[f64; 2]>, CellGeometry, Vec<f64>) {
        let x: Vec<[f64; 2]> = kind
            .reference_nodes()
            .iter()
            .map(|p| {
                let (s, t) = match kind {
                    MeridianKind::Tri3 | MeridianKind::Tri6 => (p[0], p[1]),
                    _ => (0.5 * (p[0] + 1.0), 0.5 * (p[1] + 1.0)),
                };
                [r0 + 1e-3 * s * (1.0 + 0.1 * t), 1e-3 * (t + 0.05 * s)]
            })
            .collect();
        let g = meridian_geometry(kind, &x).unwrap();
        let e_scale = (1e5f64 / (4.7 * EPSILON_0)).sqrt();
        let local = (0..4 * x.len())
            .map(|i| {
                let r = ((i as f64 * 12.9898).sin() * 43758.5453).fract();
                match i % 4 {
                    3 => 0.3 * e_scale * 1e-3 * r,
                    2 => 0.0,
                    0 if x[i / 4][0] == 0.0 => 0.0,
                    _ => 0.1 * 1e-3 * r,
                }
            })
            .collect();
        (x, g, local)
    }

    /// The total energy ∫ Ψ dV of the revolved body with the nodal fields of `local` plus the
    /// harmonic-n perturbation `dx` (module docs), from the Cartesian placement x(ξ, η, Θ) and
    /// potential: F = ∂x/∂(ξ, η, Θ) · (∂X/∂(ξ, η, Θ))⁻¹ and E₀ = −∇Φ by central differences in
    /// (ξ, η, Θ), independent of the cylindrical formulas of the kernel; Θ by the trapezoidal
    /// rule on 32 angles (exact for the quadratic terms of harmonics up to 15). The mean
    /// dilatation takes θ̄ at each angle.
    fn revolved_energy(
        kind: MeridianKind,
        x: &[[f64; 2]],
        geom: &CellGeometry,
        formulation: Formulation,
        local: &[f64],
        dx: &[f64],
        n: u32,
    ) -> f64 {
        let mat = material();
        let nn = x.len();
        let m_angles = 32;
        let nf = f64::from(n);
        let place = |xi: [f64; 2], th: f64| -> ([f64; 3], [f64; 3], f64) {
            let (sh, _) = meridian_shape_functions(kind, xi);
            let (c, s) = if n == 0 {
                (1.0, 1.0)
            } else {
                ((nf * th).cos(), (nf * th).sin())
            };
            let (mut r, mut z, mut ur, mut uz, mut ut, mut phi) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for a in 0..nn {
                r += sh[a] * x[a][0];
                z += sh[a] * x[a][1];
                ur += sh[a] * (local[a * 4] + dx[a * 4] * c);
                uz += sh[a] * (local[a * 4 + 1] + dx[a * 4 + 1] * c);
                ut += sh[a] * dx[a * 4 + 2] * s;
                phi += sh[a] * (local[a * 4 + 3] + dx[a * 4 + 3] * c);
            }
            let (er, et) = ([th.cos(), th.sin(), 0.0], [-th.sin(), th.cos(), 0.0]);
            let big = [r * er[0], r * er[1], z];
            let small = [
                big[0] + ur * er[0] + ut * et[0],
                big[1] + ur * er[1] + ut * et[1],
                big[2] + uz,
            ];
            (big, small, phi)
        };
        let hd = 1e-5;
        let mut total = 0.0;
        for m in 0..m_angles {
            let th = 2.0 * std::f64::consts::PI * m as f64 / m_angles as f64;
            let mut pts = Vec::new();
            for (q, (xi, _)) in meridian_quadrature(kind).iter().enumerate() {
                let mut jx = Mat3::zeros();
                let mut jsmall = Mat3::zeros();
                let mut dphi = Vec3::zeros();
                for d in 0..3 {
                    let shift = |sgn: f64| {
                        let mut p = *xi;
                        let mut t = th;
                        if d < 2 {
                            p[d] += sgn * hd;
                        } else {
                            t += sgn * hd;
                        }
                        place(p, t)
                    };
                    let (bp, sp, pp) = shift(1.0);
                    let (bm, sm, pm) = shift(-1.0);
                    for i in 0..3 {
                        jx[(i, d)] = (bp[i] - bm[i]) / (2.0 * hd);
                        jsmall[(i, d)] = (sp[i] - sm[i]) / (2.0 * hd);
                    }
                    dphi[d] = (pp - pm) / (2.0 * hd);
                }
                let jinv = jx.try_inverse().unwrap();
                let f = jsmall * jinv;
                let e0 = -(jinv.transpose() * dphi);
                pts.push((geom.weights[q], f, e0));
            }
            let theta_bar = pts.iter().map(|(w, f, _)| w * f.determinant()).sum::<f64>()
                / pts.iter().map(|(w, _, _)| w).sum::<f64>();
            for (w, f, e0) in pts {
                let f = match formulation {
                    Formulation::Standard => f,
                    Formulation::MeanDilatation => f * (theta_bar / f.determinant()).cbrt(),
                };
                total += w * mat.energy(&f, &e0).unwrap() / m_angles as f64;
            }
        }
        total
    }

    /// Harmonic 0 is the cell's axisymmetric tangent on (u_r, u_z, Φ), standard and
    /// mean-dilatation, with a torsional block of u_θ decoupled from them.
    #[test]
    fn harmonic_zero_is_the_axisymmetric_tangent_plus_torsion() {
        let mat = material();
        for (formulation, kind) in [
            (Formulation::Standard, MeridianKind::Quad8),
            (Formulation::Standard, MeridianKind::Tri6),
            (Formulation::MeanDilatation, MeridianKind::Quad4),
            (Formulation::MeanDilatation, MeridianKind::Quad9),
        ] {
            for r0 in [0.0, 0.7e-3] {
                let (x, g, local) = cell(kind, r0);
                let nl = 4 * x.len();
                let mut r = vec![0.0; nl];
                let mut k_axi = vec![0.0; nl * nl];
                formulation
                    .kernel(true)
                    .residual_tangent(
                        &CellInput {
                            geom: &g,
                            mat: &mat,
                            hist: CellHistory::NONE,
                            local: &local,
                        },
                        &mut r,
                        Some(&mut k_axi),
                    )
                    .unwrap();
                let mut k0 = vec![0.0; nl * nl];
                harmonic_tangent(formulation, &g, &mat, CellHistory::NONE, &local, 0, &mut k0)
                    .unwrap();
                let scale = k0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let mut torsion = 0.0f64;
                for i in 0..nl {
                    for j in 0..nl {
                        let (a, b) = (k0[i * nl + j], k_axi[i * nl + j]);
                        if i % 4 != 2 && j % 4 != 2 {
                            assert!(
                                (a - b).abs() <= 1e-12 * scale,
                                "{formulation:?} {kind:?} K[{i}][{j}]: {a} vs {b}"
                            );
                        } else if (i % 4 == 2) != (j % 4 == 2) {
                            assert!(a.abs() <= 1e-12 * scale, "{kind:?} coupling {i} {j}: {a}");
                        } else {
                            torsion = torsion.max(a.abs());
                        }
                    }
                }
                assert!(torsion > 1e-3 * scale, "{kind:?}: no torsional stiffness");
            }
        }
    }

    /// K_n times a harmonic-n perturbation is the second directional derivative of the energy of
    /// the revolved 3-D body with that perturbation revolved (central differences of
    /// [`revolved_energy`] in two perturbations), for n = 0…3, both formulations, on cells off
    /// and on the axis; the tangent is symmetric.
    #[test]
    fn harmonic_tangent_matches_the_revolved_energy() {
        let mat = material();
        let e_scale = (1e5f64 / (4.7 * EPSILON_0)).sqrt();
        for (formulation, kind) in [
            (Formulation::Standard, MeridianKind::Quad4),
            (Formulation::Standard, MeridianKind::Tri6),
            (Formulation::MeanDilatation, MeridianKind::Quad4),
            (Formulation::MeanDilatation, MeridianKind::Quad9),
        ] {
            for r0 in [0.0, 0.7e-3] {
                let (x, g, local) = cell(kind, r0);
                let nl = 4 * x.len();
                for n in 0..4u32 {
                    let mut k = vec![0.0; nl * nl];
                    harmonic_tangent(formulation, &g, &mat, CellHistory::NONE, &local, n, &mut k)
                        .unwrap();
                    // regular on the axis (u_r = u_θ = 0 for n = 0; u_z = Φ = 0, u_θ = −u_r
                    // for n = 1; all 0 for n ≥ 2): bounded strains at the points near it
                    let pert = |seed: f64| -> Vec<f64> {
                        let mut p: Vec<f64> = (0..nl)
                            .map(|i| {
                                let r = ((i as f64 * 78.233 + seed).sin() * 43758.5453).fract();
                                if i % 4 == 3 {
                                    0.3 * e_scale * 1e-3 * r
                                } else {
                                    1e-4 * r
                                }
                            })
                            .collect();
                        for (a, xa) in x.iter().enumerate() {
                            if xa[0] == 0.0 {
                                let u = &mut p[a * 4..a * 4 + 4];
                                match n {
                                    0 => (u[0], u[2]) = (0.0, 0.0),
                                    1 => (u[1], u[2], u[3]) = (0.0, -u[0], 0.0),
                                    _ => u.fill(0.0),
                                }
                            }
                        }
                        p
                    };
                    for (sx, sy) in [(1.0, 2.0), (3.0, 3.0)] {
                        let (px, py) = (pert(sx), pert(sy));
                        let kxy: f64 = (0..nl)
                            .map(|i| (0..nl).map(|j| px[i] * k[i * nl + j] * py[j]).sum::<f64>())
                            .sum();
                        // perturbations of strain ~1e-3 (n/R grows near the axis)
                        let h = 1e-2 / f64::from(1 + n);
                        let e = |a: f64, b: f64| {
                            let d: Vec<f64> =
                                (0..nl).map(|i| h * (a * px[i] + b * py[i])).collect();
                            revolved_energy(kind, &x, &g, formulation, &local, &d, n)
                        };
                        let fd = (e(1.0, 1.0) - e(1.0, -1.0) - e(-1.0, 1.0) + e(-1.0, -1.0))
                            / (4.0 * h * h);
                        // relative to the size of the product's terms: a soft direction
                        // (near a rigid motion) has a small xᵀKx beside its higher-order terms
                        let size: f64 = (0..nl)
                            .map(|i| {
                                (0..nl)
                                    .map(|j| (px[i] * k[i * nl + j] * py[j]).abs())
                                    .sum::<f64>()
                            })
                            .sum();
                        assert!(
                            (fd - kxy).abs() <= 1e-4 * size,
                            "{formulation:?} {kind:?} R0 = {r0} n = {n}: FD {fd} vs K {kxy}"
                        );
                    }
                    let scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    for i in 0..nl {
                        for j in 0..nl {
                            assert!((k[i * nl + j] - k[j * nl + i]).abs() <= 1e-12 * scale);
                        }
                    }
                }
            }
        }
    }
}
