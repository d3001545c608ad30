//! The chooser: the cheapest (order, leaf size, SVD tolerance) the error
//! model admits.

use std::sync::Arc;

use ferrofmm_field::M2lCostShape;
use ferrofmm_kernels::{EvalMode, Precision, Real};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain};

use super::cost::{CostModel, CostPrediction};
use super::error_model::{
    CHOICE_BUDGET, ErrorModel, HIGHER_ORDER_GAIN, LEAF_SIZE_CANDIDATES, MIN_CHOICE_SECONDS,
    REFINE_SHARE, SECONDS_PER_SIMULATED_BOX, STOP_FACTOR, estimated_svd_rank, f32_reaches,
};
use super::model::{LaplaceModel, TuningModel};
use super::occupancy::Occupancy;
use super::scene::Scene;
use super::work::WorkCounts;
use crate::FmmError;
use crate::validate::{check_domain_width, check_sources_and_targets, validate_tolerance};

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
    /// cache; see [`precompute_seconds`]).
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
}

/// An admissible order for a tolerance, with what goes with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct OrderChoice {
    pub(super) order: usize,
    pub(super) svd_tolerance: f64,
    pub(super) estimated_rank: usize,
    pub(super) predicted_error: f64,
}

/// A candidate tree the leaf-size search simulated.
struct SimulatedTree {
    /// Smallest leaf size giving this tree.
    leaf_size: usize,
    work: WorkCounts,
    boxes_per_level: Vec<usize>,
    /// Predicted seconds of its cheapest admissible order.
    cost: f64,
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
        }
    }

    /// The same tuner with the models of `model`.
    pub fn with_model(self, model: Arc<dyn TuningModel>) -> Self {
        Self {
            leaf_sizes: self.leaf_sizes,
            orders: self.orders,
            fixed_order: self.fixed_order,
            ..Self::from_model(model, self.precision, self.mode, self.scheme)
        }
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

    /// Predicted cost of `(order, rank)` on `work` with this tuner's scheme.
    fn predict(&self, work: &WorkCounts, order: usize, rank: usize) -> CostPrediction {
        self.cost.predict_for(self.scheme, work, order, rank)
    }

    /// The admissible orders for `eps` on a tree with rounding ratio
    /// `ratio` under the fitted `error` model: the smallest and the next
    /// `orders - 1`, or the fixed order alone ([`Tuner::with_order`];
    /// without `eps` only a fixed order has candidates). Only the SVD
    /// scheme has a compression tolerance to loosen; the others keep the
    /// base one (unused by them).
    pub(super) fn orders_for(
        &self,
        error: &ErrorModel,
        eps: Option<f64>,
        ratio: f64,
    ) -> Vec<OrderChoice> {
        let choice = |p: usize, tau: f64| OrderChoice {
            order: p,
            svd_tolerance: tau,
            estimated_rank: estimated_svd_rank(p, tau),
            predicted_error: error.predicted_error(p, tau, ratio).unwrap_or(f64::NAN),
        };
        if let Some(p) = self.fixed_order {
            let tau = match eps {
                Some(e)
                    if self.scheme == M2lCostShape::Compressed && error.admissible(p, e, ratio) =>
                {
                    error.svd_tolerance(p, e, ratio)
                }
                _ => error.base_svd_tolerance(p),
            };
            return vec![choice(p, tau)];
        }
        let Some(eps) = eps else {
            return Vec::new();
        };
        let Some(p0) = error.smallest_order(eps, ratio) else {
            return Vec::new();
        };
        (p0..p0 + self.orders.max(1))
            .filter(|&p| error.admissible(p, eps, ratio))
            .map(|p| {
                let tau = match self.scheme {
                    M2lCostShape::Compressed => error.svd_tolerance(p, eps, ratio),
                    _ => error.base_svd_tolerance(p),
                };
                choice(p, tau)
            })
            .collect()
    }

    /// Every `(order, leaf size)` weighed for `eps` on `occupancy`, in
    /// order of increasing leaf size then order; leaf sizes giving the same
    /// tree appear once (with the smallest of them). Empty when no setting
    /// reaches `eps` on these points.
    ///
    /// The search first scans every other candidate leaf size from the
    /// largest down (large leaves make small trees, cheap to simulate),
    /// then tries the two neighbours of the best. The scan stops when the
    /// work that grows with the number of boxes alone is predicted to cost
    /// more than the best setting so far (it only grows as leaves shrink),
    /// after two trees in a row predicted more than 1.5x slower than the
    /// best, or before simulating a tree would take the search past
    /// [`CHOICE_BUDGET`] of the best predicted time (or
    /// [`MIN_CHOICE_SECONDS`], whichever is larger).
    pub fn candidates(&self, eps: f64, occupancy: &Occupancy) -> Result<Vec<Candidate>, FmmError> {
        self.candidates_for(Some(eps), occupancy)
    }

    /// [`Tuner::candidates`] for a tolerance or none (then only a fixed
    /// order, [`Tuner::with_order`], has candidates).
    pub fn candidates_for(
        &self,
        eps: Option<f64>,
        occupancy: &Occupancy,
    ) -> Result<Vec<Candidate>, FmmError> {
        if let Some(eps) = eps {
            validate_tolerance(eps, self.error.precision)?;
        }
        if let Some(p) = self.fixed_order {
            crate::validate::check_order(p)?;
        }
        // The error model fitted to these points (volume, surface or
        // curve, and how many): `ErrorModel::in_scene`.
        let error = self.error.in_scene(&Scene::of(occupancy));
        let permissive = self.orders_for(&error, eps, 0.0);
        let cost_of = |w: &WorkCounts| {
            self.orders_for(&error, eps, w.rounding_ratio)
                .iter()
                .map(|o| self.predict(w, o.order, o.estimated_rank).total)
                .fold(f64::INFINITY, f64::min)
        };
        let mut trees: Vec<SimulatedTree> = Vec::new();
        let mut best = f64::INFINITY;
        // Simulated boxes so far, in units of a fully simulated box.
        let mut spent = 0.0;
        // Simulate the tree of leaf size `s` unless it is a known one or
        // over the budget; `Some(cost)` when simulated, `None` to stop.
        let mut visit = |s: usize,
                         trees: &mut Vec<SimulatedTree>,
                         best: &mut f64,
                         bounded: bool|
         -> Option<f64> {
            let refined = occupancy.refine(s.max(1));
            let shape = refined.boxes_per_level();
            let boxes: usize = shape.iter().sum();
            spent += REFINE_SHARE * boxes as f64;
            if let Some(t) = trees.iter_mut().find(|t| t.boxes_per_level == shape) {
                // The same tree: report the smallest leaf size giving it.
                t.leaf_size = t.leaf_size.min(s);
                return Some(t.cost);
            }
            // The search may spend CHOICE_BUDGET of the best time so far.
            if !trees.is_empty()
                && (spent + boxes as f64) * SECONDS_PER_SIMULATED_BOX
                    > (CHOICE_BUDGET * *best).max(MIN_CHOICE_SECONDS)
            {
                return None;
            }
            // Boxes only grow as leaves shrink: once the work that grows
            // with the boxes alone costs more than the best so far, no
            // smaller leaf size can win.
            if bounded {
                let bound = WorkCounts {
                    n_sources: occupancy.n_sources(),
                    n_targets: occupancy.n_targets(),
                    n_boxes: boxes,
                    m2l_boxes: shape.iter().skip(2).sum(),
                    ..Default::default()
                };
                let lower = permissive
                    .iter()
                    .map(|o| self.predict(&bound, o.order, o.estimated_rank).total)
                    .fold(f64::INFINITY, f64::min);
                if lower > *best {
                    return None;
                }
            }
            spent += boxes as f64;
            let work = occupancy.work_of(refined);
            let cost = cost_of(&work);
            trees.push(SimulatedTree {
                leaf_size: s,
                work,
                boxes_per_level: shape,
                cost,
            });
            *best = best.min(cost);
            Some(cost)
        };
        // Coarse scan (every other candidate, large leaves first: small
        // trees are cheap to simulate), then the neighbours of the best.
        let mut sizes = self.leaf_sizes.clone();
        sizes.sort_unstable();
        sizes.dedup();
        let mut worse = 0;
        for &s in sizes.iter().rev().step_by(2) {
            let Some(cost) = visit(s, &mut trees, &mut best, true) else {
                break;
            };
            worse = if cost > STOP_FACTOR * best && cost.is_finite() {
                worse + 1
            } else {
                0
            };
            if worse >= 2 {
                break;
            }
        }
        if let Some(s_best) = trees
            .iter()
            .filter(|t| t.cost.is_finite())
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
            .map(|t| t.leaf_size)
            && let Some(i) = sizes.iter().position(|&s| s == s_best)
        {
            for j in [i.wrapping_sub(1), i + 1] {
                if let Some(&s) = sizes.get(j)
                    && !trees.iter().any(|t| t.leaf_size == s)
                    && visit(s, &mut trees, &mut best, false).is_none()
                {
                    break;
                }
            }
        }
        trees.sort_by_key(|t| t.leaf_size);
        let mut out = Vec::new();
        for t in &trees {
            for o in self.orders_for(&error, eps, t.work.rounding_ratio) {
                out.push(Candidate {
                    order: o.order,
                    leaf_size: t.leaf_size,
                    svd_tolerance: o.svd_tolerance,
                    estimated_rank: o.estimated_rank,
                    predicted_error: o.predicted_error,
                    predicted: self.predict(&t.work, o.order, o.estimated_rank),
                    work: t.work,
                });
            }
        }
        Ok(out)
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
            model: self.model.name(),
            model_measured: self.model.measured(),
            estimated_work: best.work,
            direct: false,
            direct_seconds: None,
            precompute_seconds: 0.0,
        })
    }

    /// Predicted seconds of summing every source on every target directly
    /// (the P2P rate of the cost model, on the same threads):
    /// `p2p_pair N_s N_t + p2p_entry`.
    pub fn direct_seconds(&self, n_sources: usize, n_targets: usize) -> f64 {
        self.cost.p2p_pair * n_sources as f64 * n_targets as f64 + self.cost.p2p_entry
    }

    /// Turn `chosen` into a direct sum when that is predicted cheaper than
    /// its tree, its evaluation and `precompute` seconds of operators
    /// (what [`precompute_seconds`] predicts, 0 when they are cached).
    /// A direct sum is one leaf holding every point: no far field, no
    /// operators beyond the lowest order's (built at
    /// [`MIN_ORDER`](ferrofmm_field::MIN_ORDER)), exact to rounding
    /// (`predicted_error` 0).
    pub fn prefer_direct(
        &self,
        mut chosen: ChosenParameters,
        n_sources: usize,
        n_targets: usize,
        precompute: f64,
    ) -> ChosenParameters {
        let direct = self.direct_seconds(n_sources, n_targets);
        chosen.direct_seconds = Some(direct);
        chosen.precompute_seconds = precompute;
        if direct < chosen.predicted_seconds + precompute {
            chosen.direct = true;
            chosen.order = ferrofmm_field::MIN_ORDER;
            chosen.leaf_size = n_sources.max(n_targets).max(1);
            chosen.svd_tolerance = self.error.base_svd_tolerance(chosen.order);
            chosen.estimated_svd_rank = estimated_svd_rank(chosen.order, chosen.svd_tolerance);
            chosen.predicted_error = 0.0;
            chosen.estimated_work = WorkCounts {
                n_sources,
                n_targets,
                n_boxes: 1,
                n_leaves: 1,
                p2p_pairs: n_sources as f64 * n_targets as f64,
                u_entries: 1.0,
                ..WorkCounts::default()
            };
        }
        chosen
    }

    /// Pick the M2L scheme too: the chooser runs for the SVD scheme and for
    /// the FFT scheme, and the smaller predicted time of the tree, one
    /// evaluation and the M2L precomputation wins. The SVD scheme's
    /// precomputation (its truncated SVDs: 0.3 s at `p = 6`, 1.4 s at `p =
    /// 8`, 5 s at `p = 10` on 2 cores, from [`SvdM2l`](ferrofmm_field::SvdM2l)'s
    /// [`estimate`](ferrofmm_field::M2lScheme::estimate)) counts unless
    /// `svd_cached` (its operators come from the cache); the FFT scheme's
    /// (316 kernel FFTs, milliseconds) is left out.
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
        Ok(if fft.predicted_seconds <= svd_total {
            (M2lCostShape::Fft, fft)
        } else {
            (M2lCostShape::Compressed, svd)
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
///     None, Some(10), EvalMode::Potential, Precision::F64, &points, None, false,
/// ).unwrap();
/// assert_eq!((shape, c.order), (M2lCostShape::Fft, 10));
/// ```
///
/// # Errors
/// As [`Tuner::choose_for`]; [`FmmError::InvalidParameter`] with neither
/// a tolerance nor an order.
pub fn choose_scheme_for(
    eps: Option<f64>,
    order: Option<usize>,
    mode: EvalMode,
    precision: Precision,
    sources: &[f64],
    targets: Option<&[f64]>,
    svd_cached: bool,
) -> Result<(M2lCostShape, ChosenParameters), FmmError> {
    if let Some(eps) = eps {
        validate_tolerance(eps, precision)?;
    }
    check_sources_and_targets(sources, targets)?;
    let occupancy = Occupancy::new(sources, targets, None, DEEPEST_LEVEL)?;
    let mut tuner = Tuner::new(precision).for_mode(mode);
    if let Some(p) = order {
        tuner = tuner.with_order(p);
    }
    tuner.choose_scheme_for(eps, &occupancy, svd_cached)
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
fn checked_occupancy(
    eps: f64,
    precision: Precision,
    sources: &[f64],
    targets: Option<&[f64]>,
) -> Result<Occupancy, FmmError> {
    validate_tolerance(eps, precision)?;
    check_sources_and_targets(sources, targets)?;
    Occupancy::new(sources, targets, None, DEEPEST_LEVEL)
}
