//! The M2L scheme chosen with the parameters: SVD or FFT, whichever is
//! predicted faster with its precomputation ([`Tuner::choose_scheme_for`],
//! [`choose_scheme`]).

use ferrofmm_field::{M2lCostShape, SPECTRA_BUDGET_BYTES, n_surface_points};
use ferrofmm_kernels::{EvalMode, Precision};
use ferrofmm_tree::DEEPEST_LEVEL;

use crate::FmmError;
use crate::tuning::occupancy::Occupancy;
use crate::tuning::{ROOT_TIME_SLACK, box_bytes};
use crate::validate::{check_sources_and_targets, validate_tolerance};

use super::{ChosenParameters, Tuner};
use crate::tuning::MachineCalibration;

impl Tuner {
    /// Pick the M2L scheme too: the chooser runs for the SVD scheme and for
    /// the FFT scheme, and the smaller predicted time of the tree, one
    /// evaluation and the M2L precomputation wins. The SVD scheme's
    /// precomputation (its truncated SVDs: 0.3 s at `p = 6`, 1.4 s at `p =
    /// 8`, 5 s at `p = 10` on 2 cores, from [`SvdM2l`](ferrofmm_field::SvdM2l)'s
    /// [`estimate`](ferrofmm_field::M2lScheme::estimate)) counts unless
    /// `svd_cached` (its operators come from the cache); the FFT scheme's
    /// (316 kernel FFTs, milliseconds) is left out.
    ///
    /// Where the SVD scheme is predicted faster by at most
    /// [`ROOT_TIME_SLACK`] (5%) and the FFT scheme's memory is smaller
    /// ([`box_bytes`] of each choice, plus the FFT scheme's
    /// [`SPECTRA_BUDGET_BYTES`]), the FFT scheme is taken. (Both keep only
    /// the sibling blocks of the V lists, so only the trees' sizes and the
    /// spectra differ.)
    ///
    /// # Errors
    /// As [`Tuner::choose_with`].
    pub fn choose_scheme_with(
        &self,
        eps: f64,
        occupancy: &Occupancy,
        svd_cached: bool,
    ) -> Result<(M2lCostShape, ChosenParameters), FmmError> {
        self.choose_scheme_for(Some(eps), occupancy, svd_cached)
    }

    /// [`Tuner::choose_scheme_with`] for a tolerance or, with a fixed
    /// order ([`Tuner::with_order`]), none.
    ///
    /// # Errors
    /// As [`Tuner::choose_for`].
    pub fn choose_scheme_for(
        &self,
        eps: Option<f64>,
        occupancy: &Occupancy,
        svd_cached: bool,
    ) -> Result<(M2lCostShape, ChosenParameters), FmmError> {
        let svd = self
            .clone()
            .for_scheme(M2lCostShape::Compressed)
            .choose_for(eps, occupancy)?;
        let fft = self
            .clone()
            .for_scheme(M2lCostShape::Fft)
            .choose_for(eps, occupancy)?;
        let svd_total = svd.predicted_seconds
            + if svd_cached {
                0.0
            } else {
                svd_precompute_seconds(&svd)
            };
        // Memory breaks near-ties: each choice's boxes, and the FFT
        // scheme's spectra budget.
        let memory = |shape, c: &ChosenParameters| {
            let spectra = match shape {
                M2lCostShape::Fft => SPECTRA_BUDGET_BYTES as u64,
                _ => 0,
            };
            box_bytes(&c.estimated_work, n_surface_points(c.order), self.precision) + spectra
        };
        let fft_near = fft.predicted_seconds <= (1.0 + ROOT_TIME_SLACK) * svd_total;
        let fft_leaner = memory(M2lCostShape::Fft, &fft) < memory(M2lCostShape::Compressed, &svd);
        Ok(
            if fft.predicted_seconds <= svd_total || (fft_near && fft_leaner) {
                (M2lCostShape::Fft, fft)
            } else {
                (M2lCostShape::Compressed, svd)
            },
        )
    }
}

/// Predicted seconds of the SVD scheme's precomputation for `chosen`
/// (Laplace, every transfer vector of the chosen tree's depth).
pub fn svd_precompute_seconds(chosen: &ChosenParameters) -> f64 {
    use ferrofmm_field::{M2lScheme, M2lUsage, OperatorParams, SvdConfig, SvdM2l};
    let depth = chosen.estimated_work.depth;
    let config = SvdConfig {
        rank: None,
        tolerance: chosen.svd_tolerance,
    };
    SvdM2l::<f64>::estimate(
        &ferrofmm_kernels::Laplace3d,
        &OperatorParams::new(chosen.order),
        &config,
        depth,
        &M2lUsage::all(depth),
    )
    .seconds
}

/// [`Tuner::choose_scheme_with`] for these points (interleaved `x, y, z`;
/// `targets` `None` when they are the sources) in the bounding cube:
/// the M2L scheme, and the order and leaf size for it, that reach `eps`
/// fastest in float type `precision` and evaluation mode `mode`.
///
/// ```
/// use ferrofmm_fmm::{Geometry, tuning::{choose_scheme, M2lCostShape}};
/// use ferrofmm_kernels::{EvalMode, Precision};
/// let points: Vec<f64> = Geometry::Cube.points(20_000, 3);
/// let (shape, c) =
///     choose_scheme(1e-8, EvalMode::Potential, Precision::F64, &points, None, false).unwrap();
/// // At high order the SVD precomputation costs seconds; FFT's milliseconds.
/// assert_eq!(shape, M2lCostShape::Fft);
/// assert!(c.order >= 8);
/// ```
///
/// # Errors
/// As [`Tuner::choose`].
pub fn choose_scheme(
    eps: f64,
    mode: EvalMode,
    precision: Precision,
    sources: &[f64],
    targets: Option<&[f64]>,
    svd_cached: bool,
) -> Result<(M2lCostShape, ChosenParameters), FmmError> {
    choose_scheme_for(
        Some(eps),
        None,
        mode,
        precision,
        sources,
        targets,
        svd_cached,
        None,
    )
}

/// [`choose_scheme`] for a tolerance, a fixed order, or both (the order
/// then wins and the tolerance only sets the SVD tolerance): with an
/// order alone (`--order` without `--tolerance`), the scheme and leaf size
/// that evaluate that order fastest.
///
/// ```
/// use ferrofmm_fmm::{Geometry, tuning::{choose_scheme_for, M2lCostShape}};
/// use ferrofmm_kernels::{EvalMode, Precision};
/// let points: Vec<f64> = Geometry::Cube.points(20_000, 3);
/// let (shape, c) = choose_scheme_for(
///     None, Some(10), EvalMode::Potential, Precision::F64, &points, None, false, None,
/// ).unwrap();
/// assert_eq!((shape, c.order), (M2lCostShape::Fft, 10));
/// ```
///
/// `calibration`, when given, is this machine's calibration of the cost
/// model ([`MachineCalibration::from_cache`] finds the one a cache folder
/// holds).
///
/// # Errors
/// As [`Tuner::choose_for`]; [`FmmError::InvalidParameter`] with neither
/// a tolerance nor an order.
#[allow(clippy::too_many_arguments)]
pub fn choose_scheme_for(
    eps: Option<f64>,
    order: Option<usize>,
    mode: EvalMode,
    precision: Precision,
    sources: &[f64],
    targets: Option<&[f64]>,
    svd_cached: bool,
    calibration: Option<&MachineCalibration>,
) -> Result<(M2lCostShape, ChosenParameters), FmmError> {
    if let Some(eps) = eps {
        validate_tolerance(eps, precision)?;
    }
    check_sources_and_targets(sources, targets)?;
    let occupancy = Occupancy::new(sources, targets, None, DEEPEST_LEVEL)?;
    let mut tuner = Tuner::new(precision)
        .for_mode(mode)
        .with_calibration(calibration.cloned());
    if let Some(p) = order {
        tuner = tuner.with_order(p);
    }
    tuner.choose_scheme_for(eps, &occupancy, svd_cached)
}
