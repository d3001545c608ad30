//! Errors reported by the checked entry points of this crate.

use thiserror::Error;

/// Invalid input to a checked kernel evaluation such as
/// [`direct_sum_checked`](crate::direct_sum_checked) or
/// [`check_inputs`](crate::check_inputs).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum KernelError {
    /// A coordinate slice whose length is not a multiple of 3 (points are
    /// interleaved `[x0, y0, z0, x1, ...]`).
    #[error("{what} has {len} coordinates, which is not a multiple of 3 (interleaved xyz)")]
    NotMultipleOf3 {
        /// `"sources"` or `"targets"`.
        what: &'static str,
        /// The offending slice length.
        len: usize,
    },
    /// `charges.len()` differs from the number of sources.
    #[error("{n_sources} sources but {n_charges} charges")]
    ChargesLength {
        /// `sources.len() / 3`.
        n_sources: usize,
        /// `charges.len()`.
        n_charges: usize,
    },
    /// `out.len()` differs from `values_per_target * n_targets`.
    #[error("output has {found} values, expected {expected} ({values_per_target} per target)")]
    OutputLength {
        /// `values_per_target * n_targets`.
        expected: usize,
        /// `out.len()`.
        found: usize,
        /// 1 (potential) or 4 (potential + gradient).
        values_per_target: usize,
    },
    /// A coordinate or charge is NaN or infinite.
    #[error("{what}[{index}] is not finite ({value})")]
    NonFinite {
        /// `"sources"`, `"targets"` or `"charges"`.
        what: &'static str,
        /// Index into that slice.
        index: usize,
        /// The value, as `f64`.
        value: f64,
    },
    /// A kernel parameter outside its valid range.
    #[error("kernel parameter {name} = {value} is invalid (expected {expected})")]
    InvalidParameter {
        /// The parameter's name, e.g. `"k"`.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What would have been accepted.
        expected: &'static str,
    },
}
