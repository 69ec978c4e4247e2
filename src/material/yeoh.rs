//! Yeoh solid (Abaqus form)
//!
//! ```text
//! W = Σᵢ₌₁³ Cᵢ₀ (Ī₁ − 3)ⁱ + Σᵢ₌₁³ (1/Dᵢ)(J − 1)²ⁱ
//! ```
//!
//! A coefficient Dᵢ = 0 means that volumetric term is absent (Abaqus uses
//! D = 0 for "incompressible"; here only D₂ and D₃ may be zero, since the
//! compressible formulation needs K₀ = 2/D₁ > 0). μ₀ = 2C₁₀.

use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    i1_model_piola, i1_model_tangent, invariant_model_second, iso_stress, named, vol_poly,
    vol_poly_d, vol_stress, HFirst, HSecond, Hyperelastic, InvariantDerivs, IsoInvariants,
    PiolaTangent,
};
use super::isotropic::CKinematics;
use super::parameters::Parameters;
use super::{Known, KnownDeformation, KnownLanes, Mat3, MaterialError};
use crate::algebra::lanes::{norm_squared, Lane, F4};
use nalgebra::Matrix3;

/// Yeoh W = Σ Cᵢ₀(Ī₁ − 3)ⁱ + Σ (J − 1)²ⁱ/Dᵢ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Yeoh {
    /// C₁₀, C₂₀, C₃₀ (Pa).
    pub c: [f64; 3],
    /// D₁, D₂, D₃ (1/Pa); 0 switches the term off (D₁ must be > 0).
    pub d: [f64; 3],
}

/// [`Yeoh`] with a linear dielectric.
pub type ElectroYeoh = Electroelastic<Yeoh>;

impl Yeoh {
    /// Yeoh model from the Abaqus coefficients.
    pub fn new(c10: f64, c20: f64, c30: f64, d1: f64, d2: f64, d3: f64) -> Self {
        Self {
            c: [c10, c20, c30],
            d: [d1, d2, d3],
        }
    }

    fn inv_d(&self) -> [f64; 3] {
        self.d.map(|d| if d == 0.0 { 0.0 } else { 1.0 / d })
    }

    /// (Ŵ, Ŵ′, Ŵ″) as functions of x = Ī₁ − 3.
    #[inline(always)]
    fn iso<T: Lane + Default>(&self, i1b: T) -> (T, InvariantDerivs<T>) {
        let x = i1b - T::splat(3.0);
        let [c1, c2, c3] = self.c;
        let w = x * (T::splat(c1) + x * (T::splat(c2) + x * T::splat(c3)));
        let d = InvariantDerivs {
            w1: T::splat(c1) + x * (T::splat(2.0 * c2) + T::splat(3.0 * c3) * x),
            w11: T::splat(2.0 * c2) + T::splat(6.0 * c3) * x,
            ..Default::default()
        };
        (w, d)
    }

    /// W and P at a known deformation, of one point or a lane of points.
    #[inline(always)]
    fn piola<T: Lane + Default>(&self, k: &Known<T>) -> (T, Matrix3<T>) {
        let i1 = norm_squared(&k.f);
        let (w, d) = self.iso(k.jm23 * i1);
        let v = vol_poly(&self.inv_d(), k.j);
        (w + v.u, i1_model_piola(k, i1, d.w1, v.du))
    }
}

impl Hyperelastic for Yeoh {
    #[inline]
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok(self.iso(inv.i1b).0 + vol_poly(&self.inv_d(), k.j).u)
    }

    #[inline]
    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = self.iso(inv.i1b);
        let v = vol_poly(&self.inv_d(), k.j);
        Ok(HFirst {
            w: w + v.u,
            s: iso_stress(k, &inv, &d) + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = self.iso(inv.i1b);
        let v = vol_poly(&self.inv_d(), k.j);
        Ok(invariant_model_second(k, &inv, w + v.u, &d, &v))
    }

    #[inline]
    fn first_piola(&self, k: &KnownDeformation) -> Option<Result<(f64, Mat3), MaterialError>> {
        Some(Ok(self.piola(k)))
    }

    #[inline(always)]
    fn first_piola_lanes(&self, k: &KnownLanes) -> Option<(F4, Matrix3<F4>)> {
        Some(self.piola(k))
    }

    fn first_piola_tangent(&self, k: &KnownDeformation) -> Option<PiolaTangent> {
        let i1 = norm_squared(&k.f);
        let (w, d) = self.iso(k.jm23 * i1);
        let v = vol_poly(&self.inv_d(), k.j);
        Some(Ok((
            w + v.u,
            i1_model_piola(k, i1, d.w1, v.du),
            i1_model_tangent(k, i1, &d, &v),
        )))
    }

    fn shear_modulus(&self) -> f64 {
        2.0 * self.c[0]
    }

    fn bulk_modulus(&self) -> f64 {
        2.0 / self.d[0]
    }

    /// C₁₀, C₂₀, C₃₀, D₁ and the D₂, D₃ that are not 0 (a term switched off is no parameter).
    fn parameters(&self) -> Option<Parameters> {
        let mut p = named(
            "yeoh",
            &["c10", "c20", "c30", "d1"],
            &[self.c[0], self.c[1], self.c[2], self.d[0]],
        );
        for (i, name) in [(1, "d2"), (2, "d3")] {
            if self.d[i] != 0.0 {
                p.push(name, self.d[i]);
            }
        }
        Some(p)
    }

    /// W is linear in the Cᵢ₀ and in 1/Dᵢ.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let mut out = Vec::with_capacity(6);
        for i in 0..3 {
            let mut c = [0.0; 3];
            c[i] = 1.0;
            out.push(Yeoh { c, d: [0.0; 3] }.s(k)?);
        }
        for i in 0..3 {
            if i == 0 || self.d[i] != 0.0 {
                out.push(vol_poly_d(k, i, self.d[i]));
            }
        }
        Ok(out)
    }
}
