//! Input and output: scenario files, ParaView files, CSV/JSON histories, plots.

pub mod atomic;
pub mod build;
pub mod checkpoint;
pub mod examples;
pub mod linear;
pub mod lock;
pub mod memory;
pub mod output;
pub mod periods;
pub mod pieces;
pub mod plot;
pub mod results;
pub mod revolve;
pub mod scenario;
pub mod vtu;
