//! Arruda–Boyce eight-chain solid (Arruda & Boyce 1993), in two forms.
//!
//! [`ArrudaBoyce`] (`arruda-boyce`) is the eight-chain model with the inverse Langevin function
//! L⁻¹ replaced by Cohen's (1991) Padé approximant L⁻¹(x) ≈ x(3 − x²)/(1 − x²), the form of
//! Wang, Decker, Henann & Chester (J. Mech. Phys. Solids 95, 2016) and of their codes:
//!
//! ```text
//! ∂W/∂Ī₁ = (G₀/6)(λ_L/λ̄) L⁻¹(λ̄/λ_L),   λ̄ = √(Ī₁/3)
//!        = G₀/6 + G₀λ_L²/(3λ_L² − Ī₁)                  (Padé)
//! W = G₀/6 (Ī₁ − 3) − G₀λ_L² ln[(3λ_L² − Ī₁)/(3λ_L² − 3)] + κ/4 (J² − 1 − 2 ln J)
//! ```
//!
//! W is the exact integral of that stress function (zero at Ī₁ = 3), so energy, stress and
//! tangent are consistent. (Substituting the Padé β into the Langevin-form energy
//! G₀λ_L²[(λ̄/λ_L)β + ln(β/sinh β)] would not give this stress: that energy's derivative is β
//! only with the exact inverse.) G₀ (`mu`) is the coefficient of the eight-chain form, not the
//! initial shear modulus: μ₀ = G₀(3λ_L² − 1)/(3λ_L² − 3) ([`ArrudaBoyce::initial_shear_factor`],
//! ≈ 1.019 G₀ at λ_L = 5.99). The chains lock at λ̄ = λ_L (Ī₁ = 3λ_L²); there and beyond every
//! evaluation returns [`MaterialError::OutOfDomain`]. K₀ = κ.
//!
//! [`ArrudaBoyceSeries`] (`arruda-boyce-series`) is the five-term series of the same model in Ī₁:
//!
//! ```text
//! W = μ Σᵢ₌₁⁵ Cᵢ/λ_m^(2i−2) (Ī₁ⁱ − 3ⁱ) + κ/4 (J² − 1 − 2 ln J)
//! C = [1/2, 1/20, 11/1050, 19/7000, 519/673750]
//! ```
//!
//! defined everywhere (no locking); it falls below the eight-chain stress at large stretch. μ is
//! the series coefficient: μ₀ = μ(1 + 3/(5λ_m²) + 99/(175λ_m⁴) + 513/(875λ_m⁶)
//! + 42039/(67375λ_m⁸)) ([`ArrudaBoyceSeries::initial_shear_factor`]). K₀ = κ.

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

/// Cohen's (1991) Padé approximant of the inverse Langevin function, x(3 − x²)/(1 − x²)
/// (|x| < 1).
pub fn pade_inverse_langevin(x: f64) -> f64 {
    x * (3.0 - x * x) / (1.0 - x * x)
}

/// Eight-chain W = G₀/6 (Ī₁ − 3) − G₀λ_L² ln[(3λ_L² − Ī₁)/(3λ_L² − 3)] + κ/4 (J² − 1 − 2 ln J),
/// the energy of ∂W/∂Ī₁ = (G₀/6)(λ_L/λ̄) L⁻¹(λ̄/λ_L) with Cohen's Padé L⁻¹.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrudaBoyce {
    /// Coefficient G₀ of the eight-chain form (Pa); see [`ArrudaBoyce::initial_shear_factor`].
    pub mu: f64,
    /// Locking stretch λ_L (dimensionless), > 1.
    pub lambda_m: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

/// [`ArrudaBoyce`] with a linear dielectric.
pub type ElectroArrudaBoyce = Electroelastic<ArrudaBoyce>;

impl ArrudaBoyce {
    /// μ₀/G₀ = (3λ_L² − 1)/(3λ_L² − 3) = L⁻¹(1/λ_L) λ_L/3 with the Padé L⁻¹.
    pub fn initial_shear_factor(lambda_m: f64) -> f64 {
        let a = 3.0 * lambda_m * lambda_m;
        (a - 1.0) / (a - 3.0)
    }

    /// (Ŵ, derivatives in Ī₁) or the locking error.
    fn iso(&self, i1b: f64) -> Result<(f64, InvariantDerivs), MaterialError> {
        let l2 = self.lambda_m * self.lambda_m;
        // r = 3λ_L² − Ī₁ = 3λ_L²(1 − (λ̄/λ_L)²) > 0 below locking
        let r = 3.0 * l2 - i1b;
        if r.is_nan() || r <= 0.0 {
            return Err(MaterialError::OutOfDomain(format!(
                "Arruda–Boyce model locked: chain stretch λ̄ = √(Ī₁/3) = {:.6} ≥ λ_L = {} \
                 (parameter lambda_m)",
                (i1b / 3.0).sqrt(),
                self.lambda_m
            )));
        }
        let x = i1b - 3.0;
        let c = self.mu * l2;
        let w = self.mu / 6.0 * x - c * (-x / (3.0 * (l2 - 1.0))).ln_1p();
        let g = c / r;
        Ok((
            w,
            InvariantDerivs {
                w1: self.mu / 6.0 + g,
                w11: g / r,
                ..Default::default()
            },
        ))
    }
}

impl ArrudaBoyce {
    /// Ŵ(Ī₁) with the logarithmic volumetric part, as a [`SplitI1`].
    fn split(&self) -> SplitI1<impl Fn(f64) -> Result<(f64, InvariantDerivs), MaterialError> + '_> {
        SplitI1 {
            iso: move |i| self.iso(i),
            kappa: self.kappa,
        }
    }
}

impl Hyperelastic for ArrudaBoyce {
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
        self.mu * Self::initial_shear_factor(self.lambda_m)
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "arruda-boyce",
            &["mu", "lambda_m", "kappa"],
            &[self.mu, self.lambda_m, self.kappa],
        ))
    }

    /// W is linear in G₀ and κ. In q = λ_L² (then times dq/dλ_L = 2λ_L), with r = 3q − Ī₁:
    /// ∂Ŵ/∂q = −G₀ ln(r/(3q − 3)) − G₀q(3/r − 1/(q − 1)), ∂Ŵ₁/∂q = −G₀Ī₁/r².
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let inv = IsoInvariants::new(k);
        self.iso(inv.i1b)?; // the locking check
        let q = self.lambda_m * self.lambda_m;
        let r = 3.0 * q - inv.i1b;
        let x = inv.i1b - 3.0;
        let dq = 2.0 * self.lambda_m;
        let w = -self.mu * ((-x / (3.0 * (q - 1.0))).ln_1p() + q * (3.0 / r - 1.0 / (q - 1.0)));
        let w1 = -self.mu * inv.i1b / (r * r);
        let d_mu = ArrudaBoyce {
            mu: 1.0,
            kappa: 0.0,
            ..*self
        }
        .s(k)?;
        Ok(vec![
            d_mu,
            iso_first(k, &inv, w * dq, w1 * dq, 0.0),
            vol_log_unit(k),
        ])
    }

    /// (Ī₁ − 3)/(3λ_L² − 3): 0 at rest, 1 where the chains lock (λ̄ = λ_L).
    fn locking(&self, k: &CKinematics) -> Option<(f64, &'static str)> {
        let limit = 3.0 * self.lambda_m * self.lambda_m - 3.0;
        Some(((IsoInvariants::new(k).i1b - 3.0) / limit, "lambda_m"))
    }
}

/// Series coefficients Cᵢ of the five-term Arruda–Boyce energy.
pub const AB_COEFFS: [f64; 5] = [
    0.5,
    1.0 / 20.0,
    11.0 / 1050.0,
    19.0 / 7000.0,
    519.0 / 673750.0,
];

/// Five-term series W = μ Σ Cᵢ/λ_m^(2i−2)(Ī₁ⁱ − 3ⁱ) + κ/4 (J² − 1 − 2 ln J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrudaBoyceSeries {
    /// Series coefficient μ (Pa); see [`ArrudaBoyceSeries::initial_shear_factor`].
    pub mu: f64,
    /// Locking stretch λ_m (dimensionless), > 1.
    pub lambda_m: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

/// [`ArrudaBoyceSeries`] with a linear dielectric.
pub type ElectroArrudaBoyceSeries = Electroelastic<ArrudaBoyceSeries>;

impl ArrudaBoyceSeries {
    /// μ₀/μ = 1 + 3/(5λ_m²) + 99/(175λ_m⁴) + 513/(875λ_m⁶) + 42039/(67375λ_m⁸).
    pub fn initial_shear_factor(lambda_m: f64) -> f64 {
        let b = 1.0 / (lambda_m * lambda_m);
        1.0 + b * (3.0 / 5.0 + b * (99.0 / 175.0 + b * (513.0 / 875.0 + b * 42039.0 / 67375.0)))
    }

    /// Ŵ and its derivatives in Ī₁.
    fn iso(&self, i1b: f64) -> (f64, InvariantDerivs) {
        let b = 1.0 / (self.lambda_m * self.lambda_m);
        let (mut w, mut w1, mut w11) = (0.0, 0.0, 0.0);
        // Term i (1-based): a_i (Ī₁ⁱ − 3ⁱ), a_i = μ Cᵢ b^(i−1).
        let mut scale = self.mu; // μ b^(i−1)
        let mut ip = 1.0; // Ī₁^(i−1)
        let mut ipm1 = 0.0; // Ī₁^(i−2) (0 for i = 1)
        let mut three = 1.0; // 3^(i−1)
        for (idx, c) in AB_COEFFS.iter().enumerate() {
            let n = (idx + 1) as f64;
            let a = scale * c;
            w += a * (ip * i1b - three * 3.0);
            w1 += a * n * ip;
            w11 += a * n * (n - 1.0) * ipm1;
            ipm1 = ip;
            ip *= i1b;
            three *= 3.0;
            scale *= b;
        }
        (
            w,
            InvariantDerivs {
                w1,
                w11,
                ..Default::default()
            },
        )
    }
}

impl ArrudaBoyceSeries {
    /// Ŵ(Ī₁) with the logarithmic volumetric part, as a [`SplitI1`].
    fn split(&self) -> SplitI1<impl Fn(f64) -> Result<(f64, InvariantDerivs), MaterialError> + '_> {
        SplitI1 {
            iso: move |i| Ok(self.iso(i)),
            kappa: self.kappa,
        }
    }
}

impl Hyperelastic for ArrudaBoyceSeries {
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
        self.mu * Self::initial_shear_factor(self.lambda_m)
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    fn parameters(&self) -> Option<Parameters> {
        Some(named(
            "arruda-boyce-series",
            &["mu", "lambda_m", "kappa"],
            &[self.mu, self.lambda_m, self.kappa],
        ))
    }

    /// W is linear in μ and κ; term i's coefficient μCᵢλ_m^(2−2i) has the derivative
    /// (2 − 2i)/λ_m times itself in λ_m.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let inv = IsoInvariants::new(k);
        let i1b = inv.i1b;
        let b = 1.0 / (self.lambda_m * self.lambda_m);
        let (mut w, mut w1) = (0.0, 0.0);
        let (mut scale, mut ip, mut three) = (self.mu, 1.0, 1.0);
        for (idx, c) in AB_COEFFS.iter().enumerate() {
            let n = (idx + 1) as f64;
            let da = scale * c * (2.0 - 2.0 * n) / self.lambda_m;
            w += da * (ip * i1b - three * 3.0);
            w1 += da * n * ip;
            ip *= i1b;
            three *= 3.0;
            scale *= b;
        }
        let d_mu = ArrudaBoyceSeries {
            mu: 1.0,
            kappa: 0.0,
            ..*self
        }
        .s(k)?;
        Ok(vec![d_mu, iso_first(k, &inv, w, w1, 0.0), vol_log_unit(k)])
    }
}
