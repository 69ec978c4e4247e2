//! The dimensionless equibiaxial Gent membrane of DielectricElastomers.jl (Sheng et al. 2014;
//! docs/lumped.md): a homogeneous, incompressible membrane with in-plane stretch λ under a dead
//! load P and a voltage,
//!
//! ```text
//! λ̈ + c λ̇ + Jm(λ − λ⁻⁵)/(Jm − 2λ² − λ⁻⁴ + 3) = P + V_dc (1 + V_ac sin Ωt)² λ³
//! ```
//!
//! (time in units of the membrane's inertial time, stresses in units of μ, V_dc the square of the
//! normalised DC voltage). It derives from Π(λ, t) = −(Jm/4) ln(1 − I/Jm) − Pλ − q(t) λ⁴/4 with
//! I = 2λ² + λ⁻⁴ − 3 and q(t) = V_dc(1 + V_ac sin Ωt)², so the same integrator applies.

use super::equilibrium::{first_root, Root, Search};
use super::integrator::{integrate, Oscillator};
use super::{check, LumpedError};

/// Parameters of the dimensionless Gent membrane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GentMembrane {
    /// Locking parameter Jm > 0.
    pub jm: f64,
    /// Dimensionless dead load P.
    pub pressure: f64,
    /// DC voltage term V_dc ≥ 0.
    pub v_dc: f64,
    /// Relative AC amplitude V_ac.
    pub v_ac: f64,
    /// Dimensionless angular frequency Ω of the AC part.
    pub omega: f64,
    /// Dimensionless damping c ≥ 0.
    pub damping: f64,
}

/// One recorded instant of a [`GentMembrane`] simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GentSample {
    pub time: f64,
    pub stretch: f64,
    pub rate: f64,
    /// ½λ̇² + Π(λ, t).
    pub energy: f64,
}

impl GentMembrane {
    /// Checks the parameters: Jm > 0, V_dc ≥ 0, c ≥ 0, all finite, and P + V_dc ≥ 0 (a membrane in
    /// tension at λ = 1).
    pub fn validate(&self) -> Result<(), LumpedError> {
        check("jm", self.jm, self.jm > 0.0, "must be > 0")?;
        check("v_dc", self.v_dc, self.v_dc >= 0.0, "must be ≥ 0")?;
        check("v_ac", self.v_ac, true, "must be finite")?;
        check("omega", self.omega, true, "must be finite")?;
        check("damping", self.damping, self.damping >= 0.0, "must be ≥ 0")?;
        check(
            "pressure",
            self.pressure,
            self.pressure + self.v_dc >= 0.0,
            "P + V_dc must be ≥ 0 (the model has no compressive states)",
        )
    }

    /// Load factor q(t) = V_dc (1 + V_ac sin Ωt)².
    pub fn load(&self, t: f64) -> f64 {
        let s = 1.0 + self.v_ac * (self.omega * t).sin();
        self.v_dc * s * s
    }

    fn gent(&self, l: f64) -> Result<(f64, f64, f64), LumpedError> {
        let d = self.jm - 2.0 * l * l - l.powi(-4) + 3.0;
        if !(l > 0.0 && d > 0.0 && d.is_finite()) {
            return Err(LumpedError::NoEquilibrium {
                load: self.v_dc,
                reason: format!("stretch λ = {l} is outside the Gent model's range (locking)"),
            });
        }
        let n = self.jm * (l - l.powi(-5));
        let dn = self.jm * (1.0 + 5.0 * l.powi(-6));
        let dd = -4.0 * l + 4.0 * l.powi(-5);
        let energy = -0.25 * self.jm * (d / self.jm).ln();
        Ok((energy, n / d, (dn * d - n * dd) / (d * d)))
    }

    /// Potential Π(λ, t).
    pub fn potential(&self, l: f64, t: f64) -> Result<f64, LumpedError> {
        let (w, ..) = self.gent(l)?;
        Ok(w - self.pressure * l - 0.25 * self.load(t) * l.powi(4))
    }

    /// Static equilibrium under the DC load (V_ac off): the first stable λ ≥ 1.
    pub fn static_stretch(&self) -> Result<f64, LumpedError> {
        self.validate()?;
        let dc = Dc(self);
        let eval = |l: f64| Ok((dc.force(l, 0.0)?, dc.stiffness(l, 0.0)?));
        let search = Search {
            start: 1.0,
            limit: ((self.jm + 3.0) / 2.0).sqrt(),
            first_step: 1e-3,
            tol: 1e-14,
        };
        match first_root(eval, search)? {
            Root::At(l) => Ok(l),
            Root::None { last, reason } => Err(LumpedError::NoEquilibrium {
                load: self.v_dc,
                reason: format!("{reason} (λ up to {last})"),
            }),
        }
    }

    /// Angular frequency √k of small oscillations about [`Self::static_stretch`] (dimensionless,
    /// rad per unit time; the period is 2π/√k).
    pub fn angular_frequency(&self) -> Result<f64, LumpedError> {
        let l = self.static_stretch()?;
        let k = Dc(self).stiffness(l, 0.0)?;
        if k > 0.0 {
            Ok(k.sqrt())
        } else {
            Err(LumpedError::NoEquilibrium {
                load: self.v_dc,
                reason: format!("the equilibrium λ = {l} is not stable (k = {k})"),
            })
        }
    }

    /// Integrates from (λ₀, λ̇₀) at t = 0 to t_end with steps dt (midpoint rule).
    pub fn simulate(
        &self,
        stretch: f64,
        rate: f64,
        t_end: f64,
        dt: f64,
    ) -> Result<Vec<GentSample>, LumpedError> {
        self.validate()?;
        check("stretch", stretch, stretch > 0.0, "must be > 0")?;
        check("rate", rate, true, "must be finite")?;
        let mut out = Vec::new();
        integrate(self, 0.0, stretch, rate, t_end, dt, |t, l, v| {
            out.push(GentSample {
                time: t,
                stretch: l,
                rate: v,
                energy: 0.5 * v * v + self.potential(l, t)?,
            });
            Ok(())
        })?;
        Ok(out)
    }
}

impl Oscillator for GentMembrane {
    fn mass(&self) -> f64 {
        1.0
    }
    fn force(&self, l: f64, t: f64) -> Result<f64, LumpedError> {
        let (_, f, _) = self.gent(l)?;
        Ok(f - self.pressure - self.load(t) * l * l * l)
    }
    fn stiffness(&self, l: f64, t: f64) -> Result<f64, LumpedError> {
        let (_, _, k) = self.gent(l)?;
        Ok(k - 3.0 * self.load(t) * l * l)
    }
    fn damping(&self, _l: f64) -> Result<f64, LumpedError> {
        Ok(self.damping)
    }
}

/// The membrane under its DC load only.
struct Dc<'a>(&'a GentMembrane);

impl Oscillator for Dc<'_> {
    fn mass(&self) -> f64 {
        1.0
    }
    fn force(&self, l: f64, _t: f64) -> Result<f64, LumpedError> {
        let (_, f, _) = self.0.gent(l)?;
        Ok(f - self.0.pressure - self.0.v_dc * l * l * l)
    }
    fn stiffness(&self, l: f64, _t: f64) -> Result<f64, LumpedError> {
        let (_, _, k) = self.0.gent(l)?;
        Ok(k - 3.0 * self.0.v_dc * l * l)
    }
    fn damping(&self, _l: f64) -> Result<f64, LumpedError> {
        Ok(self.0.damping)
    }
}
