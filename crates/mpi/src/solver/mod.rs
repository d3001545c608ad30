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
//!    ([`choose_parameters`](crate::choose_parameters)); an order alone gets its leaf size and scheme
//!    from the same cost model. This is the single-machine rule
//!    ([`ferrofmm_fmm::effective_tolerance`]).
//! 2. **Build**: the distributed tree ([`DistributedTree::build`]) and the
//!    distributed FMM ([`DistributedFmm::build`](crate::DistributedFmm::build)) for the kernel, float
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

use ferrofmm_field::{CacheLocation, CacheSetting};
use ferrofmm_fmm::SchemeChoice;
use ferrofmm_fmm::verify::MAX_VERIFY_RETRIES;
use ferrofmm_kernels::{EvalMode, KernelChoice, Precision, SourceKind};
use mpi::traits::*;

use crate::error::agree_message;
use crate::{DistChoice, DistError, DistributedTree, EvalStats, SetupStats};

mod build;
mod engine;

use build::{Build, Supports};
use engine::Engine;

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
    /// [`Kernel::values_per_target`](ferrofmm_kernels::Kernel::values_per_target) values per input point of this rank,
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
            self.raise_order(comm)?;
        }
    }

    /// Rebuilds the FMM one order up, as a missed verification does: the
    /// tree stays, the operators are rebuilt (the SVD tolerance then the
    /// order's default). For a caller that checks more than this solver
    /// sees (the Stokes layers combine two solvers' values). A collective.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: an FMM setup error (the
    /// order beyond [`ferrofmm_field::MAX_ORDER`], operators that do not
    /// fit).
    pub fn raise_order(&mut self, comm: &C) -> Result<(), DistError> {
        self.plan.order += 1;
        self.plan.svd_tolerance = None;
        self.engine =
            self.engine
                .with_plan(comm, &self.tree, &self.plan, &self.request, &self.cache)?;
        Ok(())
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

    /// Density values per point ([`Kernel::values_per_source`](ferrofmm_kernels::Kernel::values_per_source)).
    pub fn values_per_source(&self) -> usize {
        self.engine.values_per_source()
    }

    /// Result values per point ([`Kernel::values_per_target`](ferrofmm_kernels::Kernel::values_per_target)).
    pub fn values_per_target(&self) -> usize {
        self.engine.values_per_target()
    }
}

/// The number of targets every rank passed (rank order): its separate
/// targets, or its points.
fn target_counts(tree: &DistributedTree) -> &[u64] {
    tree.targets
        .as_ref()
        .map_or(&tree.input_counts, |t| &t.input_counts)
}
