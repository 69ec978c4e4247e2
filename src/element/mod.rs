//! Cell kernels: turn a material and a cell's geometry into the local residual, tangent, energy
//! and output fields of the cell.

pub mod mean_dilatation;
pub mod standard;

pub use mean_dilatation::Formulation;
pub use standard::*;
