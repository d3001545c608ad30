//! One distributed run from a request to verified values: the front end
//! that the `ferrofmm-mpi eval` command and the Python module
//! (`ferrofmm.distributed`) share, so that both choose, build, evaluate
//! and verify the same way.
//!
//! # What a [`DistSolver`] does
//!
//! 1. **Plan** (a collective): an order and a leaf size given together are
//!    used as they are; otherwise the order, the leaf size, the SVD
//!    tolerance and the scheme are chosen for the requested relative L2
//!    error `eps` (or the default one) from a sample of the points
//!    ([`choose_parameters`]); an order alone gets its leaf size and scheme
//!    from the same cost model. This is the single-machine rule
//!    ([`ferrofmm_fmm::effective_tolerance`]).
//! 2. **Build**: the distributed tree ([`DistributedTree::build`]) and the
//!    distributed FMM ([`DistributedFmm::build`]) for the kernel, float
//!    type and scheme of the plan, behind one object-safe trait so that the
//!    caller holds one type whatever the combination.
//! 3. **Evaluate** ([`DistSolver::evaluate`]), as often as wanted, for
//!    densities in each rank's input order; values come back in that
//!    order. The first evaluation of a tolerance is **verified**: the
//!    relative L2 errors of potential and gradient at `k` targets sampled
//!    over the global input order are measured against direct summation
//!    over all points ([`crate::sampled_errors`]; `k = 200` unless the request
//!    says), and while the larger of the two exceeds `eps` the order is
//!    raised by one (the tree is kept, the operators rebuilt) at most
//!    [`MAX_VERIFY_RETRIES`] times; a tolerance still missed is said so
//!    ([`DistSolution::verified`] `== Some(false)`, the same on every
//!    rank): the command refuses to write such values, Python warns.
//!
//! Every failure is the same [`DistError`] on every rank: no rank goes on
//! alone into a collective the others never reach.

use ferrofmm_field::{
    CacheLocation, CacheSetting, CacheStatus, DenseM2l, FftM2l, M2lScheme, SvdConfig, SvdM2l,
};
use ferrofmm_fmm::verify::MAX_VERIFY_RETRIES;
use ferrofmm_fmm::{DEFAULT_LEAF_SIZE, DEFAULT_ORDER, FmmError, SchemeChoice, effective_tolerance};
use ferrofmm_kernels::{
    EvalMode, Kernel, KernelChoice, KernelVisitor, Precision, Real, SourceKind,
};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::agree_message;
use crate::{
    DistChoice, DistError, DistFmmOptions, DistOptions, DistributedFmm, DistributedTree, EvalStats,
    SetupStats, choose_parameters, sampled_errors_at,
};

/// Targets a verification samples when the request does not say.
pub const VERIFY_SAMPLE: usize = 200;

/// What to compute: the same on every rank (checked by
/// [`DistSolver::build`]).
#[derive(Clone, Debug)]
pub struct DistRequest {
    /// The kernel and its parameter.
    pub kernel: KernelChoice,
    /// Potentials, or potentials and gradients.
    pub mode: EvalMode,
    /// What the sources carry: charges, dipoles or both.
    pub sources: SourceKind,
    /// Float type of the passes.
    pub precision: Precision,
    /// Requested relative L2 error (`None`: the default one, unless an
    /// order is given).
    pub tolerance: Option<f64>,
    /// Expansion order (with `tolerance`: the least order to try).
    pub order: Option<usize>,
    /// Largest number of points in a leaf (used as given only with an
    /// order and no tolerance).
    pub leaf_size: Option<usize>,
    /// The M2L scheme (`Auto`: chosen).
    pub scheme: SchemeChoice,
    /// Verify the first evaluation of a tolerance (and raise the order
    /// while it is missed).
    pub verify: bool,
    /// Targets the verification samples (`0`: [`VERIFY_SAMPLE`]).
    pub samples: usize,
    /// Where the operators are cached (rank 0 fills it, the others read).
    pub cache: CacheSetting,
}

impl DistRequest {
    /// Potentials of `kernel` for charges, in `f64`, at the default
    /// tolerance (verified), the scheme chosen, no cache.
    pub fn new(kernel: KernelChoice) -> Self {
        DistRequest {
            kernel,
            mode: EvalMode::Potential,
            sources: SourceKind::Charge,
            precision: Precision::F64,
            tolerance: None,
            order: None,
            leaf_size: None,
            scheme: SchemeChoice::Auto,
            verify: true,
            samples: 0,
            cache: CacheSetting::Off,
        }
    }

    /// Every field as `(name, value)` pairs, for [`crate::agree_options`].
    fn describe(&self) -> Vec<(&'static str, String)> {
        vec![
            ("kernel", self.kernel.name()),
            ("mode", format!("{:?}", self.mode)),
            ("sources", self.sources.name().to_string()),
            ("precision", format!("{:?}", self.precision)),
            ("tolerance", format!("{:?}", self.tolerance)),
            ("order", format!("{:?}", self.order)),
            ("leaf_size", format!("{:?}", self.leaf_size)),
            ("scheme", self.scheme.name().to_string()),
            ("verify", self.verify.to_string()),
            ("samples", self.samples.to_string()),
            ("cache", format!("{:?}", self.cache)),
        ]
    }
}

/// The parameters of a run: given, or chosen for a tolerance.
#[derive(Clone, Debug)]
pub struct DistPlan {
    /// Expansion order (raised by a failed verification).
    pub order: usize,
    /// Largest number of points in a leaf.
    pub leaf_size: usize,
    /// The M2L scheme's name (`svd`, `dense`, `fft`).
    pub scheme: &'static str,
    /// The SVD scheme's relative singular-value cut (`None`: the order's
    /// default).
    pub svd_tolerance: Option<f64>,
    /// The chooser's answer, when the parameters were chosen.
    pub choice: Option<DistChoice>,
    /// The tolerance asked for or the default one (`None`: an order, or an
    /// order and a leaf size, given without one).
    pub tolerance: Option<f64>,
}

/// One verified evaluation: its order and the relative L2 errors
/// `[potential, gradient]` measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attempt {
    /// The order evaluated.
    pub order: usize,
    /// Errors against direct summation at the sampled targets.
    pub errors: [f64; 2],
}

/// The values of one evaluation and how they were obtained.
#[derive(Clone, Debug)]
pub struct DistSolution {
    /// [`Kernel::values_per_target`] values per input point of this rank,
    /// in its input order, as `f64`.
    pub values: Vec<f64>,
    /// Times and bytes of this rank's evaluation (the last one, after a
    /// raised order).
    pub stats: EvalStats,
    /// The errors measured, when this evaluation was verified.
    pub errors: Option<[f64; 2]>,
    /// Whether the tolerance was met (`None`: not verified this time).
    pub verified: Option<bool>,
}

/// A distributed FMM built from a [`DistRequest`] (see the
/// [module docs](self)).
pub struct DistSolver<C: Communicator + 'static> {
    request: DistRequest,
    plan: DistPlan,
    tree: DistributedTree,
    points: Vec<f64>,
    /// Separate targets (`None`: the points are the targets).
    targets: Option<Vec<f64>>,
    engine: Box<dyn Engine<C> + Send + Sync>,
    cache: CacheLocation,
    attempts: Vec<Attempt>,
    verified: bool,
}

impl<C: Communicator + 'static> DistSolver<C> {
    /// Plans and builds the run for this rank's `points` (interleaved
    /// `xyz`, any number including none), which are also the targets (a
    /// point does not act on itself). A collective.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: requests that differ between
    /// ranks, bad points on any rank, a tolerance out of reach, a kernel
    /// that does not take the sources, an FMM setup error.
    pub fn build(comm: &C, points: Vec<f64>, request: DistRequest) -> Result<Self, DistError> {
        Self::build_for(comm, points, None, request)
    }

    /// As [`DistSolver::build`] with this rank's own `targets` (anywhere:
    /// the tree's cube covers sources and targets; either set may be empty
    /// on a rank). [`DistSolver::evaluate`] then returns the values at this
    /// rank's targets, in their input order. A collective.
    ///
    /// # Errors
    /// As [`DistSolver::build`], and bad targets on any rank or no target
    /// on any rank ([`DistError::NoTargets`]).
    pub fn build_with_targets(
        comm: &C,
        sources: Vec<f64>,
        targets: Vec<f64>,
        request: DistRequest,
    ) -> Result<Self, DistError> {
        Self::build_for(comm, sources, Some(targets), request)
    }

    fn build_for(
        comm: &C,
        points: Vec<f64>,
        targets: Option<Vec<f64>>,
        request: DistRequest,
    ) -> Result<Self, DistError> {
        let mut described = request.describe();
        described.push(("targets", targets.is_some().to_string()));
        crate::agree_options(comm, &described)
            .map_err(|message| DistError::Fmm { rank: 0, message })?;
        let local = if request
            .kernel
            .visit(Supports(request.sources, request.mode))
        {
            Ok(())
        } else {
            Err(format!(
                "kernel {} does not take {} sources",
                request.kernel.name(),
                request.sources.name()
            ))
        };
        agree_message(comm, local)?;
        let cache = agree_message(comm, request.cache.resolve().map_err(|e| e.to_string()))?;
        request.kernel.visit(Build {
            comm,
            points,
            targets,
            request,
            cache,
        })
    }

    /// Values at this rank's input points for its `densities` (input
    /// order, [`DistSolver::values_per_source`] per point). The first
    /// evaluation of a tolerance is verified (see the [module docs](self)).
    /// A collective.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: densities of the wrong length
    /// or not finite on some rank, a result that overflowed, an FMM setup
    /// error while raising the order.
    pub fn evaluate(&mut self, comm: &C, densities: &[f64]) -> Result<DistSolution, DistError> {
        let verify = self
            .plan
            .tolerance
            .filter(|_| self.request.verify && !self.verified);
        loop {
            let (values, stats) = self.engine.evaluate(comm, &self.tree, densities)?;
            let Some(eps) = verify else {
                return Ok(DistSolution {
                    values,
                    stats,
                    errors: None,
                    verified: None,
                });
            };
            let samples = self.samples();
            let errors = self.sampled_errors(comm, densities, &values, samples);
            self.attempts.push(Attempt {
                order: self.plan.order,
                errors,
            });
            let met = errors[0].max(errors[1]) <= eps;
            if met
                || self.attempts.len() > MAX_VERIFY_RETRIES
                || self.plan.order >= ferrofmm_field::MAX_ORDER
            {
                self.verified = true;
                return Ok(DistSolution {
                    values,
                    stats,
                    errors: Some(errors),
                    verified: Some(met),
                });
            }
            // The tree stays; the operators are rebuilt one order up (the
            // SVD tolerance then the order's default).
            self.plan.order += 1;
            self.plan.svd_tolerance = None;
            self.engine =
                self.engine
                    .with_plan(comm, &self.tree, &self.plan, &self.request, &self.cache)?;
        }
    }

    /// Relative L2 errors `[potential, gradient]` of `values` (this rank's
    /// results for `densities`, input order) at `samples` targets spread
    /// over the global input order, against direct summation over all
    /// points in `f64`. A collective.
    pub fn sampled_errors(
        &self,
        comm: &C,
        densities: &[f64],
        values: &[f64],
        samples: usize,
    ) -> [f64; 2] {
        self.engine.sampled_errors(
            comm,
            self.request.sources,
            self.request.mode,
            &self.points,
            densities,
            self.targets.as_deref().unwrap_or(&self.points),
            values,
            samples.min(self.total_targets()),
        )
    }

    /// Targets a verification compares (at most every point).
    pub fn samples(&self) -> usize {
        let k = if self.request.samples > 0 {
            self.request.samples
        } else {
            VERIFY_SAMPLE
        };
        k.min(self.total_targets())
    }

    /// Targets of all ranks (the points, without separate targets).
    fn total_targets(&self) -> usize {
        let n: u64 = target_counts(&self.tree).iter().sum();
        usize::try_from(n).unwrap_or(usize::MAX)
    }

    /// The request the run was built for.
    pub fn request(&self) -> &DistRequest {
        &self.request
    }

    /// The parameters in use (the order as raised by verification).
    pub fn plan(&self) -> &DistPlan {
        &self.plan
    }

    /// The verified evaluations so far (each order tried, with its errors).
    pub fn attempts(&self) -> &[Attempt] {
        &self.attempts
    }

    /// This rank's piece of the tree.
    pub fn tree(&self) -> &DistributedTree {
        &self.tree
    }

    /// This rank's input points (interleaved `xyz`, input order).
    pub fn points(&self) -> &[f64] {
        &self.points
    }

    /// This rank's separate targets (input order), if any.
    pub fn targets(&self) -> Option<&[f64]> {
        self.targets.as_deref()
    }

    /// The number of targets every rank passed, in rank order (the points,
    /// without separate targets).
    pub fn target_counts(&self) -> &[u64] {
        target_counts(&self.tree)
    }

    /// Setup figures of this rank's FMM.
    pub fn setup_stats(&self) -> &SetupStats {
        self.engine.setup_stats()
    }

    /// Where the operators are cached.
    pub fn cache(&self) -> &CacheLocation {
        &self.cache
    }

    /// What the operator cache did on this rank, in words (`None`: no
    /// operator needed it).
    pub fn cache_summary(&self) -> Option<String> {
        self.engine.cache_summary()
    }

    /// Density values per point ([`Kernel::values_per_source`]).
    pub fn values_per_source(&self) -> usize {
        self.engine.values_per_source()
    }

    /// Result values per point ([`Kernel::values_per_target`]).
    pub fn values_per_target(&self) -> usize {
        self.engine.values_per_target()
    }
}

/// Whether a kernel takes a source kind in a mode.
struct Supports(SourceKind, EvalMode);

impl KernelVisitor for Supports {
    type Output = bool;
    fn visit<K: Kernel>(self, kernel: K) -> bool {
        kernel.supports(self.0, self.1)
    }
}

/// Plan and build for the kernel the request names.
struct Build<'a, C> {
    comm: &'a C,
    points: Vec<f64>,
    targets: Option<Vec<f64>>,
    request: DistRequest,
    cache: CacheLocation,
}

impl<C: Communicator + 'static> KernelVisitor for Build<'_, C> {
    type Output = Result<DistSolver<C>, DistError>;

    fn visit<K: Kernel>(self, kernel: K) -> Self::Output {
        let Build {
            comm,
            points,
            targets,
            request,
            cache,
        } = self;
        // Refused on every rank before the tree is built when some rank's
        // points, densities and results are predicted not to fit.
        let size = ferrofmm_fmm::RunSize {
            n_sources: points.len() / 3,
            n_targets: targets.as_ref().map(|t| t.len() / 3),
            values_per_source: kernel.values_per_source(request.sources),
            values_per_target: kernel.values_per_target(request.mode),
            n_vectors: 1,
        };
        let what = "the distributed run";
        match request.precision {
            Precision::F64 => crate::check_rank_memory::<C, f64>(comm, &size, what)?,
            Precision::F32 => crate::check_rank_memory::<C, f32>(comm, &size, what)?,
        }
        let plan = plan(comm, &points, &kernel, &request, cache.dir().is_some())?;
        let options = DistOptions::adaptive(plan.leaf_size);
        let tree = match &targets {
            None => DistributedTree::build(comm, &points, &options)?,
            Some(t) => DistributedTree::build_with_targets(comm, &points, t, &options)?,
        };
        let engine = engine_for(comm, &tree, kernel, &plan, &request, &cache)?;
        Ok(DistSolver {
            request,
            plan,
            tree,
            points,
            targets,
            engine,
            cache,
            attempts: Vec::new(),
            verified: false,
        })
    }
}

/// The one default rule: no order and no tolerance means the default
/// tolerance; an order alone gets its leaf size and scheme from the cost
/// model; an order and a leaf size are used as given.
fn plan<C: Communicator, K: Kernel>(
    comm: &C,
    points: &[f64],
    kernel: &K,
    request: &DistRequest,
    cached: bool,
) -> Result<DistPlan, DistError> {
    let eps = effective_tolerance(
        request.tolerance,
        request.order.or(request.leaf_size.map(|_| DEFAULT_ORDER)),
        request.precision,
    );
    Ok(match (eps, request.order, request.leaf_size) {
        (None, Some(_), Some(_)) | (None, None, _) => DistPlan {
            order: request.order.unwrap_or(DEFAULT_ORDER),
            leaf_size: request.leaf_size.unwrap_or(DEFAULT_LEAF_SIZE),
            scheme: match request.scheme {
                SchemeChoice::Auto if SchemeChoice::auto_is_fft(kernel) => "fft",
                SchemeChoice::Auto => "svd",
                s => s.name(),
            },
            svd_tolerance: None,
            choice: None,
            tolerance: None,
        },
        (eps, order, _) => {
            let choice = choose_parameters(
                comm,
                points,
                kernel,
                eps,
                order,
                request.precision,
                request.mode,
                request.scheme.shape(),
                cached,
            )?;
            DistPlan {
                order: choice.order,
                leaf_size: choice.leaf_size,
                scheme: SchemeChoice::of_shape(choice.shape).name(),
                svd_tolerance: Some(choice.svd_tolerance),
                choice: Some(choice),
                tolerance: eps,
            }
        }
    })
}

/// A [`DistributedFmm`] with its float type, kernel and scheme erased.
trait Engine<C> {
    fn evaluate(
        &self,
        comm: &C,
        tree: &DistributedTree,
        densities: &[f64],
    ) -> Result<(Vec<f64>, EvalStats), DistError>;
    #[allow(clippy::too_many_arguments)]
    fn sampled_errors(
        &self,
        comm: &C,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[f64],
        densities: &[f64],
        targets: &[f64],
        values: &[f64],
        samples: usize,
    ) -> [f64; 2];
    /// The same kernel, float type and scheme for another plan.
    fn with_plan(
        &self,
        comm: &C,
        tree: &DistributedTree,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError>;
    fn setup_stats(&self) -> &SetupStats;
    fn cache_summary(&self) -> Option<String>;
    fn values_per_source(&self) -> usize;
    fn values_per_target(&self) -> usize;
}

/// The configuration of a scheme for an SVD tolerance (`None`: the
/// scheme's default; only the SVD scheme has one).
trait SchemeConfig<T: Real>: M2lScheme<T> {
    fn config(svd_tolerance: Option<f64>) -> Self::Config;
}

impl<T: Real> SchemeConfig<T> for SvdM2l<T> {
    fn config(svd_tolerance: Option<f64>) -> SvdConfig {
        SvdConfig {
            rank: None,
            tolerance: svd_tolerance.unwrap_or(0.0),
        }
    }
}

impl<T: Real> SchemeConfig<T> for DenseM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

impl<T: Real> SchemeConfig<T> for FftM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

/// The engine for the plan's float type and scheme.
fn engine_for<C: Communicator + 'static, K: Kernel>(
    comm: &C,
    tree: &DistributedTree,
    kernel: K,
    plan: &DistPlan,
    request: &DistRequest,
    cache: &CacheLocation,
) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
    fn make<C: Communicator + 'static, T: Real, K: Kernel, S: SchemeConfig<T> + 'static>(
        comm: &C,
        tree: &DistributedTree,
        kernel: K,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
        let options = DistFmmOptions {
            sources: request.sources,
            cache_dir: cache.dir().map(std::path::PathBuf::from),
            cache_size_limit: cache.size_limit(),
            ..DistFmmOptions::new(plan.order, request.mode)
        };
        let config = S::config(plan.svd_tolerance);
        let fmm = DistributedFmm::<T, K, S>::build(comm, tree, kernel, &config, &options)?;
        Ok(Box::new(fmm))
    }
    match (request.precision, plan.scheme) {
        (Precision::F64, "svd") => {
            make::<C, f64, K, SvdM2l<f64>>(comm, tree, kernel, plan, request, cache)
        }
        (Precision::F64, "dense") => {
            make::<C, f64, K, DenseM2l<f64>>(comm, tree, kernel, plan, request, cache)
        }
        (Precision::F64, _) => {
            make::<C, f64, K, FftM2l<f64>>(comm, tree, kernel, plan, request, cache)
        }
        (_, "svd") => make::<C, f32, K, SvdM2l<f32>>(comm, tree, kernel, plan, request, cache),
        (_, "dense") => make::<C, f32, K, DenseM2l<f32>>(comm, tree, kernel, plan, request, cache),
        (_, _) => make::<C, f32, K, FftM2l<f32>>(comm, tree, kernel, plan, request, cache),
    }
}

impl<C, T, K, S> Engine<C> for DistributedFmm<T, K, S>
where
    C: Communicator + 'static,
    T: Real,
    K: Kernel,
    S: SchemeConfig<T> + 'static,
{
    fn evaluate(
        &self,
        comm: &C,
        tree: &DistributedTree,
        densities: &[f64],
    ) -> Result<(Vec<f64>, EvalStats), DistError> {
        let q: Vec<T> = densities.iter().map(|&x| T::from_f64(x)).collect();
        let (values, stats) = DistributedFmm::evaluate(self, comm, &q)?;
        // Finite inputs can still overflow (densities near the float
        // type's largest value): an error on every rank, naming the first
        // bad value in the global input order.
        finite_output(comm, tree, &values, self.values_per_target(), &q)?;
        Ok((values.iter().map(|v| v.to_f64()).collect(), stats))
    }

    fn sampled_errors(
        &self,
        comm: &C,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[f64],
        densities: &[f64],
        targets: &[f64],
        values: &[f64],
        samples: usize,
    ) -> [f64; 2] {
        sampled_errors_at(
            comm,
            self.local().kernel(),
            kind,
            mode,
            sources,
            densities,
            targets,
            values,
            samples,
        )
    }

    fn with_plan(
        &self,
        comm: &C,
        tree: &DistributedTree,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
        engine_for(
            comm,
            tree,
            self.local().kernel().clone(),
            plan,
            request,
            cache,
        )
    }

    fn setup_stats(&self) -> &SetupStats {
        DistributedFmm::setup_stats(self)
    }

    fn cache_summary(&self) -> Option<String> {
        CacheStatus::summary(
            self.local().operators().cache_status(),
            &self.local().m2l_scheme().cache_status(),
        )
    }

    fn values_per_source(&self) -> usize {
        DistributedFmm::values_per_source(self)
    }

    fn values_per_target(&self) -> usize {
        DistributedFmm::values_per_target(self)
    }
}

/// [`ferrofmm_fmm::check_finite_output`] on this rank's values (the
/// target index made global: input rows before this rank added; the
/// largest density over all ranks), agreed by every rank (a collective).
fn finite_output<C: Communicator, T: Real>(
    comm: &C,
    tree: &DistributedTree,
    values: &[T],
    per_target: usize,
    densities: &[T],
) -> Result<(), DistError> {
    let local_max = densities
        .iter()
        .map(|q| q.to_f64().abs())
        .fold(0.0, f64::max);
    let mut largest = 0.0f64;
    comm.all_reduce_into(&local_max, &mut largest, SystemOperation::max());
    let me = comm.rank() as usize;
    let first: u64 = target_counts(tree)[..me].iter().sum();
    let local = ferrofmm_fmm::check_finite_output(values, per_target, densities).map_err(|e| {
        match e {
            FmmError::NonFiniteResult {
                target,
                component,
                value,
                precision,
                ..
            } => FmmError::NonFiniteResult {
                target: target + first as usize,
                component,
                value,
                largest_density: largest,
                precision,
            },
            other => other,
        }
        .to_string()
    });
    agree_message(comm, local)
}

/// The number of targets every rank passed (rank order): its separate
/// targets, or its points.
fn target_counts(tree: &DistributedTree) -> &[u64] {
    tree.targets
        .as_ref()
        .map_or(&tree.input_counts, |t| &t.input_counts)
}
