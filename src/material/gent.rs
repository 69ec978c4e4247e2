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
    iso_first, named, vol_log_unit, HFirst, HSecond, Hyperelastic, InvariantDerivs, IsoInvariants,
    PiolaTangent, SplitI1,
};
use super::isotropic::CKinematics;
use super::parameters::Parameters;
use super::{KnownDeformation, KnownLanes, Mat3, MaterialError};
use crate::algebra::lanes::F4;
use nalgebra::Matrix3;

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

impl Gent {
    /// Ŵ(Ī₁) with the logarithmic volumetric part, as a [`SplitI1`].
    fn split(&self) -> SplitI1<impl Fn(f64) -> Result<(f64, InvariantDerivs), MaterialError> + '_> {
        SplitI1 {
            iso: move |i| self.iso(i),
            kappa: self.kappa,
        }
    }
}

impl Hyperelastic for Gent {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        self.split().w(k)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        self.split().s(k)
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        self.split().ll(k)
    }

    fn first_piola(&self, k: &KnownDeformation) -> Option<Result<(f64, Mat3), MaterialError>> {
        Some(self.split().first_piola(k))
    }

    #[inline(always)]
    fn first_piola_lanes(&self, k: &KnownLanes) -> Option<(F4, Matrix3<F4>)> {
        self.split().first_piola_lanes(k)
    }

    fn first_piola_tangent(&self, k: &KnownDeformation) -> Option<PiolaTangent> {
        Some(self.split().first_piola_tangent(k))
    }

    fn shear_modulus(&self) -> f64 {
        self.mu
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "gent",
            &["mu", "jm", "kappa"],
            &[self.mu, self.jm, self.kappa],
        ))
    }

    /// W is linear in μ and κ. In J_m, with x = Ī₁ − 3 and r = 1 − x/J_m:
    /// ∂Ŵ/∂J_m = −(μ/2)(ln r + x/(J_m − x)), ∂Ŵ₁/∂J_m = −(μ/2) x/(J_m − x)².
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let inv = IsoInvariants::new(k);
        self.iso(inv.i1b)?; // the locking check
        let x = inv.i1b - 3.0;
        let jx = self.jm - x;
        let d_mu = Gent {
            mu: 1.0,
            kappa: 0.0,
            ..*self
        }
        .s(k)?;
        let w = -0.5 * self.mu * ((-x / self.jm).ln_1p() + x / jx);
        let w1 = -0.5 * self.mu * x / (jx * jx);
        Ok(vec![d_mu, iso_first(k, &inv, w, w1, 0.0), vol_log_unit(k)])
    }

    /// (Ī₁ − 3)/J_m: 1 where the network locks.
    fn locking(&self, k: &CKinematics) -> Option<(f64, &'static str)> {
        Some(((IsoInvariants::new(k).i1b - 3.0) / self.jm, "jm"))
    }
}
