//! Gent solid
//!
//! ```text
//! W = −(μ J_m/2) ln(1 − (Ī₁ − 3)/J_m) + κ/4 (J² − 1 − 2 ln J)
//! ```
//!
//! Defined for Ī₁ − 3 < J_m; beyond that (chain locking) every evaluation
//! returns [`MaterialError::OutOfDomain`]. μ₀ = μ, K₀ = κ.

use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    i1_model_piola, invariant_model_second, iso_stress, vol_log, vol_stress, HFirst, HSecond,
    Hyperelastic, InvariantDerivs, IsoInvariants,
};
use super::isotropic::CKinematics;
use super::{KnownDeformation, Mat3, MaterialError};

/// Gent W = −(μJ_m/2) ln(1 − (Ī₁ − 3)/J_m) + κ/4 (J² − 1 − 2 ln J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gent {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Locking parameter J_m (dimensionless), > 0.
    pub jm: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

/// [`Gent`] with a linear dielectric.
pub type ElectroGent = Electroelastic<Gent>;

impl Gent {
    /// (Ŵ, derivatives) or the locking error.
    fn iso(&self, i1b: f64) -> Result<(f64, InvariantDerivs), MaterialError> {
        let x = i1b - 3.0;
        // r = 1 − x/J_m > 0 inside the domain.
        let r = 1.0 - x / self.jm;
        if r.is_nan() || r <= 0.0 {
            return Err(MaterialError::OutOfDomain(format!(
                "Gent model locked: Ī₁ − 3 = {x:.6} ≥ J_m = {}",
                self.jm
            )));
        }
        let w = -0.5 * self.mu * self.jm * (-x / self.jm).ln_1p();
        let w1 = 0.5 * self.mu / r;
        Ok((
            w,
            InvariantDerivs {
                w1,
                w11: w1 / (self.jm * r),
                ..Default::default()
            },
        ))
    }
}

impl Hyperelastic for Gent {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok(self.iso(inv.i1b)?.0 + vol_log(self.kappa, k.j).u)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = self.iso(inv.i1b)?;
        let v = vol_log(self.kappa, k.j);
        Ok(HFirst {
            w: w + v.u,
            s: iso_stress(k, &inv, &d) + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = self.iso(inv.i1b)?;
        let v = vol_log(self.kappa, k.j);
        Ok(invariant_model_second(k, &inv, w + v.u, &d, &v))
    }

    fn first_piola(&self, k: &KnownDeformation) -> Option<Result<(f64, Mat3), MaterialError>> {
        let i1 = k.f.norm_squared();
        let v = vol_log(self.kappa, k.j);
        Some(
            self.iso(k.jm23 * i1)
                .map(|(w, d)| (w + v.u, i1_model_piola(k, i1, d.w1, v.du))),
        )
    }

    fn shear_modulus(&self) -> f64 {
        self.mu
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    /// (Ī₁ − 3)/J_m: 1 where the network locks.
    fn locking(&self, k: &CKinematics) -> Option<(f64, &'static str)> {
        Some(((IsoInvariants::new(k).i1b - 3.0) / self.jm, "jm"))
    }
}
