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

/// Clears the upper vector state of the threads that ran a faer call with `par`: this one, and
/// with a parallel call made from outside the pool, every thread of the pool (a call from one of
/// its threads clears only that one: a broadcast would wait on the others' work).
pub fn clear_after(par: Par) {
    clear_here();
    if !matches!(par, Par::Seq)
        && rayon::current_num_threads() > 1
        && rayon::current_thread_index().is_none()
    {
        rayon::broadcast(|_| clear_here());
    }
}
