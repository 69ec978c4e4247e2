//! Compressible neo-Hookean solid with a (possibly deformation-dependent)
//! linear dielectric response.
//!
//! ```text
//! Ω(C, E0) = μ/2 (tr C − 3) − μ ln J + Λ/2 (ln J)²
//!          + c₁ E0·E0 + c₂ E0·(C E0) − ε/2 J E0·(C⁻¹E0)
//! ```
//!
//! With c₁ = c₂ = 0 this is the ideal dielectric elastomer (ε = ε_r ε₀); the
//! "Vu" form uses ε = ε₀ and electrostrictive coefficients c₁, c₂.
//!
//! The mechanical part is [`NeoHooke`] (W = μ/2 (tr C − 3) + U(J) with
//! U = −μ ln J + Λ/2 (ln J)²):
//!
//! ```text
//! S = μ(I − C⁻¹) + Λ ln J C⁻¹
//! 𝕃 = 2(μ − Λ ln J) H + Λ C⁻¹⊗C⁻¹,   H_IJKL = ½(C⁻¹_IK C⁻¹_JL + C⁻¹_IL C⁻¹_JK)
//! ```
//!
//! and the dielectric part is the shared
//! [`ElectricPart`]; [`ElectroNeoHooke`]
//! evaluates through [`Electroelastic`]`<NeoHooke>`.
//!
//! The Cauchy stress is
//! σ = (μ/J)(b − I) + (Λ ln J/J) I + ε(e⊗e − ½|e|² I) + (2c₂/J)(b e)⊗(b e),
//! with e = F⁻ᵀE0 and b = FFᵀ.

use super::electric::ElectricPart;
use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    add_vol_tangent, named, vol_stress, HFirst, HSecond, Hyperelastic, VolDerivs,
};
use super::isotropic::{CDerivs, CFirst, CKinematics, CMaterial, Tensor4};
use super::parameters::Parameters;
use super::{Mat3, Material, MaterialError, PointHistory, Stress, Tangent, Vec3, EPSILON_0};

/// Mechanical compressible neo-Hooke energy
/// W = μ/2 (tr C − 3) − μ ln J + Λ/2 (ln J)² (not split into isochoric and
/// volumetric parts; μ₀ = μ, K₀ = Λ + 2μ/3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeoHooke {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Lamé constant Λ (Pa).
    pub lambda: f64,
}

impl NeoHooke {
    /// U(J) = −μ ln J + Λ/2 (ln J)² and its derivatives.
    fn vol(&self, j: f64) -> VolDerivs {
        let ln_j = j.ln();
        VolDerivs {
            u: -self.mu * ln_j + 0.5 * self.lambda * ln_j * ln_j,
            du: (self.lambda * ln_j - self.mu) / j,
            ddu: (self.lambda + self.mu - self.lambda * ln_j) / (j * j),
        }
    }
}

impl Hyperelastic for NeoHooke {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        Ok(0.5 * self.mu * (k.c.trace() - 3.0) + self.vol(k.j).u)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let v = self.vol(k.j);
        Ok(HFirst {
            w: 0.5 * self.mu * (k.c.trace() - 3.0) + v.u,
            s: Mat3::identity() * self.mu + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let HFirst { w, s } = self.s(k)?;
        let mut ll: Tensor4 = [[[[0.0; 3]; 3]; 3]; 3];
        add_vol_tangent(k, &self.vol(k.j), &mut ll);
        Ok(HSecond { w, s, ll })
    }

    fn shear_modulus(&self) -> f64 {
        self.mu
    }

    fn bulk_modulus(&self) -> f64 {
        self.lambda + 2.0 * self.mu / 3.0
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "neo-hooke",
            &["mu", "lambda"],
            &[self.mu, self.lambda],
        ))
    }

    /// W is linear in μ and Λ: each derivative is the model with that modulus alone.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let unit = |mu, lambda| NeoHooke { mu, lambda }.s(k);
        Ok(vec![unit(1.0, 0.0)?, unit(0.0, 1.0)?])
    }
}

/// Electro-elastic compressible neo-Hooke model (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElectroNeoHooke {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Lamé constant Λ (Pa).
    pub lambda: f64,
    /// Permittivity ε (F/m).
    pub eps: f64,
    /// Electrostrictive coefficient c₁ (N/V²).
    pub c1: f64,
    /// Electrostrictive coefficient c₂ (N/V²).
    pub c2: f64,
}

impl ElectroNeoHooke {
    /// Ideal dielectric elastomer: ε = ε_r ε₀, c₁ = c₂ = 0.
    pub fn new(mu: f64, lambda: f64, eps_r: f64) -> Self {
        Self {
            mu,
            lambda,
            eps: eps_r * EPSILON_0,
            c1: 0.0,
            c2: 0.0,
        }
    }

    /// Same model with the electrostrictive coefficients set to (c₁, c₂).
    pub fn with_coupling(self, c1: f64, c2: f64) -> Self {
        Self { c1, c2, ..self }
    }

    /// Vu et al. form: ε = ε₀ and electrostrictive coefficients c₁, c₂.
    pub fn vu(mu: f64, lambda: f64, c1: f64, c2: f64) -> Self {
        Self {
            mu,
            lambda,
            eps: EPSILON_0,
            c1,
            c2,
        }
    }

    /// The same model as a generic [`Electroelastic`]`<NeoHooke>`, through
    /// which it is evaluated.
    pub fn generic(&self) -> Electroelastic<NeoHooke> {
        Electroelastic {
            mech: NeoHooke {
                mu: self.mu,
                lambda: self.lambda,
            },
            elec: ElectricPart {
                eps: self.eps,
                c1: self.c1,
                c2: self.c2,
            },
        }
    }

    /// Closed-form Cauchy stress
    /// σ = (μ/J)(b − I) + (Λ ln J/J) I + ε(e⊗e − ½|e|² I) + (2c₂/J)(b e)⊗(b e),
    /// with e = F⁻ᵀE0 and b = FFᵀ. Evaluated independently of S, for checks.
    pub fn cauchy_closed_form(&self, f: &Mat3, e0: &Vec3) -> Result<Mat3, MaterialError> {
        let j = f.determinant();
        if !(j.is_finite() && j > 0.0) {
            return Err(MaterialError::NonPositiveJ(j));
        }
        let f_inv = f.try_inverse().ok_or(MaterialError::NonPositiveJ(j))?;
        let e = f_inv.transpose() * e0;
        let b = f * f.transpose();
        let id = Mat3::identity();
        let be = b * e;
        Ok((b - id) * (self.mu / j)
            + id * (self.lambda * j.ln() / j)
            + (e * e.transpose() - id * (0.5 * e.dot(&e))) * self.eps
            + be * be.transpose() * (2.0 * self.c2 / j))
    }
}

impl CMaterial for ElectroNeoHooke {
    fn c_energy(&self, k: &CKinematics, e0: &Vec3) -> Result<f64, MaterialError> {
        self.generic().c_energy(k, e0)
    }

    fn c_first(&self, k: &CKinematics, e0: &Vec3) -> Result<CFirst, MaterialError> {
        self.generic().c_first(k, e0)
    }

    fn c_second(&self, k: &CKinematics, e0: &Vec3) -> Result<CDerivs, MaterialError> {
        self.generic().c_second(k, e0)
    }
}

impl Material for ElectroNeoHooke {
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
        self.generic().energy(f, e0)
    }

    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError> {
        self.generic().stress(f, e0)
    }

    fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError> {
        self.generic().tangent(f, e0)
    }

    fn shear_modulus(&self) -> f64 {
        self.mu
    }

    fn bulk_modulus(&self) -> f64 {
        self.lambda + 2.0 * self.mu / 3.0
    }

    fn permittivity(&self) -> f64 {
        self.eps - 2.0 * self.c1 - 2.0 * self.c2
    }

    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        self.generic().energy_split(f, e0)
    }

    fn parameters(&self) -> Option<Parameters> {
        self.generic().parameters()
    }

    fn parameter_derivatives_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<Vec<Stress>, MaterialError> {
        self.generic().parameter_derivatives_at(f, e0, h)
    }

    fn parameter_derivative_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
        index: usize,
    ) -> Result<Stress, MaterialError> {
        self.generic().parameter_derivative_at(f, e0, h, index)
    }

    fn parameter_enters_d0(&self, index: usize) -> bool {
        self.generic().parameter_enters_d0(index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> ElectroNeoHooke {
        ElectroNeoHooke::new(1e5, 1e7, 4.7).with_coupling(5e-12, 2e-12)
    }

    fn sample_f() -> Mat3 {
        Mat3::new(1.15, 0.12, -0.08, -0.05, 0.93, 0.2, 0.1, -0.17, 1.07)
    }

    fn field_scale(m: &ElectroNeoHooke) -> f64 {
        (m.mu / m.eps).sqrt() * 0.3
    }

    #[test]
    fn constructors() {
        let m = ElectroNeoHooke::new(1e5, 4e5, 4.7);
        assert_eq!(m.eps, 4.7 * EPSILON_0);
        assert_eq!((m.c1, m.c2), (0.0, 0.0));
        let m2 = m.with_coupling(1e-12, 2e-12);
        assert_eq!((m2.mu, m2.lambda, m2.eps), (m.mu, m.lambda, m.eps));
        assert_eq!((m2.c1, m2.c2), (1e-12, 2e-12));
        let v = ElectroNeoHooke::vu(1e5, 4e5, -1e-11, -3e-12);
        assert_eq!(v.eps, EPSILON_0);
        assert_eq!((v.c1, v.c2), (-1e-11, -3e-12));
    }

    #[test]
    fn moduli() {
        let m = model();
        assert_eq!(m.shear_modulus(), 1e5);
        assert!((m.bulk_modulus() - (1e7 + 2e5 / 3.0)).abs() < 1e-6);
        assert!((m.permittivity() - (4.7 * EPSILON_0 - 1e-11 - 4e-12)).abs() < 1e-24);
    }

    #[test]
    fn zero_state() {
        for m in [model(), ElectroNeoHooke::new(1e5, 4e5, 4.7)] {
            let f = Mat3::identity();
            let e0 = Vec3::zeros();
            let t = m.tangent(&f, &e0).unwrap();
            assert_eq!(m.energy(&f, &e0).unwrap(), 0.0);
            assert_eq!(t.energy, 0.0);
            assert!(t.p.amax() < 1e-9, "P = {}", t.p);
            assert_eq!(t.d0, Vec3::zeros());
            assert_eq!(t.b, crate::material::Mat93::zeros());
            let s = m.stress(&f, &e0).unwrap();
            assert!(s.p.amax() < 1e-9);
        }
    }

    #[test]
    fn small_strain_tangent_is_linear_elastic() {
        for (mu, lambda) in [(1e5, 1e7), (1e5, 4e5)] {
            let m = ElectroNeoHooke::new(mu, lambda, 4.7).with_coupling(5e-12, 2e-12);
            let t = m.tangent(&Mat3::identity(), &Vec3::zeros()).unwrap();
            let d = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
            for i in 0..3 {
                for jj in 0..3 {
                    for k in 0..3 {
                        for l in 0..3 {
                            let expect = lambda * d(i, jj) * d(k, l)
                                + mu * (d(i, k) * d(jj, l) + d(i, l) * d(jj, k));
                            let got = t.a[(i * 3 + jj, k * 3 + l)];
                            assert!(
                                (got - expect).abs() < 1e-9 * lambda.max(mu),
                                "A[{i}{jj}{k}{l}] = {got}, expected {expect}"
                            );
                        }
                    }
                }
            }
            // Small-field permittivity: G = −(ε − 2c₁ − 2c₂) I at F = I.
            let g_expect = -Mat3::identity() * m.permittivity();
            assert!((t.g - g_expect).amax() < 1e-12 * m.eps);
        }
    }

    #[test]
    fn cauchy_matches_closed_form() {
        let base = model();
        let scale = field_scale(&base);
        let e0 = Vec3::new(0.3, -0.7, 0.9) * scale;
        for m in [
            base,
            ElectroNeoHooke::new(1e5, 4e5, 4.7).with_coupling(5e-12, 2e-12),
            ElectroNeoHooke::vu(1e5, 4e5, -1.2e-11, -4e-12),
        ] {
            let f = sample_f();
            let s = m.stress(&f, &e0).unwrap();
            let sigma = crate::material::cauchy_stress(&s.p, &f);
            let closed = m.cauchy_closed_form(&f, &e0).unwrap();
            let err = (sigma - closed).amax();
            assert!(err < 1e-10 * closed.amax(), "err {err}, σ = {closed}");
            // σ must be symmetric.
            assert!((sigma - sigma.transpose()).amax() < 1e-10 * closed.amax());
            // The c2 term must be significant in the check (it is not a no-op).
            let be = f * e0;
            let c2_term = be * be.transpose() * (2.0 * m.c2 / f.determinant());
            assert!(c2_term.amax() > 1e-4 * closed.amax());
        }
    }

    #[test]
    fn non_positive_j_is_an_error() {
        let m = model();
        let e0 = Vec3::new(1.0, 2.0, 3.0);
        let mut f = Mat3::identity();
        f[(0, 0)] = -1.0;
        assert!(matches!(m.energy(&f, &e0), Err(MaterialError::NonPositiveJ(j)) if j < 0.0));
        assert!(matches!(
            m.stress(&f, &e0),
            Err(MaterialError::NonPositiveJ(_))
        ));
        assert!(matches!(
            m.tangent(&f, &e0),
            Err(MaterialError::NonPositiveJ(_))
        ));
        assert!(matches!(
            m.energy_split(&f, &e0),
            Err(MaterialError::NonPositiveJ(_))
        ));
        assert!(matches!(
            m.cauchy_closed_form(&f, &e0),
            Err(MaterialError::NonPositiveJ(_))
        ));
        // Singular F (J = 0).
        let mut z = Mat3::identity();
        z[(1, 1)] = 0.0;
        assert!(matches!(m.tangent(&z, &e0), Err(MaterialError::NonPositiveJ(j)) if j == 0.0));
        // Error message formatting.
        let msg = MaterialError::NonPositiveJ(-0.5).to_string();
        assert!(msg.contains("-5e-1"), "{msg}");
    }

    #[test]
    fn energy_split_sums_to_energy() {
        let m = model();
        let f = sample_f();
        let e0 = Vec3::new(0.5, 0.2, -0.6) * field_scale(&m);
        let (mech, elec) = m.energy_split(&f, &e0).unwrap();
        let psi = m.energy(&f, &e0).unwrap();
        assert!((mech - elec - psi).abs() < 1e-12 * psi.abs().max(mech.abs()));
        // Mechanical part does not depend on E0.
        let (mech0, elec0) = m.energy_split(&f, &Vec3::zeros()).unwrap();
        assert_eq!(mech0, mech);
        assert_eq!(elec0, 0.0);
        // For the ideal dielectric the electric energy is positive.
        let ideal = ElectroNeoHooke::new(1e5, 1e7, 4.7);
        let (_, el) = ideal.energy_split(&f, &e0).unwrap();
        let k = CKinematics::from_f(&f).unwrap();
        let expect = 0.5 * ideal.eps * k.j * e0.dot(&(k.c_inv * e0));
        assert!(el > 0.0);
        assert!((el - expect).abs() < 1e-12 * expect);
    }

    #[test]
    fn second_derivatives_have_symmetries() {
        let m = model();
        let e0 = Vec3::new(0.3, -0.7, 0.9) * field_scale(&m);
        let k = CKinematics::from_f(&sample_f()).unwrap();
        let cd = m.c_second(&k, &e0).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                for kk in 0..3 {
                    assert_eq!(cd.se[i][j][kk], cd.se[j][i][kk]);
                    for l in 0..3 {
                        let v = cd.ll[i][j][kk][l];
                        let tol = 1e-12 * v.abs().max(1.0);
                        assert!((v - cd.ll[j][i][kk][l]).abs() < tol);
                        assert!((v - cd.ll[i][j][l][kk]).abs() < tol);
                        assert!((v - cd.ll[kk][l][i][j]).abs() < tol);
                    }
                }
            }
        }
        assert!((cd.dd - cd.dd.transpose()).amax() < 1e-12 * cd.dd.amax());
    }
}
