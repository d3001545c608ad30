//! [`FmmBuilder`]: collect the problem and the parameters, validate them,
//! then build the tree and the operators once.

use std::path::PathBuf;
use std::sync::Arc;

use ferrofmm_field::{
    CacheSetting, DenseM2l, M2lScheme, MemoryLimit, OperatorParams, PrecomputeMonitor,
    SurfaceRadii, SvdConfig, SvdM2l,
};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, Precision, Real, SourceKind};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain};

use crate::coordinates::Coordinates;
use crate::fmm::ChosenScheme;
use crate::periodic::Periodic;
use crate::tuning::{CalibrationSetting, ChosenParameters, MachineCalibration, TuningModel};
use crate::{Fmm, FmmError, validate};

pub use ferrofmm_field::{MAX_ORDER, MIN_ORDER};
/// Points per leaf of a tree built with an order and without a leaf size
/// when the leaf size cannot be chosen (the distributed tree); measured
/// best for Laplace in f64 around p = 6 with the SVD scheme on a 2-core
/// AVX-512 machine (docs/performance.md). [`FmmBuilder`] itself chooses
/// the leaf size from the cost model when none is given.
pub const DEFAULT_LEAF_SIZE: usize = 150;
/// Expansion order where one is needed and none is given nor chosen (the
/// distributed tree without a tolerance).
pub const DEFAULT_ORDER: usize = 6;
/// The accuracy asked for when the caller gives neither a tolerance nor an
/// order, in `f64`: a relative L2 error of `1e-6` of the potential (and of
/// the gradient when evaluated), about six digits, what the peers' default
/// settings deliver. [`FmmBuilder`], `ferrofmm demo` / `eval`,
/// `ferrofmm-mpi` and the Python module all use it ([`effective_tolerance`]).
pub const DEFAULT_TOLERANCE: f64 = 1e-6;

/// [`DEFAULT_TOLERANCE`] in `f32`, whose rounding floor lies near `4e-6`
/// ([`crate::tuning::f32_reaches`]): `1e-4`.
pub const DEFAULT_F32_TOLERANCE: f64 = 1e-4;

/// The default tolerance of float type `precision`
/// ([`DEFAULT_TOLERANCE`], [`DEFAULT_F32_TOLERANCE`]).
pub fn default_tolerance(precision: Precision) -> f64 {
    match precision {
        Precision::F32 => DEFAULT_F32_TOLERANCE,
        _ => DEFAULT_TOLERANCE,
    }
}

/// The tolerance a run is chosen for, the one rule of every front end:
/// the caller's `tolerance` when given; else the
/// [default](default_tolerance) of `precision` unless the caller fixed the
/// `order` (then no tolerance: the order is used as given, the leaf size
/// and scheme chosen for it).
///
/// ```
/// use ferrofmm_fmm::{DEFAULT_TOLERANCE, effective_tolerance};
/// use ferrofmm_kernels::Precision::{F32, F64};
/// assert_eq!(effective_tolerance(None, None, F64), Some(DEFAULT_TOLERANCE));
/// assert_eq!(effective_tolerance(None, None, F32), Some(1e-4));
/// assert_eq!(effective_tolerance(Some(1e-3), None, F64), Some(1e-3));
/// assert_eq!(effective_tolerance(None, Some(8), F64), None);
/// assert_eq!(effective_tolerance(Some(1e-9), Some(8), F64), Some(1e-9));
/// ```
pub fn effective_tolerance(
    tolerance: Option<f64>,
    order: Option<usize>,
    precision: Precision,
) -> Option<f64> {
    match (tolerance, order) {
        (Some(eps), _) => Some(eps),
        (None, Some(_)) => None,
        (None, None) => Some(default_tolerance(precision)),
    }
}

/// Largest `k W` (wavenumber times the width of a tree's cube) the FMM
/// accepts for an oscillatory kernel ([`Kernel::wavenumber`]): the
/// equivalent surfaces of the kernel-independent method sample the field
/// at `p` points per box side, so the operators lose accuracy once boxes
/// span several wavelengths (the low-frequency regime; a high-frequency
/// FMM needs directional expansions). M2L starts at level 2, whose boxes
/// are `W / 4` wide: at `k W = 100` four wavelengths, which order 16
/// resolves to 3e-7 (N = 2e4, unit cube, FFT; order 14: 4e-5, order 12:
/// 2e-3). Measured on the unit cube (docs/kernels.md); the chooser's
/// orders for it come from
/// [`helmholtz_error_factor`](crate::tuning::helmholtz_error_factor).
pub const MAX_WAVENUMBER_WIDTH: f64 = 100.0;

/// Builder of an [`Fmm`].
///
/// ```no_run
/// use ferrofmm_fmm::FmmBuilder;
/// use ferrofmm_kernels::EvalMode;
///
/// let sources: Vec<f64> = (0..3000).map(|i| ((i * 7919) % 1000) as f64 / 1000.0).collect();
/// let charges = vec![1.0; 1000];
/// let fmm = FmmBuilder::new(&sources)
///     .order(6)
///     .leaf_size(64)
///     .mode(EvalMode::PotentialGradient)
///     .build_svd()
///     .unwrap();
/// let out = fmm.evaluate(&charges).unwrap(); // [phi, gx, gy, gz] per target
/// assert_eq!(out.len(), 4 * 1000);
/// ```
#[derive(Clone, Debug)]
pub struct FmmBuilder<'a, T: Real, K: Kernel> {
    pub(crate) sources: Coordinates<'a, T>,
    pub(crate) targets: Option<Coordinates<'a, T>>,
    pub(crate) kernel: K,
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    /// Whether the caller gave the order ([`FmmBuilder::order`]).
    pub(crate) order_given: bool,
    /// Whether the caller gave the leaf size ([`FmmBuilder::leaf_size`]).
    pub(crate) leaf_given: bool,
    /// Whether a direct sum may be chosen ([`FmmBuilder::allow_direct`]).
    pub(crate) allow_direct: bool,
    /// Whether wider roots are weighed ([`FmmBuilder::root_search`];
    /// `None`: from [`ROOT_SEARCH_MIN_POINTS`](crate::tuning::ROOT_SEARCH_MIN_POINTS) points on).
    pub(crate) root_search: Option<bool>,
    pub(crate) mode: EvalMode,
    pub(crate) source_kind: SourceKind,
    pub(crate) radii: SurfaceRadii,
    pub(crate) pinv_rcond: Option<f64>,
    pub(crate) cache: CacheSetting,
    pub(crate) domain: Option<Domain>,
    pub(crate) max_level: u32,
    pub(crate) tolerance: Option<f64>,
    pub(crate) verify: bool,
    pub(crate) memory_limit: MemoryLimit,
    pub(crate) monitor: PrecomputeMonitor,
    /// The build's progress callback ([`FmmBuilder::setup_progress`]).
    pub(crate) setup_progress: crate::setup_progress::SetupReporter,
    pub(crate) tuning_model: Option<Arc<dyn TuningModel>>,
    /// The cost model's calibration ([`FmmBuilder::calibration`]).
    pub(crate) calibration: CalibrationSetting,
    /// The periodic cell ([`FmmBuilder::periodic`]), `None` for free space.
    pub(crate) periodic: Option<Periodic>,
}

impl<'a, T: Real> FmmBuilder<'a, T, Laplace3d> {
    /// Start from the sources (interleaved `x, y, z`), with the Laplace
    /// kernel `1 / (4 pi r)`, order [`DEFAULT_ORDER`], leaf size
    /// [`DEFAULT_LEAF_SIZE`], potentials only, and the targets equal to the
    /// sources.
    pub fn new(sources: &'a [T]) -> Self {
        Self::start(Coordinates::Native(sources))
    }

    /// Start from sources held in `f64` (interleaved `x, y, z`), for a run
    /// in any float type `T`; otherwise as [`FmmBuilder::new`].
    ///
    /// For `T = f32` this is the constructor to use when the points are
    /// `f64`: the coordinates are rounded to `f32` only after the tree's
    /// origin (a point near the domain) is subtracted in `f64`, so a
    /// domain far from the origin keeps its points' separations. Rounding
    /// the absolute coordinates first (`x as f32`) moves points by up to
    /// `1e-3` at `|x| = 1e4` and merges every point of a unit cube at
    /// `1e8`. Errors checked afterwards ([`Fmm::evaluate_verified`]) are
    /// against these coordinates to within `2.5 u W` (`u` the unit
    /// roundoff of `T`, `W` the domain's width).
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, Geometry};
    /// // The unit cube shifted by 1e8: f32 cannot even tell its corners apart.
    /// let points: Vec<f64> = Geometry::Cube.points::<f64>(2000, 1).iter().map(|x| x + 1e8).collect();
    /// let fmm = FmmBuilder::<f32, _>::from_f64(&points).order(5).leaf_size(64).build_svd()?;
    /// let phi = fmm.evaluate(&vec![1.0f32; 2000])?;
    /// assert!(phi.iter().all(|p| p.is_finite() && *p > 0.0));
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn from_f64(sources: &'a [f64]) -> Self {
        Self::start(Coordinates::Wide(sources))
    }

    fn start(sources: Coordinates<'a, T>) -> Self {
        FmmBuilder {
            sources,
            targets: None,
            kernel: Laplace3d,
            order: DEFAULT_ORDER,
            leaf_size: DEFAULT_LEAF_SIZE,
            order_given: false,
            leaf_given: false,
            allow_direct: true,
            root_search: None,
            mode: EvalMode::Potential,
            source_kind: SourceKind::Charge,
            radii: SurfaceRadii::default(),
            pinv_rcond: None,
            cache: CacheSetting::Off,
            domain: None,
            max_level: DEEPEST_LEVEL,
            tolerance: None,
            verify: true,
            memory_limit: MemoryLimit::Auto,
            monitor: PrecomputeMonitor::default(),
            setup_progress: Default::default(),
            tuning_model: None,
            calibration: CalibrationSetting::FromCache,
            periodic: None,
        }
    }
}

impl<'a, T: Real, K: Kernel> FmmBuilder<'a, T, K> {
    /// Use another kernel (any [`Kernel`], including your own).
    pub fn kernel<K2: Kernel>(self, kernel: K2) -> FmmBuilder<'a, T, K2> {
        FmmBuilder {
            sources: self.sources,
            targets: self.targets,
            kernel,
            order: self.order,
            leaf_size: self.leaf_size,
            order_given: self.order_given,
            leaf_given: self.leaf_given,
            allow_direct: self.allow_direct,
            root_search: self.root_search,
            mode: self.mode,
            source_kind: self.source_kind,
            radii: self.radii,
            pinv_rcond: self.pinv_rcond,
            cache: self.cache,
            domain: self.domain,
            max_level: self.max_level,
            tolerance: self.tolerance,
            verify: self.verify,
            memory_limit: self.memory_limit,
            monitor: self.monitor,
            setup_progress: self.setup_progress,
            tuning_model: None,
            calibration: self.calibration,
            periodic: self.periodic,
        }
    }

    /// Ask for a relative L2 error `eps` of the potential (and of the
    /// gradient, with [`EvalMode::PotentialGradient`]) instead of giving
    /// the parameters: the order, the leaf size and (with
    /// [`FmmBuilder::build_svd`]) the SVD tolerance of the M2L operators are
    /// chosen from `eps`, the float type and the points, as the cheapest
    /// setting the measured error model admits (see [`crate::tuning`]; the
    /// choice is reported by [`Fmm::chosen_parameters`] and in
    /// [`Fmm::summary`]). An order or a leaf size the caller gives is kept
    /// and only the rest chosen; with no leaf size given, a direct sum is
    /// one of the candidates (exact to rounding, taken where the cost model
    /// predicts it cheaper than the tree and its operators: few points, few
    /// targets, a kernel with costly operators). [`FmmBuilder::build_with`]
    /// keeps the M2L configuration it is given.
    ///
    /// Without a tolerance and without an order, the builder chooses for
    /// [`DEFAULT_TOLERANCE`] (`1e-4` in `f32`):
    /// `FmmBuilder::new(&points).build_svd()` is the right-sized run, not a
    /// fixed order and leaf size.
    ///
    /// `eps` must lie in `(0, 1)` ([`FmmError::InvalidTolerance`]) and be
    /// reachable in the float type ([`FmmError::ToleranceBeyondPrecision`]:
    /// `f32` reaches about `4e-6`, see [`tuning::f32_reaches`](crate::tuning::f32_reaches); `f64` about
    /// `1.2e-10`, with gradients about `1e-5` and `8e-10`). The model is
    /// measured for the Laplace kernel on seven geometries and zero-mean and
    /// positive charges; [`Fmm::evaluate_verified`] checks the result and
    /// raises the order when it falls short (see [`FmmBuilder::verify`]).
    ///
    /// ```no_run
    /// use ferrofmm_fmm::{FmmBuilder, Geometry};
    /// let points: Vec<f64> = Geometry::Plummer.points(100_000, 1);
    /// let fmm = FmmBuilder::new(&points).tolerance(1e-7).build_svd().unwrap();
    /// let chosen = fmm.chosen_parameters().unwrap();
    /// println!("order {} leaf {} svd {:e}", chosen.order, chosen.leaf_size, chosen.svd_tolerance);
    /// ```
    pub fn tolerance(mut self, eps: f64) -> Self {
        self.tolerance = Some(eps);
        self
    }

    /// The models a [`FmmBuilder::tolerance`] is chosen with: your own
    /// [`TuningModel`] for a kernel or scheme the defaults do not know
    /// ([`tuning::default_model`](crate::tuning::default_model): measured for Laplace and modified
    /// Helmholtz, Laplace's tables borrowed for other kernels). Changing
    /// the kernel with [`FmmBuilder::kernel`] resets it.
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, Geometry, tuning::LaplaceModel};
    /// let points: Vec<f64> = Geometry::Cube.points(5000, 1);
    /// let fmm = FmmBuilder::new(&points)
    ///     .tolerance(1e-5)
    ///     .tuning_model(LaplaceModel)
    ///     .build_svd()?;
    /// assert_eq!(fmm.chosen_parameters().unwrap().model, "laplace");
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn tuning_model(mut self, model: impl TuningModel + 'static) -> Self {
        self.tuning_model = Some(Arc::new(model));
        self
    }

    /// Whether [`Fmm::evaluate_verified`] checks the [`FmmBuilder::tolerance`]
    /// after evaluating (on by default): it estimates the achieved error
    /// on a sample of targets against direct summation, at a cost of a few
    /// percent of the evaluation, and raises the order (at most twice)
    /// when the estimate is above the tolerance. Off, the tolerance is
    /// only predicted, and the result says so.
    pub fn verify(mut self, on: bool) -> Self {
        self.verify = on;
        self
    }

    /// Evaluate at these targets (interleaved `x, y, z`) instead of at the sources.
    pub fn targets(mut self, targets: &'a [T]) -> Self {
        self.targets = Some(Coordinates::Native(targets));
        self
    }

    /// [`FmmBuilder::targets`] held in `f64`, for a run in any float type
    /// (rounded relative to the tree's origin, as [`FmmBuilder::from_f64`]).
    pub fn targets_f64(mut self, targets: &'a [f64]) -> Self {
        self.targets = Some(Coordinates::Wide(targets));
        self
    }

    /// Expansion order `p`: each box carries `6 (p - 1)^2 + 2` equivalent
    /// densities. The error falls roughly 7-10x per order.
    ///
    /// Without a [`FmmBuilder::tolerance`] the order is used as given and
    /// the leaf size, unless given too, is the one the cost model predicts
    /// fastest for it (or a direct sum, when that is predicted faster
    /// still: [`crate::tuning::Tuner::prefer_direct`]). With a tolerance,
    /// the order is fixed and verification may still raise it.
    pub fn order(mut self, order: usize) -> Self {
        self.order = order;
        self.order_given = true;
        self
    }

    /// Whether the chooser may make the run a direct sum where the cost
    /// model predicts that cheaper (default `true`; see
    /// [`FmmBuilder::tolerance`]). `false` always builds a tree with
    /// expansions: for benchmarks and tests of the FMM itself.
    pub fn allow_direct(mut self, allowed: bool) -> Self {
        self.allow_direct = allowed;
        self
    }

    /// Whether the chooser weighs roots wider than the points' bounding
    /// cube ([`crate::tuning::choose_root`]): `true` always, `false` never;
    /// by default from
    /// [`ROOT_SEARCH_MIN_POINTS`](crate::tuning::ROOT_SEARCH_MIN_POINTS)
    /// points on. Only where the chooser shapes the tree: a tolerance or
    /// the default one, no leaf size, no domain, no periodic cell, one
    /// cluster, a kernel without a length scale.
    pub fn root_search(mut self, on: bool) -> Self {
        self.root_search = Some(on);
        self
    }

    /// Largest number of points in a leaf before it is split. A given leaf
    /// size is always used (never a direct sum); the order is then chosen
    /// for it (for the [`FmmBuilder::tolerance`] or
    /// [`DEFAULT_TOLERANCE`]) unless given too.
    pub fn leaf_size(mut self, leaf_size: usize) -> Self {
        self.leaf_size = leaf_size;
        self.leaf_given = true;
        self
    }

    /// What is evaluated at the targets: potentials, with gradients, or
    /// with gradients and Hessians (see [`EvalMode`]).
    pub fn mode(mut self, mode: EvalMode) -> Self {
        self.mode = mode;
        self
    }

    /// What each source carries ([`SourceKind`]): charges (the default),
    /// dipole vectors, or both. The densities given to [`Fmm::evaluate`]
    /// then hold `kind.values_per_source()` values per source, interleaved
    /// (`[q]`, `[nx, ny, nz]` or `[q, nx, ny, nz]`), and each source
    /// contributes `q K(x, y) + n . grad_x K(x, y)` (a double-layer
    /// potential for dipoles). Only the source-side operators (P2M, P2L,
    /// P2P) see the dipoles; the expansions stay those of the kernel.
    ///
    /// The kernel must [support](Kernel::supports) the kind with the
    /// [mode](FmmBuilder::mode) (Laplace, modified Helmholtz and Helmholtz
    /// support every pair), else building fails with
    /// [`KernelError::Unsupported`](ferrofmm_kernels::KernelError::Unsupported).
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, Geometry};
    /// use ferrofmm_kernels::{EvalMode, SourceKind};
    /// let points: Vec<f64> = Geometry::Cube.points(2000, 1);
    /// let dipoles: Vec<f64> = Geometry::Sphere.points(2000, 2); // any vectors
    /// let fmm = FmmBuilder::new(&points)
    ///     .source_kind(SourceKind::Dipole)
    ///     .mode(EvalMode::PotentialGradientHessian)
    ///     .build_svd()
    ///     .unwrap();
    /// let out = fmm.evaluate(&dipoles).unwrap(); // 10 values per target
    /// assert_eq!(out.len(), 10 * 2000);
    /// ```
    pub fn source_kind(mut self, kind: SourceKind) -> Self {
        self.source_kind = kind;
        self
    }

    /// Radii of the check and equivalent surfaces (multiples of the box half-width).
    pub fn surface_radii(mut self, radii: SurfaceRadii) -> Self {
        self.radii = radii;
        self
    }

    /// Relative singular-value cutoff of the check-to-equivalent
    /// pseudo-inverses (`None`: the float type's default; `Some(0.0)`: none).
    ///
    /// A cutoff too small for the float type at the chosen order (rounding
    /// errors amplified more than
    /// [`AMPLIFICATION_WARNING`](ferrofmm_field::AMPLIFICATION_WARNING)-fold,
    /// e.g. no cutoff in `f32` from `p = 7` on) makes the build fail with
    /// [`FmmError::IllConditioned`] rather than return noise.
    pub fn pinv_rcond(mut self, rcond: Option<f64>) -> Self {
        self.pinv_rcond = rcond;
        self
    }

    /// Directory for the on-disk operator cache (none by default):
    /// `.cache(CacheSetting::Dir(dir))`.
    pub fn cache_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.cache = CacheSetting::Dir(dir.into());
        self
    }

    /// Which on-disk operator cache to use: [`CacheSetting::Off`] (the
    /// default), [`CacheSetting::Default`] or [`CacheSetting::Dir`].
    ///
    /// The library keeps operators in memory unless asked, so a program or
    /// a test suite never writes into the user's home folder by surprise;
    /// the `ferrofmm` command, `ferrofmm-mpi` and the Python module ask for
    /// [`CacheSetting::Default`] (see [`FmmBuilder::default_cache`]). With
    /// a folder, at most its size cap of cache files is kept there
    /// (`FERROFMM_CACHE_SIZE`, default
    /// [`DEFAULT_CACHE_SIZE`](ferrofmm_field::DEFAULT_CACHE_SIZE)), least
    /// recently used first out; a folder that cannot be written leaves the
    /// operators in memory (the [`CacheStatus`](ferrofmm_field::CacheStatus)
    /// of [`Fmm::operators`] says why), never an error.
    pub fn cache(mut self, setting: CacheSetting) -> Self {
        self.cache = setting;
        self
    }

    /// Which calibration of the cost model the parameter chooser uses
    /// (with a tolerance, or an order without a leaf size):
    /// [`CalibrationSetting::FromCache`] (the default) takes the one
    /// `ferrofmm calibrate` (or [`MachineCalibration::save`](crate::tuning::MachineCalibration::save))
    /// left in the operator cache folder for this processor and number of
    /// threads, if any; without a cache folder, or without a calibration
    /// for this machine there, the built-in model is used
    /// ([`crate::tuning::calibration`](crate::tuning::MachineCalibration)).
    ///
    /// ```
    /// use ferrofmm_fmm::{CalibrationSetting, FmmBuilder, Geometry};
    /// let points = Geometry::Cube.points(3_000, 1);
    /// // The built-in cost model, whatever the cache folder holds.
    /// let fmm = FmmBuilder::<f64, _>::new(&points)
    ///     .tolerance(1e-4)
    ///     .calibration(CalibrationSetting::Off)
    ///     .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())?;
    /// assert!(!fmm.chosen_parameters().unwrap().model.contains("calibrated"));
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn calibration(mut self, setting: CalibrationSetting) -> Self {
        self.calibration = setting;
        self
    }

    /// The calibration the chooser uses ([`FmmBuilder::calibration`]).
    pub(crate) fn machine_calibration(&self) -> Option<MachineCalibration> {
        match &self.calibration {
            CalibrationSetting::Off => None,
            CalibrationSetting::Given(c) => Some(c.clone()),
            CalibrationSetting::FromCache => MachineCalibration::from_cache(&self.cache),
        }
    }

    /// Use the default on-disk cache, as the command-line tools do:
    /// `FERROFMM_CACHE` (a folder, or `off`), else
    /// `$XDG_CACHE_HOME/ferrofmm`, else `$HOME/.cache/ferrofmm`, else memory
    /// only ([`CacheSetting::resolve`]). A `FERROFMM_CACHE_SIZE` that is
    /// not a size makes the build fail with [`FmmError::Field`].
    ///
    /// ```
    /// use ferrofmm_fmm::FmmBuilder;
    /// use ferrofmm_fmm::CacheSetting;
    /// # let dir = std::env::temp_dir().join(format!("ferrofmm-doc-{}", std::process::id()));
    /// let points = ferrofmm_fmm::Geometry::Cube.points(500, 1);
    /// // A folder of one's own; `.default_cache()` for the user's cache folder.
    /// let fmm = FmmBuilder::<f64, _>::new(&points)
    ///     .order(4)
    ///     .cache(CacheSetting::Dir(dir.clone()))
    ///     .build_svd()?;
    /// assert!(fmm.operators().cache_status().path().unwrap().starts_with(&dir));
    /// # std::fs::remove_dir_all(&dir).ok();
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn default_cache(self) -> Self {
        self.cache(CacheSetting::Default)
    }

    /// How much memory the run may take (default [`MemoryLimit::Auto`]:
    /// `FERROFMM_MEMORY_LIMIT`, else the memory available). Checked twice,
    /// so that a run that cannot fit fails with the estimate instead of
    /// swapping or being killed:
    ///
    /// * first, before anything is allocated for the points: the bytes the
    ///   point counts alone imply ([`MemoryReport::predict`](crate::MemoryReport::predict),
    ///   a lower bound), else [`FmmError::RunMemory`];
    /// * then, before precomputing, the operators' peak memory `M` and
    ///   time, predicted from the operators the tree needs (only the
    ///   levels and transfer vectors its V lists use), else
    ///   [`FmmError::PrecomputeMemory`].
    ///
    /// [`MemoryLimit::Unlimited`] forces both.
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, MemoryLimit};
    /// let points = ferrofmm_fmm::Geometry::Cube.points(2000, 1);
    /// let err = FmmBuilder::<f64, _>::new(&points)
    ///     .order(8)
    ///     .leaf_size(20)
    ///     .memory_limit(MemoryLimit::Bytes(1 << 20))
    ///     .build_dense()
    ///     .err()
    ///     .unwrap();
    /// assert!(err.to_string().contains("predicted to need"));
    /// // 2000 points in 1 KiB: refused before the tree is built.
    /// let err = FmmBuilder::<f64, _>::new(&points)
    ///     .memory_limit(MemoryLimit::Bytes(1 << 10))
    ///     .build_svd()
    ///     .err()
    ///     .unwrap();
    /// assert!(matches!(err, ferrofmm_fmm::FmmError::RunMemory { .. }), "{err}");
    /// ```
    pub fn memory_limit(mut self, limit: MemoryLimit) -> Self {
        self.memory_limit = limit;
        self
    }

    /// Progress callback and cancel flag of the operator precomputation
    /// (see [`PrecomputeMonitor`]): a cancelled build fails with
    /// `FmmError::Field(FieldError::Cancelled)` ([`FmmError::is_cancelled`]).
    pub fn monitor(mut self, monitor: PrecomputeMonitor) -> Self {
        self.monitor = monitor;
        self
    }

    /// Call `f` as the build goes (see [`SetupProgress`](crate::SetupProgress)):
    /// the tuning, the tree, the operators and the layout each report how
    /// much of them is done, so that a front end can show a bar with the
    /// time left for each. The operators' reports also reach a
    /// [`FmmBuilder::monitor`]'s callback. Nothing changes in the result.
    ///
    /// ```
    /// use std::sync::{Arc, Mutex};
    /// use ferrofmm_fmm::{FmmBuilder, Geometry, SetupStep};
    /// let points: Vec<f64> = Geometry::Cube.points(5000, 1);
    /// let seen = Arc::new(Mutex::new(Vec::new()));
    /// let log = seen.clone();
    /// let fmm = FmmBuilder::new(&points)
    ///     .tolerance(1e-4)
    ///     .allow_direct(false)
    ///     .setup_progress(move |p| log.lock().unwrap().push(p))
    ///     .build_svd()?;
    /// let seen = seen.lock().unwrap();
    /// assert_eq!(seen.first().map(|p| p.step), Some(SetupStep::Tuning));
    /// assert_eq!(seen.last().map(|p| (p.step, p.done == p.total)), Some((SetupStep::Layout, true)));
    /// # let _ = fmm;
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn setup_progress(
        mut self,
        f: impl Fn(crate::SetupProgress) + Send + Sync + 'static,
    ) -> Self {
        self.setup_progress = crate::setup_progress::SetupReporter::new(Arc::new(f));
        self
    }

    /// Use this bounding cube instead of the points' own.
    pub fn domain(mut self, domain: Domain) -> Self {
        self.domain = Some(domain);
        self
    }

    /// Deepest tree level allowed (at most [`DEEPEST_LEVEL`]).
    pub fn max_level(mut self, level: u32) -> Self {
        self.max_level = level;
        self
    }

    /// Periodic boundary conditions: the sources and targets lie in a cell
    /// that repeats ([`Periodic`]), and every target sees every image of
    /// every source (the Ewald convention; see [`crate::periodic`] for
    /// the maths and the conventions). Points outside the cell are wrapped
    /// into it; results come in the caller's order.
    ///
    /// This release runs the Laplace kernel, the Yukawa kernel
    /// ([`ferrofmm_kernels::ModifiedHelmholtz3d`]) and the Stokeslet
    /// ([`ferrofmm_kernels::Stokes3d`]) with charges (point forces) in a
    /// cubic cell periodic in `x`, `y` and `z` ([`crate::periodic::lattice_sum`]
    /// says which kernels). A Laplace cell must be neutral
    /// ([`FmmError::NotNeutral`] at evaluation otherwise); a Yukawa cell
    /// need not be, and takes no vacuum surface term (its sum converges
    /// absolutely); Stokes takes any forces, with Hasimoto's convention
    /// (zero mean velocity, a net force balanced by a uniform pressure
    /// gradient). Laplace and Yukawa also run in slabs (`x` and `y`
    /// repeat, [`crate::PeriodicAxes::Xy`]) and rods (`x` repeats,
    /// [`crate::PeriodicAxes::X`]), whose points must lie within the cell
    /// along the open axes. Any other kernel whose lattice sum converges
    /// absolutely (your own [`Kernel`], damped Helmholtz waves) runs in
    /// bulk, slabs and rods too, its far images summed over super-cells
    /// with its own values ([`crate::periodic::LatticeSum::Images`]); one
    /// whose sum does not converge (decaying as `r^-3` or slower in bulk,
    /// undamped waves) is refused when building, with the reason. Dipoles,
    /// Stokes slabs and rods, non-cubic boxes and a [`FmmBuilder::domain`]
    /// beside the cell are refused when building. A tolerance is chosen and
    /// verified as in free space, the verification's truth being an Ewald
    /// sum ([`ferrofmm_kernels::EwaldSum`], screened for Yukawa;
    /// [`ferrofmm_kernels::StokesEwaldSum`] for Stokes;
    /// [`ferrofmm_kernels::SlabGreen`] and [`ferrofmm_kernels::RodGreen`]
    /// pair by pair for slabs and rods), or for the other kernels the image
    /// sum itself, shell by shell (refused, with the reason, when it would
    /// take more than `4e10` kernel evaluations).
    ///
    /// ```
    /// use ferrofmm_fmm::{FmmBuilder, Periodic};
    /// use ferrofmm_kernels::EvalMode;
    /// // A CsCl crystal: two ions per cubic cell of side 1.
    /// let points = [0.0, 0.0, 0.0, 0.5, 0.5, 0.5];
    /// let fmm = FmmBuilder::new(&points)
    ///     .periodic(Periodic::cube(1.0))
    ///     .mode(EvalMode::Potential)
    ///     .build_svd()?;
    /// let q = [1.0, -1.0];
    /// let phi = fmm.evaluate(&q)?;
    /// // The Madelung constant, in units of the nearest-neighbour distance.
    /// let madelung = -phi[0] * 4.0 * std::f64::consts::PI * 3f64.sqrt() / 2.0;
    /// assert!((madelung - 1.762_674_773_070).abs() < 1e-5);
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn periodic(mut self, cell: Periodic) -> Self {
        self.periodic = Some(cell);
        self
    }

    /// Operator parameters as they will be used (the cache setting
    /// resolved: a `FERROFMM_CACHE_SIZE` that is not a size is an error).
    pub(crate) fn operator_params(&self) -> Result<OperatorParams, FmmError> {
        let mut params = OperatorParams::new(self.order);
        params.radii = self.radii;
        params.pinv_rcond = self.pinv_rcond;
        let cache = self.cache.resolve()?;
        params.cache_dir = cache.dir().map(PathBuf::from);
        params.cache_size_limit = cache.size_limit();
        params.memory_limit = self.memory_limit;
        params.monitor = match self.setup_progress.operators() {
            Some(f) => self.monitor.clone().and_progress(f),
            None => self.monitor.clone(),
        };
        Ok(params)
    }

    /// Check every parameter and every coordinate before any work
    /// ([`crate::validate`]).
    pub(crate) fn validate(&self) -> Result<(), FmmError> {
        validate::check_parameters(
            &self.kernel,
            self.source_kind,
            self.mode,
            self.tolerance.map(|eps| (eps, T::PRECISION)),
            self.order,
            self.leaf_size,
            self.max_level,
        )?;
        self.sources.check("sources")?;
        if let Some(t) = &self.targets {
            t.check("targets")?;
        }
        self.cache.resolve()?;
        if let Some(cell) = &self.periodic {
            cell.validate()?;
            check_periodic_problem(
                &self.kernel,
                cell,
                self.source_kind,
                self.mode,
                self.domain.is_some(),
            )?;
            if let Some(eps) = self.tolerance {
                crate::periodic::check_screened_tolerance(&self.kernel, cell, eps, T::PRECISION)?;
            }
        }
        Ok(())
    }

    /// Build with the M2L scheme `S` and its configuration.
    pub fn build_with<S: M2lScheme<T>>(self, config: S::Config) -> Result<Fmm<T, K, S>, FmmError> {
        Fmm::build(self, config, None)
    }

    /// Build with the SVD-compressed M2L scheme (the default choice). With
    /// a [`FmmBuilder::tolerance`], the SVD tolerance is chosen too.
    pub fn build_svd(self) -> Result<Fmm<T, K, SvdM2l<T>>, FmmError> {
        Fmm::build(
            self,
            SvdConfig::default(),
            Some(ChosenScheme {
                config: |c: &ChosenParameters| SvdConfig {
                    rank: None,
                    tolerance: c.svd_tolerance,
                },
                rank: SvdM2l::rank,
            }),
        )
    }

    /// Build with the dense (reference) M2L scheme.
    pub fn build_dense(self) -> Result<Fmm<T, K, DenseM2l<T>>, FmmError> {
        self.build_with(Default::default())
    }
}

/// Refuse what periodic runs do not support yet (see
/// [`FmmBuilder::periodic`]).
fn check_periodic_problem<K: Kernel>(
    kernel: &K,
    cell: &Periodic,
    kind: SourceKind,
    mode: EvalMode,
    domain_given: bool,
) -> Result<(), FmmError> {
    if mode.has_hessian() {
        return Err(FmmError::InvalidParameter(
            "periodic boundaries give potentials and gradients in this release, not Hessians"
                .to_string(),
        ));
    }
    // The name every front end takes (`yukawa`), with the library's.
    let name = || match ferrofmm_kernels::KernelChoice::of(kernel) {
        Some(c) => format!("{} ({})", c.description().name, kernel.name()),
        None => kernel.name(),
    };
    use crate::periodic::LatticeSum;
    match crate::periodic::lattice_sum(kernel) {
        None => {
            return Err(FmmError::InvalidParameter(format!(
                "{} has no periodic lattice sum: undamped waves' sums over the images do not \
                 converge; give the wavenumber a positive imaginary part (damped waves), whose \
                 sums do",
                name()
            )));
        }
        Some(LatticeSum::Yukawa { .. } | LatticeSum::Images { .. })
            if cell.surface() == crate::SurfaceTerm::Vacuum =>
        {
            return Err(FmmError::InvalidParameter(format!(
                "the vacuum surface term belongs to the Laplace lattice sum, which converges \
                 only conditionally; {}'s converges absolutely and has none: leave the surface \
                 term at its default",
                name()
            )));
        }
        Some(LatticeSum::Stokes { .. }) if cell.surface() == crate::SurfaceTerm::Vacuum => {
            return Err(FmmError::InvalidParameter(format!(
                "the vacuum surface term belongs to the Laplace lattice sum; {}'s is Hasimoto's \
                 (zero mean velocity, the net force balanced by a uniform pressure gradient) \
                 and has none: leave the surface term at its default",
                name()
            )));
        }
        Some(LatticeSum::Stokes { .. }) if cell.axes() != crate::PeriodicAxes::Xyz => {
            return Err(FmmError::InvalidParameter(format!(
                "{} runs fully periodic (\"xyz\") cells only in this release, not a {}: the \
                 Stokeslet's lattice sum over a plane or a line of cells diverges unless the \
                 net force vanishes, and that sum is not built here",
                name(),
                cell.axes().kind()
            )));
        }
        Some(_) => {}
    }
    if kind != SourceKind::Charge {
        return Err(FmmError::InvalidParameter(
            "periodic boundaries take charges only in this release, not dipoles".to_string(),
        ));
    }
    if domain_given {
        return Err(FmmError::InvalidParameter(
            "a periodic run's domain is its cell: give the cell (Periodic) and no domain"
                .to_string(),
        ));
    }
    Ok(())
}
