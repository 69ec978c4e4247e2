//! Stop requests: a process-wide one (set by SIGINT/SIGTERM in the binary), a cancel flag the
//! caller of a run on this thread holds (the library's cancel token) and one of the calling thread
//! (set by a step observer, e.g. on dielectric breakdown). Drivers check them between steps
//! and stop cleanly at the last accepted state, so that the outputs stay valid.
//!
//! On several MPI ranks a request seen by one rank must stop them all at the same step, or the
//! others would wait for it in their next collective call: a run installs [`agree_over`] and every
//! check then sums the ranks' requests.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A sum over the ranks of a distributed run, every rank receiving the same values.
pub type RankSum = Box<dyn Fn(&mut [f64]) -> Result<(), String> + Send>;

thread_local! {
    static LOCAL: RefCell<Option<String>> = const { RefCell::new(None) };
    /// The sum over the ranks this thread's run agrees its stop requests by, if it runs on several.
    static AGREE: RefCell<Option<RankSum>> = const { RefCell::new(None) };
    /// Whether some rank of this thread's run was signalled, as the ranks last agreed (see
    /// [`requested`]).
    static SIGNALLED: RefCell<bool> = const { RefCell::new(false) };
    /// The cancel flag of the run on this thread, if its caller gave one.
    static CANCEL: RefCell<Option<Arc<AtomicBool>>> = const { RefCell::new(None) };
}

/// From now on the drivers on this thread also stop when `flag` is set (by another thread: a
/// user interface, a Python KeyboardInterrupt); `None` forgets the flag.
pub fn watch(flag: Option<Arc<AtomicBool>>) {
    CANCEL.with(|c| *c.borrow_mut() = flag);
}

/// Whether the flag this thread watches is set.
fn cancelled() -> bool {
    CANCEL.with(|c| {
        c.borrow()
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst))
    })
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

/// From now on, every [`pending`] on this thread is a collective call over the ranks summed by
/// `sum`: each rank makes it at the same point of the run, and all learn the same answer.
pub fn agree_over(sum: RankSum) {
    AGREE.with(|a| *a.borrow_mut() = Some(sum));
    SIGNALLED.with(|s| *s.borrow_mut() = false);
}

/// The reason to stop now, if any: the signal first, then this thread's request. On ranks that
/// agree (see [`agree_over`]) a request of any rank stops every rank.
pub fn pending() -> Option<String> {
    let signalled = REQUESTED.load(Ordering::SeqCst);
    let local = LOCAL.with(|l| l.borrow().clone());
    let local = if cancelled() {
        Some(CANCELLED.to_string())
    } else {
        local
    };
    let agreed = AGREE.with(|a| {
        a.borrow()
            .as_ref()
            .map(|sum| decide(signalled, local.clone(), sum))
    });
    match agreed {
        Some(answer) => answer,
        None if signalled => Some(MESSAGE.to_string()),
        None => local,
    }
}

/// The ranks' common answer to [`pending`] from this rank's `signalled` and `local` request.
fn decide(
    signalled: bool,
    local: Option<String>,
    sum: &dyn Fn(&mut [f64]) -> Result<(), String>,
) -> Option<String> {
    let mut requests = [
        f64::from(u8::from(signalled)),
        f64::from(u8::from(local.is_some())),
    ];
    if let Err(e) = sum(&mut requests) {
        // the ranks cannot talk: each stops on its own, as the next collective call would fail
        return Some(format!(
            "the MPI ranks could not agree whether to stop: {e}"
        ));
    }
    if requests[0] > 0.0 {
        SIGNALLED.with(|s| *s.borrow_mut() = true);
        return Some(MESSAGE.to_string());
    }
    if requests[1] > 0.0 {
        return Some(local.unwrap_or_else(|| {
            "stopped with another MPI rank, which asked to stop (its message is in its output)"
                .to_string()
        }));
    }
    None
}

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks the running drivers to stop after the current step. Returns true if a stop had already
/// been requested.
pub fn request() -> bool {
    REQUESTED.swap(true, Ordering::SeqCst)
}

/// True once a stop has been requested by a signal. On ranks that agree (see [`agree_over`]): once
/// the ranks' last agreement found a signal to any of them, so that all ranks give the same
/// answer even when the signal reaches this process between two checks.
pub fn requested() -> bool {
    if AGREE.with(|a| a.borrow().is_some()) {
        return SIGNALLED.with(|s| *s.borrow());
    }
    REQUESTED.load(Ordering::SeqCst) || cancelled()
}

/// The message drivers report when they stop on request.
pub const MESSAGE: &str = "interrupted by a signal";

/// The message drivers report when they stop on the caller's cancel flag ([`watch`]).
pub const CANCELLED: &str = "cancelled by the caller";

/// Whether a driver's stop `reason` is a stop on request (a signal or a cancel), not a failure.
pub fn is_request(reason: &str) -> bool {
    reason == MESSAGE || reason == CANCELLED
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Barrier, Mutex};

    /// A sum over `ranks` threads: each adds its values, waits for the others, reads the total.
    fn thread_sum(ranks: usize) -> impl Fn() -> RankSum {
        let shared = Arc::new((Mutex::new(Vec::<f64>::new()), Barrier::new(ranks)));
        move || {
            let shared = Arc::clone(&shared);
            Box::new(move |v: &mut [f64]| {
                let (total, barrier) = &*shared;
                {
                    let mut t = total.lock().unwrap();
                    t.resize(v.len(), 0.0);
                    t.iter_mut().zip(v.iter()).for_each(|(t, x)| *t += x);
                }
                barrier.wait();
                v.copy_from_slice(&total.lock().unwrap());
                if barrier.wait().is_leader() {
                    total.lock().unwrap().clear();
                }
                barrier.wait();
                Ok(())
            })
        }
    }

    /// A request of one rank (a signal or its own) stops every rank at the same check, and after
    /// a signal to one rank every rank counts itself signalled ([`requested`]).
    #[test]
    fn a_request_of_one_rank_stops_every_rank() {
        let sums = thread_sum(3);
        let answers: Vec<_> = (0..3)
            .map(|rank| {
                let sum = sums();
                std::thread::spawn(move || {
                    let sum = &*sum;
                    // check 1: nobody asks; check 2: rank 2 asks for itself; check 3: rank 1 is
                    // signalled
                    let first = decide(false, None, sum);
                    let second = decide(false, (rank == 2).then(|| "breakdown".to_string()), sum);
                    let signalled_before = SIGNALLED.with(|s| *s.borrow());
                    let third = decide(rank == 1, None, sum);
                    let signalled = SIGNALLED.with(|s| *s.borrow());
                    (first, second, signalled_before, third, signalled)
                })
            })
            .collect();
        for (rank, a) in answers.into_iter().enumerate() {
            let (first, second, signalled_before, third, signalled) = a.join().unwrap();
            assert_eq!(first, None, "rank {rank}");
            let second = second.expect("every rank stops with rank 2");
            if rank == 2 {
                assert_eq!(second, "breakdown");
            } else {
                assert!(second.contains("another MPI rank"), "{second}");
            }
            assert!(!signalled_before, "rank {rank}");
            assert_eq!(third.as_deref(), Some(MESSAGE), "rank {rank}");
            assert!(signalled, "rank {rank}");
        }
    }

    /// Without an agreement a thread's request is its own.
    #[test]
    fn without_ranks_a_request_is_local() {
        std::thread::spawn(|| {
            assert_eq!(pending(), None);
            stop_here("done".into());
            assert_eq!(pending().as_deref(), Some("done"));
            clear_local();
            assert_eq!(pending(), None);
            let flag = Arc::new(AtomicBool::new(false));
            watch(Some(Arc::clone(&flag)));
            assert_eq!(pending(), None);
            assert!(!requested());
            flag.store(true, Ordering::SeqCst);
            assert_eq!(pending().as_deref(), Some(CANCELLED));
            assert!(requested() && is_request(CANCELLED));
            watch(None);
            assert_eq!(pending(), None);
        })
        .join()
        .unwrap();
    }
}
