//! Analysis drivers: stages of a simulation on a model.

pub mod probes;
pub mod run;
pub mod statics;
