//! Time integration: the mass matrix, the step operators (midpoint variational integrator and the
//! Newmark reference) and the driver of a dynamic stage with adaptive steps.

pub mod integrator;
pub mod mass;
pub mod stage;
pub mod trapezoidal;
