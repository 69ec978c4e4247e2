//! Lumped (one-degree-of-freedom) models of dielectric elastomer actuators (docs/lumped.md).
//!
//! * [`Diaphragm`]: the circular actuator of the experimental study (docs/validation.md) as a Ritz
//!   model: a pre-stretched annular membrane between a rigid, mass-carrying pad and a clamped rim,
//!   deflecting with the logarithmic small-deflection shape; any [`crate::material::Material`].
//!   Its linearisation about the loaded state is the study's m ẍ + c ẋ + k x = F(t)
//!   ([`Linearised`]).
//! * [`GentMembrane`]: the dimensionless equibiaxial Gent membrane of DielectricElastomers.jl.
//!
//! All are integrated in time by the midpoint rule of deasim's finite element dynamics
//! ([`integrator`]). The derivation and the measured figures are in `docs/lumped.md`.

pub mod diaphragm;
pub mod equilibrium;
pub mod gent_membrane;
pub mod history;
pub mod integrator;
pub mod linearised;
pub mod plane_stress;
pub mod quadrature;
pub mod setup;

pub use diaphragm::{Diaphragm, DiaphragmParams};
pub use gent_membrane::{GentMembrane, GentSample};
pub use history::{History, Sample};
pub use integrator::Oscillator;
pub use linearised::Linearised;

use crate::material::MaterialError;

/// What went wrong in a lumped model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LumpedError {
    /// A parameter is outside its valid range.
    #[error("invalid lumped-model parameter `{name}` = {value:e}: {requirement}")]
    InvalidParameter {
        name: &'static str,
        value: f64,
        requirement: String,
    },
    /// The material could not be evaluated (or has no plane-stress state) at a radial stretch.
    #[error("material evaluation failed at radial stretch {stretch}: {source}")]
    Material {
        stretch: f64,
        #[source]
        source: MaterialError,
    },
    /// No static equilibrium exists (pull-in, loss of tension, locking), or none was found.
    #[error("no static equilibrium at load {load:e}: {reason}")]
    NoEquilibrium { load: f64, reason: String },
    /// A time step failed (its nonlinear equation did not converge or the model failed).
    #[error("time step from t = {time:e} s failed: {reason}")]
    StepFailed { time: f64, reason: String },
}

/// `Ok(())` when `value` is finite and satisfies `ok`, otherwise an [`LumpedError::InvalidParameter`].
pub(crate) fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    requirement: &str,
) -> Result<(), LumpedError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(LumpedError::InvalidParameter {
            name,
            value,
            requirement: requirement.to_string(),
        })
    }
}
