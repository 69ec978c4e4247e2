//! Optimal control's numerics: the feasible set of a drive (bounds and rate limits) with its
//! projection, and a projected limited-memory quasi-Newton minimiser on it. What is minimised
//! (a run's objective with its adjoint gradient) is wired in `api::control`.

pub mod feasible;
pub mod quasi_newton;

pub use feasible::Feasible;
pub use quasi_newton::{minimize, minimize_with, Curvature, Iteration, Minimum, Options};
