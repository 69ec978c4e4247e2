//! Nonlinear and linear solvers: Newton with line search, load stepping with cut-back, and sparse
//! direct factorisation of the symmetric indefinite tangent. Solvers know nothing of elements.

pub mod amg;
pub mod auto;
pub mod continuation;
pub mod factory;
pub mod interrupt;
pub mod iterative;
pub mod krylov;
pub mod linear;
pub mod newton;
pub mod ordering;
#[cfg(feature = "petsc")]
pub mod petsc;
pub mod reused;
pub mod stepping;
pub mod supernodal;
pub mod transposed;
pub mod vector_state;
