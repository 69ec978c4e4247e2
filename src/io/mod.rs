//! Input and output: scenario files, ParaView files, CSV/JSON histories, plots.

pub mod atomic;
pub mod plot;
pub mod vtu;
