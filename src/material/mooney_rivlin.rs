//! Mooney–Rivlin solid (Abaqus form)
//!
//! ```text
//! W = C₁₀ (Ī₁ − 3) + C₀₁ (Ī₂ − 3) + (1/D₁)(J − 1)²
//! ```
//!
//! μ₀ = 2(C₁₀ + C₀₁), K₀ = 2/D₁.

use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    invariant_model_second, iso_first, iso_stress, named, vol_poly, vol_poly_d, vol_stress, HFirst,
    HSecond, Hyperelastic, InvariantDerivs, IsoInvariants,
};
use super::isotropic::CKinematics;
use super::parameters::Parameters;
use super::MaterialError;

/// Mooney–Rivlin W = C₁₀(Ī₁ − 3) + C₀₁(Ī₂ − 3) + (J − 1)²/D₁.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MooneyRivlin {
    /// C₁₀ (Pa).
    pub c10: f64,
    /// C₀₁ (Pa).
    pub c01: f64,
    /// D₁ (1/Pa), > 0.
    pub d1: f64,
}

/// [`MooneyRivlin`] with a linear dielectric.
pub type ElectroMooneyRivlin = Electroelastic<MooneyRivlin>;

impl MooneyRivlin {
    fn derivs(&self) -> InvariantDerivs {
        InvariantDerivs {
            w1: self.c10,
            w2: self.c01,
            ..Default::default()
        }
    }

    fn inv_d(&self) -> [f64; 1] {
        [1.0 / self.d1]
    }

    fn w_iso(&self, inv: &IsoInvariants) -> f64 {
        self.c10 * (inv.i1b - 3.0) + self.c01 * (inv.i2b - 3.0)
    }
}

impl Hyperelastic for MooneyRivlin {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok(self.w_iso(&inv) + vol_poly(&self.inv_d(), k.j).u)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let inv = IsoInvariants::new(k);
        let v = vol_poly(&self.inv_d(), k.j);
        Ok(HFirst {
            w: self.w_iso(&inv) + v.u,
            s: iso_stress(k, &inv, &self.derivs()) + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let inv = IsoInvariants::new(k);
        let v = vol_poly(&self.inv_d(), k.j);
        let w = self.w_iso(&inv) + v.u;
        Ok(invariant_model_second(k, &inv, w, &self.derivs(), &v))
    }

    fn shear_modulus(&self) -> f64 {
        2.0 * (self.c10 + self.c01)
    }

    fn bulk_modulus(&self) -> f64 {
        2.0 / self.d1
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "mooney-rivlin",
            &["c10", "c01", "d1"],
            &[self.c10, self.c01, self.d1],
        ))
    }

    /// W is linear in C₁₀, C₀₁ and 1/D₁.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok(vec![
            iso_first(k, &inv, inv.i1b - 3.0, 1.0, 0.0),
            iso_first(k, &inv, inv.i2b - 3.0, 0.0, 1.0),
            vol_poly_d(k, 0, self.d1),
        ])
    }
}
