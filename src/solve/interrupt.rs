//! A process-wide stop request (set by SIGINT/SIGTERM in the binary). Drivers check it between
//! steps and stop cleanly at the last accepted state, so that the outputs stay valid.

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks the running drivers to stop after the current step. Returns true if a stop had already
/// been requested.
pub fn request() -> bool {
    REQUESTED.swap(true, Ordering::SeqCst)
}

/// True once a stop has been requested.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// The message drivers report when they stop on request.
pub const MESSAGE: &str = "interrupted by a signal";
