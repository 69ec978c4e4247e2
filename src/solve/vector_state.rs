//! The upper halves of the x86 vector registers after faer's kernels.
//!
//! faer's dense kernels (through `gemm` and `pulp`) run AVX and AVX-512 code chosen at run time,
//! and can return with the upper halves of the vector registers still in use ("dirty"). The rest
//! of deasim is compiled for the baseline x86-64 and runs legacy SSE instructions; on a thread
//! whose upper state is dirty every such instruction waits on the merge with those upper bits.
//! Measured on this project's machine (`deasim bench --speed`, the film 40 × 40 × 8 on 2
//! threads): after a run, the pool's threads assembled a tangent at 2.07 µs a quadrature point
//! against 0.78 µs once cleared, and a residual at 113 against 54 ns. `vzeroupper` clears the
//! state; it changes no value the program holds (SSE code uses only the lower halves), so the
//! results are the same bits. On other architectures, and on x86-64 without AVX, nothing is done.

use faer::Par;

/// Clears the upper vector state of this thread.
#[inline]
pub fn clear_here() {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked above.
        unsafe { zero_upper() }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn zero_upper() {
    std::arch::x86_64::_mm256_zeroupper();
}

/// The order of a system below which the pool's threads are not cleared after a faer call on
/// it: the broadcast costs tens of µs and wakes every thread, which on small systems solved
/// thousands of times (an adjoint sweep of an axisymmetric model) cost more than the whole
/// solve (measured: the adjoint of `diaphragm-control`'s 300 steps spent 0.20 s of system
/// time on broadcasts against 0.18 s of work). The slowdown a dirty state causes is a fraction
/// of the next assembly, which on such a system takes microseconds.
pub const BROADCAST_ORDER: usize = 5_000;

/// Clears the upper vector state of the threads that ran a faer call with `par` on a system of
/// order `n`: this one, and with a parallel call made from outside the pool on a system of at
/// least [`BROADCAST_ORDER`] unknowns, every thread of the pool (a call from one of its threads
/// clears only that one: a broadcast would wait on the others' work).
pub fn clear_after(par: Par, n: usize) {
    clear_here();
    if !matches!(par, Par::Seq)
        && n >= BROADCAST_ORDER
        && rayon::current_num_threads() > 1
        && rayon::current_thread_index().is_none()
    {
        rayon::broadcast(|_| clear_here());
    }
}
