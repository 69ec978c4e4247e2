//! A parallel loop for short regions that follow each other closely: the residuals of a time
//! step's Newton iterations, a few hundred microseconds of work each with a sequential solve
//! between them.
//!
//! rayon's idle threads sleep after a few dozen yields, and the sequential solve between two
//! residuals is longer than that: each residual then waits for a sleeping thread to be woken,
//! which on a virtual machine takes tens of microseconds, and the thread that is awake has
//! done most of the cells by the time the other arrives (on `diaphragm-3d` one thread
//! evaluated about seven eighths of the residual's cells). Here the calling thread works with
//! helper threads that, after a region, wait for the next one busily for a short while
//! ([`SPIN`], then [`YIELD`] of yielding) before they sleep, and the cells are handed out in
//! small chunks from a shared counter, so a late helper takes fewer. rayon, which the rest of
//! the project uses, lets neither the calling thread take part nor idle threads stay awake
//! longer; these few lines do both rather than a second thread-pool crate.
//!
//! The loop gives no order: callers write each index's result into its own slot and add them
//! in index order afterwards, so the sums are the same bits on any number of threads. Called
//! from inside rayon's pool (a parallel loop over experiments, a test's pool of its own), or
//! while another thread holds the helpers, it runs on rayon instead, so that the helpers never
//! compete with rayon's threads for the cores.

use rayon::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};
use std::thread::{self, Thread};
use std::time::{Duration, Instant};

/// How long an idle helper spins on the next region before it yields.
const SPIN: Duration = Duration::from_micros(100);
/// How long it then yields between looks before it sleeps.
const YIELD: Duration = Duration::from_micros(400);
/// Chunks a thread takes per region on average: small enough to balance, large enough that the
/// shared counter is not contended.
const CHUNKS_PER_THREAD: usize = 16;

/// One region, on the caller's stack while [`try_for_each`] runs.
struct Region<'a> {
    body: &'a (dyn Fn(usize) -> bool + Sync),
    n: usize,
    chunk: usize,
    next: AtomicUsize,
    /// Set when a body returned false or panicked: the others stop taking chunks.
    stop: AtomicBool,
    panicked: AtomicBool,
    /// Helpers inside the region.
    inside: AtomicUsize,
}

impl Region<'_> {
    /// Takes chunks until none is left or the region stops.
    fn work(&self) {
        while !self.stop.load(Ordering::Relaxed) {
            let start = self.next.fetch_add(self.chunk, Ordering::Relaxed);
            if start >= self.n {
                return;
            }
            for i in start..(start + self.chunk).min(self.n) {
                if !(self.body)(i) {
                    self.stop.store(true, Ordering::Relaxed);
                    return;
                }
            }
        }
    }
}

/// The helpers and the region they may join.
struct Helpers {
    /// The open region (null when none); helpers enter it under this lock, the caller closes it
    /// under it, so that no helper enters a region after it closed.
    open: Mutex<usize>,
    /// Counts the regions opened, for idle helpers to notice a new one.
    epoch: AtomicUsize,
    /// Helpers asleep (or about to be).
    sleeping: AtomicUsize,
    threads: Mutex<Vec<Thread>>,
    /// Held by the thread whose region runs.
    busy: Mutex<()>,
}

fn helpers() -> &'static Helpers {
    static HELPERS: OnceLock<Helpers> = OnceLock::new();
    HELPERS.get_or_init(|| Helpers {
        open: Mutex::new(0),
        epoch: AtomicUsize::new(0),
        sleeping: AtomicUsize::new(0),
        threads: Mutex::new(Vec::new()),
        busy: Mutex::new(()),
    })
}

impl Helpers {
    /// Starts helpers until there are `count`.
    fn ensure(&'static self, count: usize) -> bool {
        let Ok(mut threads) = self.threads.lock() else {
            return false;
        };
        while threads.len() < count {
            let spawned = thread::Builder::new()
                .name(format!("deasim-helper-{}", threads.len()))
                .spawn(move || self.serve());
            match spawned {
                Ok(handle) => threads.push(handle.thread().clone()),
                Err(_) => return false,
            }
        }
        true
    }

    /// A helper's life: wait for a region, work in it, wait again.
    fn serve(&self) {
        let mut seen = self.epoch.load(Ordering::Acquire);
        loop {
            seen = self.wait_after(seen);
            let region = {
                let Ok(open) = self.open.lock() else { return };
                let ptr = *open as *const Region<'static>;
                if ptr.is_null() {
                    continue;
                }
                // SAFETY: the region stays on its caller's stack until it is closed (under
                // this lock) and every helper that entered has left (`inside` back to 0)
                let region = unsafe { &*ptr };
                region.inside.fetch_add(1, Ordering::AcqRel);
                region
            };
            if catch_unwind(AssertUnwindSafe(|| region.work())).is_err() {
                region.panicked.store(true, Ordering::Relaxed);
                region.stop.store(true, Ordering::Relaxed);
            }
            region.inside.fetch_sub(1, Ordering::AcqRel);
        }
    }

    /// Waits until the epoch moves past `seen`: spinning, then yielding, then asleep.
    fn wait_after(&self, seen: usize) -> usize {
        let start = Instant::now();
        let mut looks = 0u32;
        loop {
            let now = self.epoch.load(Ordering::Acquire);
            if now != seen {
                return now;
            }
            looks = looks.wrapping_add(1);
            if !looks.is_multiple_of(64) {
                std::hint::spin_loop();
                continue;
            }
            let idle = start.elapsed();
            if idle < SPIN {
                continue;
            }
            if idle < SPIN + YIELD {
                thread::yield_now();
                continue;
            }
            self.sleeping.fetch_add(1, Ordering::SeqCst);
            while self.epoch.load(Ordering::SeqCst) == seen {
                thread::park();
            }
            self.sleeping.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

/// Closes the region and waits for the helpers inside it to leave, also when the caller's own
/// share panicked.
struct Close<'r, 'a> {
    helpers: &'static Helpers,
    region: &'r Region<'a>,
}

impl Drop for Close<'_, '_> {
    fn drop(&mut self) {
        match self.helpers.open.lock() {
            Ok(mut open) => *open = 0,
            Err(poisoned) => *poisoned.into_inner() = 0,
        }
        while self.region.inside.load(Ordering::Acquire) != 0 {
            std::hint::spin_loop();
        }
    }
}

/// Calls `body(i)` for every i in 0..n on the calling thread and the helpers (rayon's thread
/// count less one), in no particular order, until a call returns false. Returns whether every
/// call returned true. A body that panics on a helper panics the caller.
pub fn try_for_each(n: usize, body: &(dyn Fn(usize) -> bool + Sync)) -> bool {
    let threads = rayon::current_num_threads();
    let helpers = helpers();
    let guard = if threads > 1 && rayon::current_thread_index().is_none() {
        helpers.busy.try_lock().ok()
    } else {
        None
    };
    let Some(_guard) = guard.filter(|_| helpers.ensure(threads - 1)) else {
        return (0..n).into_par_iter().all(body);
    };
    let region = Region {
        body,
        n,
        chunk: (n / (threads * CHUNKS_PER_THREAD)).max(1),
        next: AtomicUsize::new(0),
        stop: AtomicBool::new(false),
        panicked: AtomicBool::new(false),
        inside: AtomicUsize::new(0),
    };
    {
        let close = Close {
            helpers,
            region: &region,
        };
        match helpers.open.lock() {
            Ok(mut open) => *open = &region as *const Region as usize,
            Err(_) => return (0..n).into_par_iter().all(body),
        }
        helpers.epoch.fetch_add(1, Ordering::SeqCst);
        if helpers.sleeping.load(Ordering::SeqCst) > 0 {
            if let Ok(threads) = helpers.threads.lock() {
                threads.iter().for_each(Thread::unpark);
            }
        }
        region.work();
        drop(close);
    }
    if region.panicked.load(Ordering::Relaxed) {
        panic!("a helper thread panicked in a parallel loop");
    }
    !region.stop.load(Ordering::Relaxed)
}

/// A pointer that threads may share: each writes only its own part.
struct Parts<T>(*mut T);
impl<T> Clone for Parts<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Parts<T> {}
impl<T> Parts<T> {
    /// The address of value `i` (a method, so that closures capture the whole `Parts`).
    fn at(self, i: usize) -> *mut T {
        self.0.wrapping_add(i)
    }
}
// SAFETY: every index writes a part of its own (see `try_fill`)
unsafe impl<T: Send> Send for Parts<T> {}
unsafe impl<T: Send> Sync for Parts<T> {}

/// [`try_for_each`] with a slot for each index: `body(i, part)` may write the i-th `stride`
/// values of `out`. Returns whether every call returned true.
pub fn try_fill<T: Send>(
    out: &mut [T],
    stride: usize,
    body: impl Fn(usize, &mut [T]) -> bool + Sync,
) -> bool {
    assert!(stride > 0, "a slot holds at least one value");
    let n = out.len() / stride;
    let base = Parts(out.as_mut_ptr());
    try_for_each(n, &|i| {
        // SAFETY: the loop calls each index once, and index i touches only its own slot,
        // values i·stride .. (i + 1)·stride of `out`, which outlives the loop
        let part = unsafe { std::slice::from_raw_parts_mut(base.at(i * stride), stride) };
        body(i, part)
    })
}

/// `f(i)` for every i in 0..n, in index order (evaluated as [`try_for_each`] does).
pub fn map<R: Send>(n: usize, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
    let mut out: Vec<Option<R>> = (0..n).map(|_| None).collect();
    try_fill(&mut out, 1, |i, part| {
        part[0] = Some(f(i));
        true
    });
    out.into_iter()
        .map(|r| r.expect("the loop calls every index"))
        .collect()
}

/// Runs `a` and `b`, side by side where a helper is free (as [`try_for_each`] over two
/// indices).
pub fn join(a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
    let (a, b) = (Mutex::new(Some(a)), Mutex::new(Some(b)));
    try_for_each(2, &|i| {
        if i == 0 {
            if let Some(f) = a.lock().ok().and_then(|mut f| f.take()) {
                f();
            }
        } else if let Some(f) = b.lock().ok().and_then(|mut f| f.take()) {
            f();
        }
        true
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_once_and_stops_on_false() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        // from outside the pool, with helpers; then inside it, on rayon
        for inside in [false, true] {
            let counts: Vec<AtomicUsize> = (0..1000).map(|_| AtomicUsize::new(0)).collect();
            let run = || {
                try_for_each(1000, &|i| {
                    counts[i].fetch_add(1, Ordering::Relaxed);
                    true
                })
            };
            let all = if inside { pool.install(run) } else { run() };
            assert!(all);
            assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1));
            let stopped = try_for_each(1000, &|i| i != 500);
            assert!(!stopped);
        }
        // many regions in a row, with pauses that put the helpers to sleep
        for round in 0..50 {
            let sum = AtomicUsize::new(0);
            assert!(try_for_each(round, &|i| {
                sum.fetch_add(i + 1, Ordering::Relaxed);
                true
            }));
            assert_eq!(sum.load(Ordering::Relaxed), round * (round + 1) / 2);
            if round % 10 == 0 {
                thread::sleep(SPIN + YIELD + Duration::from_millis(1));
            }
        }
    }

    #[test]
    fn slots_and_maps_in_index_order() {
        let mut out = vec![0.0; 3 * 500];
        assert!(try_fill(&mut out, 3, |i, part| {
            part.iter_mut()
                .enumerate()
                .for_each(|(k, v)| *v = (3 * i + k) as f64);
            true
        }));
        assert!(out.iter().enumerate().all(|(k, &v)| v == k as f64));
        assert_eq!(
            map(300, |i| i * i),
            (0..300).map(|i| i * i).collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_nested_loop_runs_on_rayon() {
        let sum = AtomicUsize::new(0);
        assert!(try_for_each(10, &|_| {
            try_for_each(10, &|j| {
                sum.fetch_add(j, Ordering::Relaxed);
                true
            })
        }));
        assert_eq!(sum.load(Ordering::Relaxed), 450);
    }
}
