//! Cell kernels: turn a material and a cell's geometry into the local residual, tangent, energy
//! and output fields of the cell.

pub mod mean_dilatation;
pub mod standard;

pub use mean_dilatation::Formulation;
pub use standard::*;

use crate::material::PointHistory;

/// The committed internal variables of a cell's quadrature points (`size` values per point,
/// point-major) and the time step of the state being evaluated. Empty for elastic materials.
#[derive(Debug, Clone, Copy)]
pub struct CellHistory<'a> {
    pub state: &'a [f64],
    pub size: usize,
    pub dt: f64,
}

impl<'a> CellHistory<'a> {
    /// No internal variables.
    pub const NONE: CellHistory<'static> = CellHistory {
        state: &[],
        size: 0,
        dt: 0.0,
    };

    /// The history of quadrature point `q`.
    pub fn at(&self, q: usize) -> PointHistory<'a> {
        PointHistory {
            state: if self.size == 0 {
                &[]
            } else {
                &self.state[q * self.size..(q + 1) * self.size]
            },
            dt: self.dt,
        }
    }
}
