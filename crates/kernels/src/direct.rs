//! Parallel direct summation: the `O(N M)` reference the FMM is measured
//! against, and the fastest method for small problems.

use rayon::prelude::*;

use crate::{EvalMode, Kernel, KernelError, Real};

/// Targets per rayon task in [`direct_sum`].
pub const DIRECT_SUM_BLOCK: usize = 256;

/// Accumulate `out[j] += sum_i K(x_i, y_j) q_i` (and gradients for
/// [`EvalMode::PotentialGradient`]) by direct summation, in parallel over
/// blocks of [`DIRECT_SUM_BLOCK`] targets (each block one
/// [`Kernel::evaluate`] call over all sources, so every target's sum is
/// identical to a serial `evaluate`).
///
/// Layout as in [`Kernel`]: interleaved xyz, `mode.values_per_target()`
/// outputs per target.
///
/// # Panics
/// When lengths are inconsistent; [`direct_sum_checked`] reports them (and
/// non-finite input) as errors instead.
///
/// ```
/// use ferrofmm_kernels::{direct_sum, EvalMode, Laplace3d};
/// let points = [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0];
/// let mut phi = [0.0f64; 2];
/// direct_sum(&Laplace3d, EvalMode::Potential, &points, &[1.0, 1.0], &points, &mut phi);
/// let k = 1.0 / (4.0 * std::f64::consts::PI);
/// assert!((phi[0] - k).abs() < 1e-16 && (phi[1] - k).abs() < 1e-16);
/// ```
pub fn direct_sum<K: Kernel, T: Real>(
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    if let Err(e) = check_lengths(mode, sources, charges, targets, out) {
        panic!("direct_sum: {e}");
    }
    let w = mode.values_per_target();
    targets
        .par_chunks(3 * DIRECT_SUM_BLOCK)
        .zip(out.par_chunks_mut(w * DIRECT_SUM_BLOCK))
        .for_each(|(t, o)| kernel.evaluate(mode, sources, charges, t, o));
}

/// [`direct_sum`] after [`check_inputs`].
///
/// # Errors
/// See [`check_inputs`]; `out` is untouched on error.
///
/// ```
/// use ferrofmm_kernels::{direct_sum_checked, EvalMode, KernelError, Laplace3d};
/// let mut out = [0.0f64; 4];
/// let err = direct_sum_checked(&Laplace3d, EvalMode::Potential, &[0.0; 3], &[1.0], &[1.0; 3], &mut out);
/// assert!(matches!(err, Err(KernelError::OutputLength { expected: 1, found: 4, .. })));
/// ```
pub fn direct_sum_checked<K: Kernel, T: Real>(
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) -> Result<(), KernelError> {
    check_inputs(mode, sources, charges, targets, out)?;
    direct_sum(kernel, mode, sources, charges, targets, out);
    Ok(())
}

/// Validate an evaluation's inputs: coordinate lengths are multiples of 3,
/// one charge per source, `mode.values_per_target()` outputs per target, and
/// every coordinate and charge is finite.
///
/// # Errors
/// The first problem found, as a [`KernelError`].
pub fn check_inputs<T: Real>(
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &[T],
) -> Result<(), KernelError> {
    check_lengths(mode, sources, charges, targets, out)?;
    for (what, values) in [
        ("sources", sources),
        ("charges", charges),
        ("targets", targets),
    ] {
        if let Some((index, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(KernelError::NonFinite {
                what,
                index,
                value: v.to_f64(),
            });
        }
    }
    Ok(())
}

pub(crate) fn check_lengths<T: Real>(
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &[T],
) -> Result<(), KernelError> {
    for (what, p) in [("sources", sources), ("targets", targets)] {
        if !p.len().is_multiple_of(3) {
            return Err(KernelError::NotMultipleOf3 { what, len: p.len() });
        }
    }
    if charges.len() != sources.len() / 3 {
        return Err(KernelError::ChargesLength {
            n_sources: sources.len() / 3,
            n_charges: charges.len(),
        });
    }
    let w = mode.values_per_target();
    let expected = w * (targets.len() / 3);
    if out.len() != expected {
        return Err(KernelError::OutputLength {
            expected,
            found: out.len(),
            values_per_target: w,
        });
    }
    Ok(())
}
