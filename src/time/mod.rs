//! Time integration: the mass matrix, the step operators (midpoint variational integrator and the
//! Newmark reference), the driver of a dynamic stage with adaptive steps, and the small
//! vibrations about a converged state (modes, frequency response, the reduced state-space model
//! and its sampled LQR/Kalman design).

pub mod frequency;
pub mod harmonic;
pub mod integrator;
pub mod lqr;
pub mod mass;
pub mod modal;
pub mod reduced;
pub mod reduction;
pub mod riccati;
pub mod rigid_tilt;
pub mod stage;
pub mod trapezoidal;
