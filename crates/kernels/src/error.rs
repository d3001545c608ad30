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
    /// The densities of sources with dipoles do not match the number of
    /// sources (`per_source` values each, interleaved).
    #[error("{n_sources} sources with {kind} densities need {per_source} values each ({expected} in all), found {found}", expected = per_source * n_sources)]
    DensitiesLength {
        /// `sources.len() / 3`.
        n_sources: usize,
        /// The source kind's name, e.g. `"dipole"`.
        kind: &'static str,
        /// Values per source: 3 for dipoles, 4 for charge + dipole.
        per_source: usize,
        /// `densities.len()`.
        found: usize,
    },
    /// The kernel does not evaluate this source kind with these outputs
    /// (see `Kernel::supports`).
    #[error("kernel {kernel} does not support {kind} sources with {mode} outputs")]
    Unsupported {
        /// The kernel's name.
        kernel: String,
        /// The source kind's name.
        kind: &'static str,
        /// The evaluation mode's name.
        mode: &'static str,
    },
    /// `out.len()` differs from `values_per_target * n_targets`.
    #[error("output has {found} values, expected {expected} ({values_per_target} per target)")]
    OutputLength {
        /// `values_per_target * n_targets`.
        expected: usize,
        /// `out.len()`.
        found: usize,
        /// 1 (potential), 4 (+ gradient) or 10 (+ Hessian).
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
    /// A periodic cell whose origin is not finite or whose side length is
    /// not finite and positive.
    #[error("periodic cell {what}[{axis}] = {value} is invalid (expected {expected})")]
    InvalidCell {
        /// `"origin"` or `"lengths"`.
        what: &'static str,
        /// The axis, 0 (x), 1 (y) or 2 (z).
        axis: usize,
        /// The rejected value.
        value: f64,
        /// What would have been accepted.
        expected: &'static str,
    },
    /// A source index out of range (e.g. a target of
    /// [`EwaldSum::at_sources`](crate::EwaldSum::at_sources)).
    #[error("source index {index} out of range ({n_sources} sources)")]
    SourceIndex {
        /// The offending index.
        index: usize,
        /// The number of sources.
        n_sources: usize,
    },
}

/// `k` when it is a valid wavenumber (finite and `>= 0`) of either
/// Helmholtz kernel.
///
/// # Errors
/// [`KernelError::InvalidParameter`] otherwise.
pub(crate) fn check_wavenumber(k: f64) -> Result<f64, KernelError> {
    check_parameter("k", k)
}

/// `value` when it is finite and non-negative,
/// [`KernelError::InvalidParameter`] naming `name` otherwise.
pub(crate) fn check_parameter(name: &'static str, value: f64) -> Result<f64, KernelError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(KernelError::InvalidParameter {
            name,
            value,
            expected: "finite and >= 0",
        })
    }
}
