//! [`TreeFmm`]: the single-machine passes over a tree the caller supplies,
//! one pass at a time.
//!
//! [`crate::Fmm`] builds its own tree and runs every pass in one call.
//! A distributed driver (the `ferrofmm-mpi` crate) holds on each process a
//! *piece* of the global tree (its own boxes, the coarse tree above them and
//! the ghost boxes its lists reference: a locally essential tree), with
//! lists of its own choosing, and must communicate between the passes. It
//! runs the same passes and operators through this type:
//!
//! 1. [`TreeFmm::upward`]: P2M at every leaf holding sources,
//!    `u_B = UC2E_l (K(y_check_B, x) q)`, then M2M bottom up,
//!    `u_P += M2M_{l, octant} u_C`;
//! 2. the caller may overwrite or add to multipoles (ghost boxes, partial
//!    sums of shared boxes);
//! 3. [`TreeFmm::downward`]: level by level, the downward check potentials
//!    `c_B = sum_{A in V(B)} K(y_check_B, x_equiv_A) u_A + sum_{A in X(B)}
//!    K(y_check_B, x_A) q_A`, handed to a callback (which may combine them
//!    with other processes'), then `d_B = DC2E_l c_B + L2L_{l, octant}
//!    d_parent`;
//! 4. [`TreeFmm::leaf_passes`]: L2P, M2P over W lists and P2P over U lists
//!    at every leaf holding targets.
//!
//! Every pass is linear in the charges, the multipoles and the check
//! potentials, which is what lets a distributed driver sum partial results.
//! No code is duplicated: [`crate::Fmm::evaluate`] runs the same functions.

use std::ops::Range;
use std::time::Instant;

use ferrofmm_field::{M2lScheme, M2lUsage, OperatorParams, Operators};
use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use ferrofmm_tree::Octree;

use crate::FmmError;
use crate::part::TreePart;
use crate::passes::{self, Ctx};
use crate::precompute::{OperatorNeeds, operators_for};
use crate::progress::Work;
use crate::timings::{EvalTimings, SetupTimings};
use crate::validate::{check_domain_width, check_order, check_tree_points};

/// A tree and its points for [`TreeFmm::new`].
pub struct LocalTree<'a> {
    /// The tree: keys, point ranges and the lists the passes follow (for
    /// instance from [`Octree::from_parts`]).
    pub tree: Octree,
    /// Source coordinates, absolute, interleaved, in the order of the
    /// tree's source ranges.
    pub sources: &'a [f64],
    /// Target coordinates in the order of the target ranges (`None`: the
    /// sources).
    pub targets: Option<&'a [f64]>,
    /// Levels the operators cover, `0..=depth` (at least the tree's depth;
    /// the global tree's depth for a piece of it).
    pub depth: u32,
    /// The transfer vectors to precompute M2L operators for (for a piece of
    /// a tree: the union over all pieces, so that every process gets the
    /// operators of the whole tree; see [`crate::m2l_usage`]).
    pub usage: &'a M2lUsage,
}

/// The FMM passes over a caller's tree, one at a time: [`TreeFmm::upward`]
/// (P2M, M2M), then whatever the caller does to the multipoles (a
/// distributed driver fills in ghost boxes and sums shared ones),
/// [`TreeFmm::downward`] (M2L, P2L, L2L, with a callback on each level's
/// check potentials) and [`TreeFmm::leaf_passes`] (L2P, M2P, P2P). Every
/// pass is linear in the charges, multipoles and check potentials, so
/// partial results of several processes add up. The same functions run
/// [`crate::Fmm::evaluate`].
pub struct TreeFmm<T: Real, K: Kernel, S: M2lScheme<T>> {
    kernel: K,
    mode: EvalMode,
    kind: SourceKind,
    unit_surface: Vec<f64>,
    part: TreePart<T, S>,
    setup: SetupTimings,
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> TreeFmm<T, K, S> {
    /// Precomputes the operators (order and surfaces from `params`, the M2L
    /// scheme from `config`) for `local` and stores its points relative to
    /// the domain's coordinate origin, as [`crate::Fmm`] does.
    ///
    /// # Errors
    /// An order outside `MIN_ORDER..=MAX_ORDER`, a point count that does
    /// not match the tree's ranges, a domain the
    /// float type cannot resolve at this depth, ill-conditioned operators,
    /// or a precomputation that does not fit in memory (as
    /// [`crate::FmmBuilder`]).
    pub fn new(
        kernel: K,
        mode: EvalMode,
        params: &OperatorParams,
        config: &S::Config,
        local: LocalTree<'_>,
    ) -> Result<Self, FmmError> {
        let t0 = Instant::now();
        check_order(params.order)?;
        let tree = local.tree;
        let depth = local.depth.max(tree.depth());
        let targets_len = local.targets.map_or(local.sources.len(), <[f64]>::len);
        check_tree_points(&tree, local.sources.len(), targets_len)?;
        let width = tree.domain().width;
        check_domain_width(width, T::PRECISION, depth)?;
        let mut setup = SetupTimings::default();
        let (operators, m2l) = operators_for::<T, K, S>(
            &kernel,
            params,
            config,
            width,
            depth,
            // Pieces of a distributed tree: the coarse levels serve the
            // coarse tree's passes, so every level gets its operators.
            0,
            local.usage,
            &mut setup,
        )?;
        let t = Instant::now();
        let part = TreePart::assemble(
            tree,
            (operators, m2l),
            local.sources,
            local.targets,
            false,
            (true, true),
            OperatorNeeds {
                usage: local.usage.clone(),
                first_level: 0,
            },
        )?;
        let unit_surface = ferrofmm_field::surface_points::<f64>(params.order, [0.0; 3], 1.0, 1.0);
        setup.layout = t.elapsed();
        setup.total = t0.elapsed();
        Ok(TreeFmm {
            kernel,
            mode,
            kind: SourceKind::Charge,
            unit_surface,
            part,
            setup,
        })
    }

    fn ctx(&self) -> Ctx<'_, K> {
        Ctx {
            kernel: &self.kernel,
            mode: self.mode,
            kind: self.kind,
            unit_surface: &self.unit_surface,
        }
    }

    /// The same passes for sources of `kind` (charges, the default;
    /// dipoles; or both): the charge vectors the passes take then hold
    /// [`Kernel::values_per_source`] values per source, interleaved
    /// (`c` per charge, `3 c` per dipole for a kernel with `c`
    /// components). The operators do not depend on it.
    #[must_use]
    pub fn with_source_kind(mut self, kind: SourceKind) -> Self {
        self.kind = kind;
        self
    }

    /// What each source carries.
    pub fn source_kind(&self) -> SourceKind {
        self.kind
    }

    /// Restricts the box-by-box work to the boxes marked `true` (one flag
    /// per box of the tree, in box order; the parent of a marked box should
    /// be marked too): P2M, UC2E and M2M skip the other boxes, so their
    /// multipoles stay zero until the caller fills them in, and DC2E and
    /// L2L skip them, so their locals stay zero. M2L and P2L still
    /// compute every box's check potential, which the caller may send
    /// elsewhere. A distributed driver marks its own boxes and the shared
    /// ancestors above them: ghost boxes get their multipoles from their
    /// owners and need no locals, and shared boxes away from its range
    /// need neither (without it, every process would compute the locals of
    /// every shared box). `Fmm` marks nothing and runs every box.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when `active` has not one flag per
    /// box.
    pub fn with_active_boxes(mut self, active: Vec<bool>) -> Result<Self, FmmError> {
        self.check("active", active.len(), self.tree().n_boxes())?;
        self.part.active = Some(active);
        Ok(self)
    }

    /// The tree.
    pub fn tree(&self) -> &Octree {
        &self.part.tree
    }

    /// Values per box expansion, `n = c (6 (p - 1)^2 + 2)` for a kernel
    /// with `c` [components](Kernel::components) (one per equivalent point
    /// for scalar kernels): box `b`'s multipole and local are entries
    /// `n b .. n (b + 1)` of the vectors the passes return.
    pub fn n_surface(&self) -> usize {
        self.part.operators.n_surface()
    }

    /// What is evaluated.
    pub fn mode(&self) -> EvalMode {
        self.mode
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The M2L scheme.
    pub fn m2l_scheme(&self) -> &S {
        &self.part.m2l
    }

    /// The per-box translation operators (and their
    /// [`cache_status`](Operators::cache_status)).
    pub fn operators(&self) -> &Operators<T> {
        &self.part.operators
    }

    /// Time spent precomputing operators and laying out the points.
    pub fn setup_timings(&self) -> &SetupTimings {
        &self.setup
    }

    fn check(&self, what: &'static str, len: usize, expected: usize) -> Result<(), FmmError> {
        if len == expected {
            Ok(())
        } else {
            Err(FmmError::InvalidParameter(format!(
                "TreeFmm: {what} has length {len}, expected {expected}"
            )))
        }
    }

    fn check_charges(&self, charges: &[T]) -> Result<(), FmmError> {
        let expected = self.kernel.values_per_source(self.kind) * self.part.sources.len() / 3;
        if charges.len() != expected {
            return Err(FmmError::ChargeCount {
                expected,
                got: charges.len(),
            });
        }
        Ok(())
    }

    /// P2M and M2M: the multipole (upward equivalent density) of every box,
    /// `n` values per box in box order, from the densities of the sources
    /// in the order of the tree's source ranges
    /// ([`Kernel::values_per_source`] each for the [source
    /// kind](TreeFmm::with_source_kind): one charge per source for a scalar
    /// kernel).
    ///
    /// # Errors
    /// [`FmmError::ChargeCount`] for a charge vector of the wrong length.
    pub fn upward(&self, charges: &[T], timings: &mut EvalTimings) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges)?;
        Ok(passes::upward(
            &self.ctx(),
            &self.part,
            charges,
            timings,
            &Work::none(),
        ))
    }

    /// M2L, P2L and L2L, top down: the local (downward equivalent density)
    /// of every box. After the check potentials of level `l` (boxes
    /// `range`, `n` values each, in `checks`) are summed and before they
    /// become locals, `on_checks(l, range, checks)` may change them (a
    /// distributed driver adds other processes' contributions there).
    /// Level 0 (the root) is never passed: its local is zero.
    ///
    /// # Errors
    /// Charges or multipoles of the wrong length.
    pub fn downward(
        &self,
        charges: &[T],
        multipoles: &[T],
        timings: &mut EvalTimings,
        on_checks: impl FnMut(u32, Range<usize>, &mut [T]),
    ) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges)?;
        let len = self.n_surface() * self.tree().n_boxes();
        self.check("multipoles", multipoles.len(), len)?;
        let mut locals = vec![T::ZERO; len];
        passes::downward(
            &self.ctx(),
            &self.part,
            charges,
            multipoles,
            None,
            &mut locals,
            timings,
            &Work::none(),
            on_checks,
        );
        Ok(locals)
    }

    /// L2P, M2P and P2P at every leaf holding targets: the values at the
    /// targets (in the order of the target ranges),
    /// [`EvalMode::values_per_target`] values each.
    ///
    /// # Errors
    /// Charges, multipoles or locals of the wrong length.
    pub fn leaf_passes(
        &self,
        charges: &[T],
        multipoles: &[T],
        locals: &[T],
        timings: &mut EvalTimings,
    ) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges)?;
        let len = self.n_surface() * self.tree().n_boxes();
        self.check("multipoles", multipoles.len(), len)?;
        self.check("locals", locals.len(), len)?;
        let n_targets = self.part.target_points().len() / 3;
        let mut values = vec![T::ZERO; self.kernel.values_per_target(self.mode) * n_targets];
        passes::leaf_passes(
            &self.ctx(),
            &self.part,
            charges,
            multipoles,
            locals,
            &mut values,
            timings,
            &Work::none(),
        );
        Ok(values)
    }
}
