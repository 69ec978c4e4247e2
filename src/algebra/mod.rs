//! The algebra shared by the discrete problem and its solvers: the sparse matrix, the nonlinear
//! system a solver sees, and how divided processes exchange their parts of a vector. Knows
//! neither elements nor meshes, so that `problem` and `solve` both build on it.

pub mod csr;
pub mod exchange;
pub mod lanes;
pub mod spin;
pub mod system;
