//! Generic conversion from a "C-form" energy Ω(C, E0) to the F-form
//! quantities required by [`Material`](super::Material).
//!
//! A model implements [`CMaterial`], providing
//!
//! * `S = 2 ∂Ω/∂C` (second Piola–Kirchhoff stress),
//! * `D0 = −∂Ω/∂E0`,
//! * `𝕃 = 4 ∂²Ω/∂C∂C` (with minor and major symmetry),
//! * `∂S_IJ/∂E0_K` and `∂D0/∂E0`,
//!
//! and the functions [`energy_from_c`], [`stress_from_c`] and
//! [`tangent_from_c`] turn them into Ψ, P, D0, A, B, G. With
//! `dS_IJ = ½ 𝕃_IJKL dC_KL` and `dC = dFᵀF + FᵀdF` one obtains
//!
//! ```text
//! P_iJ          = F_iI S_IJ
//! ∂P_iJ/∂F_mL   = δ_im S_JL + F_iI 𝕃_IJKL F_mK
//! ∂P_iJ/∂E0_K   = F_iI ∂S_IJ/∂E0_K
//! G             = −∂D0/∂E0
//! ```
//!
//! Everything lives on the stack; no heap allocation is performed.

use super::{KnownDeformation, Mat3, Mat9, Mat93, MaterialError, Stress, Tangent, Vec3};

/// Fourth-order tensor with indices `[I][J][K][L]`.
pub type Tensor4 = [[[[f64; 3]; 3]; 3]; 3];
/// Third-order tensor with indices `[I][J][K]`.
pub type Tensor3 = [[[f64; 3]; 3]; 3];

/// Right Cauchy–Green kinematics precomputed once per evaluation point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CKinematics {
    /// C = FᵀF.
    pub c: Mat3,
    /// C⁻¹ (exactly symmetric).
    pub c_inv: Mat3,
    /// J = det F > 0.
    pub j: f64,
}

impl CKinematics {
    /// Compute C, C⁻¹ and J from F. Fails with
    /// [`MaterialError::NonPositiveJ`] if J <= 0 or J is not finite.
    #[inline(always)]
    pub fn from_f(f: &Mat3) -> Result<Self, MaterialError> {
        let j = f.determinant();
        if !(j.is_finite() && j > 0.0) {
            return Err(MaterialError::NonPositiveJ(j));
        }
        let f_inv = f.try_inverse().ok_or(MaterialError::NonPositiveJ(j))?;
        // C⁻¹ = F⁻¹ F⁻ᵀ: entry (I,J) = Σ_k Fi_Ik Fi_Jk, symmetric bit-for-bit.
        let c_inv = f_inv * f_inv.transpose();
        let c = f.transpose() * f;
        Ok(Self { c, c_inv, j })
    }

    /// C, C⁻¹ and J of a deformation whose inverse is known (J > 0 checked by the caller).
    #[inline]
    pub fn from_known(k: &KnownDeformation) -> Self {
        let fit = &k.f_inv_t;
        Self {
            c: k.f.transpose() * k.f,
            c_inv: fit.transpose() * fit,
            j: k.j,
        }
    }
}

/// First derivatives of a C-form energy.
#[derive(Debug, Clone, PartialEq)]
pub struct CFirst {
    /// Ω.
    pub energy: f64,
    /// S = 2 ∂Ω/∂C.
    pub s: Mat3,
    /// D0 = −∂Ω/∂E0.
    pub d0: Vec3,
}

/// First and second derivatives of a C-form energy.
#[derive(Debug, Clone, PartialEq)]
pub struct CDerivs {
    /// Ω.
    pub energy: f64,
    /// S = 2 ∂Ω/∂C.
    pub s: Mat3,
    /// D0 = −∂Ω/∂E0.
    pub d0: Vec3,
    /// 𝕃 = 4 ∂²Ω/∂C∂C = 2 ∂S/∂C, with minor and major symmetry.
    pub ll: Tensor4,
    /// ∂S_IJ/∂E0_K, indexed `[I][J][K]`.
    pub se: Tensor3,
    /// ∂D0/∂E0.
    pub dd: Mat3,
}

/// An energy written as Ω(C, E0) (C symmetric; J = √det C is passed
/// separately for convenience together with C⁻¹).
pub trait CMaterial {
    /// Ω(C, E0).
    fn c_energy(&self, k: &CKinematics, e0: &Vec3) -> Result<f64, MaterialError>;
    /// Ω, S and D0.
    fn c_first(&self, k: &CKinematics, e0: &Vec3) -> Result<CFirst, MaterialError>;
    /// Ω, S, D0, 𝕃, ∂S/∂E0 and ∂D0/∂E0.
    fn c_second(&self, k: &CKinematics, e0: &Vec3) -> Result<CDerivs, MaterialError>;
}

/// Fails unless every component of E0 is finite (the first check of every evaluation).
pub(crate) fn check_field(e0: &Vec3) -> Result<(), MaterialError> {
    if e0.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(MaterialError::OutOfDomain(format!(
            "non-finite electric field E0 = [{}, {}, {}]",
            e0[0], e0[1], e0[2]
        )))
    }
}

/// P = F S.
#[inline]
pub fn piola_from_s(f: &Mat3, s: &Mat3) -> Mat3 {
    f * s
}

/// A_iJ,mL = δ_im S_JL + Σ_{I,K} F_iI 𝕃_IJKL F_mK.
pub fn a_from_c(f: &Mat3, s: &Mat3, ll: &Tensor4) -> Mat9 {
    // T[i][J][K][L] = Σ_I F_iI 𝕃_IJKL
    let mut t: Tensor4 = [[[[0.0; 3]; 3]; 3]; 3];
    for (i, ti) in t.iter_mut().enumerate() {
        for (jj, tij) in ti.iter_mut().enumerate() {
            for (kk, tijk) in tij.iter_mut().enumerate() {
                for (l, v) in tijk.iter_mut().enumerate() {
                    *v = f[(i, 0)] * ll[0][jj][kk][l]
                        + f[(i, 1)] * ll[1][jj][kk][l]
                        + f[(i, 2)] * ll[2][jj][kk][l];
                }
            }
        }
    }
    let mut a = Mat9::zeros();
    for (i, ti) in t.iter().enumerate() {
        for (jj, tij) in ti.iter().enumerate() {
            let row = i * 3 + jj;
            for m in 0..3 {
                for l in 0..3 {
                    let mut v =
                        tij[0][l] * f[(m, 0)] + tij[1][l] * f[(m, 1)] + tij[2][l] * f[(m, 2)];
                    if i == m {
                        v += s[(jj, l)];
                    }
                    a[(row, m * 3 + l)] = v;
                }
            }
        }
    }
    a
}

/// B_iJ,K = Σ_I F_iI ∂S_IJ/∂E0_K.
pub fn b_from_c(f: &Mat3, se: &Tensor3) -> Mat93 {
    let mut b = Mat93::zeros();
    for i in 0..3 {
        for jj in 0..3 {
            for k in 0..3 {
                b[(i * 3 + jj, k)] =
                    f[(i, 0)] * se[0][jj][k] + f[(i, 1)] * se[1][jj][k] + f[(i, 2)] * se[2][jj][k];
            }
        }
    }
    b
}

/// The kinematics of F after checking the inputs (a finite E0, J > 0), as every conversion
/// below does.
#[inline(always)]
pub fn checked_kinematics(f: &Mat3, e0: &Vec3) -> Result<CKinematics, MaterialError> {
    check_field(e0)?;
    CKinematics::from_f(f)
}

/// Ψ(F, E0) = Ω(FᵀF, E0).
pub fn energy_from_c<M: CMaterial + ?Sized>(
    m: &M,
    f: &Mat3,
    e0: &Vec3,
) -> Result<f64, MaterialError> {
    let k = checked_kinematics(f, e0)?;
    m.c_energy(&k, e0)
}

/// Ψ, P, D0 from a C-form model.
#[inline]
pub fn stress_from_c<M: CMaterial + ?Sized>(
    m: &M,
    f: &Mat3,
    e0: &Vec3,
) -> Result<Stress, MaterialError> {
    let k = checked_kinematics(f, e0)?;
    let cf = m.c_first(&k, e0)?;
    Ok(Stress {
        energy: cf.energy,
        p: piola_from_s(f, &cf.s),
        d0: cf.d0,
    })
}

/// Ψ, P, D0, A, B, G from a C-form model.
pub fn tangent_from_c<M: CMaterial + ?Sized>(
    m: &M,
    f: &Mat3,
    e0: &Vec3,
) -> Result<Tangent, MaterialError> {
    let k = checked_kinematics(f, e0)?;
    let cd = m.c_second(&k, e0)?;
    Ok(Tangent {
        energy: cd.energy,
        p: piola_from_s(f, &cd.s),
        d0: cd.d0,
        a: a_from_c(f, &cd.s, &cd.ll),
        b: b_from_c(f, &cd.se),
        g: -cd.dd,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Saint Venant–Kirchhoff with a linear dielectric in C-form, used to
    /// test the conversion independently of the neo-Hooke model:
    /// Ω = λ/2 (tr Ē)² + μ tr(Ē²) + κ E0·(C E0), Ē = ½(C − I).
    #[derive(Debug)]
    struct Svk {
        mu: f64,
        lambda: f64,
        kappa: f64,
    }

    impl CMaterial for Svk {
        fn c_energy(&self, k: &CKinematics, e0: &Vec3) -> Result<f64, MaterialError> {
            let eg = (k.c - Mat3::identity()) * 0.5;
            let tr = eg.trace();
            Ok(0.5 * self.lambda * tr * tr
                + self.mu * (eg * eg).trace()
                + self.kappa * e0.dot(&(k.c * e0)))
        }
        fn c_first(&self, k: &CKinematics, e0: &Vec3) -> Result<CFirst, MaterialError> {
            let eg = (k.c - Mat3::identity()) * 0.5;
            let s = Mat3::identity() * (self.lambda * eg.trace())
                + eg * (2.0 * self.mu)
                + e0 * e0.transpose() * (2.0 * self.kappa);
            Ok(CFirst {
                energy: self.c_energy(k, e0)?,
                s,
                d0: -(k.c * e0) * (2.0 * self.kappa),
            })
        }
        fn c_second(&self, k: &CKinematics, e0: &Vec3) -> Result<CDerivs, MaterialError> {
            let cf = self.c_first(k, e0)?;
            let d = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
            let mut ll = [[[[0.0; 3]; 3]; 3]; 3];
            let mut se = [[[0.0; 3]; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    for kk in 0..3 {
                        se[i][j][kk] = 2.0 * self.kappa * (d(i, kk) * e0[j] + e0[i] * d(j, kk));
                        for (l, v) in ll[i][j][kk].iter_mut().enumerate() {
                            *v = self.lambda * d(i, j) * d(kk, l)
                                + self.mu * (d(i, kk) * d(j, l) + d(i, l) * d(j, kk));
                        }
                    }
                }
            }
            Ok(CDerivs {
                energy: cf.energy,
                s: cf.s,
                d0: cf.d0,
                ll,
                se,
                dd: -k.c * (2.0 * self.kappa),
            })
        }
    }

    fn sample_f() -> Mat3 {
        Mat3::new(1.1, 0.2, -0.1, 0.05, 0.9, 0.15, -0.2, 0.1, 1.2)
    }

    #[test]
    fn kinematics_rejects_non_positive_j() {
        let mut f = Mat3::identity();
        f[(2, 2)] = -0.5;
        assert!(matches!(
            CKinematics::from_f(&f),
            Err(MaterialError::NonPositiveJ(j)) if j < 0.0
        ));
        assert!(matches!(
            CKinematics::from_f(&Mat3::zeros()),
            Err(MaterialError::NonPositiveJ(_))
        ));
        let mut g = Mat3::identity();
        g[(0, 1)] = f64::NAN;
        assert!(matches!(
            CKinematics::from_f(&g),
            Err(MaterialError::NonPositiveJ(_))
        ));
    }

    #[test]
    fn kinematics_values() {
        let f = sample_f();
        let k = CKinematics::from_f(&f).unwrap();
        assert!((k.j - f.determinant()).abs() < 1e-14);
        assert!((k.c * k.c_inv - Mat3::identity()).norm() < 1e-13);
        assert_eq!(k.c_inv, k.c_inv.transpose());
    }

    #[test]
    fn non_finite_field_is_rejected() {
        let m = Svk {
            mu: 1.0,
            lambda: 2.0,
            kappa: 0.3,
        };
        let e0 = Vec3::new(0.0, f64::INFINITY, 0.0);
        assert!(matches!(
            stress_from_c(&m, &Mat3::identity(), &e0),
            Err(MaterialError::OutOfDomain(_))
        ));
    }

    /// The converted A and B of the SVK model must match finite differences
    /// of P = F S computed independently.
    #[test]
    fn conversion_matches_finite_differences() {
        let m = Svk {
            mu: 1.3,
            lambda: 2.1,
            kappa: 0.7,
        };
        let f = sample_f();
        let e0 = Vec3::new(0.4, -0.3, 0.8);
        let t = tangent_from_c(&m, &f, &e0).unwrap();
        let h = 1e-6;
        let mut a_fd = Mat9::zeros();
        for kk in 0..3 {
            for l in 0..3 {
                let mut fp = f;
                fp[(kk, l)] += h;
                let mut fm = f;
                fm[(kk, l)] -= h;
                let pp = stress_from_c(&m, &fp, &e0).unwrap().p;
                let pm = stress_from_c(&m, &fm, &e0).unwrap().p;
                let dp = (pp - pm) / (2.0 * h);
                for i in 0..3 {
                    for j in 0..3 {
                        a_fd[(i * 3 + j, kk * 3 + l)] = dp[(i, j)];
                    }
                }
            }
        }
        let mut b_fd = Mat93::zeros();
        let mut g_fd = Mat3::zeros();
        for kk in 0..3 {
            let mut ep = e0;
            ep[kk] += h;
            let mut em = e0;
            em[kk] -= h;
            let sp = stress_from_c(&m, &f, &ep).unwrap();
            let sm = stress_from_c(&m, &f, &em).unwrap();
            let dp = (sp.p - sm.p) / (2.0 * h);
            for i in 0..3 {
                for j in 0..3 {
                    b_fd[(i * 3 + j, kk)] = dp[(i, j)];
                }
            }
            let dd = -(sp.d0 - sm.d0) / (2.0 * h);
            g_fd.set_column(kk, &dd);
        }
        assert!((t.a - a_fd).amax() < 1e-7 * t.a.amax(), "A mismatch");
        assert!((t.b - b_fd).amax() < 1e-7 * t.b.amax(), "B mismatch");
        assert!((t.g - g_fd).amax() < 1e-7 * t.g.amax(), "G mismatch");
        let s = m.c_first(&CKinematics::from_f(&f).unwrap(), &e0).unwrap().s;
        assert!((t.p - f * s).amax() < 1e-14 * t.p.amax());
    }
}
