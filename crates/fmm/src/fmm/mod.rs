//! [`Fmm`]: a built problem (tree + operators) that evaluates any number of
//! charge vectors.

use std::sync::Arc;

use ferrofmm_field::{M2lScheme, OperatorParams, Operators};
use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use ferrofmm_tree::Octree;

use crate::memory::MemoryReport;
use crate::part::{Part, TreePart};
use crate::passes;
use crate::periodic::FarImages;
use crate::progress::ProgressFn;
use crate::timings::SetupTimings;
use crate::tuning::{ChosenParameters, ErrorModel};
use crate::verify::Verification;

mod build;
mod evaluate;
mod summary;

pub use summary::FmmSummary;

/// How a scheme follows parameters chosen for a tolerance (the SVD
/// tolerance of [`crate::FmmBuilder::build_svd`]), also when verification
/// raises the order; schemes given to [`crate::FmmBuilder::build_with`]
/// keep their configuration (`None`).
pub(crate) struct ChosenScheme<C, S> {
    /// The configuration for the chosen parameters.
    pub(crate) config: fn(&ChosenParameters) -> C,
    /// The rank the built scheme reports (for [`ChosenParameters::svd_rank`]).
    pub(crate) rank: fn(&S) -> usize,
}

/// [`ChosenScheme`] when there is one.
pub(crate) type ConfigFromChosen<C, S> = Option<ChosenScheme<C, S>>;

/// A kernel-independent FMM, built once for fixed sources, targets, kernel
/// and parameters, then evaluated for as many charge vectors as needed.
///
/// `T` is the float type (`f32` or `f64`), `K` the kernel and `S` the M2L
/// translation scheme. `Fmm` is `Sync`: [`Fmm::evaluate`] takes `&self`
/// and may be called from several threads at once.
pub struct Fmm<T: Real, K: Kernel, S: M2lScheme<T>> {
    pub(crate) kernel: K,
    pub(crate) mode: EvalMode,
    /// What each source carries (densities per source).
    pub(crate) source_kind: SourceKind,
    /// The far-separated clusters of the problem ([`crate::part`]); part 0
    /// is the largest and always has a tree. One part for most inputs.
    pub(crate) parts: Vec<Part<T, S>>,
    /// Whether targets were given apart from the sources.
    pub(crate) separate_targets: bool,
    /// Unit-cube surface grid (centre 0, half-width 1, radius 1), interleaved, f64.
    pub(crate) unit_surface: Vec<f64>,
    pub(crate) n_sources: usize,
    pub(crate) n_targets: usize,
    pub(crate) order: usize,
    pub(crate) leaf_size: usize,
    pub(crate) setup: SetupTimings,
    /// Parameters chosen for a tolerance (`None`: given by the caller).
    pub(crate) chosen: Option<ChosenParameters>,
    /// Operator parameters as built (the order among them).
    pub(crate) params: OperatorParams,
    /// The M2L configuration as built.
    pub(crate) config: S::Config,
    /// How to remake it for new chosen parameters (see [`ConfigFromChosen`]).
    pub(crate) config_from_chosen: ConfigFromChosen<S::Config, S>,
    /// Whether [`Fmm::evaluate_verified`] checks a tolerance.
    pub(crate) verify: bool,
    /// The error model the parameters were chosen with (`None`: given by
    /// the caller); the verification raises the order with it.
    pub(crate) error_model: Option<ErrorModel>,
    /// The last verification (see [`Fmm::evaluate_verified`]).
    pub(crate) verification: Option<Verification>,
    /// The far images of a periodic cell ([`crate::periodic`]); `None` in
    /// free space.
    pub(crate) periodic: Option<FarImages>,
    /// Told the progress of each evaluation ([`Fmm::set_progress`]).
    pub(crate) progress: Option<Arc<ProgressFn>>,
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    /// Values in one box's expansion: one per surface point and kernel
    /// [component](Kernel::components).
    pub(crate) fn expansion_len(&self) -> usize {
        self.kernel.components() * (self.unit_surface.len() / 3)
    }

    /// What the passes read besides a tree part.
    pub(crate) fn ctx(&self) -> passes::Ctx<'_, K> {
        passes::Ctx {
            kernel: &self.kernel,
            mode: self.mode,
            kind: self.source_kind,
            unit_surface: &self.unit_surface,
        }
    }

    /// The largest cluster's tree part (part 0 always has a tree).
    pub(crate) fn main(&self) -> &TreePart<T, S> {
        self.parts[0]
            .tree_part()
            .expect("the largest cluster has a tree")
    }

    /// The octree (plain data: keys, ranges, lists) of the largest
    /// cluster: the whole problem unless it has far-separated clusters
    /// (see [`Fmm::n_clusters`]).
    pub fn tree(&self) -> &Octree {
        &self.main().tree
    }

    /// Number of far-separated clusters the problem was split into: 1 for
    /// most inputs; more when a group of points lies at least 256 times
    /// its own width (and the rest's) away. Each cluster with more than
    /// `leaf_size` points has a tree of its own; the clusters interact
    /// through their roots' expansions.
    pub fn n_clusters(&self) -> usize {
        self.parts.len()
    }

    /// The check-to-equivalent and parent/child operators (their
    /// [`Operators::diagnostics`] and [`Operators::cache_status`]) of the
    /// largest cluster's tree.
    pub fn operators(&self) -> &Operators<T> {
        &self.main().operators
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The M2L scheme (of the largest cluster's tree).
    pub fn m2l_scheme(&self) -> &S {
        &self.main().m2l
    }

    /// What is evaluated.
    pub fn mode(&self) -> EvalMode {
        self.mode
    }

    /// What each source carries (see [`FmmBuilder::source_kind`](crate::FmmBuilder::source_kind)).
    pub fn source_kind(&self) -> SourceKind {
        self.source_kind
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.n_sources
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.n_targets
    }

    /// Expansion order.
    pub fn order(&self) -> usize {
        self.order
    }

    /// The parameters chosen for [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) (with the built
    /// SVD rank when built by [`FmmBuilder::build_svd`](crate::FmmBuilder::build_svd)); `None` when the
    /// caller gave them.
    pub fn chosen_parameters(&self) -> Option<&ChosenParameters> {
        self.chosen.as_ref()
    }

    /// Leaf size the tree was built with.
    pub fn leaf_size(&self) -> usize {
        self.leaf_size
    }

    /// An accounting of the big buffers, in bytes: what is held between
    /// evaluations and what one evaluation allocates. Every per-box buffer
    /// is sized by the boxes that exist (boxes holding points), never by
    /// `8^depth`.
    pub fn memory(&self) -> MemoryReport {
        MemoryReport::of(self)
    }

    /// Total of [`Fmm::memory`]: bytes held plus bytes one evaluation allocates.
    pub fn memory_bytes(&self) -> usize {
        self.memory().total
    }

    /// Time spent building.
    pub fn setup_timings(&self) -> &SetupTimings {
        &self.setup
    }
}
