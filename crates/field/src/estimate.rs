//! Predicted cost of a precomputation ([`PrecomputeEstimate`]) and the
//! time model behind it: `seconds = flops / (R t)` with a sustained rate
//! `R` of [`FLOPS_PER_THREAD`] per worker thread and `t` the threads that
//! really run at once ([`effective_threads`]).
//!
//! Uses [`crate::threads`].

use crate::threads::effective_threads;

/// Predicted cost of an M2L precomputation (see
/// [`M2lScheme::estimate`](crate::M2lScheme::estimate)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrecomputeEstimate {
    /// Kernel matrices `K_v` to assemble.
    pub matrices: usize,
    /// Peak bytes held while precomputing (an upper bound: the stored
    /// operators plus the scratch of every worker thread).
    pub peak_bytes: u64,
    /// Floating-point operations (rough).
    pub flops: f64,
    /// Predicted seconds on `threads` threads (rough: a sustained rate of
    /// a few GFLOP/s per thread).
    pub seconds: f64,
}

/// Sustained precomputation rate per thread assumed by the estimates
/// (flop/s: blocked QR, SVD and kernel assembly on one core).
pub(crate) const FLOPS_PER_THREAD: f64 = 8e9;

/// Predicted seconds for `flops` floating-point operations on the
/// [`effective_threads`]: `flops / (FLOPS_PER_THREAD t)`.
pub(crate) fn seconds_for(flops: f64) -> f64 {
    flops / (FLOPS_PER_THREAD * effective_threads() as f64)
}
