//! Analysis drivers: stages of a simulation on a model.

pub mod statics;
