//! The axisymmetric (meridian) kernel: Π = ∫ Ψ(F, E₀) 2πR dR dZ with the kinematics of
//! `fem::axisymmetric` (hoop stretch 1 + u_r/R).
//!
//! Local dofs are node-major (u_r, u_z, ·, Φ); slot 2 is neither read nor given a residual (it is
//! held at zero). With the variation of F for the unknown (b, k), k ∈ {r, z}:
//! δF = e_k ⊗ ∇₀N_b (in-plane) plus, for k = r, (N_b/R) e_Θ ⊗ e_Θ, the residual is
//! r_{b,k} = ∫ P : δF dV, r_{b,Φ} = ∫ D₀·∇₀N_b dV, and the tangent their exact derivative
//! (Zienkiewicz & Taylor, vol. 1, axisymmetric analysis; Henann, Chester & Bertoldi, Soft Matter
//! 9 (2013) 6318, for the electro-elastic form).

use super::{CellFields, CellInput, CellKernel, PointFailure};
use crate::fem::axisymmetric::meridian_kinematics;
use crate::fem::{CellGeometry, FIELDS, MAX_NODES};
use crate::material::{Mat3, Mat9, Mat93, Vec3};

/// The axisymmetric kernel with full integration, for cells from
/// `fem::axisymmetric::meridian_geometry`.
#[derive(Debug, Clone, Copy)]
pub struct AxisymmetricKernel;

fn split(n: usize, local: &[f64]) -> ([[f64; 3]; MAX_NODES], [f64; MAX_NODES]) {
    let mut u = [[0.0; 3]; MAX_NODES];
    let mut phi = [0.0; MAX_NODES];
    for a in 0..n {
        u[a] = [local[a * 4], local[a * 4 + 1], 0.0];
        phi[a] = local[a * 4 + 3];
    }
    (u, phi)
}

fn point(geom: &CellGeometry, q: usize, local: &[f64]) -> (Mat3, Vec3) {
    let n = geom.n_nodes;
    let (u, phi) = split(n, local);
    meridian_kinematics(&geom.grad[q][..n], &geom.hoop(q)[..n], &u[..n], &phi[..n])
}

/// δF of unknown (b, k) at point q as three (row-major index of F, value) pairs: e_k ⊗ ∇₀N_b
/// in a 3-D cell; in a meridian cell the in-plane part plus, for k = 0, the hoop entry N_b/R,
/// and nothing for k = 2 (the held slot).
pub(crate) fn delta_f(geom: &CellGeometry, q: usize, b: usize, k: usize) -> [(usize, f64); 3] {
    let g = geom.grad[q][b];
    if !geom.axisymmetric {
        return [(k * 3, g[0]), (k * 3 + 1, g[1]), (k * 3 + 2, g[2])];
    }
    match k {
        0 => [(0, g[0]), (1, g[1]), (8, geom.hoop(q)[b])],
        1 => [(3, g[0]), (4, g[1]), (8, 0.0)],
        _ => [(0, 0.0), (1, 0.0), (8, 0.0)],
    }
}

/// Adds w·(P : δF, D₀ · ∇₀N) of one point of a meridian cell to the residual `r`.
pub(crate) fn add_residual_meridian(
    geom: &CellGeometry,
    q: usize,
    w: f64,
    p: &Mat3,
    d0: &Vec3,
    r: &mut [f64],
) {
    let g = &geom.grad[q];
    for a in 0..geom.n_nodes {
        for i in 0..2 {
            let s: f64 = delta_f(geom, q, a, i)
                .iter()
                .map(|&(m, v)| v * p[(m / 3, m % 3)])
                .sum();
            r[a * 4 + i] += w * s;
        }
        r[a * 4 + 3] += w * (d0[0] * g[a][0] + d0[1] * g[a][1]);
    }
}

/// Adds w·∂r/∂x of one point of a meridian cell to the local tangent `k` (leading dimension
/// 4n), given the point's blocks A = ∂P/∂F (9×9), B = ∂P/∂E₀ (9×3) and G = ∂D₀/∂E₀ (3×3); the
/// meridian counterpart of `element::add_point_tangent`.
pub(crate) fn add_point_tangent_meridian(
    geom: &CellGeometry,
    q: usize,
    w: f64,
    a_blk: &Mat9,
    b_blk: &Mat93,
    g_blk: &Mat3,
    k: &mut [f64],
) {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let g = &geom.grad[q];
    for a in 0..n {
        for i in 0..2 {
            let da = delta_f(geom, q, a, i);
            // δF_a : A and δF_a : B
            let mut ra = [0.0; 9];
            let mut rb = [0.0; 3];
            for &(m, v) in &da {
                for col in 0..9 {
                    ra[col] += v * a_blk[(m, col)];
                }
                for col in 0..3 {
                    rb[col] += v * b_blk[(m, col)];
                }
            }
            for b in 0..n {
                let row = (a * 4 + i) * nl + b * 4;
                for kk in 0..2 {
                    let s: f64 = delta_f(geom, q, b, kk)
                        .iter()
                        .map(|&(m, v)| v * ra[m])
                        .sum();
                    k[row + kk] += w * s;
                }
                // ∂E₀/∂Φ_b = −∇₀N_b
                k[row + 3] += -w * (rb[0] * g[b][0] + rb[1] * g[b][1]);
            }
        }
    }
    // the Φ rows, the transpose of the u–Φ block above and the Φ–Φ block
    add_point_potential_tangent_meridian(geom, q, w, b_blk, g_blk, k);
}

/// The Φ rows of [`add_point_tangent_meridian`]: alone, what the projection's adjoint needs.
pub(crate) fn add_point_potential_tangent_meridian(
    geom: &CellGeometry,
    q: usize,
    w: f64,
    b_blk: &Mat93,
    g_blk: &Mat3,
    k: &mut [f64],
) {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let g = &geom.grad[q];
    for a in 0..n {
        for i in 0..2 {
            let mut rb = [0.0; 3];
            for &(m, v) in &delta_f(geom, q, a, i) {
                for col in 0..3 {
                    rb[col] += v * b_blk[(m, col)];
                }
            }
            for b in 0..n {
                k[(b * 4 + 3) * nl + a * 4 + i] += -w * (rb[0] * g[b][0] + rb[1] * g[b][1]);
            }
        }
        for b in 0..n {
            let mut s = 0.0;
            for jj in 0..2 {
                for kk in 0..2 {
                    s += g[a][jj] * g_blk[(jj, kk)] * g[b][kk];
                }
            }
            k[(a * 4 + 3) * nl + b * 4 + 3] += w * s;
        }
    }
}

fn residual_tangent(
    c: &CellInput,
    r: &mut [f64],
    mut k: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    let geom = c.geom;
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    r[..nl].iter_mut().for_each(|v| *v = 0.0);
    if let Some(k) = k.as_deref_mut() {
        k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    }
    let mut energy = 0.0;
    for q in 0..geom.n_qp {
        let w = geom.weights[q];
        let (f, e0) = point(geom, q, c.local);
        let fail = |error| PointFailure { qp: q, error };
        let (p, d0, tan) = match k {
            None => {
                let s = c.mat.stress_at(&f, &e0, c.hist.at(q)).map_err(fail)?;
                energy += w * s.energy;
                (s.p, s.d0, None)
            }
            Some(_) => {
                let t = c.mat.tangent_at(&f, &e0, c.hist.at(q)).map_err(fail)?;
                energy += w * t.energy;
                (t.p, t.d0, Some(t))
            }
        };
        add_residual_meridian(geom, q, w, &p, &d0, r);
        let (Some(t), Some(k)) = (tan, k.as_deref_mut()) else {
            continue;
        };
        add_point_tangent_meridian(geom, q, w, &t.a, &t.b, &t.g, k);
    }
    Ok(energy)
}

impl CellKernel for AxisymmetricKernel {
    fn residual_tangent(
        &self,
        c: &CellInput,
        r: &mut [f64],
        k: Option<&mut [f64]>,
    ) -> Result<f64, PointFailure> {
        residual_tangent(c, r, k)
    }

    fn energy(&self, c: &CellInput) -> Result<f64, PointFailure> {
        let mut e = 0.0;
        for q in 0..c.geom.n_qp {
            let (f, e0) = point(c.geom, q, c.local);
            e += c.geom.weights[q]
                * c.mat
                    .energy_at(&f, &e0, c.hist.at(q))
                    .map_err(|error| PointFailure { qp: q, error })?;
        }
        Ok(e)
    }

    fn energy_split(&self, c: &CellInput) -> Result<(f64, f64), PointFailure> {
        let (mut m, mut el) = (0.0, 0.0);
        for q in 0..c.geom.n_qp {
            let (f, e0) = point(c.geom, q, c.local);
            let (a, b) = c
                .mat
                .energy_split_at(&f, &e0, c.hist.at(q).state)
                .map_err(|error| PointFailure { qp: q, error })?;
            m += c.geom.weights[q] * a;
            el += c.geom.weights[q] * b;
        }
        Ok((m, el))
    }

    fn fields(&self, c: &CellInput) -> Result<CellFields, PointFailure> {
        let geom = c.geom;
        let mut out = CellFields::zero();
        let vol: f64 = geom.weights[..geom.n_qp].iter().sum();
        for q in 0..geom.n_qp {
            let (f, e0) = point(geom, q, c.local);
            out.add_material_point(geom.weights[q] / vol, c.mat, &f, &e0, c.hist.at(q))
                .map_err(|error| PointFailure { qp: q, error })?;
        }
        Ok(out)
    }

    fn point_deformations(
        &self,
        c: &CellInput,
        out: &mut [(Mat3, Vec3)],
    ) -> Result<(), PointFailure> {
        for (q, o) in out.iter_mut().enumerate().take(c.geom.n_qp) {
            *o = point(c.geom, q, c.local);
        }
        Ok(())
    }
}

/// The Kelvin–Voigt forces of a meridian cell: the meridian counterpart of
/// `element::cell_viscous` (same contract). With h_a = F⁻ᵀ∇₀N_a (in-plane) and s_a = (N_a/R)/F_ΘΘ,
/// the rate of deformation has the in-plane part sym Σ v_a ⊗ h_a and d_ΘΘ = Σ v_{r,a} s_a; the
/// force is r_{a,i} = ∫ Jη d : sym(δl_{a,i}) dV with δl_{a,r} = e_r ⊗ h_a + s_a e_Θ ⊗ e_Θ.
pub(crate) fn cell_viscous_meridian(
    geom: &CellGeometry,
    eta: f64,
    local: &[f64],
    vel: &[f64],
    r: &mut [f64],
    mut kv: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    use crate::material::MaterialError;
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let mut power = 0.0;
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let (f, _) = point(geom, q, local);
        let j = f.determinant();
        let fail = |error| PointFailure { qp: q, error };
        if j.is_nan() || j <= 0.0 {
            return Err(fail(MaterialError::NonPositiveJ(j)));
        }
        let finv = f
            .try_inverse()
            .ok_or(fail(MaterialError::NonPositiveJ(j)))?;
        let mut h = [[0.0; 2]; MAX_NODES];
        let mut s = [0.0; MAX_NODES];
        for a in 0..n {
            for i in 0..2 {
                h[a][i] = finv[(0, i)] * g[a][0] + finv[(1, i)] * g[a][1];
            }
            s[a] = geom.hoop(q)[a] * finv[(2, 2)];
        }
        let mut l = [[0.0; 2]; 2];
        let mut d_hoop = 0.0;
        for a in 0..n {
            let v = [vel[a * 4], vel[a * 4 + 1]];
            for i in 0..2 {
                for m in 0..2 {
                    l[i][m] += v[i] * h[a][m];
                }
            }
            d_hoop += v[0] * s[a];
        }
        let mut d = [[0.0; 2]; 2];
        for i in 0..2 {
            for m in 0..2 {
                d[i][m] = 0.5 * (l[i][m] + l[m][i]);
            }
        }
        let dd = d[0][0] * d[0][0] + 2.0 * d[0][1] * d[0][1] + d[1][1] * d[1][1] + d_hoop * d_hoop;
        let c = w * j * eta;
        power += c * dd;
        for a in 0..n {
            for i in 0..2 {
                let hoop = if i == 0 { d_hoop * s[a] } else { 0.0 };
                r[a * 4 + i] += c * (d[i][0] * h[a][0] + d[i][1] * h[a][1] + hoop);
            }
        }
        if let Some(kv) = kv.as_deref_mut() {
            for a in 0..n {
                for b in 0..n {
                    let hab = h[a][0] * h[b][0] + h[a][1] * h[b][1];
                    for i in 0..2 {
                        let row = (a * 4 + i) * nl + b * 4;
                        for k in 0..2 {
                            let delta = if i == k { hab } else { 0.0 };
                            let hoop = if i == 0 && k == 0 { s[a] * s[b] } else { 0.0 };
                            kv[row + k] += c * (0.5 * (delta + h[b][i] * h[a][k]) + hoop);
                        }
                    }
                }
            }
        }
    }
    Ok(power)
}

/// The derivative of the forces of [`cell_viscous_meridian`] with respect to the configuration
/// at fixed nodal velocities, added to `kq` (row-major 4n × 4n; u_r, u_z rows and columns). As in
/// `element::cell_viscous_configuration`, with the hoop terms: for k = r, δF_ΘΘ = N_b/R gives
/// δJ/J = h_{b,r} + s_b, δs_a = −s_a s_b and δd_ΘΘ = −s_b d_ΘΘ.
pub(crate) fn cell_viscous_meridian_configuration(
    geom: &CellGeometry,
    eta: f64,
    local: &[f64],
    vel: &[f64],
    kq: &mut [f64],
) -> Result<(), PointFailure> {
    use crate::material::MaterialError;
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let (f, _) = point(geom, q, local);
        let j = f.determinant();
        let fail = |error| PointFailure { qp: q, error };
        if j.is_nan() || j <= 0.0 {
            return Err(fail(MaterialError::NonPositiveJ(j)));
        }
        let finv = f
            .try_inverse()
            .ok_or(fail(MaterialError::NonPositiveJ(j)))?;
        let mut h = [[0.0; 2]; MAX_NODES];
        let mut s = [0.0; MAX_NODES];
        for a in 0..n {
            for i in 0..2 {
                h[a][i] = finv[(0, i)] * g[a][0] + finv[(1, i)] * g[a][1];
            }
            s[a] = geom.hoop(q)[a] * finv[(2, 2)];
        }
        let mut l = [[0.0; 2]; 2];
        let mut d_hoop = 0.0;
        for a in 0..n {
            let v = [vel[a * 4], vel[a * 4 + 1]];
            for i in 0..2 {
                for m in 0..2 {
                    l[i][m] += v[i] * h[a][m];
                }
            }
            d_hoop += v[0] * s[a];
        }
        let d: [[f64; 2]; 2] =
            std::array::from_fn(|i| std::array::from_fn(|m| 0.5 * (l[i][m] + l[m][i])));
        // the force per c of each node (r̃_a), d h_a and lᵀ h_a
        let mut dh = [[0.0; 2]; MAX_NODES];
        let mut lth = [[0.0; 2]; MAX_NODES];
        for a in 0..n {
            for i in 0..2 {
                dh[a][i] = d[i][0] * h[a][0] + d[i][1] * h[a][1];
                lth[a][i] = l[0][i] * h[a][0] + l[1][i] * h[a][1];
            }
        }
        let c = geom.weights[q] * j * eta;
        for a in 0..n {
            for b in 0..n {
                let hab = h[a][0] * h[b][0] + h[a][1] * h[b][1];
                for i in 0..2 {
                    let force = dh[a][i] + if i == 0 { d_hoop * s[a] } else { 0.0 };
                    let row = (a * 4 + i) * nl + b * 4;
                    for k in 0..2 {
                        let dj = h[b][k] + if k == 0 { s[b] } else { 0.0 };
                        let hoop = if i == 0 && k == 0 {
                            -2.0 * s[a] * s[b] * d_hoop
                        } else {
                            0.0
                        };
                        kq[row + k] += c
                            * (dj * force
                                - h[a][k] * dh[b][i]
                                - 0.5 * l[i][k] * hab
                                - 0.5 * h[b][i] * lth[a][k]
                                + hoop);
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::axisymmetric::{meridian_geometry, MeridianKind};

    /// The configuration derivative of a meridian cell's Kelvin–Voigt forces at fixed velocity
    /// matches central differences, hoop terms included, on every meridian cell kind.
    #[test]
    fn viscous_configuration_tangent_matches_finite_differences() {
        for kind in MeridianKind::ALL {
            let x: Vec<[f64; 2]> = kind
                .reference_nodes()
                .iter()
                .map(|p| {
                    let (s, t) = match kind {
                        MeridianKind::Tri3 | MeridianKind::Tri6 => (p[0], p[1]),
                        _ => (0.5 * (p[0] + 1.0), 0.5 * (p[1] + 1.0)),
                    };
                    [0.5e-3 + 1e-3 * s * (1.0 + 0.1 * t), 1e-3 * (t + 0.05 * s)]
                })
                .collect();
            let g = meridian_geometry(kind, &x).unwrap();
            let n = x.len() * 4;
            let wave = |i: usize, a: f64| ((i as f64 * 12.9898 + a).sin() * 43758.5453).fract();
            let local: Vec<f64> = (0..n)
                .map(|i| if i % 4 < 2 { 1e-4 * wave(i, 0.0) } else { 0.0 })
                .collect();
            let vel: Vec<f64> = (0..n)
                .map(|i| if i % 4 < 2 { 1e-3 * wave(i, 1.0) } else { 0.0 })
                .collect();
            let eta = 2000.0;
            let mut kq = vec![0.0; n * n];
            cell_viscous_meridian_configuration(&g, eta, &local, &vel, &mut kq).unwrap();
            crate::element::standard::tests::check_configuration_tangent(
                &local,
                &kq,
                |j| j % 4 < 2,
                |q| {
                    let mut r = vec![0.0; n];
                    cell_viscous_meridian(&g, eta, q, &vel, &mut r, None).unwrap();
                    r
                },
            );
        }
    }

    /// The Kelvin–Voigt forces of a meridian cell are half the velocity gradient of the
    /// dissipation power, ∫ Jη d:d dV, and their velocity tangent is its derivative (central
    /// differences); a rigid axial translation dissipates nothing.
    #[test]
    fn viscous_forces_match_finite_differences() {
        for kind in MeridianKind::ALL {
            let x: Vec<[f64; 2]> = kind
                .reference_nodes()
                .iter()
                .map(|p| {
                    let (s, t) = match kind {
                        MeridianKind::Tri3 | MeridianKind::Tri6 => (p[0], p[1]),
                        _ => (0.5 * (p[0] + 1.0), 0.5 * (p[1] + 1.0)),
                    };
                    [0.5e-3 + 1e-3 * s * (1.0 + 0.1 * t), 1e-3 * (t + 0.05 * s)]
                })
                .collect();
            let g = meridian_geometry(kind, &x).unwrap();
            let n = x.len() * 4;
            let wave = |i: usize, a: f64| ((i as f64 * 12.9898 + a).sin() * 43758.5453).fract();
            let local: Vec<f64> = (0..n)
                .map(|i| if i % 4 < 2 { 1e-4 * wave(i, 0.0) } else { 0.0 })
                .collect();
            let vel: Vec<f64> = (0..n)
                .map(|i| if i % 4 < 2 { 1e-3 * wave(i, 1.0) } else { 0.0 })
                .collect();
            let eta = 2000.0;
            let mut r = vec![0.0; n];
            let mut kv = vec![0.0; n * n];
            let power =
                cell_viscous_meridian(&g, eta, &local, &vel, &mut r, Some(&mut kv)).unwrap();
            assert!(power > 0.0);
            let rmax = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let kmax = kv.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let h = 1e-9;
            for j in 0..n {
                let (mut vp, mut vm) = (vel.clone(), vel.clone());
                vp[j] += h;
                vm[j] -= h;
                let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
                let pp = cell_viscous_meridian(&g, eta, &local, &vp, &mut rp, None).unwrap();
                let pm = cell_viscous_meridian(&g, eta, &local, &vm, &mut rm, None).unwrap();
                let dp = (pp - pm) / (2.0 * h);
                assert!((0.5 * dp - r[j]).abs() < 1e-6 * rmax, "{kind:?} r[{j}]");
                for i in 0..n {
                    let fd = (rp[i] - rm[i]) / (2.0 * h);
                    assert!(
                        (fd - kv[i * n + j]).abs() < 1e-6 * kmax,
                        "{kind:?} K[{i}][{j}]"
                    );
                    assert!((kv[i * n + j] - kv[j * n + i]).abs() < 1e-12 * kmax);
                }
            }
            // an axial translation is rigid
            let axial: Vec<f64> = (0..n)
                .map(|i| if i % 4 == 1 { 1e-3 } else { 0.0 })
                .collect();
            let mut r0 = vec![0.0; n];
            let p0 = cell_viscous_meridian(&g, eta, &vec![0.0; n], &axial, &mut r0, None).unwrap();
            assert!(p0.abs() < 1e-20, "{kind:?}: {p0}");
        }
    }
}
