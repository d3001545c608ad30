//! Validation of the inputs, before any work: every check that refuses a
//! parameter, a point set, a density vector, a tolerance, a domain or a
//! wavenumber lives here, and the builder ([`crate::FmmBuilder`]), the
//! parameter chooser ([`crate::tuning`]), the error model and
//! [`crate::TreeFmm`] call the same functions, so one input gets one
//! answer whichever path meets it first.
//!
//! * Points: non-empty, a multiple of 3, finite ([`check_points`]); for a
//!   caller's tree, arrays that hold its ranges ([`check_tree_points`]).
//! * Parameters: order in `MIN_ORDER..=MAX_ORDER` ([`check_order`]), a
//!   positive leaf size, a level a Morton key holds, a kernel that supports
//!   the source kind and the evaluation mode ([`check_parameters`]).
//! * Tolerance: `eps` in `(0, 1)` and no smaller than the float type can
//!   promise ([`validate_tolerance`]).
//! * Domain: a width whose smallest and largest distances the float type
//!   represents at the tree's depth ([`check_domain_width`], from
//!   [`width_range`]).
//! * Wavenumber: `k W <=` [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH)
//!   ([`check_wavenumber`]).
//! * Densities given in `f64`: representable in the run's float type
//!   ([`check_representable`]).
//!
//! The result of an evaluation is checked after it
//! ([`crate::check_finite_output`], in `overflow`).

use std::ops::Range;

use ferrofmm_field::{MAX_ORDER, MIN_ORDER};
use ferrofmm_kernels::{EvalMode, Kernel, KernelError, Precision, Real, SourceKind};
use ferrofmm_tree::{DEEPEST_LEVEL, Octree};
use rayon::prelude::*;

use crate::FmmError;
use crate::tuning::smallest_tolerance;

/// An expansion order in `MIN_ORDER..=MAX_ORDER`
/// ([`FmmError::InvalidOrder`]).
pub(crate) fn check_order(order: usize) -> Result<(), FmmError> {
    if !(MIN_ORDER..=MAX_ORDER).contains(&order) {
        return Err(FmmError::InvalidOrder {
            order,
            min: MIN_ORDER,
            max: MAX_ORDER,
        });
    }
    Ok(())
}

/// Point arrays (`sources_len`, `targets_len` values, three per point)
/// that hold every point the ranges of `tree` index
/// ([`FmmError::InvalidParameter`] otherwise): what [`crate::TreeFmm`]
/// needs of a caller's tree and points.
pub(crate) fn check_tree_points(
    tree: &Octree,
    sources_len: usize,
    targets_len: usize,
) -> Result<(), FmmError> {
    let reach = |len: usize, r: &dyn Fn(usize) -> Range<usize>| {
        (0..tree.n_boxes()).all(|b| r(b).end <= len / 3) && len.is_multiple_of(3)
    };
    if !reach(sources_len, &|b| tree.source_range(b))
        || !reach(targets_len, &|b| tree.target_range(b))
    {
        return Err(FmmError::InvalidParameter(
            "TreeFmm: point arrays shorter than the tree's ranges".into(),
        ));
    }
    Ok(())
}

/// The build parameters that do not depend on the points: the kernel
/// supports `kind` and `mode` ([`KernelError::Unsupported`]), the tolerance
/// when one is asked for ([`validate_tolerance`]), the order
/// ([`check_order`]), a leaf size of at least 1 and a `max_level` of at
/// most [`DEEPEST_LEVEL`].
pub(crate) fn check_parameters<K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    tolerance: Option<(f64, Precision)>,
    order: usize,
    leaf_size: usize,
    max_level: u32,
) -> Result<(), FmmError> {
    if !kernel.supports(kind, mode) {
        return Err(FmmError::Kernel(KernelError::Unsupported {
            kernel: kernel.name(),
            kind: kind.name(),
            mode: mode.name(),
        }));
    }
    if let Some((eps, precision)) = tolerance {
        validate_tolerance(eps, precision)?;
    }
    check_order(order)?;
    if leaf_size == 0 {
        return Err(FmmError::InvalidLeafSize(0));
    }
    if max_level > DEEPEST_LEVEL {
        return Err(FmmError::InvalidParameter(format!(
            "max_level {max_level} exceeds the deepest level {DEEPEST_LEVEL} a Morton key can hold"
        )));
    }
    Ok(())
}

/// [`check_points`] on the sources and, when given, the targets.
pub(crate) fn check_sources_and_targets<T: Real>(
    sources: &[T],
    targets: Option<&[T]>,
) -> Result<(), FmmError> {
    check_points("sources", sources)?;
    if let Some(t) = targets {
        check_points("targets", t)?;
    }
    Ok(())
}

/// Non-empty, a multiple of 3, all finite.
pub(crate) fn check_points<T: Real>(what: &'static str, points: &[T]) -> Result<(), FmmError> {
    if points.is_empty() {
        return Err(FmmError::Empty(what));
    }
    if !points.len().is_multiple_of(3) {
        return Err(FmmError::RaggedPoints {
            what,
            len: points.len(),
        });
    }
    if let Some(index) = points.iter().position(|x| !x.is_finite()) {
        return Err(FmmError::NonFiniteCoordinate {
            what,
            index,
            value: points[index].to_f64(),
        });
    }
    Ok(())
}

/// Check a tolerance before looking at the points: `eps` in `(0, 1)`
/// ([`FmmError::InvalidTolerance`]) and at least [`smallest_tolerance`]
/// ([`FmmError::ToleranceBeyondPrecision`]). The chooser may still refuse
/// it for points that need more digits than the float type has.
pub fn validate_tolerance(eps: f64, precision: Precision) -> Result<(), FmmError> {
    if !(eps.is_finite() && eps > 0.0 && eps < 1.0) {
        return Err(FmmError::InvalidTolerance(eps));
    }
    let limit = smallest_tolerance(precision);
    if eps < limit {
        return Err(FmmError::ToleranceBeyondPrecision {
            tolerance: eps,
            precision: precision.name(),
            limit,
        });
    }
    Ok(())
}

/// Domain widths `T` resolves in a tree of depth `depth`, `(min, max)`.
///
/// Kernel evaluations in the passes involve distances from about a quarter
/// of the deepest boxes' width (points to the surfaces of their own or
/// neighbouring boxes) up to a few domain widths (surfaces of level-1 boxes
/// and their check surfaces): with `W` the width and `h = W / 2^(depth+1)`,
/// `(h / 2)^2` must not underflow (`>= MIN_POSITIVE`, else pairs silently
/// count as coincident) and `64 W^2` must not overflow.
pub(crate) fn width_range(precision: Precision, depth: u32) -> (f64, f64) {
    let largest = largest(precision);
    let smallest = match precision {
        Precision::F32 => f32::MIN_POSITIVE as f64,
        Precision::F64 => f64::MIN_POSITIVE,
    };
    let min = smallest.sqrt() * 2f64.powi(depth as i32 + 2);
    (min, largest.sqrt() / 8.0)
}

/// [`FmmError::DomainOutOfRange`] for a domain width a tree of depth
/// `depth` does not resolve in `precision` (outside [`width_range`]).
/// Depth 0 (no tree resolves it) is checked before parameters are chosen
/// for a tolerance, whose error model would otherwise only find that no
/// order reaches it; the built tree's depth before its operators.
pub(crate) fn check_domain_width(
    width: f64,
    precision: Precision,
    depth: u32,
) -> Result<(), FmmError> {
    let (min, max) = width_range(precision, depth);
    if (min..=max).contains(&width) {
        return Ok(());
    }
    Err(FmmError::DomainOutOfRange {
        width,
        min,
        max,
        depth,
        precision: precision.name(),
    })
}

/// Relative room above [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH)
/// for the root box's padding (see [`check_wavenumber`]).
pub(crate) const WAVENUMBER_WIDTH_SLACK: f64 = 1e-5;

/// [`FmmError::BeyondLowFrequency`] when `k W` exceeds
/// [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH) for the kernel's
/// wavenumber `k` and the domain width `W`.
///
/// The comparison allows a relative [`WAVENUMBER_WIDTH_SLACK`]: the tree's
/// root is the points' bounding cube enlarged by about `2^-20` of its width
/// (so that every point lies strictly inside), and points whose extent is
/// exactly `100 / k` (`k D = 100`, the limit as users state it) must pass.
pub(crate) fn check_wavenumber<K: Kernel>(kernel: &K, width: f64) -> Result<(), FmmError> {
    let k = kernel.wavenumber();
    if k * width > crate::MAX_WAVENUMBER_WIDTH * (1.0 + WAVENUMBER_WIDTH_SLACK) {
        return Err(FmmError::BeyondLowFrequency {
            kernel: kernel.name(),
            wavenumber: k,
            width,
            limit: crate::MAX_WAVENUMBER_WIDTH,
        });
    }
    Ok(())
}

/// The largest finite value of `precision`, as `f64`.
pub(crate) fn largest(precision: Precision) -> f64 {
    match precision {
        Precision::F32 => f64::from(f32::MAX),
        Precision::F64 => f64::MAX,
    }
}

/// `Ok` when every density given in `f64` is representable in the run's
/// float type `T`, else [`FmmError::DensityBeyondPrecision`] for the first
/// that is not: converted, it would become infinite (`1e39` in `f32`), and
/// the evaluation would report a non-finite charge the caller never gave.
///
/// ```
/// use ferrofmm_fmm::{FmmError, check_representable};
/// assert!(check_representable::<f32>(&[1e38, -2.0]).is_ok());
/// let err = check_representable::<f32>(&[1.0, -1e39]).unwrap_err();
/// assert!(matches!(err, FmmError::DensityBeyondPrecision { index: 1, .. }));
/// ```
pub fn check_representable<T: Real>(densities: &[f64]) -> Result<(), FmmError> {
    let limit = largest(T::PRECISION);
    match densities.par_iter().position_first(|x| x.abs() > limit) {
        None => Ok(()),
        Some(index) => Err(FmmError::DensityBeyondPrecision {
            index,
            value: densities[index],
            largest: limit,
            precision: T::PRECISION.name(),
        }),
    }
}

#[cfg(test)]
mod tests {
    /// With a tolerance, a domain beyond the float type and a wavenumber
    /// beyond the low-frequency limit are refused with the build's own
    /// errors (naming the cause), not "no order reaches eps" (whose limit
    /// was `inf`), in every path that chooses parameters.
    #[test]
    fn tolerance_paths_name_the_cause() {
        use crate::tuning::choose_scheme;
        use crate::{FmmBuilder, FmmError};
        use ferrofmm_kernels::{EvalMode, Helmholtz3d, Precision};
        let unit: Vec<f64> = (0..600)
            .map(|i| ((i * 7919) % 997) as f64 / 997.0)
            .collect();
        for scale in [1e300, 1e-300] {
            let x: Vec<f64> = unit.iter().map(|v| v * scale).collect();
            let built = FmmBuilder::new(&x).tolerance(1e-6).build_dense();
            assert!(
                matches!(built, Err(FmmError::DomainOutOfRange { .. })),
                "{scale}"
            );
            let chosen = choose_scheme(1e-6, EvalMode::Potential, Precision::F64, &x, None, false);
            assert!(
                matches!(chosen, Err(FmmError::DomainOutOfRange { .. })),
                "{scale}"
            );
        }
        let x32: Vec<f32> = unit.iter().map(|v| (v * 1e20) as f32).collect();
        let built = FmmBuilder::new(&x32).tolerance(1e-3).build_dense();
        assert!(matches!(built, Err(FmmError::DomainOutOfRange { .. })));
        let built = FmmBuilder::new(&unit)
            .kernel(Helmholtz3d::new(1e6).unwrap())
            .tolerance(1e-6)
            .build_dense();
        match built {
            Err(e @ FmmError::BeyondLowFrequency { .. }) => {
                assert!(e.to_string().contains("narrower than 1.000e-4"), "{e}");
            }
            other => panic!("{:?}", other.err()),
        }
    }

    /// Points spanning exactly `100 / k` (`k D = 100`) pass although the
    /// root box is a little wider than they are; 1% more is refused.
    #[test]
    fn the_wavenumber_limit_is_k_times_the_points_extent() {
        use crate::FmmError;
        use ferrofmm_kernels::Helmholtz3d;
        use ferrofmm_tree::Domain;
        let x = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.3, 0.7, 0.2];
        let d = Domain::from_points(&[&x]).unwrap();
        assert!(d.width > 1.0);
        let at = |k: f64| super::check_wavenumber(&Helmholtz3d::new(k).unwrap(), d.width);
        assert!(at(crate::MAX_WAVENUMBER_WIDTH).is_ok());
        assert!(matches!(
            at(1.01 * crate::MAX_WAVENUMBER_WIDTH),
            Err(FmmError::BeyondLowFrequency { .. })
        ));
    }
}
