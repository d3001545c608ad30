//! The error model: measured errors per order, SVD and rounding terms, the
//! f32/f64 limits.

use ferrofmm_field::{default_svd_tolerance, n_surface_points};
use ferrofmm_kernels::{EvalMode, Precision};

use super::scene::Scene;

/// Safety factor `S` between the measured worst error of an order and the
/// tolerance it is used for, for a model that knows nothing of the scene
/// (the worst-case tables, e.g. [`StokesModel`](super::StokesModel)'s and
/// [`HelmholtzModel`](super::HelmholtzModel)'s, or any model before
/// [`ErrorModel::in_scene`]). The table is already the worst of 42 settings
/// per order (seven geometries, two kinds of charges, three leaf sizes);
/// `S` covers larger N (errors grow about 1.5x from 2e4 to 1e6 points)
/// and inputs not measured, and the after-the-fact verification
/// ([`crate::verify`]) catches what it does not.
pub const SAFETY_FACTOR: f64 = 1.6;

/// Safety factor `S` of a model fitted to the scene
/// ([`ErrorModel::in_scene`]): its tables are the typical error of the
/// scene's kind (the cube and two clusters for volumes, not the Plummer
/// sphere, which measures 2-3x higher), so that the median workload gets
/// the smallest order that meets `eps`; `S` leaves room for the
/// verification's noise margin ([`crate::verify::VERIFY_NOISE`]: an
/// estimate is accepted when `(1 + 4 / sqrt(s))` times it is at most
/// `eps`, 1.13 to 1.7 for the 32 to 1000 targets sampled, a larger sample
/// deciding within the band), and the
/// verification raises the order for the inputs above the typical error
/// (the Plummer sphere; all-positive charges in volumes, whose gradient is
/// 1-4x that of zero-mean charges).
pub const SCENE_SAFETY_FACTOR: f64 = 1.5;

/// Number of points the scene tables were measured at
/// ([`ErrorModel::in_scene`]).
pub const SCENE_REFERENCE_POINTS: f64 = 2e4;

/// The potential's error grows with the number of points as
/// `(N / 2e4)^SCENE_POTENTIAL_GROWTH` (never below the table): uniform
/// cube, zero-mean charges, order 6, leaf 150: 1.8e-6 at 2e4, 3.6e-6 at
/// 1e6 (2.0x; `0.2` gives 2.2x); 1.2e-5 at 1e5 and order 5 against 1.7e-5
/// at 2e4 (the growth is not monotone: it follows the tree's depth). The
/// gradient's error does not grow (zero-mean charges, order 6: 6.0e-6 at
/// 2e4, 1.3e-6 at 1e6), and is kept at its table.
pub const SCENE_POTENTIAL_GROWTH: f64 = 0.2;

/// Error `f32` rounding adds at every order (measured worst over the four
/// test geometries: about `1e-6` on uniform points, `2.4e-6` on two
/// clusters whose coordinates are `1.0 + 1e-4 u`).
pub const F32_ERROR_FLOOR: f64 = 2.5e-6;

/// As [`F32_ERROR_FLOOR`] for the gradient (measured on zero-mean and
/// positive charges, orders 7 to 10: 2.9e-6 to 5.4e-6).
pub const F32_GRADIENT_FLOOR: f64 = 6e-6;

/// Rounding error per unit roundoff and unit of [`WorkCounts::rounding_ratio`](super::WorkCounts::rounding_ratio)
/// (measured: `f32` on two clusters, ratios 0.7e5 to 4.5e5, errors 1.3e-4 to
/// 9e-4, i.e. 0.02 to 0.06 `u ratio`).
pub const ROUNDING_FACTOR: f64 = 0.1;

/// `e_svd(tau) = SVD_POTENTIAL_FACTOR tau`: upper envelope of the extra
/// relative potential error of an SVD tolerance `tau` (measured on
/// zero-mean charges, orders 3 to 12: 0.5 to 1.1 `tau`;
/// `examples/error_model.rs`, `docs/tolerance.md`).
pub(super) const SVD_POTENTIAL_FACTOR: f64 = 1.2;

/// As [`SVD_POTENTIAL_FACTOR`] for the gradient (measured 1.9 to 2.4 `tau`).
pub(super) const SVD_GRADIENT_FACTOR: f64 = 3.0;

/// Loosest SVD tolerance the chooser uses.
pub const MAX_SVD_TOLERANCE: f64 = 1e-2;

/// A higher order than the smallest admissible one is chosen only when it
/// is predicted at least this fraction cheaper.
pub const HIGHER_ORDER_GAIN: f64 = 0.1;

/// Highest order of the Laplace tables (f64 errors stop falling beyond it;
/// see [`MAX_OSCILLATORY_ORDER`] for kernels whose errors do not).
pub const MAX_TUNED_ORDER: usize = 12;

/// Highest order an oscillatory kernel's model goes to
/// ([`HelmholtzModel`](super::HelmholtzModel) in `f64`): at `k W` near
/// [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH) a level-2 box is
/// four wavelengths wide and only orders 14 to 16 resolve it (`k W = 100`,
/// N = 2e4 cube: 2.2e-3 at order 12, 3.6e-5 at 14, 3.3e-7 at 16;
/// `docs/kernels.md`). The Laplace tables stop at [`MAX_TUNED_ORDER`]; the
/// Helmholtz model's orders above it are measured
/// ([`HELMHOLTZ_HIGH_ORDER_ERRORS`](super::HELMHOLTZ_HIGH_ORDER_ERRORS)).
pub const MAX_OSCILLATORY_ORDER: usize = 16;

/// Highest order used in `f32`: beyond it rounding dominates and the error
/// no longer falls (measured: 3e-7..1e-6 at p = 7..8, 6e-7..1.4e-6 at
/// p = 9..10).
pub const MAX_F32_ORDER: usize = 8;

/// Lowest order the error model knows.
pub const MIN_TUNED_ORDER: usize = 2;

/// The leaf-size scan stops after two trees in a row predicted this much
/// slower than the best so far, for every order considered.
pub(super) const STOP_FACTOR: f64 = 1.5;

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
pub(super) const REFINE_SHARE: f64 = 0.25;

/// Leaf sizes the chooser considers. Below 32 points per leaf the P2P
/// blocks are too small to run at speed and the trees are large to
/// simulate; no measured optimum lay there (`docs/tolerance.md`).
pub const LEAF_SIZE_CANDIDATES: [usize; 13] = [
    32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048,
];

/// Worst relative L2 potential error measured at orders 2..=12 (f64, SVD
/// M2L at the default tolerance, zero-mean and positive charges, seven
/// geometries, leaf sizes 32..400, N = 2e4 and 1e5; `docs/tolerance.md`).
pub(super) const F64_POTENTIAL_ERRORS: [f64; MAX_TUNED_ORDER - MIN_TUNED_ORDER + 1] = [
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
pub(super) const F64_GRADIENT_ERRORS: [f64; MAX_TUNED_ORDER - MIN_TUNED_ORDER + 1] = [
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

/// Typical errors per kind of scene, orders 2..=12: relative L2 error of
/// the potential and of the gradient, f64, SVD M2L at the default
/// tolerance, N = 2e4, leaf sizes 150 and 400 (what the chooser takes in
/// practice), raw data `docs/data/error_model_f64_2e4.md`. **Volumes**: the
/// worse of the uniform cube and the two clusters, zero-mean charges (the
/// Plummer sphere measures 2-3x higher; all-positive charges have a
/// gradient 1-4x higher at orders up to 6: the verification raises the
/// order for them). **Surfaces**: the worst of the sphere, the plane and
/// the torus, both kinds of charges. **Curves**: the trefoil, both kinds of
/// charges (all-positive charges 10-50x above zero-mean ones at low order).
/// Surfaces and curves have far smaller gradient errors than potential
/// errors: their gradients are dominated by close neighbours.
pub(super) const VOLUME_POTENTIAL_ERRORS: [f64; 11] = [
    2.7e-2, 1.5e-3, 1.9e-4, 1.7e-5, 1.9e-6, 2.8e-7, 3.8e-8, 5.0e-9, 8.0e-10, 1.1e-10, 4.9e-11,
];

/// See [`VOLUME_POTENTIAL_ERRORS`].
pub(super) const VOLUME_GRADIENT_ERRORS: [f64; 11] = [
    2.0e-2, 2.3e-3, 3.7e-4, 4.5e-5, 6.7e-6, 1.0e-6, 1.8e-7, 2.7e-8, 5.2e-9, 8.2e-10, 3.1e-10,
];

/// See [`VOLUME_POTENTIAL_ERRORS`].
pub(super) const SURFACE_POTENTIAL_ERRORS: [f64; 11] = [
    2.1e-2, 7.5e-4, 8.9e-5, 9.2e-6, 1.2e-6, 1.2e-7, 2.9e-8, 3.6e-9, 3.7e-10, 8.3e-11, 2.4e-11,
];

/// See [`VOLUME_POTENTIAL_ERRORS`].
pub(super) const SURFACE_GRADIENT_ERRORS: [f64; 11] = [
    7.7e-4, 4.2e-5, 1.2e-5, 6.7e-7, 1.4e-7, 1.0e-8, 1.9e-9, 2.8e-10, 3.0e-11, 8.3e-12, 9.3e-13,
];

/// See [`VOLUME_POTENTIAL_ERRORS`] (orders 11 and 12 stop at the rounding
/// floor of the curve's potential, 1.5e-12).
pub(super) const CURVE_POTENTIAL_ERRORS: [f64; 11] = [
    1.7e-3, 2.2e-5, 4.6e-6, 2.4e-7, 2.2e-8, 2.1e-9, 2.1e-10, 2.3e-11, 2.7e-12, 1.5e-12, 1.5e-12,
];

/// See [`VOLUME_POTENTIAL_ERRORS`] (at the rounding floor from order 7).
pub(super) const CURVE_GRADIENT_ERRORS: [f64; 11] = [
    1.1e-9, 7.8e-11, 2.1e-11, 1.5e-12, 2.4e-13, 1.1e-13, 1.1e-13, 1.1e-13, 1.1e-13, 1.1e-13,
    1.1e-13,
];

/// Dimensions ([`Scene::dimension`]) at which the scene tables apply: the
/// curve's up to `CURVE_DIMENSION`, the surfaces' from `SURFACE_DIMENSIONS.0`
/// to `.1`, the volumes' from `VOLUME_DIMENSION`; in between the errors are
/// interpolated in `log`. Measured dimensions: trefoil 1.51, plane 2.00,
/// sphere and torus 2.24-2.55, cube, Plummer and two clusters 2.79-3.00
/// (`Scene`). A dimension read too high costs an order too many; too low,
/// a retry of the verification.
pub const CURVE_DIMENSION: f64 = 1.6;

/// See [`CURVE_DIMENSION`].
pub const SURFACE_DIMENSIONS: (f64, f64) = (2.0, 2.6);

/// See [`CURVE_DIMENSION`].
pub const VOLUME_DIMENSION: f64 = 2.8;

/// Typical Laplace error of order `order` (index `i` into the tables) for
/// `mode` in a scene of dimension `d` and `n` sources: potential and
/// gradient from the scene tables, interpolated in `d`, the potential
/// grown with `n` ([`SCENE_POTENTIAL_GROWTH`]).
fn scene_error(i: usize, mode: EvalMode, scene: &Scene) -> f64 {
    let d = scene.dimension;
    let (s0, s1) = SURFACE_DIMENSIONS;
    let interp = |curve: &[f64; 11], surface: &[f64; 11], volume: &[f64; 11]| -> f64 {
        let mix = |a: f64, b: f64, t: f64| (a.ln() * (1.0 - t) + b.ln() * t).exp();
        if d <= CURVE_DIMENSION {
            curve[i]
        } else if d < s0 {
            mix(
                curve[i],
                surface[i],
                (d - CURVE_DIMENSION) / (s0 - CURVE_DIMENSION),
            )
        } else if d <= s1 {
            surface[i]
        } else if d < VOLUME_DIMENSION {
            mix(surface[i], volume[i], (d - s1) / (VOLUME_DIMENSION - s1))
        } else {
            volume[i]
        }
    };
    let growth = (scene.n_sources as f64 / SCENE_REFERENCE_POINTS)
        .max(1.0)
        .powf(SCENE_POTENTIAL_GROWTH);
    let pot = growth
        * interp(
            &CURVE_POTENTIAL_ERRORS,
            &SURFACE_POTENTIAL_ERRORS,
            &VOLUME_POTENTIAL_ERRORS,
        );
    if mode.values_per_target() == 1 {
        return pot;
    }
    let hessian = hessian_factor(mode);
    let grad = hessian
        * interp(
            &CURVE_GRADIENT_ERRORS,
            &SURFACE_GRADIENT_ERRORS,
            &VOLUME_GRADIENT_ERRORS,
        );
    pot.max(grad)
}

/// The worst-case Laplace table entry (index `i`) for `mode`.
fn worst_error(i: usize, mode: EvalMode) -> f64 {
    if mode.values_per_target() == 1 {
        return F64_POTENTIAL_ERRORS[i];
    }
    let hessian = hessian_factor(mode);
    F64_POTENTIAL_ERRORS[i].max(F64_GRADIENT_ERRORS[i] * hessian)
}

/// The Hessian's error against the gradient's at the same order: at most
/// 2.14 measured (Laplace and modified Helmholtz, f64, SVD M2L, cube and
/// Plummer, zero-mean and positive charges, orders 4..10, N = 2e4,
/// `examples/sources_sweep.rs`; zero-mean charges 0.1..0.7). The table of
/// `F64_GRADIENT_ERRORS` is scaled by it for
/// `EvalMode::PotentialGradientHessian`.
pub const HESSIAN_ERROR_FACTOR: f64 = 2.5;

/// [`HESSIAN_ERROR_FACTOR`] when `mode` evaluates Hessians, else 1: the
/// factor on a gradient error table.
pub(super) fn hessian_factor(mode: EvalMode) -> f64 {
    if mode.has_hessian() {
        HESSIAN_ERROR_FACTOR
    } else {
        1.0
    }
}

/// Ranks of the SVD-compressed M2L stack at tolerances `10^-2 .. 10^-11`
/// (measured, order 9; lower orders cap the rank at the number of surface
/// points).
pub(super) const SVD_RANKS: [f64; 10] = [
    9.0, 22.0, 47.0, 81.0, 124.0, 176.0, 234.0, 304.0, 348.0, 371.0,
];

/// The error model: predicted relative L2 error from the order, the SVD
/// tolerance, the float type and how finely the tree resolves the
/// coordinates (see the [module docs](crate::tuning)), for the potential or, with
/// [`ErrorModel::laplace_for`], for everything an evaluation mode computes.
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
    /// `Some(mode)` when `order_errors` are the Laplace worst-case tables
    /// for `mode` (or a multiple of them, order by order) and
    /// [`ErrorModel::in_scene`] may fit them to a scene; `None` for tables
    /// of another shape and for a model already fitted.
    pub scalable: Option<EvalMode>,
    /// The scene the model was fitted to ([`ErrorModel::in_scene`]).
    pub scene: Option<Scene>,
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

    /// The measured Laplace model for everything `mode` evaluates: with
    /// gradients, the worse of the potential's and the gradient's error at
    /// each order (and the gradient's larger SVD error and rounding), so
    /// that a tolerance holds for both.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::ErrorModel;
    /// use ferrofmm_kernels::{EvalMode, Precision};
    /// let pot = ErrorModel::laplace(Precision::F64);
    /// let both = ErrorModel::laplace_for(Precision::F64, EvalMode::PotentialGradient);
    /// assert!(both.order_error(6).unwrap() >= pot.order_error(6).unwrap());
    /// assert_eq!(ErrorModel::laplace_for(Precision::F64, EvalMode::Potential), pot);
    /// ```
    pub fn laplace_for(precision: Precision, mode: EvalMode) -> Self {
        if mode.values_per_target() == 1 {
            return Self::laplace(precision);
        }
        let hessian = hessian_factor(mode);
        let worst: Vec<f64> = F64_POTENTIAL_ERRORS
            .iter()
            .zip(&F64_GRADIENT_ERRORS)
            .map(|(p, g)| p.max(*g * hessian))
            .collect();
        let mut m = Self::from_table(
            precision,
            &worst,
            SVD_POTENTIAL_FACTOR.max(SVD_GRADIENT_FACTOR),
        );
        if precision == Precision::F32 {
            m.floor = F32_GRADIENT_FLOOR;
        }
        m.rounding_factor = 3.0 * hessian * ROUNDING_FACTOR;
        m.scalable = Some(mode);
        m
    }

    /// The model fitted to `scene`: each order's error times the ratio of
    /// the typical Laplace error in such a scene to the worst-case one,
    ///
    /// ```text
    /// E'_p = E_p * T_p(d, N) / W_p,   S' = SCENE_SAFETY_FACTOR
    /// ```
    ///
    /// with `W_p` the worst-case table ([`ErrorModel::laplace_for`]) and
    /// `T_p(d, N)` the typical error of a scene of dimension `d` (the
    /// tables of volumes, surfaces and curves, interpolated in `log`
    /// between [`CURVE_DIMENSION`], [`SURFACE_DIMENSIONS`] and
    /// [`VOLUME_DIMENSION`]) and `N` sources (the potential's grown by
    /// `(N / 2e4)^`[`SCENE_POTENTIAL_GROWTH`]); with gradients the larger
    /// of the potential's and the gradient's. Only `f64` models are fitted
    /// (`f32`'s floor is a worst case and its orders stop at
    /// [`MAX_F32_ORDER`], beyond the verification's reach). A model scaled from the
    /// Laplace tables (`E_p = c_p W_p`, as a kernel author's may be) keeps
    /// its factors. A model that is not [`ErrorModel::scalable`] is
    /// returned as it is.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::{ErrorModel, Scene};
    /// use ferrofmm_kernels::{EvalMode, Precision};
    /// let worst = ErrorModel::laplace_for(Precision::F64, EvalMode::PotentialGradient);
    /// let cube = Scene { dimension: 3.0, n_sources: 20_000 };
    /// let sphere = Scene { dimension: 2.3, n_sources: 20_000 };
    /// let (v, s) = (worst.in_scene(&cube), worst.in_scene(&sphere));
    /// // A volume's typical error is below the worst case, a surface's far below.
    /// assert!(v.order_error(6).unwrap() < worst.order_error(6).unwrap());
    /// assert!(s.order_error(6).unwrap() < 0.5 * v.order_error(6).unwrap());
    /// assert!(v.smallest_order(2e-5, 0.0) < worst.smallest_order(2e-5, 0.0));
    /// ```
    pub fn in_scene(&self, scene: &Scene) -> ErrorModel {
        // f32's floor is a worst case over its measurements, and its orders
        // stop at MAX_F32_ORDER, where the verification cannot raise them:
        // it keeps the worst-case model.
        let (Some(mode), Precision::F64) = (self.scalable, self.precision) else {
            return self.clone();
        };
        let mut m = self.clone();
        for (p, e) in m.order_errors.iter_mut() {
            if let Some(i) = p.checked_sub(MIN_TUNED_ORDER).filter(|&i| i < 11) {
                *e *= scene_error(i, mode, scene) / worst_error(i, mode);
            }
        }
        m.safety = SCENE_SAFETY_FACTOR;
        m.scalable = None;
        m.scene = Some(*scene);
        m
    }

    /// The model with orders above its table: `(order, E_p)` appended in
    /// `f64` (`f32` models stop at [`MAX_F32_ORDER`] and are returned as
    /// they are), for kernels whose error keeps falling past
    /// [`MAX_TUNED_ORDER`] (see
    /// [`HELMHOLTZ_HIGH_ORDER_ERRORS`](super::HELMHOLTZ_HIGH_ORDER_ERRORS)).
    /// Orders the model already has are kept.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::ErrorModel;
    /// use ferrofmm_kernels::Precision;
    /// let m = ErrorModel::laplace(Precision::F64).with_orders(&[(13, 5e-11), (12, 1.0)]);
    /// assert_eq!(m.order_error(13), Some(5e-11));
    /// assert!(m.order_error(12).unwrap() < 1e-9);
    /// assert_eq!(ErrorModel::laplace(Precision::F32).with_orders(&[(13, 5e-11)]).order_error(13), None);
    /// ```
    pub fn with_orders(mut self, extra: &[(usize, f64)]) -> Self {
        if self.precision != Precision::F64 {
            return self;
        }
        for &(p, e) in extra {
            if self.order_error(p).is_none() {
                self.order_errors.push((p, e));
            }
        }
        self.order_errors.sort_by_key(|&(p, _)| p);
        self
    }

    pub(super) fn from_table(precision: Precision, table: &[f64], svd_factor: f64) -> Self {
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
            scalable: Some(EvalMode::Potential),
            scene: None,
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
    /// ([`WorkCounts::rounding_ratio`](super::WorkCounts::rounding_ratio)): the larger of the float type's
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
    pub(super) fn svd_tolerance_adding(&self, err: f64) -> f64 {
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
/// [`choose_precision`](super::choose_precision).
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svd_tolerance_inverse() {
        let m = ErrorModel::laplace(Precision::F64);
        for tau in [1e-9, 1e-6, 1e-4, 1e-3, 5e-3] {
            let e = m.svd_error(tau);
            let back = m.svd_tolerance_adding(e);
            assert!((back / tau - 1.0).abs() < 1e-9, "{tau} -> {back}");
        }
    }
}
