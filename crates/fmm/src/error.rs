//! Typed errors of the FMM driver.

use ferrofmm_field::FieldError;
use ferrofmm_kernels::KernelError;
use ferrofmm_tree::TreeError;

/// Everything that can go wrong building or evaluating an [`crate::Fmm`].
///
/// Bad user input always ends here, never in a panic.
#[derive(Debug, thiserror::Error)]
pub enum FmmError {
    /// The point set or tree parameters were rejected by the octree.
    #[error("tree: {0}")]
    Tree(#[from] TreeError),
    /// The translation operators could not be built.
    #[error("operators: {0}")]
    Field(#[from] FieldError),
    /// A kernel rejected its inputs or parameters.
    #[error("kernel: {0}")]
    Kernel(#[from] KernelError),
    /// The expansion order is outside the supported range.
    #[error("expansion order {order} is not supported (use {min}..={max})")]
    InvalidOrder {
        /// The order asked for.
        order: usize,
        /// Smallest supported order.
        min: usize,
        /// Largest supported order.
        max: usize,
    },
    /// `leaf_size` must be at least 1.
    #[error("leaf size must be at least 1 (got {0})")]
    InvalidLeafSize(usize),
    /// A coordinate array whose length is not a multiple of 3.
    #[error("{what} has {len} values, which is not a multiple of 3 (interleaved x, y, z)")]
    RaggedPoints {
        /// "sources" or "targets".
        what: &'static str,
        /// Length of the array.
        len: usize,
    },
    /// No points given.
    #[error("{0} are empty")]
    Empty(&'static str),
    /// A NaN or infinite coordinate.
    #[error("{what} coordinate {index} is not finite ({value})")]
    NonFiniteCoordinate {
        /// "sources" or "targets".
        what: &'static str,
        /// Index into the flat coordinate array.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The charge array does not match the number of sources.
    #[error("expected {expected} charges (one per source per vector), got {got}")]
    ChargeCount {
        /// Number of charges expected.
        expected: usize,
        /// Number given.
        got: usize,
    },
    /// A NaN or infinite charge.
    #[error("charge {index} is not finite ({value})")]
    NonFiniteCharge {
        /// Index into the flat charge array.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A tolerance outside (0, 1) or otherwise unreachable.
    #[error("invalid tolerance {0}: use a value in (0, 1), e.g. 1e-6")]
    InvalidTolerance(f64),
    /// Any other impossible parameter.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
}
