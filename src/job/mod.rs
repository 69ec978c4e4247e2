//! The job: the plan of a run executed stage by stage, the recorder of accepted states, probes
//! and observers.

mod prestretch;
pub mod plan;
pub mod probes;
mod recorder;
pub mod run;
pub mod statics;
