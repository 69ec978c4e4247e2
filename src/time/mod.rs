//! Time integration: the mass matrix, the step operators (midpoint variational integrator and the
//! Newmark reference), the driver of a dynamic stage with adaptive steps, and the small
//! vibrations about a converged state (modes, frequency response).

pub mod frequency;
pub mod harmonic;
pub mod integrator;
pub mod mass;
pub mod modal;
pub mod reduced;
pub mod reduction;
pub mod rigid_tilt;
pub mod stage;
pub mod trapezoidal;
