//! Parallel direct summation: the `O(N M)` reference the FMM is measured
//! against, and the fastest method for small problems.

use rayon::prelude::*;

use crate::{EvalMode, Kernel, KernelError, Real, SourceKind};

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
    direct_sum_sources(
        kernel,
        SourceKind::Charge,
        mode,
        sources,
        charges,
        targets,
        out,
    );
}

/// [`direct_sum`] for sources of any [`SourceKind`] (charges, dipoles or
/// both; `densities` interleaved, [`SourceKind::values_per_source`] per
/// source) through [`Kernel::evaluate_sources`]:
///
/// ```text
/// out_j += sum_i D_y^m [ q_i K(x_i, y_j) + n_i . grad_x K(x_i, y_j) ]
/// ```
///
/// # Panics
/// When lengths are inconsistent or the kernel does not
/// [support](Kernel::supports) `(kind, mode)`;
/// [`direct_sum_sources_checked`] reports both as errors instead.
///
/// ```
/// use ferrofmm_kernels::{direct_sum_sources, EvalMode, Laplace3d, SourceKind};
/// // A unit dipole along z at the origin, seen from (0, 0, 2).
/// let mut out = [0.0f64; 10]; // [u, grad u, H11, H22, H33, H12, H13, H23]
/// direct_sum_sources(&Laplace3d, SourceKind::Dipole, EvalMode::PotentialGradientHessian,
///     &[0.0; 3], &[0.0, 0.0, 1.0], &[0.0, 0.0, 2.0], &mut out);
/// let k = 1.0 / (4.0 * std::f64::consts::PI);
/// assert!((out[0] - k / 4.0).abs() < 1e-16); // n . (y - x) / (4 pi r^3) = 1 / (4 pi z^2)
/// assert!((out[3] + k / 4.0).abs() < 1e-16); // d/dz: -2 / (4 pi z^3)
/// assert!((out[6] - 3.0 * k / 8.0).abs() < 1e-16); // d2/dz2: 6 / (4 pi z^4)
/// ```
#[allow(clippy::too_many_arguments)]
pub fn direct_sum_sources<K: Kernel, T: Real>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let slices = [sources, densities, targets, &*out];
    assert_evaluation(|| "direct_sum".into(), kernel, kind, mode, slices);
    let w = kernel.values_per_target(mode);
    targets
        .par_chunks(3 * DIRECT_SUM_BLOCK)
        .zip(out.par_chunks_mut(w * DIRECT_SUM_BLOCK))
        .for_each(|(t, o)| kernel.evaluate_sources(kind, mode, sources, densities, t, o));
}

/// [`direct_sum_sources`] after [`check_source_inputs`] and
/// [`Kernel::supports`].
///
/// # Errors
/// See [`check_source_inputs`], and [`KernelError::Unsupported`]; `out` is
/// untouched on error.
#[allow(clippy::too_many_arguments)]
pub fn direct_sum_sources_checked<K: Kernel, T: Real>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &mut [T],
) -> Result<(), KernelError> {
    check_kernel_inputs(kernel, kind, mode, sources, densities, targets, out)?;
    if !kernel.supports(kind, mode) {
        return Err(KernelError::Unsupported {
            kernel: kernel.name(),
            kind: kind.name(),
            mode: mode.name(),
        });
    }
    direct_sum_sources(kernel, kind, mode, sources, densities, targets, out);
    Ok(())
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
    direct_sum_sources_checked(
        kernel,
        SourceKind::Charge,
        mode,
        sources,
        charges,
        targets,
        out,
    )
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
    check_source_inputs(SourceKind::Charge, mode, sources, charges, targets, out)
}

/// [`check_inputs`] for sources of any [`SourceKind`]:
/// `kind.values_per_source()` densities per source.
///
/// # Errors
/// The first problem found, as a [`KernelError`].
pub fn check_source_inputs<T: Real>(
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &[T],
) -> Result<(), KernelError> {
    check_values(1, kind, mode, [sources, densities, targets, out])
}

/// [`check_source_inputs`] for `kernel`, whose densities and outputs have
/// [`Kernel::components`] values per quantity
/// ([`Kernel::values_per_source`] per source,
/// [`Kernel::values_per_target`] per target).
///
/// # Errors
/// The first problem found, as a [`KernelError`].
pub fn check_kernel_inputs<K: Kernel, T: Real>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &[T],
) -> Result<(), KernelError> {
    let slices = [sources, densities, targets, out];
    check_values(kernel.components(), kind, mode, slices)
}

/// Lengths, then finiteness, for `components` values per quantity, of
/// `[sources, densities, targets, out]`.
fn check_values<T: Real>(
    components: usize,
    kind: SourceKind,
    mode: EvalMode,
    slices: [&[T]; 4],
) -> Result<(), KernelError> {
    check_lengths(components, kind, mode, slices)?;
    let [sources, densities, targets, _] = slices;
    let densities_name = match kind {
        SourceKind::Charge => "charges",
        SourceKind::Dipole => "dipoles",
        SourceKind::ChargeDipole => "densities",
    };
    for (what, values) in [
        ("sources", sources),
        (densities_name, densities),
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

/// Panic, `context()` first, when `slices` (`[sources, densities,
/// targets, out]`) do not have the lengths of an evaluation of `kernel` in
/// `mode`, or the kernel does not [support](Kernel::supports) `(kind,
/// mode)`: what the unchecked evaluations refuse ([`direct_sum_sources`],
/// [`lanes::evaluate_sources_with`](crate::lanes::evaluate_sources_with)).
pub(crate) fn assert_evaluation<K: Kernel, T: Real>(
    context: impl Fn() -> String,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    slices: [&[T]; 4],
) {
    if let Err(e) = check_lengths(kernel.components(), kind, mode, slices) {
        panic!("{}: {e}", context());
    }
    assert!(
        kernel.supports(kind, mode),
        "{}: {} sources with {} outputs are not supported (Kernel::supports)",
        context(),
        kind.name(),
        mode.name()
    );
}

/// Lengths of an evaluation with `components` values per quantity:
/// `[sources, densities, targets, out]`.
pub(crate) fn check_lengths<T: Real>(
    components: usize,
    kind: SourceKind,
    mode: EvalMode,
    [sources, densities, targets, out]: [&[T]; 4],
) -> Result<(), KernelError> {
    for (what, p) in [("sources", sources), ("targets", targets)] {
        if !p.len().is_multiple_of(3) {
            return Err(KernelError::NotMultipleOf3 { what, len: p.len() });
        }
    }
    let n_sources = sources.len() / 3;
    if kind == SourceKind::Charge && components == 1 && densities.len() != n_sources {
        return Err(KernelError::ChargesLength {
            n_sources,
            n_charges: densities.len(),
        });
    }
    let per_source = components * kind.values_per_source();
    if densities.len() != per_source * n_sources {
        return Err(KernelError::DensitiesLength {
            n_sources,
            kind: kind.name(),
            per_source,
            found: densities.len(),
        });
    }
    let w = components * mode.values_per_target();
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
