//! Stop requests: a process-wide one (set by SIGINT/SIGTERM in the binary) and one of the calling
//! thread (set by a step observer, e.g. on dielectric breakdown). Drivers check them between steps
//! and stop cleanly at the last accepted state, so that the outputs stay valid.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};

thread_local! {
    static LOCAL: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Asks the drivers running on this thread to stop after the current step, for `reason`.
pub fn stop_here(reason: String) {
    LOCAL.with(|l| {
        l.borrow_mut().get_or_insert(reason);
    });
}

/// Clears this thread's stop request (at the start of a run).
pub fn clear_local() {
    LOCAL.with(|l| *l.borrow_mut() = None);
}

/// The reason to stop now, if any: the signal first, then this thread's request.
pub fn pending() -> Option<String> {
    if requested() {
        return Some(MESSAGE.to_string());
    }
    LOCAL.with(|l| l.borrow().clone())
}

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
