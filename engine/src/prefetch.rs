//! A hint to the CPU to bring a value into its cache ahead of use.
//!
//! The removal pass reads the rays it intersects in an order known a few rays ahead
//! (the candidates of a row), each after some hundreds of instructions of exact
//! geometry: fetching the next one while the current is solved hides the wait for
//! memory that the first read of each ray otherwise costs. A tilted flank's engagement
//! finds the Z rays of a batch of test points before it reads them, and asks for them
//! all first.

/// Asks for the cache line holding `value` (no effect on the program's results; a no-op
/// off x86-64).
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch only hints the cache; it never dereferences the address, and
    // this one comes from a reference, so it is valid in any case. SSE is part of the
    // x86-64 baseline.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
