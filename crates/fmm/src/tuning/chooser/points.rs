//! The chooser straight from points: the parameters
//! ([`choose_parameters`]) and the float type ([`choose_precision`]) for a
//! tolerance, the inputs checked first.

use ferrofmm_kernels::{EvalMode, Precision, Real};
use ferrofmm_tree::DEEPEST_LEVEL;

use crate::FmmError;
use crate::tuning::error_model::f32_reaches;
use crate::tuning::occupancy::Occupancy;
use crate::validate::{check_sources_and_targets, validate_tolerance};

use super::{ChosenParameters, Tuner};

/// Choose order, leaf size and SVD tolerance for the Laplace FMM of these
/// points in float type `T` to the relative L2 potential error `eps`,
/// without building anything (what [`FmmBuilder::tolerance`](
/// crate::FmmBuilder::tolerance) does before building).
///
/// ```
/// use ferrofmm_fmm::{Geometry, tuning::{self, choose_parameters}};
/// let points: Vec<f64> = Geometry::Sphere.points(10_000, 3);
/// let c = choose_parameters(1e-7, &points, None).unwrap();
/// assert!(c.order >= 6);
/// assert!(tuning::SCENE_SAFETY_FACTOR * c.predicted_error <= 1e-7 * (1.0 + 1e-9));
/// let points32: Vec<f32> = points.iter().map(|&x| x as f32).collect();
/// assert!(choose_parameters(1e-7, &points32, None).is_err());
/// ```
pub fn choose_parameters<T: Real>(
    eps: f64,
    sources: &[T],
    targets: Option<&[T]>,
) -> Result<ChosenParameters, FmmError> {
    validate_tolerance(eps, T::PRECISION)?;
    check_sources_and_targets(sources, targets)?;
    let up = |p: &[T]| p.iter().map(|x| x.to_f64()).collect::<Vec<f64>>();
    let src = up(sources);
    let tgt = targets.map(up);
    Tuner::new(T::PRECISION).choose(eps, &src, tgt.as_deref(), None, DEEPEST_LEVEL)
}

/// The float type to use for `eps` on these points (`--precision auto`):
/// `f32` when the chooser finds an `f32` setting that reaches `eps` (it is
/// about twice as fast), else `f64` when that reaches it, else the `f64`
/// error ([`FmmError::ToleranceBeyondPrecision`] or
/// [`FmmError::InvalidTolerance`]).
///
/// ```
/// use ferrofmm_fmm::Geometry;
/// use ferrofmm_fmm::tuning::choose_precision;
/// use ferrofmm_kernels::{EvalMode, Precision};
/// let pot = EvalMode::Potential;
/// let cube: Vec<f64> = Geometry::Cube.points(5000, 1);
/// assert_eq!(choose_precision(1e-4, pot, &cube, None).unwrap(), Precision::F32);
/// assert_eq!(choose_precision(1e-8, pot, &cube, None).unwrap(), Precision::F64);
/// // f32 gradients level off near 5e-6.
/// let both = EvalMode::PotentialGradient;
/// assert_eq!(choose_precision(1e-5, both, &cube, None).unwrap(), Precision::F64);
/// // A cluster of size 1e-4 at (1, 1, 1): f32 cannot resolve it to 1e-4.
/// let clusters: Vec<f64> = Geometry::TwoClusters.points(5000, 1);
/// assert_eq!(choose_precision(1e-4, pot, &clusters, None).unwrap(), Precision::F64);
/// ```
pub fn choose_precision(
    eps: f64,
    mode: EvalMode,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Precision, FmmError> {
    let occupancy = checked_occupancy(eps, Precision::F64, sources, targets)?;
    if f32_reaches(eps)
        && Tuner::new(Precision::F32)
            .for_mode(mode)
            .choose_with(eps, &occupancy)
            .is_ok()
    {
        return Ok(Precision::F32);
    }
    Tuner::new(Precision::F64)
        .for_mode(mode)
        .choose_with(eps, &occupancy)
        .map(|_| Precision::F64)
}

/// The occupancy of checked inputs: `eps` for `precision`
/// ([`validate_tolerance`]) and the points ([`check_sources_and_targets`]),
/// in their bounding cube.
pub(super) fn checked_occupancy(
    eps: f64,
    precision: Precision,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Occupancy, FmmError> {
    validate_tolerance(eps, precision)?;
    check_sources_and_targets(sources, targets)?;
    Occupancy::new(sources, targets, None, DEEPEST_LEVEL)
}
