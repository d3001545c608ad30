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
//! `max(E_p, G_p)` when gradients are evaluated: [`ErrorModel::for_mode`]),
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
//! `|center| / half-width` of the leaves ([`WorkCounts::rounding_ratio`]:
//! surfaces of small boxes far from the origin are off by `u |center|`) and
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
//! U-, V-, W- and X-list work, boxes) within about 1% of the real tree.
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
//! # Scope of the promise
//!
//! Measured for the Laplace kernel (potential and gradient) and the
//! [`SvdM2l`](ferrofmm_field::SvdM2l) and
//! [`DenseM2l`](ferrofmm_field::DenseM2l) schemes. Other kernels get the same
//! choice without a measured model behind it; the verification of
//! [`crate::verify`] measures whatever the kernel.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use ferrofmm_field::{default_svd_tolerance, n_surface_points};
use ferrofmm_kernels::{EvalMode, Precision, Real};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain, MortonKey, Octree};
use rayon::prelude::*;

use crate::{EvalTimings, FmmError};

/// Safety factor `S` between the measured worst error of an order and the
/// tolerance it is used for. The table is already the worst of 42 settings
/// per order (seven geometries, two kinds of charges, three leaf sizes);
/// `S` covers larger N (errors grow about 1.5x from 2e4 to 1e6 points)
/// and inputs not measured, and the after-the-fact verification
/// ([`crate::verify`]) catches what it does not.
pub const SAFETY_FACTOR: f64 = 1.6;

/// Error `f32` rounding adds at every order (measured worst over the four
/// test geometries: about `1e-6` on uniform points, `2.4e-6` on two
/// clusters whose coordinates are `1.0 + 1e-4 u`).
pub const F32_ERROR_FLOOR: f64 = 2.5e-6;

/// As [`F32_ERROR_FLOOR`] for the gradient (measured on zero-mean and
/// positive charges, orders 7 to 10: 2.9e-6 to 5.4e-6).
pub const F32_GRADIENT_FLOOR: f64 = 6e-6;

/// Rounding error per unit roundoff and unit of [`WorkCounts::rounding_ratio`]
/// (measured: `f32` on two clusters, ratios 0.7e5 to 4.5e5, errors 1.3e-4 to
/// 9e-4, i.e. 0.02 to 0.06 `u ratio`).
pub const ROUNDING_FACTOR: f64 = 0.1;

/// `e_svd(tau) = SVD_POTENTIAL_FACTOR tau`: upper envelope of the extra
/// relative potential error of an SVD tolerance `tau` (measured on
/// zero-mean charges, orders 3 to 12: 0.5 to 1.1 `tau`;
/// `examples/error_model.rs`, `docs/tolerance.md`).
const SVD_POTENTIAL_FACTOR: f64 = 1.2;

/// As [`SVD_POTENTIAL_FACTOR`] for the gradient (measured 1.9 to 2.4 `tau`).
const SVD_GRADIENT_FACTOR: f64 = 3.0;

/// Loosest SVD tolerance the chooser uses.
pub const MAX_SVD_TOLERANCE: f64 = 1e-2;

/// A higher order than the smallest admissible one is chosen only when it
/// is predicted at least this fraction cheaper.
pub const HIGHER_ORDER_GAIN: f64 = 0.1;

/// Highest order the error model knows (f64 errors stop falling beyond it).
pub const MAX_TUNED_ORDER: usize = 12;

/// Highest order used in `f32`: beyond it rounding dominates and the error
/// no longer falls (measured: 3e-7..1e-6 at p = 7..8, 6e-7..1.4e-6 at
/// p = 9..10).
pub const MAX_F32_ORDER: usize = 8;

/// Lowest order the error model knows.
pub const MIN_TUNED_ORDER: usize = 2;

/// The leaf-size scan stops after two trees in a row predicted this much
/// slower than the best so far, for every order considered.
const STOP_FACTOR: f64 = 1.5;

/// The search for a leaf size stops before it has spent this fraction of
/// the best predicted time so far (estimated as [`SECONDS_PER_SIMULATED_BOX`]
/// per box of the simulated trees), so that choosing stays cheap next to
/// what it chooses for.
pub const CHOICE_BUDGET: f64 = 0.05;

/// The search may always spend this many seconds (estimated), whatever
/// [`CHOICE_BUDGET`] allows: on small problems 5% of a 50 ms run is too
/// little to reach the trees of small leaves, and a wrong leaf size there
/// costs 2x (N = 1e5 cube at 1e-3, `docs/tolerance.md`).
pub const MIN_CHOICE_SECONDS: f64 = 0.01;

/// Seconds to simulate one box of a candidate tree (refine, balance, count
/// the work; measured 0.2 to 0.8 us on the 2-core machine, Plummer the
/// costliest).
pub const SECONDS_PER_SIMULATED_BOX: f64 = 0.8e-6;

/// Share of a box's simulation cost spent refining it (every candidate is
/// refined; only distinct trees are simulated further).
const REFINE_SHARE: f64 = 0.25;

/// Leaf sizes the chooser considers. Below 32 points per leaf the P2P
/// blocks are too small to run at speed and the trees are large to
/// simulate; no measured optimum lay there (`docs/tolerance.md`).
pub const LEAF_SIZE_CANDIDATES: [usize; 13] = [
    32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048,
];

/// Worst relative L2 potential error measured at orders 2..=12 (f64, SVD
/// M2L at the default tolerance, zero-mean and positive charges, seven
/// geometries, leaf sizes 32..400, N = 2e4 and 1e5; `docs/tolerance.md`).
const F64_POTENTIAL_ERRORS: [f64; MAX_TUNED_ORDER - MIN_TUNED_ORDER + 1] = [
    5.0e-2,  // p = 2
    3.6e-3,  // p = 3
    4.4e-4,  // p = 4
    4.3e-5,  // p = 5
    5.3e-6,  // p = 6
    6.3e-7,  // p = 7
    1.1e-7,  // p = 8
    1.5e-8,  // p = 9
    2.3e-9,  // p = 10
    3.9e-10, // p = 11
    7.5e-11, // p = 12
];

/// As [`F64_POTENTIAL_ERRORS`] for the gradient (its worst cases are
/// all-positive charges at low orders, whose mean field nearly cancels in
/// the cloud, and zero-mean charges at high orders).
const F64_GRADIENT_ERRORS: [f64; MAX_TUNED_ORDER - MIN_TUNED_ORDER + 1] = [
    1.8e-1,  // p = 2
    9.0e-3,  // p = 3
    3.1e-3,  // p = 4
    1.4e-4,  // p = 5
    3.6e-5,  // p = 6
    2.5e-6,  // p = 7
    4.5e-7,  // p = 8
    7.3e-8,  // p = 9
    1.0e-8,  // p = 10
    2.1e-9,  // p = 11
    5.2e-10, // p = 12
];

/// Ranks of the SVD-compressed M2L stack at tolerances `10^-2 .. 10^-11`
/// (measured, order 9; lower orders cap the rank at the number of surface
/// points).
const SVD_RANKS: [f64; 10] = [
    9.0, 22.0, 47.0, 81.0, 124.0, 176.0, 234.0, 304.0, 348.0, 371.0,
];

/// The error model: predicted relative L2 error from the order, the SVD
/// tolerance, the float type and how finely the tree resolves the
/// coordinates (see the [module docs](self)), for the potential or, with
/// [`ErrorModel::for_mode`], for everything an evaluation mode computes.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorModel {
    /// Float type the model is for.
    pub precision: Precision,
    /// `(order, E_p)`: worst measured error per order (f64, base SVD
    /// tolerance), for the orders this precision may use.
    pub order_errors: Vec<(usize, f64)>,
    /// `e_svd(tau) = svd_factor tau`: error added by an SVD tolerance.
    pub svd_factor: f64,
    /// Rounding error per unit roundoff and unit of rounding ratio
    /// ([`ROUNDING_FACTOR`]; three times that with gradients, which
    /// difference nearby values).
    pub rounding_factor: f64,
    /// Error floor of the float type for well-centred points (0 in `f64`,
    /// [`F32_ERROR_FLOOR`] in `f32`).
    pub floor: f64,
    /// Safety factor `S`.
    pub safety: f64,
}

impl ErrorModel {
    /// The measured model of the Laplace potential in `precision`.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::ErrorModel;
    /// use ferrofmm_kernels::Precision;
    /// let m = ErrorModel::laplace(Precision::F64);
    /// assert!(m.order_error(8).unwrap() < m.order_error(6).unwrap());
    /// assert_eq!(m.smallest_order(1e-2, 0.0), Some(3));
    /// ```
    pub fn laplace(precision: Precision) -> Self {
        Self::from_table(precision, &F64_POTENTIAL_ERRORS, SVD_POTENTIAL_FACTOR)
    }

    /// The model for everything `mode` evaluates: with gradients, the
    /// worse of the potential's and the gradient's error at each order
    /// (and the gradient's larger SVD error), so that a tolerance holds
    /// for both.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::ErrorModel;
    /// use ferrofmm_kernels::{EvalMode, Precision};
    /// let pot = ErrorModel::laplace(Precision::F64);
    /// let both = pot.clone().for_mode(EvalMode::PotentialGradient);
    /// assert!(both.order_error(6).unwrap() >= pot.order_error(6).unwrap());
    /// ```
    pub fn for_mode(self, mode: EvalMode) -> Self {
        if mode.values_per_target() == 1 {
            return self;
        }
        let worst: Vec<f64> = F64_POTENTIAL_ERRORS
            .iter()
            .zip(&F64_GRADIENT_ERRORS)
            .map(|(p, g)| p.max(*g))
            .collect();
        let mut m = Self::from_table(
            self.precision,
            &worst,
            SVD_POTENTIAL_FACTOR.max(SVD_GRADIENT_FACTOR),
        );
        m.safety = self.safety;
        if self.precision == Precision::F32 {
            m.floor = F32_GRADIENT_FLOOR;
        }
        m.rounding_factor = 3.0 * ROUNDING_FACTOR;
        m
    }

    fn from_table(precision: Precision, table: &[f64], svd_factor: f64) -> Self {
        let (floor, max_order) = match precision {
            Precision::F64 => (0.0, MAX_TUNED_ORDER),
            Precision::F32 => (F32_ERROR_FLOOR, MAX_F32_ORDER),
        };
        ErrorModel {
            precision,
            order_errors: table
                .iter()
                .enumerate()
                .map(|(i, &e)| (MIN_TUNED_ORDER + i, e))
                .filter(|&(p, _)| p <= max_order)
                .collect(),
            svd_factor,
            rounding_factor: ROUNDING_FACTOR,
            floor,
            safety: SAFETY_FACTOR,
        }
    }

    /// `E_p`: the worst measured error at `order` with the base SVD
    /// tolerance (`None` outside the orders of this precision).
    pub fn order_error(&self, order: usize) -> Option<f64> {
        self.order_errors
            .iter()
            .find(|&&(p, _)| p == order)
            .map(|&(_, e)| e)
    }

    /// Unit roundoff of the float type (`2^-24` or `2^-53`).
    pub fn unit_roundoff(&self) -> f64 {
        match self.precision {
            Precision::F32 => f64::powi(2.0, -24),
            Precision::F64 => f64::powi(2.0, -53),
        }
    }

    /// Error from rounding, for a tree whose leaves have
    /// `max |center| / half-width = ratio`
    /// ([`WorkCounts::rounding_ratio`]): the larger of the float type's
    /// floor (measured on well-centred points, ratios up to a few hundred)
    /// and `rounding_factor u ratio`. Equivalent and check surfaces are points
    /// of the float type: around a box of half-width `h` centred at `c`
    /// they are off by about `u |c|`, a relative `u |c| / h` of the
    /// surface. Small boxes far from the origin (two clusters, one of size
    /// `1e-4` at `(1, 1, 1)`) lose digits this way, in `f32` about `1e-3`.
    pub fn rounding_floor(&self, ratio: f64) -> f64 {
        self.floor
            .max(self.rounding_factor * self.unit_roundoff() * ratio.max(0.0))
    }

    /// `e_svd(tau) = svd_factor tau`: error added by an SVD tolerance `tau`
    /// looser than the base ([`ErrorModel::base_svd_tolerance`]).
    pub fn svd_error(&self, tau: f64) -> f64 {
        self.svd_factor * tau
    }

    /// Inverse of [`ErrorModel::svd_error`]: the `tau` adding `err`.
    fn svd_tolerance_adding(&self, err: f64) -> f64 {
        err / self.svd_factor
    }

    /// The tightest SVD tolerance the chooser uses at `order`, the one
    /// `E_p` was measured with: the library's default,
    /// [`default_svd_tolerance`].
    pub fn base_svd_tolerance(&self, order: usize) -> f64 {
        default_svd_tolerance(self.precision, order)
    }

    /// Predicted error at `order` with SVD tolerance `svd_tolerance` on a
    /// tree with rounding ratio `ratio` (`None` outside the orders of this
    /// precision): `sqrt(E_p^2 + e_svd(tau)^2) + rounding_floor(ratio)`
    /// (the truncation of the expansion and of the SVD are independent and
    /// add in quadrature; measured: order 9, Plummer, `E_p` 3.9e-10,
    /// `e_svd(1e-8)` 4.7e-10, error 5.7e-10).
    pub fn predicted_error(&self, order: usize, svd_tolerance: f64, ratio: f64) -> Option<f64> {
        let e = self.order_error(order)?;
        let extra = if svd_tolerance > self.base_svd_tolerance(order) {
            self.svd_error(svd_tolerance)
        } else {
            0.0
        };
        Some(e.hypot(extra) + self.rounding_floor(ratio))
    }

    /// Whether `order` reaches `eps` (with the safety factor) at the base
    /// SVD tolerance on a tree with rounding ratio `ratio`.
    pub fn admissible(&self, order: usize, eps: f64, ratio: f64) -> bool {
        let d = self.base_svd_tolerance(order);
        self.predicted_error(order, d, ratio)
            .is_some_and(|e| self.safety * e <= eps * (1.0 + 1e-9))
    }

    /// The smallest order that reaches `eps`, if any.
    pub fn smallest_order(&self, eps: f64, ratio: f64) -> Option<usize> {
        self.order_errors
            .iter()
            .map(|&(p, _)| p)
            .find(|&p| self.admissible(p, eps, ratio))
    }

    /// The loosest SVD tolerance with which `order` still reaches `eps`:
    /// between [`ErrorModel::base_svd_tolerance`] and [`MAX_SVD_TOLERANCE`]
    /// (the base when the order has no room to spare or is not
    /// admissible).
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::ErrorModel;
    /// use ferrofmm_kernels::Precision;
    /// let m = ErrorModel::laplace(Precision::F64);
    /// // Order 6 reaches 1e-5 with room to spare: compress harder.
    /// let tau = m.svd_tolerance(6, 1e-5, 0.0);
    /// assert!(tau > m.base_svd_tolerance(6));
    /// assert!(m.safety * m.predicted_error(6, tau, 0.0).unwrap() <= 1e-5 * (1.0 + 1e-9));
    /// ```
    pub fn svd_tolerance(&self, order: usize, eps: f64, ratio: f64) -> f64 {
        let default = self.base_svd_tolerance(order);
        let Some(e) = self.order_error(order) else {
            return default;
        };
        // sqrt(E_p^2 + e_svd^2) + floor <= eps / S
        let budget = eps / self.safety - self.rounding_floor(ratio);
        if budget <= e {
            return default;
        }
        let room = (budget * budget - e * e).sqrt();
        self.svd_tolerance_adding(room)
            .clamp(default, MAX_SVD_TOLERANCE.max(default))
    }

    /// The smallest tolerance this model can promise (at any order) on a
    /// tree with rounding ratio `ratio`.
    pub fn smallest_reachable(&self, ratio: f64) -> f64 {
        self.order_errors
            .iter()
            .map(|&(_, e)| self.safety * (e + self.rounding_floor(ratio)))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Whether `f32` can reach the relative potential error `eps` on
/// well-centred points: `eps >=` [`smallest_tolerance`]`(F32)`, about
/// `5e-6`. Well-centred means that every leaf's `|center| / half-width`
/// stays below about 400 (true of uniform, sphere-surface and Plummer
/// points centred near the origin up to millions of points; not of a tiny
/// cluster far from the origin). For a decision about given points use
/// [`choose_precision`].
///
/// ```
/// use ferrofmm_fmm::tuning::f32_reaches;
/// assert!(f32_reaches(1e-3));
/// assert!(f32_reaches(1e-5));
/// assert!(!f32_reaches(1e-7));
/// ```
pub fn f32_reaches(eps: f64) -> bool {
    eps.is_finite() && eps < 1.0 && eps >= smallest_tolerance(Precision::F32)
}

/// The smallest tolerance `precision` can promise on any points (the
/// best case: well-centred points).
pub fn smallest_tolerance(precision: Precision) -> f64 {
    ErrorModel::laplace(precision).smallest_reachable(0.0)
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
    validate_tolerance(eps, Precision::F64)?;
    crate::builder::check_sources_and_targets(sources, targets)?;
    let occupancy = Occupancy::new(sources, targets, None, DEEPEST_LEVEL)?;
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

/// Estimated rank of the SVD-compressed M2L operators at `order` and
/// tolerance `tau` (measured ranks, interpolated in `log10 tau`, capped at
/// the number of surface points).
pub fn estimated_svd_rank(order: usize, tau: f64) -> usize {
    let n = n_surface_points(order);
    let x = -tau.max(1e-300).log10(); // 2 .. 11 in the table
    let pos = (x - 2.0).clamp(0.0, (SVD_RANKS.len() - 1) as f64);
    let i = (pos.floor() as usize).min(SVD_RANKS.len() - 2);
    let f = pos - i as f64;
    let mut k = SVD_RANKS[i] + f * (SVD_RANKS[i + 1] - SVD_RANKS[i]);
    if x > 11.0 {
        k += (x - 11.0) * 25.0;
    } else if x < 2.0 {
        k *= (0.5f64).powf(2.0 - x);
    }
    (k.round() as usize).clamp(1, n)
}

// ---------------------------------------------------------------------------
// Work counts
// ---------------------------------------------------------------------------

/// The work of one evaluation, counted on a tree (exactly, with
/// [`WorkCounts::of_tree`]) or estimated from the point distribution
/// without building one ([`Occupancy::work`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct WorkCounts {
    /// Sources.
    pub n_sources: usize,
    /// Targets.
    pub n_targets: usize,
    /// Deepest level.
    pub depth: u32,
    /// Boxes.
    pub n_boxes: usize,
    /// Leaves.
    pub n_leaves: usize,
    /// Boxes on levels 2 and deeper (columns of the M2L products).
    pub m2l_boxes: usize,
    /// Source-target pairs of the near field (P2P over U lists).
    pub p2p_pairs: f64,
    /// V-list pairs (M2L).
    pub m2l_pairs: f64,
    /// Points evaluated against surfaces beyond P2M and L2P: targets times
    /// W-list boxes (M2P) plus sources of X-list leaves (P2L). Each costs
    /// `n` kernel evaluations like a P2M or L2P point.
    pub far_points: f64,
    /// U-list entries of the leaves (one P2P block each).
    pub u_entries: f64,
    /// `max |center| / half-width` over the leaves (Euclidean norm of the
    /// centre, in the caller's coordinates): how many digits of the
    /// coordinates the smallest boxes need ([`ErrorModel::rounding_floor`]).
    pub rounding_ratio: f64,
}

impl WorkCounts {
    /// Exact counts of a built tree.
    pub fn of_tree(tree: &Octree) -> Self {
        let n = tree.n_boxes();
        let (p2p, m2l, far, u) = (0..n)
            .into_par_iter()
            .map(|b| {
                let nt = tree.target_range(b).len() as f64;
                let mut p2p = 0.0;
                let mut u = 0.0;
                if tree.is_leaf(b) && nt > 0.0 {
                    let ns: usize = tree
                        .u_list(b)
                        .iter()
                        .map(|&a| tree.source_range(a).len())
                        .sum();
                    p2p = nt * ns as f64;
                    u = tree.u_list(b).len() as f64;
                }
                let x: usize = tree
                    .x_list(b)
                    .iter()
                    .map(|&a| tree.source_range(a).len())
                    .sum();
                let far = nt * tree.w_list(b).len() as f64 + x as f64;
                (p2p, tree.v_list(b).len() as f64, far, u)
            })
            .reduce(
                || (0.0, 0.0, 0.0, 0.0),
                |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3 + b.3),
            );
        let domain = tree.domain();
        let rounding_ratio = tree
            .leaves()
            .par_iter()
            .map(|&b| center_ratio(tree.key(b), domain))
            .reduce(|| 0.0, f64::max);
        let depth = tree.depth();
        let top = if depth >= 2 {
            tree.level_range(2).start
        } else {
            n
        };
        WorkCounts {
            n_sources: tree.n_sources(),
            n_targets: tree.n_targets(),
            depth,
            n_boxes: n,
            n_leaves: tree.leaves().len(),
            m2l_boxes: n - top,
            p2p_pairs: p2p,
            m2l_pairs: m2l,
            far_points: far,
            u_entries: u,
            rounding_ratio,
        }
    }
}

// ---------------------------------------------------------------------------
// Pre-pass: occupancy of the adaptive tree for any leaf size
// ---------------------------------------------------------------------------

/// A fast mixer for Morton keys (the std SipHash is several times slower,
/// and no attacker chooses these keys). SplitMix64's finaliser: every input
/// bit reaches the low bits the table indexes with.
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(self.0 ^ b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = z ^ (z >> 31);
    }
}

type KeyMap = HashMap<u64, u32, BuildHasherDefault<KeyHasher>>;

/// A box of a simulated tree: its level and integer coordinates on that
/// level's grid (cheaper to step to neighbours than Morton keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cell {
    level: u32,
    c: [u32; 3],
}

impl Cell {
    const ROOT: Cell = Cell {
        level: 0,
        c: [0; 3],
    };

    fn level(self) -> u32 {
        self.level
    }

    /// Key in the level's lookup table (21 bits per coordinate).
    fn raw(self) -> u64 {
        self.c[0] as u64 | (self.c[1] as u64) << 21 | (self.c[2] as u64) << 42
    }

    /// The same-level box at `offset`, if inside the domain.
    fn neighbour(self, offset: [i32; 3]) -> Option<Cell> {
        let n = 1i64 << self.level;
        let mut c = [0u32; 3];
        for a in 0..3 {
            let x = self.c[a] as i64 + offset[a] as i64;
            if x < 0 || x >= n {
                return None;
            }
            c[a] = x as u32;
        }
        Some(Cell {
            level: self.level,
            c,
        })
    }

    /// The 8 children in octant order (bit 0: upper half in `x`, bit 1 in
    /// `y`, bit 2 in `z`, as Morton digits and `MortonKey::octant`).
    fn children(self) -> [Cell; 8] {
        std::array::from_fn(|d| Cell {
            level: self.level + 1,
            c: [
                2 * self.c[0] + (d & 1) as u32,
                2 * self.c[1] + ((d >> 1) & 1) as u32,
                2 * self.c[2] + ((d >> 2) & 1) as u32,
            ],
        })
    }

    fn octant(self) -> usize {
        (self.c[0] & 1) as usize | ((self.c[1] & 1) as usize) << 1 | ((self.c[2] & 1) as usize) << 2
    }

    fn ancestor(self, level: u32) -> Cell {
        let up = self.level - level;
        Cell {
            level,
            c: self.c.map(|x| x >> up),
        }
    }

    fn parent(self) -> Cell {
        self.ancestor(self.level - 1)
    }

    /// Whether the closed boxes touch (or overlap).
    fn is_adjacent(self, other: Cell) -> bool {
        let d = DEEPEST_LEVEL;
        (0..3).all(|a| {
            let (s0, s1) = (1u64 << (d - self.level), 1u64 << (d - other.level));
            let (lo0, lo1) = (self.c[a] as u64 * s0, other.c[a] as u64 * s1);
            lo0 <= lo1 + s1 && lo1 <= lo0 + s0
        })
    }

    fn center_ratio(self, domain: &Domain) -> f64 {
        let h = domain.width / (1u64 << (self.level + 1)) as f64;
        let r2: f64 = (0..3)
            .map(|a| {
                let x = domain.origin[a] + (2 * self.c[a] + 1) as f64 * h;
                x * x
            })
            .sum();
        r2.sqrt() / h
    }
}

/// A box of a simulated tree: key and point ranges in the sorted codes.
type SimNode = (Cell, [usize; 2], [usize; 2]);

/// One level of a simulated adaptive tree.
#[derive(Default)]
struct SimLevel {
    keys: Vec<Cell>,
    sources: Vec<[usize; 2]>,
    targets: Vec<[usize; 2]>,
    /// Octants of the existing children (0 for a leaf).
    masks: Vec<u8>,
    index: KeyMap,
}

impl SimLevel {
    fn find(&self, key: Cell) -> Option<usize> {
        self.index.get(&key.raw()).map(|&i| i as usize)
    }

    fn push(&mut self, node: SimNode) -> usize {
        let i = self.keys.len();
        self.index.insert(node.0.raw(), i as u32);
        self.keys.push(node.0);
        self.sources.push(node.1);
        self.targets.push(node.2);
        self.masks.push(0);
        i
    }

    fn n_sources(&self, i: usize) -> usize {
        self.sources[i][1] - self.sources[i][0]
    }

    fn n_targets(&self, i: usize) -> usize {
        self.targets[i][1] - self.targets[i][0]
    }
}

/// The box with `key` in simulated `levels`: `(level, index)`.
fn sim_find(levels: &[SimLevel], key: Cell) -> Option<(usize, usize)> {
    let l = key.level() as usize;
    levels.get(l)?.find(key).map(|i| (l, i))
}

/// The 27 offsets of a box's neighbourhood (itself at index 13).
fn offsets() -> impl Iterator<Item = [i32; 3]> {
    (0..27).map(|i| [i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1])
}

/// `NONADJ[o][i]`: mask of the children `j` of the neighbour at offset `o`
/// (index into [`offsets`]) of a parent that are not adjacent to its child
/// `i`, i.e. the V-list candidates. Octant bit 0 is `x`, 1 is `y`, 2 is `z`.
fn non_adjacent_masks() -> [[u8; 8]; 27] {
    let mut out = [[0u8; 8]; 27];
    for (oi, o) in offsets().enumerate() {
        for (i, row) in out[oi].iter_mut().enumerate() {
            for j in 0..8usize {
                let far = (0..3).any(|a| {
                    let ci = ((i >> a) & 1) as i32;
                    let cj = ((j >> a) & 1) as i32;
                    (2 * o[a] + cj - ci).abs() >= 2
                });
                if far {
                    *row |= 1 << j;
                }
            }
        }
    }
    out
}

/// Leaves (and split parents) per level whose work is counted exactly; a
/// level with more is estimated from an evenly spaced sample of this many
/// (in Morton order, so every region is represented).
const MAX_SAMPLED_LEAVES: usize = 2048;

/// Items per rayon task in the simulation (small levels run on one thread).
const MIN_PARALLEL: usize = 512;

/// `ADJ[o]`: mask of the children of the same-level neighbour at offset `o`
/// (index into [`offsets`]) of a box that touch the box.
fn adjacent_child_masks() -> [u8; 27] {
    let mut out = [0u8; 27];
    for (oi, o) in offsets().enumerate() {
        for j in 0..8usize {
            if (0..3).all(|a| {
                let cj = ((j >> a) & 1) as i32;
                (-1..=2).contains(&(2 * o[a] + cj))
            }) {
                out[oi] |= 1 << j;
            }
        }
    }
    out
}

/// The point distribution as sorted Morton codes: enough to simulate the
/// adaptive, 2:1-balanced refinement for any leaf size and count its work
/// ([`Occupancy::work`]) without building a tree, at a fraction of the
/// cost of building one.
///
/// ```
/// use ferrofmm_fmm::Geometry;
/// use ferrofmm_fmm::tuning::Occupancy;
/// let points: Vec<f64> = Geometry::Cube.points(20_000, 1);
/// let occ = Occupancy::new(&points, None, None, 19).unwrap();
/// let coarse = occ.work(400);
/// let fine = occ.work(32);
/// assert!(fine.n_boxes > coarse.n_boxes);
/// assert!(fine.p2p_pairs < coarse.p2p_pairs);
/// ```
pub struct Occupancy {
    domain: Domain,
    sources: Vec<u64>,
    targets: Option<Vec<u64>>,
    max_level: u32,
}

impl Occupancy {
    /// Morton codes (deepest level) of the sources and, when different, the
    /// targets, in the bounding cube of both (or `domain`), sorted.
    /// `max_level` is the deepest level a box may have.
    pub fn new(
        sources: &[f64],
        targets: Option<&[f64]>,
        domain: Option<Domain>,
        max_level: u32,
    ) -> Result<Self, FmmError> {
        let domain = match domain {
            Some(d) => d,
            None => match targets {
                Some(t) => Domain::from_points(&[sources, t])?,
                None => Domain::from_points(&[sources])?,
            },
        };
        let codes = |p: &[f64]| {
            let mut c: Vec<u64> = p
                .par_chunks_exact(3)
                .map(|x| MortonKey::from_point([x[0], x[1], x[2]], &domain, DEEPEST_LEVEL).morton())
                .collect();
            c.par_sort_unstable();
            c
        };
        Ok(Occupancy {
            domain,
            sources: codes(sources),
            targets: targets.map(codes),
            max_level: max_level.min(DEEPEST_LEVEL),
        })
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.sources.len()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.targets.as_ref().map_or(self.sources.len(), Vec::len)
    }

    /// Size of a box for the refinement rule: `max(#sources, #targets)`.
    fn count(&self, n: &SimNode) -> usize {
        let s = n.1[1] - n.1[0];
        if self.targets.is_some() {
            s.max(n.2[1] - n.2[0])
        } else {
            s
        }
    }

    /// The non-empty children of a box.
    fn split(&self, n: &SimNode) -> impl Iterator<Item = SimNode> + use<> {
        let level = n.0.level();
        let shift = 3 * (DEEPEST_LEVEL - level - 1);
        let digit = |c: u64| ((c >> shift) & 7) as usize;
        let bounds = |codes: &[u64], r: [usize; 2]| {
            let s = &codes[r[0]..r[1]];
            let mut b = [r[0]; 9];
            for (d, slot) in b.iter_mut().enumerate().skip(1) {
                *slot = r[0] + s.partition_point(|&c| digit(c) < d);
            }
            b[8] = r[1];
            b
        };
        let bs = bounds(&self.sources, n.1);
        let bt = match &self.targets {
            Some(t) => bounds(t, n.2),
            None => bs,
        };
        n.0.children()
            .into_iter()
            .enumerate()
            .filter(move |&(d, _)| bs[d] < bs[d + 1] || bt[d] < bt[d + 1])
            .map(move |(d, k)| (k, [bs[d], bs[d + 1]], [bt[d], bt[d + 1]]))
    }

    /// The adaptive refinement for `leaf_size` (before balancing), level by
    /// level, without the lookup tables.
    fn refine(&self, leaf_size: usize) -> Vec<SimLevel> {
        let mut levels: Vec<SimLevel> = Vec::new();
        let mut current: Vec<SimNode> =
            vec![(Cell::ROOT, [0, self.sources.len()], [0, self.n_targets()])];
        loop {
            let level = levels.len() as u32;
            let children: Vec<(u32, SimNode)> = current
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .enumerate()
                .filter(|(_, n)| self.count(n) > leaf_size && level < self.max_level)
                .flat_map_iter(|(i, n)| self.split(n).map(move |c| (i as u32, c)))
                .collect();
            let mut lv = SimLevel {
                masks: vec![0; current.len()],
                ..Default::default()
            };
            for &(i, c) in &children {
                lv.masks[i as usize] |= 1 << c.0.octant();
            }
            lv.keys = current.iter().map(|n| n.0).collect();
            lv.sources = current.iter().map(|n| n.1).collect();
            lv.targets = current.iter().map(|n| n.2).collect();
            levels.push(lv);
            if children.is_empty() {
                break;
            }
            current = children.into_iter().map(|(_, c)| c).collect();
        }
        levels
    }

    /// The refinement for `leaf_size`, 2:1 balanced with the rule of
    /// `ferrofmm_tree::balance` (a leaf adjacent to an internal box one
    /// level deeper is split), with lookup tables.
    fn balanced(&self, mut levels: Vec<SimLevel>) -> Vec<SimLevel> {
        levels.par_iter_mut().for_each(|lv| {
            lv.index.reserve(lv.keys.len());
            for (i, k) in lv.keys.iter().enumerate() {
                lv.index.insert(k.raw(), i as u32);
            }
        });
        self.balance(&mut levels);
        levels
    }

    /// Ripple the 2:1 balance to a fixed point.
    fn balance(&self, levels: &mut Vec<SimLevel>) {
        let adj = adjacent_child_masks();
        let depth = levels.len();
        let mut candidates: Vec<(usize, usize)> = levels
            .iter()
            .enumerate()
            .take(depth.saturating_sub(2))
            .flat_map(|(l, lv)| {
                (0..lv.keys.len())
                    .filter(|&i| lv.masks[i] == 0)
                    .map(move |i| (l, i))
            })
            .collect();
        while !candidates.is_empty() {
            let lv: &[SimLevel] = levels;
            let mut violators: Vec<(usize, usize)> = candidates
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .copied()
                .filter(|&(l, i)| lv[l].masks[i] == 0 && violates(lv, l, i, &adj))
                .collect();
            violators.sort_unstable();
            violators.dedup();
            let mut next = Vec::new();
            for &(l, i) in &violators {
                let node = (
                    levels[l].keys[i],
                    levels[l].sources[i],
                    levels[l].targets[i],
                );
                let children: Vec<SimNode> = self.split(&node).collect();
                if levels.len() == l + 1 {
                    levels.push(SimLevel::default());
                }
                let mut mask = 0u8;
                for c in children {
                    mask |= 1 << c.0.octant();
                    let j = levels[l + 1].push(c);
                    next.push((l + 1, j));
                }
                levels[l].masks[i] = mask;
                // Leaves one level coarser and adjacent to the new internal box.
                if l >= 1 {
                    for o in offsets() {
                        if let Some(nk) = node.0.neighbour(o)
                            && let Some(j) = levels[l - 1].find(nk.parent())
                            && levels[l - 1].masks[j] == 0
                        {
                            next.push((l - 1, j));
                        }
                    }
                }
            }
            next.sort_unstable();
            next.dedup();
            candidates = next;
        }
    }

    /// Estimated [`WorkCounts`] of the tree built with `leaf_size`, counted
    /// on the simulated 2:1-balanced tree: U-, W- and X-list work by walking
    /// each leaf's neighbourhood as the interaction lists do, V-list pairs
    /// from the child masks of adjacent parents. Close to the real tree's
    /// counts (within a few percent for uniform points, within about 20% for
    /// strongly clustered ones; the differences come from boxes holding
    /// only sources or only targets and from balancing details).
    pub fn work(&self, leaf_size: usize) -> WorkCounts {
        self.work_of(self.refine(leaf_size.max(1)))
    }

    /// [`Occupancy::work`] of a refinement.
    fn work_of(&self, refined: Vec<SimLevel>) -> WorkCounts {
        let levels = self.balanced(refined);
        let nonadj = non_adjacent_masks();
        let adj = adjacent_child_masks();
        let depth = (levels.len() - 1) as u32;
        let n_boxes: usize = levels.iter().map(|l| l.keys.len()).sum();
        let n_leaves: usize = levels
            .iter()
            .map(|l| l.masks.iter().filter(|&&m| m == 0).count())
            .sum();
        let m2l_boxes: usize = levels.iter().skip(2).map(|l| l.keys.len()).sum();

        // V-list pairs, counted from the parents' level.
        let mut m2l_pairs = 0.0;
        for parents in levels.iter().skip(1) {
            let split: Vec<usize> = (0..parents.keys.len())
                .filter(|&i| parents.masks[i] != 0)
                .collect();
            let stride = split.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = split.iter().step_by(stride).copied().collect();
            let scale = split.len() as f64 / sampled.len().max(1) as f64;
            m2l_pairs += scale
                * sampled
                    .par_iter()
                    .with_min_len(MIN_PARALLEL)
                    .map(|&i| {
                        let mp = parents.masks[i];
                        let mut pairs = 0u32;
                        for (oi, o) in offsets().enumerate() {
                            let Some(q) = parents.keys[i].neighbour(o) else {
                                continue;
                            };
                            let Some(j) = parents.find(q) else {
                                continue;
                            };
                            let mq = parents.masks[j];
                            if mq == 0 {
                                continue;
                            }
                            for (c, &far) in nonadj[oi].iter().enumerate() {
                                if mp & (1 << c) != 0 {
                                    pairs += (far & mq).count_ones();
                                }
                            }
                        }
                        pairs as f64
                    })
                    .sum::<f64>();
        }

        // U (P2P) and W/X (M2P/P2L) work, per leaf.
        let (mut p2p_pairs, mut far_points, mut u_entries) = (0.0, 0.0, 0.0);
        for (l, lv) in levels.iter().enumerate() {
            let leaves: Vec<usize> = (0..lv.keys.len()).filter(|&i| lv.masks[i] == 0).collect();
            // A level with many leaves is estimated from an evenly spaced
            // sample of them (Morton order, so all regions are represented).
            let stride = leaves.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = leaves.iter().step_by(stride).copied().collect();
            if sampled.is_empty() {
                continue;
            }
            let scale = leaves.len() as f64 / sampled.len() as f64;
            let (p, f, u) = sampled
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .map_init(Vec::new, |stack, &i| leaf_work(&levels, l, i, &adj, stack))
                .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
            p2p_pairs += scale * p;
            far_points += scale * f;
            u_entries += scale * u;
        }

        WorkCounts {
            n_sources: self.n_sources(),
            n_targets: self.n_targets(),
            depth,
            n_boxes,
            n_leaves,
            m2l_boxes,
            p2p_pairs,
            m2l_pairs,
            far_points,
            u_entries,
            rounding_ratio: levels
                .iter()
                .flat_map(|lv| lv.keys.iter().zip(&lv.masks))
                .filter(|&(_, &m)| m == 0)
                .map(|(&k, _)| k.center_ratio(&self.domain))
                .fold(0.0, f64::max),
        }
    }
}

/// `|center| / half-width` of a box.
fn center_ratio(key: MortonKey, domain: &Domain) -> f64 {
    let c = key.center(domain);
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / key.half_width(domain)
}

/// Whether leaf `(l, i)` is adjacent to an internal box one level deeper.
fn violates(levels: &[SimLevel], l: usize, i: usize, adj: &[u8; 27]) -> bool {
    if l + 2 >= levels.len() {
        return false;
    }
    let key = levels[l].keys[i];
    offsets().enumerate().any(|(oi, o)| {
        if oi == 13 {
            return false;
        }
        let Some(nk) = key.neighbour(o) else {
            return false;
        };
        let Some(j) = levels[l].find(nk) else {
            return false;
        };
        let touching = levels[l].masks[j] & adj[oi];
        touching != 0
            && nk.children().into_iter().enumerate().any(|(c, ck)| {
                touching & (1 << c) != 0
                    && levels[l + 1]
                        .find(ck)
                        .is_some_and(|m| levels[l + 1].masks[m] != 0)
            })
    })
}

/// `(P2P pairs, far points, U-list entries)` of leaf `(l, i)`: its
/// targets times the sources of its U list, for every W-list box `a` its
/// targets (M2P) plus, for the matching X-list entry of `a`, its sources
/// (P2L), and the length of its U list.
///
/// The children of an internal colleague that touch the leaf are U-list
/// leaves (2:1 balance: a box one level deeper touching a leaf is a leaf;
/// deeper ones are still walked), the others are its W list.
fn leaf_work(
    levels: &[SimLevel],
    l: usize,
    i: usize,
    adj: &[u8; 27],
    stack: &mut Vec<(usize, usize)>,
) -> (f64, f64, f64) {
    let lv = &levels[l];
    let key = lv.keys[i];
    let nt = lv.n_targets(i) as f64;
    let ns_self = lv.n_sources(i) as f64;
    let mut u_sources = 0.0;
    let mut u_entries = 0u32;
    let mut w_boxes = 0u32;
    let mut coarse: [(usize, usize); 8] = [(usize::MAX, 0); 8];
    let mut n_coarse = 0;
    for (oi, o) in offsets().enumerate() {
        let Some(nk) = key.neighbour(o) else {
            continue;
        };
        if let Some(j) = lv.find(nk) {
            let mask = lv.masks[j];
            if mask == 0 {
                u_sources += lv.n_sources(j) as f64;
                u_entries += 1;
                continue;
            }
            w_boxes += (mask & !adj[oi]).count_ones();
            let touching = mask & adj[oi];
            for (c, ck) in nk.children().into_iter().enumerate() {
                if touching & (1 << c) == 0 {
                    continue;
                }
                let Some(b) = levels[l + 1].find(ck) else {
                    continue;
                };
                if levels[l + 1].masks[b] == 0 {
                    u_sources += levels[l + 1].n_sources(b) as f64;
                    u_entries += 1;
                    continue;
                }
                // Not balanced here (never after `balance`): walk deeper.
                stack.clear();
                stack.push((l + 1, b));
                while let Some((m, a)) = stack.pop() {
                    let mask = levels[m].masks[a];
                    for (c, ck) in levels[m].keys[a].children().into_iter().enumerate() {
                        if mask & (1 << c) == 0 {
                            continue;
                        }
                        let Some(b) = levels[m + 1].find(ck) else {
                            continue;
                        };
                        if !ck.is_adjacent(key) {
                            w_boxes += 1;
                        } else if levels[m + 1].masks[b] == 0 {
                            u_sources += levels[m + 1].n_sources(b) as f64;
                            u_entries += 1;
                        } else {
                            stack.push((m + 1, b));
                        }
                    }
                }
            }
            continue;
        }
        // Covered by a coarser leaf (U), or empty.
        for up in (0..l).rev() {
            let Some((m, a)) = sim_find(levels, nk.ancestor(up as u32)) else {
                continue;
            };
            if levels[m].masks[a] == 0 && !coarse[..n_coarse].contains(&(m, a)) {
                if n_coarse < coarse.len() {
                    coarse[n_coarse] = (m, a);
                    n_coarse += 1;
                }
                u_sources += levels[m].n_sources(a) as f64;
                u_entries += 1;
            }
            break;
        }
    }
    (
        nt * u_sources,
        w_boxes as f64 * (nt + ns_self),
        u_entries as f64,
    )
}

// ---------------------------------------------------------------------------
// Cost model
// ---------------------------------------------------------------------------

/// Seconds per unit of work, one coefficient per kind of work, fitted on a
/// 2-core AMD EPYC Zen 4 with AVX-512 and 2 rayon threads
/// (`docs/tolerance.md`). Only the ratios matter to the choice, so another
/// machine of the same kind chooses the same. When an operator gets faster,
/// re-fit with [`CostModel::fit`] (the example `tolerance_grid -- fit`
/// prints a new set to paste into [`CostModel::default`]).
///
/// With `n` points per surface and M2L rank `k`, the predicted time of the
/// tree and one evaluation is
///
/// ```text
/// P2P    p2p_pair p2p_pairs + p2p_entry u_entries
/// far    surface_point n (N_s + N_t) + far_point n far_points
///        + dense n^2 boxes + box_surface n boxes
/// M2L    m2l_flop k^2 v_pairs + m2l_pair k v_pairs + m2l_box n k m2l_boxes
/// tree   tree_point (N_s + N_t) + tree_box boxes + tree_pair v_pairs
/// ```
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CostModel {
    /// Per P2P source-target pair.
    pub p2p_pair: f64,
    /// Per U-list entry (one leaf-to-leaf block).
    pub p2p_entry: f64,
    /// Per point-surface kernel evaluation of P2M and L2P (`n` per point).
    pub surface_point: f64,
    /// Per point-surface kernel evaluation of M2P and P2L (`n` per far
    /// point).
    pub far_point: f64,
    /// Per `n^2` per box (check-to-equivalent, M2M and L2L products).
    pub dense: f64,
    /// Per `n` per box (surfaces, gathers, scatters).
    pub box_surface: f64,
    /// Per `k^2` per V-list pair (the compressed M2L products).
    pub m2l_flop: f64,
    /// Per `k` per V-list pair (gathering and scattering compressed
    /// expansions).
    pub m2l_pair: f64,
    /// Per `n k` per box on levels `>= 2` (compressing multipoles,
    /// expanding check potentials).
    pub m2l_box: f64,
    /// Tree: per point (Morton codes, sort, permutations).
    pub tree_point: f64,
    /// Tree: per box (refinement, balance).
    pub tree_box: f64,
    /// Tree: per V-list pair (interaction lists).
    pub tree_pair: f64,
}

impl Default for CostModel {
    /// The model fitted on this machine (`docs/tolerance.md`).
    fn default() -> Self {
        CostModel {
            p2p_pair: 2.45e-10,
            p2p_entry: 3.06e-8,
            surface_point: 3.18e-10,
            far_point: 2.63e-10,
            dense: 9.67e-11,
            box_surface: 1.84e-8,
            m2l_flop: 5.32e-12,
            m2l_pair: 9.48e-10,
            m2l_box: 2.32e-10,
            tree_point: 2.43e-8,
            tree_box: 1.00e-6,
            tree_pair: 1.51e-8,
        }
    }
}

/// Cost of a target-side kernel evaluation with the gradient relative to
/// the potential alone: the measured P2P rates on one core, 2.32e9
/// (potential) against 1.55e9 (potential and gradient) interactions per
/// second.
pub const GRADIENT_COST_FACTOR: f64 = 1.5;

impl CostModel {
    /// The model for evaluation mode `mode`. The coefficients are fitted on
    /// potentials; with gradients, target-side kernel work (P2P, L2P, M2P)
    /// costs [`GRADIENT_COST_FACTOR`] more. Surface work counts P2M and L2P
    /// (and P2L and M2P) together, so it takes half of the extra.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::CostModel;
    /// use ferrofmm_kernels::EvalMode;
    /// let pot = CostModel::default();
    /// let grad = CostModel::default().for_mode(EvalMode::PotentialGradient);
    /// assert!(grad.p2p_pair > pot.p2p_pair);
    /// assert_eq!(CostModel::default().for_mode(EvalMode::Potential), pot);
    /// ```
    pub fn for_mode(self, mode: EvalMode) -> Self {
        match mode {
            EvalMode::Potential => self,
            EvalMode::PotentialGradient => {
                let half = 0.5 * (1.0 + GRADIENT_COST_FACTOR);
                CostModel {
                    p2p_pair: self.p2p_pair * GRADIENT_COST_FACTOR,
                    surface_point: self.surface_point * half,
                    far_point: self.far_point * half,
                    ..self
                }
            }
        }
    }
}

/// Predicted seconds, by kind of work.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CostPrediction {
    /// P2P.
    pub p2p: f64,
    /// P2M, L2P, M2P, P2L kernel evaluations, check-to-equivalent, M2M, L2L.
    pub far: f64,
    /// M2L.
    pub m2l: f64,
    /// Building the tree.
    pub tree: f64,
    /// All of the above.
    pub total: f64,
}

/// One measured run, for [`CostModel::fit`].
#[derive(Clone, Copy, Debug)]
pub struct CostSample {
    /// Work of the run's tree ([`WorkCounts::of_tree`]).
    pub work: WorkCounts,
    /// Expansion order.
    pub order: usize,
    /// M2L rank (`n` for the dense scheme).
    pub rank: usize,
    /// Measured evaluation.
    pub eval: EvalTimings,
    /// Measured tree construction, seconds.
    pub tree_seconds: f64,
}

/// Units of work of each group, in the order of the coefficients.
struct Features {
    p2p: [f64; 2],
    far: [f64; 4],
    m2l: [f64; 3],
    tree: [f64; 3],
}

fn features(w: &WorkCounts, order: usize, rank: usize) -> Features {
    let n = n_surface_points(order) as f64;
    let k = rank as f64;
    let points = (w.n_sources + w.n_targets) as f64;
    let boxes = w.n_boxes as f64;
    Features {
        p2p: [w.p2p_pairs, w.u_entries],
        far: [n * points, n * w.far_points, n * n * boxes, n * boxes],
        m2l: [
            k * k * w.m2l_pairs,
            k * w.m2l_pairs,
            n * k * w.m2l_boxes as f64,
        ],
        tree: [points, boxes, w.m2l_pairs],
    }
}

fn dot(c: &[f64], x: &[f64]) -> f64 {
    c.iter().zip(x).map(|(a, b)| a * b).sum()
}

impl CostModel {
    fn groups(&self) -> ([f64; 2], [f64; 4], [f64; 3], [f64; 3]) {
        (
            [self.p2p_pair, self.p2p_entry],
            [
                self.surface_point,
                self.far_point,
                self.dense,
                self.box_surface,
            ],
            [self.m2l_flop, self.m2l_pair, self.m2l_box],
            [self.tree_point, self.tree_box, self.tree_pair],
        )
    }

    /// Predicted time of building the tree and one evaluation.
    pub fn predict(&self, work: &WorkCounts, order: usize, rank: usize) -> CostPrediction {
        let f = features(work, order, rank);
        let (p2p, far, m2l, tree) = self.groups();
        let p = CostPrediction {
            p2p: dot(&p2p, &f.p2p),
            far: dot(&far, &f.far),
            m2l: dot(&m2l, &f.m2l),
            tree: dot(&tree, &f.tree),
            total: 0.0,
        };
        CostPrediction {
            total: p.p2p + p.far + p.m2l + p.tree,
            ..p
        }
    }

    /// Fit the coefficients to measured runs: non-negative least squares
    /// of the relative error, group by group (P2P; P2M + L2P + M2P + P2L +
    /// M2M + L2L; M2L; the tree). A group without data keeps the default.
    pub fn fit(samples: &[CostSample]) -> CostModel {
        let mut m = CostModel::default();
        let fs: Vec<Features> = samples
            .iter()
            .map(|s| features(&s.work, s.order, s.rank))
            .collect();
        let secs = |d: std::time::Duration| d.as_secs_f64();
        let rows = |x: &dyn Fn(&Features) -> Vec<f64>, y: &dyn Fn(&CostSample) -> f64| {
            fs.iter()
                .zip(samples)
                .map(|(f, s)| (x(f), y(s)))
                .collect::<Vec<_>>()
        };
        if let Some(c) = fit_nonnegative(&rows(&|f| f.p2p.to_vec(), &|s| secs(s.eval.p2p))) {
            [m.p2p_pair, m.p2p_entry] = [c[0], c[1]];
        }
        let far = rows(&|f| f.far.to_vec(), &|s| {
            let e = &s.eval;
            secs(e.p2m) + secs(e.l2p) + secs(e.m2p) + secs(e.p2l) + secs(e.m2m) + secs(e.l2l)
        });
        if let Some(c) = fit_nonnegative(&far) {
            [m.surface_point, m.far_point, m.dense, m.box_surface] = [c[0], c[1], c[2], c[3]];
        }
        if let Some(c) = fit_nonnegative(&rows(&|f| f.m2l.to_vec(), &|s| secs(s.eval.m2l))) {
            [m.m2l_flop, m.m2l_pair, m.m2l_box] = [c[0], c[1], c[2]];
        }
        if let Some(c) = fit_nonnegative(&rows(&|f| f.tree.to_vec(), &|s| s.tree_seconds)) {
            [m.tree_point, m.tree_box, m.tree_pair] = [c[0], c[1], c[2]];
        }
        m
    }
}

/// Non-negative least squares of the relative residual: minimise
/// `sum_i ((c . x_i - y_i) / y_i)^2` over `c >= 0` (features whose
/// coefficient would be negative are dropped one at a time). `None` when
/// no row has a positive finite `y`.
fn fit_nonnegative(rows: &[(Vec<f64>, f64)]) -> Option<Vec<f64>> {
    let rows: Vec<(Vec<f64>, f64)> = rows
        .iter()
        .filter(|(_, y)| *y > 0.0 && y.is_finite())
        .map(|(x, y)| (x.iter().map(|v| v / y).collect(), 1.0))
        .collect();
    let dim = rows.first()?.0.len();
    let mut active: Vec<bool> = vec![true; dim];
    loop {
        let idx: Vec<usize> = (0..dim).filter(|&i| active[i]).collect();
        let c = least_squares(&rows, &idx)?;
        let mut full = vec![0.0; dim];
        for (&i, &v) in idx.iter().zip(&c) {
            full[i] = v;
        }
        match idx
            .iter()
            .zip(&c)
            .filter(|(_, v)| **v < 0.0)
            .min_by(|a, b| a.1.total_cmp(b.1))
        {
            Some((&i, _)) => active[i] = false,
            None => return Some(full),
        }
    }
}

/// Least squares on the columns `idx` (scaled to unit norm) through faer's
/// thin SVD: `c = V diag(1 / s) U^T y` over the singular values above
/// `1e-10 s_0`, so a column that depends on the others takes no weight
/// instead of blowing up. `None` when the SVD fails.
fn least_squares(rows: &[(Vec<f64>, f64)], idx: &[usize]) -> Option<Vec<f64>> {
    let d = idx.len();
    let scale: Vec<f64> = idx
        .iter()
        .map(|&i| {
            let s = rows.iter().map(|(x, _)| x[i] * x[i]).sum::<f64>().sqrt();
            if s > 0.0 { s } else { 1.0 }
        })
        .collect();
    let x = faer::Mat::<f64>::from_fn(rows.len(), d, |r, c| rows[r].0[idx[c]] / scale[c]);
    let svd = x.thin_svd().ok()?;
    let (u, sv, v) = (svd.U(), svd.S(), svd.V());
    let s0 = if sv.dim() > 0 { sv[0] } else { 0.0 };
    let mut c = vec![0.0; d];
    for k in 0..sv.dim() {
        let sk = sv[k];
        if sk.is_nan() || sk <= 1e-10 * s0 {
            continue;
        }
        let uty: f64 = (0..rows.len()).map(|r| u[(r, k)] * rows[r].1).sum();
        for (j, cj) in c.iter_mut().enumerate() {
            *cj += v[(j, k)] * uty / sk;
        }
    }
    Some(c.iter().zip(&scale).map(|(c, s)| c / s).collect())
}

// ---------------------------------------------------------------------------
// The chooser
// ---------------------------------------------------------------------------

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
    /// Predicted seconds for the tree and one evaluation.
    pub predicted_seconds: f64,
    /// Estimated work of the chosen tree.
    pub estimated_work: WorkCounts,
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
/// [module docs](self)). [`Tuner::new`] holds the measured models; both
/// can be replaced.
#[derive(Clone, Debug)]
pub struct Tuner {
    /// The error model.
    pub error: ErrorModel,
    /// The cost model.
    pub cost: CostModel,
    /// Leaf sizes to consider.
    pub leaf_sizes: Vec<usize>,
    /// How many admissible orders to consider, from the smallest up.
    pub orders: usize,
}

impl Tuner {
    /// The measured Laplace models for `precision`.
    pub fn new(precision: Precision) -> Self {
        Tuner {
            error: ErrorModel::laplace(precision),
            cost: CostModel::default(),
            leaf_sizes: LEAF_SIZE_CANDIDATES.to_vec(),
            orders: 3,
        }
    }

    /// The same tuner for evaluation mode `mode` (the cost model of
    /// [`CostModel::for_mode`] and [`ErrorModel::for_mode`]).
    pub fn for_mode(mut self, mode: EvalMode) -> Self {
        self.cost = self.cost.for_mode(mode);
        self.error = self.error.for_mode(mode);
        self
    }

    /// The admissible `(order, svd tolerance, estimated rank, predicted
    /// error)` for `eps` on a tree with rounding ratio `ratio`: the
    /// smallest admissible order and the next `orders - 1`.
    fn orders_for(&self, eps: f64, ratio: f64) -> Vec<(usize, f64, usize, f64)> {
        let Some(p0) = self.error.smallest_order(eps, ratio) else {
            return Vec::new();
        };
        (p0..p0 + self.orders.max(1))
            .filter(|&p| self.error.admissible(p, eps, ratio))
            .map(|p| {
                let tau = self.error.svd_tolerance(p, eps, ratio);
                let err = self
                    .error
                    .predicted_error(p, tau, ratio)
                    .expect("admissible order");
                (p, tau, estimated_svd_rank(p, tau), err)
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
        validate_tolerance(eps, self.error.precision)?;
        let mut sizes = self.leaf_sizes.clone();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        sizes.dedup();
        let permissive = self.orders_for(eps, 0.0);
        let cost_of = |w: &WorkCounts| {
            self.orders_for(eps, w.rounding_ratio)
                .iter()
                .map(|&(p, _, k, _)| self.cost.predict(w, p, k).total)
                .fold(f64::INFINITY, f64::min)
        };
        // (leaf size, work, boxes per level of the refinement, cost)
        let mut trees: Vec<(usize, WorkCounts, Vec<usize>, f64)> = Vec::new();
        let mut best = f64::INFINITY;
        // Simulated boxes so far, in units of a fully simulated box.
        let mut spent = 0.0;
        // Simulate the tree of leaf size `s` unless it is a known one or
        // over the budget; `Some(cost)` when simulated, `None` to stop.
        let mut visit = |s: usize,
                         trees: &mut Vec<(usize, WorkCounts, Vec<usize>, f64)>,
                         best: &mut f64,
                         bounded: bool|
         -> Option<f64> {
            let refined = occupancy.refine(s.max(1));
            let shape: Vec<usize> = refined.iter().map(|l| l.keys.len()).collect();
            let boxes: usize = shape.iter().sum();
            spent += REFINE_SHARE * boxes as f64;
            if let Some(t) = trees.iter_mut().find(|t| t.2 == shape) {
                // The same tree: report the smallest leaf size giving it.
                t.0 = t.0.min(s);
                return Some(t.3);
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
                    .map(|&(p, _, k, _)| self.cost.predict(&bound, p, k).total)
                    .fold(f64::INFINITY, f64::min);
                if lower > *best {
                    return None;
                }
            }
            spent += boxes as f64;
            let w = occupancy.work_of(refined);
            let cost = cost_of(&w);
            trees.push((s, w, shape, cost));
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
        if let Some(&(s_best, ..)) = trees
            .iter()
            .filter(|t| t.3.is_finite())
            .min_by(|a, b| a.3.total_cmp(&b.3))
            && let Some(i) = sizes.iter().position(|&s| s == s_best)
        {
            for j in [i.wrapping_sub(1), i + 1] {
                if let Some(&s) = sizes.get(j)
                    && !trees.iter().any(|t| t.0 == s)
                    && visit(s, &mut trees, &mut best, false).is_none()
                {
                    break;
                }
            }
        }
        trees.sort_by_key(|t| t.0);
        let mut out = Vec::new();
        for (s, w, ..) in &trees {
            for (p, tau, k, err) in self.orders_for(eps, w.rounding_ratio) {
                out.push(Candidate {
                    order: p,
                    leaf_size: *s,
                    svd_tolerance: tau,
                    estimated_rank: k,
                    predicted_error: err,
                    predicted: self.cost.predict(w, p, k),
                    work: *w,
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
        let candidates = self.candidates(eps, occupancy)?;
        let Some(p_min) = candidates.iter().map(|c| c.order).min() else {
            // No leaf size works: report the limit at the finest resolution
            // the points need (the coarsest tree considered).
            let w = occupancy.work(*self.leaf_sizes.iter().max().unwrap_or(&1));
            return Err(FmmError::ToleranceBeyondPrecision {
                tolerance: eps,
                precision: self.error.precision.name(),
                limit: self.error.smallest_reachable(w.rounding_ratio),
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
            tolerance: eps,
            precision: self.error.precision.name().to_string(),
            order: best.order,
            leaf_size: best.leaf_size,
            svd_tolerance: best.svd_tolerance,
            svd_rank: None,
            estimated_svd_rank: best.estimated_rank,
            predicted_error: best.predicted_error,
            predicted_seconds: best.predicted.total,
            estimated_work: best.work,
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
/// assert!(tuning::SAFETY_FACTOR * c.predicted_error <= 1e-7 * (1.0 + 1e-9));
/// let points32: Vec<f32> = points.iter().map(|&x| x as f32).collect();
/// assert!(choose_parameters(1e-7, &points32, None).is_err());
/// ```
pub fn choose_parameters<T: Real>(
    eps: f64,
    sources: &[T],
    targets: Option<&[T]>,
) -> Result<ChosenParameters, FmmError> {
    validate_tolerance(eps, T::PRECISION)?;
    crate::builder::check_sources_and_targets(sources, targets)?;
    let up = |p: &[T]| p.iter().map(|x| x.to_f64()).collect::<Vec<f64>>();
    let src = up(sources);
    let tgt = targets.map(up);
    Tuner::new(T::PRECISION).choose(eps, &src, tgt.as_deref(), None, DEEPEST_LEVEL)
}

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
                    (
                        "boxes",
                        ratio(est.n_boxes as f64, real.n_boxes as f64),
                        0.01,
                    ),
                    (
                        "leaves",
                        ratio(est.n_leaves as f64, real.n_leaves as f64),
                        0.01,
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
                let f = features(&w, p, k);
                let (gp, gf, gm, gt) = truth.groups();
                let d = std::time::Duration::from_secs_f64;
                let far = dot(&gf, &f.far);
                let eval = EvalTimings {
                    p2p: d(dot(&gp, &f.p2p)),
                    p2m: d(0.3 * far),
                    l2p: d(0.3 * far),
                    m2m: d(0.1 * far),
                    l2l: d(0.3 * far),
                    m2l: d(dot(&gm, &f.m2l)),
                    ..Default::default()
                };
                samples.push(CostSample {
                    work: w,
                    order: p,
                    rank: k,
                    eval,
                    tree_seconds: dot(&gt, &f.tree),
                });
            }
        }
        let fit = CostModel::fit(&samples);
        let (a, b) = (fit.groups(), truth.groups());
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(u, v)| (u / v - 1.0).abs() < 1e-4);
        assert!(close(&a.0, &b.0), "{fit:?}");
        assert!(close(&a.1, &b.1), "{fit:?}");
        assert!(close(&a.2, &b.2), "{fit:?}");
        assert!(close(&a.3, &b.3), "{fit:?}");
        // Predictions of the fitted model reproduce the samples.
        for s in &samples {
            let t = fit.predict(&s.work, s.order, s.rank);
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
