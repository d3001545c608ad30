//! The chooser: the cheapest (order, leaf size, SVD tolerance) the error
//! model admits.

use std::sync::Arc;

use ferrofmm_field::M2lCostShape;
use ferrofmm_kernels::{EvalMode, Precision};
use ferrofmm_tree::Domain;

use super::calibration::MachineCalibration;
use super::cost::{CostModel, CostPrediction};
use super::error_model::{ErrorModel, HIGHER_ORDER_GAIN, LEAF_SIZE_CANDIDATES};
use super::model::{LaplaceModel, TuningModel};
use super::occupancy::Occupancy;
use super::scene::Scene;
use super::work::WorkCounts;
use crate::FmmError;
use crate::validate::{check_domain_width, validate_tolerance};

mod candidates;
mod direct;
mod points;
mod scheme;

pub use points::{choose_parameters, choose_precision};
pub use scheme::{choose_scheme, choose_scheme_for, svd_precompute_seconds};

/// The parameters chosen for a tolerance, and what the models predict for
/// them. Reported by [`Fmm::chosen_parameters`](crate::Fmm::chosen_parameters)
/// and in [`FmmSummary`](crate::FmmSummary) (JSON), so they can be read and
/// reused with [`FmmBuilder::order`](crate::FmmBuilder::order),
/// [`FmmBuilder::leaf_size`](crate::FmmBuilder::leaf_size) and
/// [`SvdConfig`](ferrofmm_field::SvdConfig).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ChosenParameters {
    /// The relative L2 potential error asked for.
    pub tolerance: f64,
    /// Float type (`"f32"` or `"f64"`).
    pub precision: String,
    /// Expansion order.
    pub order: usize,
    /// Leaf size (largest number of points in a leaf).
    pub leaf_size: usize,
    /// Width of the root box as a multiple of the points' bounding cube
    /// (1: the bounding cube; larger roots put a near-uniform set's points
    /// in leaves of a better size, see [`choose_root`](super::choose_root)).
    pub root_scale: f64,
    /// SVD tolerance of the M2L compression.
    pub svd_tolerance: f64,
    /// Rank of the built SVD M2L operators (`None` before building, or for
    /// another scheme).
    pub svd_rank: Option<usize>,
    /// Rank the cost model assumed.
    pub estimated_svd_rank: usize,
    /// Predicted relative L2 potential error (`S` times this is at most the
    /// tolerance).
    pub predicted_error: f64,
    /// Predicted seconds for the tree and one evaluation (for a direct
    /// sum: of the FMM setting it was weighed against, whose order the
    /// verification raises from should the sum miss; see
    /// [`ChosenParameters::direct_seconds`]).
    pub predicted_seconds: f64,
    /// The M2L cost shape the prediction assumed (`"compressed"` for the
    /// SVD scheme, `"fft"`, `"dense"`).
    pub m2l_cost: String,
    /// The [`TuningModel`] the choice came from.
    pub model: String,
    /// Whether its error table was measured for this kernel (`false`: a
    /// borrowed table, backed only by the verification).
    pub model_measured: bool,
    /// Estimated work of the chosen tree.
    pub estimated_work: WorkCounts,
    /// Whether the run is a direct sum (one leaf holding every point, no
    /// far field: exact to rounding) because the cost model predicts it
    /// cheaper than any tree and its operators ([`Tuner::prefer_direct`]).
    pub direct: bool,
    /// Predicted seconds of the direct sum of every source on every
    /// target (`None` when it was not a candidate: a leaf size given by
    /// the caller, or far-separated clusters).
    pub direct_seconds: Option<f64>,
    /// Predicted seconds of precomputing the chosen tree's operators and
    /// M2L scheme from nothing (0 when they are known to come from the
    /// cache; see [`precompute_seconds`](crate::tuning::precompute_seconds)).
    pub precompute_seconds: f64,
}

/// One `(order, leaf size)` the chooser weighed.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Candidate {
    /// Expansion order.
    pub order: usize,
    /// Leaf size.
    pub leaf_size: usize,
    /// SVD tolerance for this order and the tolerance asked for.
    pub svd_tolerance: f64,
    /// Estimated rank at that SVD tolerance.
    pub estimated_rank: usize,
    /// Predicted error.
    pub predicted_error: f64,
    /// Predicted seconds (tree + one evaluation).
    pub predicted: CostPrediction,
    /// Estimated work.
    pub work: WorkCounts,
}

/// Chooses order, leaf size and SVD tolerance for a tolerance (see the
/// [module docs](crate::tuning)). The error and cost models come from a
/// [`TuningModel`] (the measured Laplace one by default), for the float
/// type, the evaluation mode and the M2L scheme's cost shape; both can also
/// be replaced directly.
#[derive(Clone, Debug)]
pub struct Tuner {
    /// Where [`Tuner::error`] and [`Tuner::cost`] come from.
    pub model: Arc<dyn TuningModel>,
    /// Float type.
    pub precision: Precision,
    /// What is evaluated.
    pub mode: EvalMode,
    /// How the M2L scheme to be built scales (the SVD scheme's by
    /// default).
    pub scheme: M2lCostShape,
    /// The error model (from [`Tuner::model`]).
    pub error: ErrorModel,
    /// The cost model (from [`Tuner::model`]).
    pub cost: CostModel,
    /// Leaf sizes to consider.
    pub leaf_sizes: Vec<usize>,
    /// How many admissible orders to consider, from the smallest up.
    pub orders: usize,
    /// An order the caller fixed ([`Tuner::with_order`]): the only one
    /// considered, admissible or not; the search is then for the leaf
    /// size (and, with [`Tuner::choose_scheme_with`], the scheme).
    pub fixed_order: Option<usize>,
    /// This machine's calibration of the cost model, applied to
    /// [`Tuner::cost`] ([`Tuner::with_calibration`]).
    pub calibration: Option<MachineCalibration>,
}

/// An admissible order for a tolerance, with what goes with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::tuning) struct OrderChoice {
    pub(in crate::tuning) order: usize,
    pub(in crate::tuning) svd_tolerance: f64,
    pub(in crate::tuning) estimated_rank: usize,
    pub(in crate::tuning) predicted_error: f64,
}

impl Tuner {
    /// The measured Laplace models for `precision`, potentials, the SVD
    /// scheme.
    pub fn new(precision: Precision) -> Self {
        Self::from_model(
            Arc::new(LaplaceModel),
            precision,
            EvalMode::Potential,
            M2lCostShape::Compressed,
        )
    }

    /// The models of `model` for `precision`, `mode` and `scheme`.
    pub fn from_model(
        model: Arc<dyn TuningModel>,
        precision: Precision,
        mode: EvalMode,
        scheme: M2lCostShape,
    ) -> Self {
        Tuner {
            error: model.error_model(precision, mode, scheme),
            cost: model.cost_model(mode, scheme),
            model,
            precision,
            mode,
            scheme,
            leaf_sizes: LEAF_SIZE_CANDIDATES.to_vec(),
            orders: 3,
            fixed_order: None,
            calibration: None,
        }
    }

    /// The same tuner with the models of `model` (and the calibration it
    /// had).
    pub fn with_model(self, model: Arc<dyn TuningModel>) -> Self {
        Self {
            leaf_sizes: self.leaf_sizes,
            orders: self.orders,
            fixed_order: self.fixed_order,
            ..Self::from_model(model, self.precision, self.mode, self.scheme)
        }
        .with_calibration(self.calibration)
    }

    /// The same tuner with the cost model calibrated on this machine
    /// ([`MachineCalibration::apply`] on the model's costs), or, with
    /// `None`, the model's costs as they are.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::{GroupScales, MachineCalibration, Tuner, this_processor};
    /// use ferrofmm_fmm::Geometry;
    /// use ferrofmm_kernels::Precision;
    /// let points: Vec<f64> = Geometry::Cube.points(20_000, 1);
    /// // A machine whose kernel evaluations are 20x dearer: smaller leaves.
    /// let slow_p2p = MachineCalibration {
    ///     processor: this_processor(),
    ///     threads: 2,
    ///     scales: GroupScales { p2p: 20.0, ..GroupScales::default() },
    /// };
    /// let leaf = |c: Option<MachineCalibration>| {
    ///     let tuner = Tuner::new(Precision::F64).with_calibration(c);
    ///     tuner.choose(1e-6, &points, None, None, 16).unwrap().leaf_size
    /// };
    /// assert!(leaf(Some(slow_p2p)) < leaf(None));
    /// ```
    pub fn with_calibration(mut self, calibration: Option<MachineCalibration>) -> Self {
        let cost = self.model.cost_model(self.mode, self.scheme);
        self.cost = match &calibration {
            Some(c) => c.apply(cost),
            None => cost,
        };
        self.calibration = calibration;
        self
    }

    /// The same tuner with the order fixed to `order` (a caller's
    /// `--order` without `--leaf-size`): only the leaf size (and the
    /// scheme, or a direct sum) is chosen, whatever the error model says
    /// of that order.
    pub fn with_order(mut self, order: usize) -> Self {
        self.fixed_order = Some(order);
        self
    }

    /// The same tuner with the leaf size fixed to `leaf_size` (a caller's
    /// `--leaf-size`): only the order (and SVD tolerance) is chosen.
    pub fn with_leaf_size(mut self, leaf_size: usize) -> Self {
        self.leaf_sizes = vec![leaf_size.max(1)];
        self
    }

    /// The same tuner for an M2L scheme that scales as `shape`
    /// ([`M2lScheme::COST_SHAPE`](ferrofmm_field::M2lScheme::COST_SHAPE));
    /// the models are asked again.
    pub fn for_scheme(mut self, shape: M2lCostShape) -> Self {
        self.scheme = shape;
        let model = self.model.clone();
        self.with_model(model)
    }

    /// The same tuner for evaluation mode `mode`; the models are asked
    /// again (with gradients: the worse of the potential's and the
    /// gradient's error, dearer target-side kernel work).
    pub fn for_mode(mut self, mode: EvalMode) -> Self {
        self.mode = mode;
        let model = self.model.clone();
        self.with_model(model)
    }

    /// The cheapest predicted candidate for `eps` on `occupancy`; a higher
    /// order than the smallest admissible one only when predicted at least
    /// [`HIGHER_ORDER_GAIN`] cheaper.
    ///
    /// # Errors
    /// [`FmmError::InvalidTolerance`], or
    /// [`FmmError::ToleranceBeyondPrecision`] when no order reaches `eps`
    /// at any leaf size on these points (with the limit for them).
    pub fn choose_with(
        &self,
        eps: f64,
        occupancy: &Occupancy,
    ) -> Result<ChosenParameters, FmmError> {
        self.choose_for(Some(eps), occupancy)
    }

    /// [`Tuner::choose_with`] for a tolerance or, with a fixed order
    /// ([`Tuner::with_order`]), none: then the cheapest leaf size for that
    /// order (`tolerance` is reported as NaN).
    ///
    /// # Errors
    /// As [`Tuner::choose_with`]; [`FmmError::InvalidParameter`] without
    /// a tolerance and without a fixed order.
    pub fn choose_for(
        &self,
        eps: Option<f64>,
        occupancy: &Occupancy,
    ) -> Result<ChosenParameters, FmmError> {
        if eps.is_none() && self.fixed_order.is_none() {
            return Err(FmmError::InvalidParameter(
                "the chooser needs a tolerance or a fixed order".to_string(),
            ));
        }
        if let Some(p) = self.fixed_order {
            crate::validate::check_order(p)?;
        }
        // A domain the float type cannot resolve has no order: say so
        // (the build's message), not "no order reaches eps".
        check_domain_width(occupancy.domain().width, self.error.precision, 0)?;
        let candidates = self.candidates_for(eps, occupancy)?;
        let Some(p_min) = candidates.iter().map(|c| c.order).min() else {
            // No leaf size works: report the limit at the finest resolution
            // the points need (the coarsest tree considered).
            let w = occupancy.work(*self.leaf_sizes.iter().max().unwrap_or(&1));
            return Err(FmmError::ToleranceBeyondPrecision {
                tolerance: eps.unwrap_or(f64::NAN),
                precision: self.error.precision.name(),
                limit: self
                    .error
                    .in_scene(&Scene::of(occupancy))
                    .smallest_reachable(w.rounding_ratio),
            });
        };
        let best_of = |p: usize| {
            candidates
                .iter()
                .filter(|c| c.order == p)
                .min_by(|a, b| a.predicted.total.total_cmp(&b.predicted.total))
        };
        let p_max = candidates.iter().map(|c| c.order).max().unwrap_or(p_min);
        let mut best = best_of(p_min).expect("candidates of the smallest order");
        for p in p_min + 1..=p_max {
            if let Some(c) = best_of(p)
                && c.predicted.total < (1.0 - HIGHER_ORDER_GAIN) * best.predicted.total
            {
                best = c;
            }
        }
        Ok(ChosenParameters {
            tolerance: eps.unwrap_or(f64::NAN),
            precision: self.error.precision.name().to_string(),
            order: best.order,
            leaf_size: best.leaf_size,
            root_scale: 1.0,
            svd_tolerance: best.svd_tolerance,
            svd_rank: None,
            estimated_svd_rank: best.estimated_rank,
            predicted_error: best.predicted_error,
            predicted_seconds: best.predicted.total,
            m2l_cost: self.scheme.name().to_string(),
            model: match &self.calibration {
                Some(c) => format!(
                    "{} (costs calibrated on this machine, {} threads)",
                    self.model.name(),
                    c.threads
                ),
                None => self.model.name(),
            },
            model_measured: self.model.measured(),
            estimated_work: best.work,
            direct: false,
            direct_seconds: None,
            precompute_seconds: 0.0,
        })
    }

    /// Choose for `eps` and these points (interleaved `x, y, z`; `targets`
    /// `None` when they are the sources), in `domain` (or the bounding cube)
    /// with boxes no deeper than `max_level`.
    pub fn choose(
        &self,
        eps: f64,
        sources: &[f64],
        targets: Option<&[f64]>,
        domain: Option<Domain>,
        max_level: u32,
    ) -> Result<ChosenParameters, FmmError> {
        validate_tolerance(eps, self.error.precision)?;
        let occupancy = Occupancy::new(sources, targets, domain, max_level)?;
        self.choose_with(eps, &occupancy)
    }
}
