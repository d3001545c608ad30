//! The last check of an evaluation: every value is finite.
//!
//! Finite coordinates and densities can still give infinite or NaN
//! results: `sum_i q_i K(x_i, y)` overflows the float type when the
//! densities are within a few orders of its largest value (`|q| ~ 1e307`
//! in `f64`, `1e37` in `f32`), or when a user kernel is singular at
//! distances the points reach. Such values are never returned as a result:
//! the evaluation fails with [`FmmError::NonFiniteResult`], which names
//! the first bad value and the largest density, so the caller can rescale
//! (the potential is linear in the densities).

use ferrofmm_kernels::Real;
use rayon::prelude::*;

use crate::FmmError;

/// `Ok` when every entry of `values` is finite, else
/// [`FmmError::NonFiniteResult`] for the first that is not.
///
/// `values` holds `per_target` values per target (as [`crate::Fmm::evaluate`]
/// returns them); `densities` are the charges (or dipole densities) that
/// produced them, for the message. Runs in parallel; a small fraction of
/// an evaluation's time (one pass over the output).
///
/// ```
/// use ferrofmm_fmm::{FmmError, check_finite_output};
/// assert!(check_finite_output(&[1.0f64, 2.0], 1, &[1.0]).is_ok());
/// let err = check_finite_output(&[1.0f64, f64::INFINITY], 1, &[1e308]).unwrap_err();
/// assert!(matches!(err, FmmError::NonFiniteResult { target: 1, .. }));
/// ```
pub fn check_finite_output<T: Real>(
    values: &[T],
    per_target: usize,
    densities: &[T],
) -> Result<(), FmmError> {
    let Some(index) = values.par_iter().position_first(|v| !v.is_finite()) else {
        return Ok(());
    };
    let largest = densities
        .par_iter()
        .map(|q| q.to_f64().abs())
        .reduce(|| 0.0, f64::max);
    let per_target = per_target.max(1);
    Err(FmmError::NonFiniteResult {
        target: index / per_target,
        component: index % per_target,
        value: values[index].to_f64(),
        largest_density: largest,
        precision: T::PRECISION.name(),
    })
}
