//! Neo-Hooke solid in the isochoric/volumetric split form
//!
//! ```text
//! W = μ/2 (Ī₁ − 3) + κ/4 (J² − 1 − 2 ln J)
//! ```
//!
//! (the energy of the deal.II Cook's membrane benchmark). μ₀ = μ, K₀ = κ.

use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    i1_model_piola, i1_model_tangent, invariant_model_second, iso_stress, named, vol_log,
    vol_stress, HFirst, HSecond, Hyperelastic, InvariantDerivs, IsoInvariants, PiolaTangent,
};
use super::isotropic::CKinematics;
use super::parameters::Parameters;
use super::{Known, KnownDeformation, KnownLanes, Mat3, MaterialError};
use crate::algebra::lanes::{norm_squared, Lane, F4};
use nalgebra::Matrix3;

/// Split neo-Hooke W = μ/2 (Ī₁ − 3) + κ/4 (J² − 1 − 2 ln J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeoHookeSplit {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

/// [`NeoHookeSplit`] with a linear dielectric.
pub type ElectroNeoHookeSplit = Electroelastic<NeoHookeSplit>;

impl NeoHookeSplit {
    fn derivs(&self) -> InvariantDerivs {
        InvariantDerivs {
            w1: 0.5 * self.mu,
            ..Default::default()
        }
    }
}

impl NeoHookeSplit {
    /// W and P at a known deformation, of one point or a lane of points.
    #[inline(always)]
    fn piola<T: Lane>(&self, k: &Known<T>) -> (T, Matrix3<T>) {
        let i1 = norm_squared(&k.f);
        let v = vol_log(self.kappa, k.j);
        let w = T::splat(0.5 * self.mu) * (k.jm23 * i1 - T::splat(3.0)) + v.u;
        (w, i1_model_piola(k, i1, T::splat(0.5 * self.mu), v.du))
    }
}

impl Hyperelastic for NeoHookeSplit {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok(0.5 * self.mu * (inv.i1b - 3.0) + vol_log(self.kappa, k.j).u)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let inv = IsoInvariants::new(k);
        let v = vol_log(self.kappa, k.j);
        Ok(HFirst {
            w: 0.5 * self.mu * (inv.i1b - 3.0) + v.u,
            s: iso_stress(k, &inv, &self.derivs()) + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let inv = IsoInvariants::new(k);
        let v = vol_log(self.kappa, k.j);
        let w = 0.5 * self.mu * (inv.i1b - 3.0) + v.u;
        Ok(invariant_model_second(k, &inv, w, &self.derivs(), &v))
    }

    fn first_piola(&self, k: &KnownDeformation) -> Option<Result<(f64, Mat3), MaterialError>> {
        Some(Ok(self.piola(k)))
    }

    #[inline(always)]
    fn first_piola_lanes(&self, k: &KnownLanes) -> Option<(F4, Matrix3<F4>)> {
        Some(self.piola(k))
    }

    fn first_piola_tangent(&self, k: &KnownDeformation) -> Option<PiolaTangent> {
        let (w, p) = self.piola(k);
        let i1 = norm_squared(&k.f);
        let v = vol_log(self.kappa, k.j);
        Some(Ok((w, p, i1_model_tangent(k, i1, &self.derivs(), &v))))
    }

    fn shear_modulus(&self) -> f64 {
        self.mu
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "neo-hooke-split",
            &["mu", "kappa"],
            &[self.mu, self.kappa],
        ))
    }

    /// W is linear in μ and κ.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let unit = |mu, kappa| NeoHookeSplit { mu, kappa }.s(k);
        Ok(vec![unit(1.0, 0.0)?, unit(0.0, 1.0)?])
    }
}
