//! The crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong while building translation operators.
///
/// Cache problems are **not** errors of the computation: a missing, stale,
/// truncated or corrupt cache file is recomputed (and rewritten), and a cache
/// that cannot be written only shows up in
/// [`CacheStatus`](crate::CacheStatus). The cache variants below are used by
/// the low-level cache routines and reported inside that status.
#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    /// [`OperatorParams`](crate::OperatorParams) (or a scheme configuration)
    /// failed validation; the message says which field and why.
    #[error("invalid operator parameters: {0}")]
    InvalidParams(String),

    /// Arguments of an operator constructor other than the parameters
    /// (domain width, depth) are unusable.
    #[error("invalid geometry: {0}")]
    InvalidGeometry(String),

    /// The pairs given to [`M2lInteractions`](crate::M2lInteractions) are
    /// inconsistent (column out of range, transfer vector not in the V-list
    /// set).
    #[error("invalid M2L interactions: {0}")]
    InvalidInteractions(String),

    /// The kernel returned NaN or infinity while assembling an operator
    /// (usually a kernel that is singular away from the origin, or surfaces
    /// that touch).
    #[error("kernel `{kernel}` returned a non-finite value while assembling {what}")]
    NonFiniteKernel {
        /// [`Kernel::name`](ferrofmm_kernels::Kernel::name).
        kernel: String,
        /// Which operator was being assembled.
        what: String,
    },

    /// A singular value decomposition did not converge.
    #[error("SVD did not converge while computing {what}")]
    SvdFailed {
        /// Which operator was being computed.
        what: String,
    },

    /// Reading or writing a cache file failed at the I/O level.
    #[error("cache I/O error at {}: {source}", path.display())]
    CacheIo {
        /// The cache file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// A cache file exists but cannot be trusted (wrong magic or format
    /// version, other parameters, truncated, bad checksum, inconsistent
    /// layout).
    #[error("cache file {} rejected: {reason}", path.display())]
    CacheInvalid {
        /// The cache file.
        path: PathBuf,
        /// Why it was rejected.
        reason: String,
    },

    /// The M2L scheme cannot translate this kernel (for a scheme written
    /// outside the crate, say, for scalar kernels only; the built-in
    /// schemes take every kernel).
    #[error("the {scheme} M2L scheme does not handle kernel `{kernel}`: {reason}")]
    UnsupportedKernel {
        /// The scheme's name.
        scheme: &'static str,
        /// The kernel's name.
        kernel: String,
        /// Why, and what to use instead.
        reason: &'static str,
    },
    /// The precomputation was cancelled through its
    /// [`PrecomputeMonitor`](crate::PrecomputeMonitor) (e.g. Ctrl-C).
    #[error("operator precomputation cancelled")]
    Cancelled,
}
