//! Finite-difference and invariance tests that apply to any [`Material`].
//!
//! The helpers (random generator, finite differences) are shared with
//! [`model_tests`](super::model_tests).
//!
//! All randomness comes from a small inline xorshift generator with a fixed
//! seed, so the tests are deterministic.

use super::ElectroNeoHooke;
use super::{Mat3, Mat9, Mat93, Material, MaterialError, Vec3};

/// xorshift64* pseudo-random generator.
pub(super) struct Rng(u64);

impl Rng {
    pub(super) fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }
    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub(super) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [-1, 1).
    pub(super) fn sym(&mut self) -> f64 {
        2.0 * self.uniform() - 1.0
    }
    pub(super) fn mat3(&mut self) -> Mat3 {
        Mat3::from_fn(|_, _| self.sym())
    }
    pub(super) fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.sym(), self.sym(), self.sym())
    }
    /// F = I + 0.3·random with det F comfortably positive.
    pub(super) fn deformation(&mut self) -> Mat3 {
        loop {
            let f = Mat3::identity() + self.mat3() * 0.3;
            if f.determinant() > 0.3 {
                return f;
            }
        }
    }
    /// E0 with magnitude ~ 0.3·sqrt(μ/ε) (times 0.5..1.5), random direction.
    pub(super) fn field(&mut self, m: &dyn Material) -> Vec3 {
        let scale = (m.shear_modulus() / m.permittivity()).sqrt() * 0.3;
        loop {
            let v = self.vec3();
            let n = v.norm();
            if n > 0.2 && n <= 1.0 {
                return v / n * scale * (0.5 + self.uniform());
            }
        }
    }
    /// Random proper rotation.
    pub(super) fn rotation(&mut self) -> Mat3 {
        let axis_angle = self.vec3() * 3.0;
        nalgebra::Rotation3::new(axis_angle).into_inner()
    }
}

/// The material parameter sets exercised by every test here.
fn materials() -> Vec<(&'static str, ElectroNeoHooke)> {
    vec![
        ("ideal, lambda=1e7", ElectroNeoHooke::new(1e5, 1e7, 4.7)),
        ("ideal, lambda=4mu", ElectroNeoHooke::new(1e5, 4e5, 4.7)),
        (
            "coupled, lambda=1e7",
            ElectroNeoHooke::new(1e5, 1e7, 4.7).with_coupling(5e-12, 2e-12),
        ),
        (
            "coupled, lambda=4mu",
            ElectroNeoHooke::new(1e5, 4e5, 4.7).with_coupling(5e-12, 2e-12),
        ),
        ("vu", ElectroNeoHooke::vu(1e5, 4e5, -1.2e-11, -4e-12)),
    ]
}

const POINTS_PER_MATERIAL: usize = 12;
pub(super) const TOL: f64 = 1e-6;

/// Error `got` relative to `reference` (guarded against a zero reference).
pub(super) fn rel_err(got: f64, reference: f64) -> f64 {
    got / reference.max(f64::MIN_POSITIVE)
}

/// Finite-difference step for F entries (entries are O(1)).
pub(super) const H_F: f64 = 1e-6;
/// Relative finite-difference step for E0. P is dominated by the Λ term
/// (~1e6 Pa) while ∂P/∂E0 ~ εE0 is tiny, so round-off, not truncation,
/// limits the accuracy; 1e-4·|E0| keeps both well below the tolerance (for
/// energies quadratic in E0 the central difference is exact anyway).
const H_E_REL: f64 = 1e-4;

pub(super) fn fd_p_from_energy(m: &dyn Material, f: &Mat3, e0: &Vec3) -> Mat3 {
    let mut p = Mat3::zeros();
    for i in 0..3 {
        for j in 0..3 {
            let mut fp = *f;
            fp[(i, j)] += H_F;
            let mut fm = *f;
            fm[(i, j)] -= H_F;
            p[(i, j)] = (m.energy(&fp, e0).unwrap() - m.energy(&fm, e0).unwrap()) / (2.0 * H_F);
        }
    }
    p
}

pub(super) fn fd_d0_from_energy(m: &dyn Material, f: &Mat3, e0: &Vec3) -> Vec3 {
    let h = H_E_REL * e0.norm();
    let mut d = Vec3::zeros();
    for k in 0..3 {
        let mut ep = *e0;
        ep[k] += h;
        let mut em = *e0;
        em[k] -= h;
        d[k] = -(m.energy(f, &ep).unwrap() - m.energy(f, &em).unwrap()) / (2.0 * h);
    }
    d
}

/// Returns (A_fd, (∂D0/∂F)_fd as 3x9 transposed into 9x3 with sign so that it
/// should equal B) from differences of P and D0 with respect to F.
pub(super) fn fd_wrt_f(m: &dyn Material, f: &Mat3, e0: &Vec3) -> (Mat9, Mat93) {
    let mut a = Mat9::zeros();
    let mut b_from_d = Mat93::zeros();
    for k in 0..3 {
        for l in 0..3 {
            let mut fp = *f;
            fp[(k, l)] += H_F;
            let mut fm = *f;
            fm[(k, l)] -= H_F;
            let sp = m.stress(&fp, e0).unwrap();
            let sm = m.stress(&fm, e0).unwrap();
            let dp = (sp.p - sm.p) / (2.0 * H_F);
            let dd = (sp.d0 - sm.d0) / (2.0 * H_F);
            for i in 0..3 {
                for j in 0..3 {
                    a[(i * 3 + j, k * 3 + l)] = dp[(i, j)];
                }
            }
            // B_kL,M = ∂P_kL/∂E0_M = ∂²Ψ/∂F_kL∂E0_M = −∂D0_M/∂F_kL
            for mm in 0..3 {
                b_from_d[(k * 3 + l, mm)] = -dd[mm];
            }
        }
    }
    (a, b_from_d)
}

/// (B_fd, G_fd) from differences of P and D0 with respect to E0.
pub(super) fn fd_wrt_e(m: &dyn Material, f: &Mat3, e0: &Vec3) -> (Mat93, Mat3) {
    let h = H_E_REL * e0.norm();
    let mut b = Mat93::zeros();
    let mut g = Mat3::zeros();
    for k in 0..3 {
        let mut ep = *e0;
        ep[k] += h;
        let mut em = *e0;
        em[k] -= h;
        let sp = m.stress(f, &ep).unwrap();
        let sm = m.stress(f, &em).unwrap();
        let dp = (sp.p - sm.p) / (2.0 * h);
        for i in 0..3 {
            for j in 0..3 {
                b[(i * 3 + j, k)] = dp[(i, j)];
            }
        }
        g.set_column(k, &(-(sp.d0 - sm.d0) / (2.0 * h)));
    }
    (b, g)
}

#[test]
fn first_derivatives_match_finite_differences() {
    let mut rng = Rng::new(0x5eed_1234_abcd_0001);
    for (name, m) in materials() {
        for _ in 0..POINTS_PER_MATERIAL {
            let f = rng.deformation();
            let e0 = rng.field(&m);
            let s = m.stress(&f, &e0).unwrap();
            let t = m.tangent(&f, &e0).unwrap();
            let psi = m.energy(&f, &e0).unwrap();
            // All three entry points agree.
            assert_eq!(s.energy, psi, "{name}");
            super::model_tests::assert_tangent_values(name, &m, &t, &s, psi);

            let p_fd = fd_p_from_energy(&m, &f, &e0);
            let ep = rel_err((s.p - p_fd).amax(), s.p.amax());
            assert!(
                ep < TOL,
                "{name}: P rel err {ep:e}\nF = {f}\nP = {}\nFD = {p_fd}",
                s.p
            );

            let d_fd = fd_d0_from_energy(&m, &f, &e0);
            let ed = rel_err((s.d0 - d_fd).amax(), s.d0.amax());
            assert!(
                ed < TOL,
                "{name}: D0 rel err {ed:e}\nD0 = {}\nFD = {d_fd}",
                s.d0
            );
        }
    }
}

#[test]
fn second_derivatives_match_finite_differences() {
    let mut rng = Rng::new(0x0bad_cafe_f00d_0002);
    for (name, m) in materials() {
        for _ in 0..POINTS_PER_MATERIAL {
            let f = rng.deformation();
            let e0 = rng.field(&m);
            let t = m.tangent(&f, &e0).unwrap();

            let (a_fd, b_from_d) = fd_wrt_f(&m, &f, &e0);
            let (b_fd, g_fd) = fd_wrt_e(&m, &f, &e0);

            let ea = rel_err((t.a - a_fd).amax(), t.a.amax());
            assert!(ea < TOL, "{name}: A rel err {ea:e}\nF = {f}");
            let eb = rel_err((t.b - b_fd).amax(), t.b.amax());
            assert!(eb < TOL, "{name}: B (dP/dE0) rel err {eb:e}\nF = {f}");
            let eb2 = rel_err((t.b - b_from_d).amax(), t.b.amax());
            assert!(eb2 < TOL, "{name}: B (-dD0/dF) rel err {eb2:e}\nF = {f}");
            let eg = rel_err((t.g - g_fd).amax(), t.g.amax());
            assert!(eg < TOL, "{name}: G rel err {eg:e}\nF = {f}");

            // Major symmetry of A and symmetry of G.
            let sa = rel_err((t.a - t.a.transpose()).amax(), t.a.amax());
            assert!(sa < 1e-12, "{name}: A not symmetric ({sa:e})");
            let sg = rel_err((t.g - t.g.transpose()).amax(), t.g.amax());
            assert!(sg < 1e-12, "{name}: G not symmetric ({sg:e})");

            // Ideal dielectric: G = −εJ C⁻¹ is negative definite.
            if m.c1 == 0.0 && m.c2 == 0.0 {
                let eig = t.g.symmetric_eigenvalues();
                assert!(eig.iter().all(|&x| x < 0.0), "{name}: G eigenvalues {eig}");
            }
        }
    }
}

#[test]
fn objectivity() {
    let mut rng = Rng::new(0x0123_4567_89ab_cdef);
    for (name, m) in materials() {
        for _ in 0..POINTS_PER_MATERIAL {
            let f = rng.deformation();
            let e0 = rng.field(&m);
            let q = rng.rotation();
            assert!((q.transpose() * q - Mat3::identity()).amax() < 1e-14);
            assert!((q.determinant() - 1.0).abs() < 1e-14);
            let qf = q * f;

            let t = m.tangent(&f, &e0).unwrap();
            let tq = m.tangent(&qf, &e0).unwrap();

            let ee = rel_err((tq.energy - t.energy).abs(), t.energy.abs());
            assert!(ee < 1e-10, "{name}: energy not objective ({ee:e})");
            let ep = rel_err((tq.p - q * t.p).amax(), t.p.amax());
            assert!(ep < 1e-10, "{name}: P(QF) != Q P(F) ({ep:e})");
            let ed = rel_err((tq.d0 - t.d0).amax(), t.d0.amax());
            assert!(ed < 1e-10, "{name}: D0 not objective ({ed:e})");

            // A(QF)_iJ,kL = Q_ia Q_kb A(F)_aJ,bL ; B(QF)_iJ,K = Q_ia B(F)_aJ,K.
            let mut a_rot = Mat9::zeros();
            let mut b_rot = Mat93::zeros();
            for i in 0..3 {
                for jj in 0..3 {
                    for kk in 0..3 {
                        let mut bv = 0.0;
                        for a in 0..3 {
                            bv += q[(i, a)] * t.b[(a * 3 + jj, kk)];
                        }
                        b_rot[(i * 3 + jj, kk)] = bv;
                        for l in 0..3 {
                            let mut v = 0.0;
                            for a in 0..3 {
                                for b in 0..3 {
                                    v += q[(i, a)] * q[(kk, b)] * t.a[(a * 3 + jj, b * 3 + l)];
                                }
                            }
                            a_rot[(i * 3 + jj, kk * 3 + l)] = v;
                        }
                    }
                }
            }
            let ea = rel_err((tq.a - a_rot).amax(), t.a.amax());
            assert!(ea < 1e-10, "{name}: A not objective ({ea:e})");
            let eb = rel_err((tq.b - b_rot).amax(), t.b.amax());
            assert!(eb < 1e-10, "{name}: B not objective ({eb:e})");
            let eg = rel_err((tq.g - t.g).amax(), t.g.amax());
            assert!(eg < 1e-10, "{name}: G not objective ({eg:e})");
        }
    }
}

/// Isotropy: Ψ(F Q, Qᵀ E0) = Ψ(F, E0) for any rotation Q of the reference
/// configuration.
#[test]
fn material_isotropy() {
    let mut rng = Rng::new(0xfeed_beef_0000_0003);
    for (name, m) in materials() {
        for _ in 0..POINTS_PER_MATERIAL {
            let f = rng.deformation();
            let e0 = rng.field(&m);
            let q = rng.rotation();
            let s = m.stress(&f, &e0).unwrap();
            let sq = m.stress(&(f * q), &(q.transpose() * e0)).unwrap();
            let ee = rel_err((sq.energy - s.energy).abs(), s.energy.abs());
            assert!(ee < 1e-10, "{name}: energy not isotropic ({ee:e})");
            // P(FQ) = P(F) Q and D0 transforms as Qᵀ D0.
            let ep = rel_err((sq.p - s.p * q).amax(), s.p.amax());
            assert!(ep < 1e-10, "{name}: P not isotropic ({ep:e})");
            let ed = rel_err((sq.d0 - q.transpose() * s.d0).amax(), s.d0.amax());
            assert!(ed < 1e-10, "{name}: D0 not isotropic ({ed:e})");
        }
    }
}

#[test]
fn random_inverted_deformations_are_rejected() {
    let mut rng = Rng::new(0x1111_2222_3333_4444);
    for (name, m) in materials() {
        for _ in 0..POINTS_PER_MATERIAL {
            // Reflect a valid F to get det F < 0.
            let mut f = rng.deformation();
            f.row_mut(0).neg_mut();
            let e0 = rng.field(&m);
            let j = f.determinant();
            assert!(j < 0.0);
            assert_eq!(
                m.energy(&f, &e0),
                Err(MaterialError::NonPositiveJ(j)),
                "{name}"
            );
            assert!(matches!(
                m.stress(&f, &e0),
                Err(MaterialError::NonPositiveJ(_))
            ));
            assert!(matches!(
                m.tangent(&f, &e0),
                Err(MaterialError::NonPositiveJ(_))
            ));
        }
    }
}
