//! The search of the chooser: the admissible orders for a tolerance
//! ([`Tuner::orders_for`]) and every `(order, leaf size)` weighed on
//! simulated trees ([`Tuner::candidates_for`]).

use ferrofmm_field::M2lCostShape;

use crate::FmmError;
use crate::tuning::cost::CostPrediction;
use crate::tuning::error_model::{
    CHOICE_BUDGET, ErrorModel, MIN_CHOICE_SECONDS, REFINE_SHARE, SECONDS_PER_SIMULATED_BOX,
    STOP_FACTOR, estimated_svd_rank,
};
use crate::tuning::occupancy::Occupancy;
use crate::tuning::scene::Scene;
use crate::tuning::work::WorkCounts;
use crate::validate::validate_tolerance;

use super::{Candidate, OrderChoice, Tuner};

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
    /// Predicted cost of `(order, rank)` on `work` with this tuner's scheme.
    pub(super) fn predict(&self, work: &WorkCounts, order: usize, rank: usize) -> CostPrediction {
        self.cost.predict_for(self.scheme, work, order, rank)
    }

    /// The admissible orders for `eps` on a tree with rounding ratio
    /// `ratio` under the fitted `error` model: the smallest and the next
    /// `orders - 1`, or the fixed order alone ([`Tuner::with_order`];
    /// without `eps` only a fixed order has candidates). Only the SVD
    /// scheme has a compression tolerance to loosen; the others keep the
    /// base one (unused by them).
    pub(in crate::tuning) fn orders_for(
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
}
