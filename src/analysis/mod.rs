//! Analysis drivers: stages of a simulation on a model.

mod prestretch;
pub mod probes;
mod recorder;
pub mod run;
pub mod statics;
