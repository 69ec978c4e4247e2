//! The commands of the `deasim` binary; `main.rs` only parses arguments.

pub mod app;
pub mod bench;
pub mod calibrate;
pub mod control;
pub mod estimate;
pub mod gradient;
pub mod lumped;
pub mod material;
pub mod modes;
pub mod response;
pub mod stderr_log;
pub mod sweep;
pub mod validate;
