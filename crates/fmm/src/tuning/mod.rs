//! Ask for an accuracy, get the cheapest parameters that reach it.
//!
//! [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) takes a target
//! relative L2 error `eps` of the potential (and of the gradient when it is
//! evaluated) and picks the expansion order
//! `p`, the leaf size and the SVD compression tolerance of the M2L operators
//! from `eps`, the float type and the point distribution
//! ([`Tuner::choose`]). Two models make the choice, both measured on this
//! code and both easy to re-measure (`docs/tolerance.md` has the commands
//! and the tables).
//!
//! # The error model ([`ErrorModel`])
//!
//! The relative L2 error of the Laplace FMM depends mostly on the order:
//! over seven geometries (uniform cube, sphere surface, Plummer sphere, two
//! clusters 1000x apart in size, a plane, a trefoil curve, a torus),
//! zero-mean and all-positive charges and leaf sizes 32 to 400, the worst
//! error at an order is within about 10x of the best. So the model is a
//! table of the **worst** error measured at each order with the default
//! SVD tolerance (`E_p` for the potential, `G_p` for the gradient, used as
//! `max(E_p, G_p)` when gradients are evaluated: [`ErrorModel::laplace_for`]),
//! what a looser SVD tolerance `tau` adds, and what rounding adds:
//!
//! ```text
//! predicted(p, tau, R) = sqrt(E_p^2 + e_svd(tau)^2) + floor(R)
//! e_svd(tau)           = 1.2 tau (potential), 3.0 tau (with gradients)
//! floor(R)             = max(F, r u R),  r = 0.1 (potential), 0.3 (with gradients)
//! ```
//!
//! `e_svd` is the upper envelope of the measured extra error of dropping
//! singular values below `tau sigma_0` of the stacked M2L operators, on
//! zero-mean charges (0.5 to 1.1 `tau` for the potential, 1.9 to 2.4 `tau`
//! for the gradient); the two truncations are independent and add in
//! quadrature. `u` is the unit roundoff of the float type, `R` the largest
//! `|center - o| / half-width` of the leaves, `o` the point near the domain
//! the coordinates are made relative to ([`WorkCounts::rounding_ratio`]:
//! surfaces of small boxes far from `o` are off by `u |center - o|`) and
//! `F` the float type's floor on well-centred points (0 in `f64`;
//! [`F32_ERROR_FLOOR`], or [`F32_GRADIENT_FLOOR`] with gradients, in `f32`).
//! An order is admissible for `eps` when `S predicted <= eps` with the
//! safety factor `S` = [`SAFETY_FACTOR`], the room left for sizes and inputs
//! that were not measured; [`crate::verify`] checks the result afterwards.
//! `f32` cannot promise less than about `S F32_ERROR_FLOOR` (see
//! [`f32_reaches`]) and uses orders up to [`MAX_F32_ORDER`]; in `f64` the
//! table ends at order [`MAX_TUNED_ORDER`].
//!
//! For an admissible order the SVD tolerance is the loosest `tau` that keeps
//! `S predicted <= eps`, never tighter than the measured one and never
//! looser than [`MAX_SVD_TOLERANCE`]: at a loose `eps` the M2L rank, and
//! with it the M2L time, drops several-fold.
//!
//! # The cost model ([`CostModel`], [`WorkCounts`])
//!
//! The leaf size sets the balance between the near field (P2P, growing with
//! the points per leaf) and the far field (M2L and the dense level
//! operators, growing with the number of boxes, the more the higher the
//! order). For uniform points the adaptive tree is a step function of the
//! leaf size (a level splits or it does not; in between, mixed depths pay
//! for W and X lists), for clustered points it varies from box to box, so
//! no fixed "points per leaf" rule fits all inputs. The chooser runs a
//! cheap pre-pass instead ([`Occupancy`]): Morton codes of all points and
//! one sort; then, for candidate leaf sizes from [`LEAF_SIZE_CANDIDATES`],
//! a simulation of the adaptive refinement and the 2:1 balance on the
//! sorted codes, from which it counts the work ([`WorkCounts`]: P2P pairs,
//! U-, V-, W- and X-list work, boxes). The simulation is the tree crate's
//! own refinement and balance ([`ferrofmm_tree::MortonCodes`],
//! [`ferrofmm_tree::TreeShape`]), so the boxes and leaves are exactly those
//! of the tree that will be built; the list work is counted from child
//! masks without the lists' pruning, within a few percent.
//! [`CostModel`] turns work into seconds with one coefficient per kind of
//! work, fitted by [`CostModel::fit`] on measured runs (the example
//! `tolerance_grid -- fit` prints a new set when the operators get faster).
//! The chooser predicts the time of the tree plus one evaluation for the
//! three smallest admissible orders and the candidate leaf sizes, and takes
//! the cheapest ([`Tuner::candidates`] describes the search and what bounds
//! its cost). Precomputing operators is not counted (it does not depend on
//! the points and is cached on disk with
//! [`FmmBuilder::cache_dir`](crate::FmmBuilder::cache_dir)), but a higher
//! order must be predicted at least [`HIGHER_ORDER_GAIN`] cheaper to be
//! taken, since it costs more to precompute and to store.
//!
//! # Models per kernel and scheme ([`TuningModel`])
//!
//! Both models come from a [`TuningModel`], asked for the float type, the
//! evaluation mode and the M2L scheme's cost shape
//! ([`M2lScheme::COST_SHAPE`](ferrofmm_field::M2lScheme::COST_SHAPE)):
//! [`default_model`] gives [`LaplaceModel`] for the Laplace kernel,
//! [`YukawaModel`] for modified Helmholtz (Laplace's error tables, which
//! bound it where measured, `k W <=` [`YUKAWA_MEASURED_K`]; a P2P cost
//! [`YUKAWA_P2P_FACTOR`] times Laplace's) and, for any other kernel, the
//! Laplace model as a [`BorrowedModel`] (reported with
//! [`ChosenParameters::model_measured`] `false`). A kernel's author supplies
//! a model of their own with
//! [`FmmBuilder::tuning_model`](crate::FmmBuilder::tuning_model).
//!
//! # Scope of the promise
//!
//! The error tables were measured for the Laplace kernel (potential and
//! gradient) with the [`SvdM2l`](ferrofmm_field::SvdM2l) and
//! [`DenseM2l`](ferrofmm_field::DenseM2l) schemes; the FFT scheme applies
//! the same operators without truncation. A borrowed model makes the same
//! choice without a measurement behind it; the verification of
//! [`crate::verify`] measures whatever the kernel.

pub use ferrofmm_field::M2lCostShape;
use ferrofmm_field::{default_svd_tolerance, fft_frequencies, n_surface_points};
use ferrofmm_kernels::{EvalMode, Kernel, Precision, Real};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain, MortonCodes, MortonKey, Octree, ShapeBox, TreeShape};
use rayon::prelude::*;
use std::sync::Arc;

use crate::{EvalTimings, FmmError};

// One job per module: `error_model` (errors per order, SVD and rounding
// terms, limits), `work` (work counts of a built tree), `occupancy` (the
// simulated tree for any leaf size), `cost` (seconds from work, and the
// fit), `chooser` (the cheapest admissible parameters).
mod chooser;
mod cost;
mod error_model;
mod model;
mod occupancy;
mod work;

pub use chooser::*;
pub use cost::*;
pub use error_model::*;
pub use model::*;
pub use occupancy::*;
pub use work::*;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;
    use ferrofmm_tree::TreeOptions;

    #[test]
    fn non_adjacent_masks_count_the_v_list() {
        // A child has 6^3 - 3^3 = 189 V-list candidates among the children
        // of its parent's 27 neighbourhood.
        let m = non_adjacent_masks();
        for c in 0..8 {
            let total: u32 = m.iter().map(|row| row[c].count_ones()).sum();
            assert_eq!(total, 189, "child {c}");
        }
        // Its own parent's children are all adjacent to it.
        assert_eq!(m[13], [0; 8]);
    }

    #[test]
    fn octant_bits_match_the_tree() {
        for (i, k) in MortonKey::ROOT.children().iter().enumerate() {
            assert_eq!(k.octant(), i);
            let a = k.anchor();
            let half = ferrofmm_tree::FINEST_GRID / 2;
            assert_eq!(
                [a[0] / half, a[1] / half, a[2] / half],
                [(i & 1) as u32, ((i >> 1) & 1) as u32, ((i >> 2) & 1) as u32]
            );
        }
    }

    /// The shape is the tree builder's (boxes and leaves exactly); the
    /// list work is counted from child masks, without the lists' pruning
    /// of boxes that exchange nothing, so it is close, not equal.
    #[test]
    fn estimated_work_follows_the_real_tree() {
        for g in Geometry::ALL {
            let pts: Vec<f64> = g.points(20_000, 5);
            let occ = Occupancy::new(&pts, None, None, DEEPEST_LEVEL).unwrap();
            for leaf in [32, 150, 400] {
                let tree = Octree::new(&pts, None, &TreeOptions::adaptive(leaf)).unwrap();
                let real = WorkCounts::of_tree(&tree);
                let est = occ.work(leaf);
                let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 1.0 + a };
                let checks = [
                    ("boxes", ratio(est.n_boxes as f64, real.n_boxes as f64), 0.0),
                    (
                        "leaves",
                        ratio(est.n_leaves as f64, real.n_leaves as f64),
                        0.0,
                    ),
                    ("p2p", ratio(est.p2p_pairs, real.p2p_pairs), 0.05),
                    ("m2l", ratio(est.m2l_pairs, real.m2l_pairs), 0.05),
                    ("u", ratio(est.u_entries, real.u_entries), 0.05),
                    ("far", ratio(est.far_points, real.far_points), 0.1),
                    (
                        "ratio",
                        ratio(est.rounding_ratio, real.rounding_ratio),
                        0.01,
                    ),
                ];
                for (what, r, tol) in checks {
                    assert!((r - 1.0).abs() <= tol, "{g:?} leaf {leaf}: {what} {r}");
                }
                assert_eq!(est.depth, real.depth);
            }
        }
    }

    #[test]
    fn svd_tolerance_inverse() {
        let m = ErrorModel::laplace(Precision::F64);
        for tau in [1e-9, 1e-6, 1e-4, 1e-3, 5e-3] {
            let e = m.svd_error(tau);
            let back = m.svd_tolerance_adding(e);
            assert!((back / tau - 1.0).abs() < 1e-9, "{tau} -> {back}");
        }
    }

    #[test]
    fn fit_recovers_known_coefficients() {
        let truth = CostModel {
            p2p_pair: 1e-9,
            p2p_entry: 3e-8,
            surface_point: 2e-9,
            far_point: 1.5e-9,
            dense: 3e-11,
            box_surface: 4e-8,
            m2l_flop: 5e-11,
            m2l_pair: 6e-10,
            m2l_box: 7e-11,
            tree_point: 1e-7,
            tree_box: 2e-6,
            tree_pair: 5e-8,
            fft_pair: 2e-10,
            fft_box: 3e-9,
        };
        let mut samples = Vec::new();
        for (g, n) in [(Geometry::Cube, 6000), (Geometry::Plummer, 9000)] {
            let pts: Vec<f64> = g.points(n, 1);
            let occ = Occupancy::new(&pts, None, None, DEEPEST_LEVEL).unwrap();
            for (p, leaf, tau) in [
                (3, 16, 1e-3),
                (4, 64, 1e-5),
                (6, 32, 1e-6),
                (8, 256, 1e-8),
                (5, 128, 1e-4),
                (7, 24, 1e-7),
                (9, 48, 1e-9),
            ] {
                let w = occ.work(leaf);
                let k = estimated_svd_rank(p, tau);
                for shape in [M2lCostShape::Compressed, M2lCostShape::Fft] {
                    let f = features_for(shape, &w, p, k);
                    let (gp, gf, gm, gt) = truth.groups();
                    let d = std::time::Duration::from_secs_f64;
                    let far = dot(&gf, &f.far);
                    let m2l = dot(&gm, &f.m2l) + dot(&[truth.fft_pair, truth.fft_box], &f.fft);
                    let eval = EvalTimings {
                        p2p: d(dot(&gp, &f.p2p)),
                        p2m: d(0.3 * far),
                        l2p: d(0.3 * far),
                        m2m: d(0.1 * far),
                        l2l: d(0.3 * far),
                        m2l: d(m2l),
                        ..Default::default()
                    };
                    samples.push(CostSample {
                        work: w,
                        order: p,
                        rank: k,
                        shape,
                        eval,
                        tree_seconds: dot(&gt, &f.tree),
                    });
                }
            }
        }
        let fit = CostModel::fit(&samples);
        let (a, b) = (fit.groups(), truth.groups());
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(u, v)| (u / v - 1.0).abs() < 1e-4);
        assert!(close(&a.0, &b.0), "{fit:?}");
        assert!(close(&a.1, &b.1), "{fit:?}");
        assert!(close(&a.2, &b.2), "{fit:?}");
        assert!(close(&a.3, &b.3), "{fit:?}");
        assert!(
            close(
                &[fit.fft_pair, fit.fft_box],
                &[truth.fft_pair, truth.fft_box]
            ),
            "{fit:?}"
        );
        // Predictions of the fitted model reproduce the samples.
        for s in &samples {
            let t = fit.predict_for(s.shape, &s.work, s.order, s.rank);
            let measured =
                s.eval.p2p + s.eval.p2m + s.eval.l2p + s.eval.m2m + s.eval.l2l + s.eval.m2l;
            let measured = measured.as_secs_f64() + s.tree_seconds;
            assert!((t.total / measured - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn non_negative_fit_drops_harmful_features() {
        // y = 2 x0 exactly; x1 anti-correlated noise would get a negative
        // coefficient in plain least squares.
        let rows: Vec<(Vec<f64>, f64)> = (1..20)
            .map(|i| {
                let x0 = i as f64;
                let x1 = if i % 2 == 0 { 1.0 } else { 0.5 };
                (vec![x0, x1], 2.0 * x0 - 0.01 * x1)
            })
            .collect();
        let c = fit_nonnegative(&rows).unwrap();
        assert!(c[1] == 0.0 && (c[0] / 2.0 - 1.0).abs() < 0.01, "{c:?}");
    }
}
