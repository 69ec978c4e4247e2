//! The job: the plan of a run executed stage by stage, the recorder of accepted states, probes
//! and observers.

pub mod controller;
pub mod linear;
pub mod noise;
pub mod observer;
pub mod part;
pub mod plan;
mod prestretch;
pub mod probes;
pub mod rank;
mod recorder;
pub mod run;
pub mod stability;
pub mod state;
pub mod state_feedback;
pub mod statics;
