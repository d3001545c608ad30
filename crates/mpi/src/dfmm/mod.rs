//! The distributed FMM: the single-machine passes of `ferrofmm-fmm`
//! ([`TreeFmm`]) run on each rank's locally essential tree, with the
//! communication between them.
//!
//! # One evaluation
//!
//! With `n` equivalent points per box and every pass linear in its inputs:
//!
//! 1. **Charges to owners** (`dfmm/route.rs`): each rank's charges, given in its
//!    input order, go to the ranks that hold the points (skipped by
//!    [`DistributedFmm::evaluate_sorted`]). With separate targets
//!    ([`DistributedTree::build_with_targets`]) the charges are those of
//!    the rank's input sources: the tree was built on the union of sources
//!    and targets (a box exists when it holds either, and is split while
//!    `max(#sources, #targets) > leaf_size`), each rank's range holds
//!    both kinds, and the lists are pruned as on one machine (entries
//!    holding sources, in rows of boxes holding targets), so the ghosts
//!    below are boxes with sources and only sources' charges travel.
//! 2. **Upward** (P2M, M2M) on the rank's tree with the ghost points'
//!    charges set to zero: the multipoles of the rank's own boxes are
//!    complete (all their points are here); those of the coarse boxes (which
//!    straddle cuts) are this rank's share.
//! 3. **Ghost exchange** (`dfmm/ghost_plan.rs`): each rank sends the multipoles
//!    of the boxes that others' V and W lists reference and the charges of
//!    the leaves that others' U and X lists reference, point to point, only
//!    to the ranks that asked when the FMM was built.
//! 4. **Coarse multipoles** (`dfmm/coarse_plan.rs`, `dfmm/sparse_sum.rs`):
//!    `u_C = sum_r u_C^(r)` because M2M is linear. The shares (`n` values
//!    a box) go from the ranks whose ranges meet `C` (its owners, a
//!    contiguous run of ranks) to its root, its first owner, which adds them
//!    and sends the sum only to the ranks whose local tree reads it (`C` in
//!    the V or W row of one of their boxes, or in the coarse-to-coarse part
//!    of a coarse box they are the root of). Point to point, planned at
//!    build: a rank moves the few coarse boxes above and near its range,
//!    not the whole coarse tree (which has up to `R - 1` boxes a level).
//! 5. **Downward** (M2L, P2L, L2L), level by level: a coarse box's check
//!    potential `c_C` is summed from V- and X-list entries of all ranks, so
//!    each rank adds the part from its own boxes (and `C`'s root the
//!    coarse-to-coarse part); the ranks with a nonzero part send it to the
//!    root, which sends the sum to `C`'s other owners, the ranks where `C`
//!    is active, before `d_C = DC2E c_C + L2L d_parent` (each rank computes
//!    it for the coarse boxes above its own boxes only; see
//!    docs/distributed.md for why not gathered on one rank). The rank's own
//!    boxes then get their locals from whole parents. Where a sum has no
//!    share (no V or X entry anywhere) or no rank reads it, nothing is sent.
//! 6. **Leaf passes** (L2P, M2P, P2P) at the rank's leaves, for its
//!    targets: `phi(y) = sum_{x in U(B)} K(y, x) q_x + sum_{A in W(B)}
//!    K(y, x_equiv_A) u_A + K(y, x_equiv_B) d_B` for a target `y` of leaf
//!    `B` (its points, or its own targets with separate targets).
//! 7. **Values back** to the ranks that gave the targets, in their order:
//!    the points' values, or with separate targets those of each rank's
//!    input targets (a second routing, built from the targets' ids).
//!
//! The tree, the ghost points, the plans and the operators are made once
//! ([`DistributedFmm::build`]); each evaluation only moves multipoles,
//! charges and check potentials (the ghost exchange and the coarse sums
//! point to point, with the partners planned at build). The result equals the single-machine
//! [`ferrofmm_fmm::Fmm`] on the same tree (built with the same domain,
//! which keeps it one tree: the distributed FMM does not split
//! far-separated clusters into separate trees) up to rounding.

mod coarse_plan;
mod ghost_plan;
mod local_tree;
mod memory;
mod route;
mod sparse_sum;
mod stats;

use std::path::PathBuf;
use std::time::Instant;

use ferrofmm_field::{M2lScheme, M2lUsage, N_TRANSFER_VECTORS, OperatorParams};
use ferrofmm_fmm::{EvalTimings, LocalTree, TreeFmm, m2l_usage};
use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::DistributedTree;
use crate::error::{DistError, InputProblem, agree, agree_message};
use coarse_plan::CoarsePlan;
use ghost_plan::GhostPlan;
use local_tree::Kind;
pub use memory::check_rank_memory;
use route::Route;
pub use stats::{EVAL_PHASES, EvalStats, SetupStats};

/// Parameters of a distributed FMM (the same on every rank).
#[derive(Clone, Debug)]
pub struct DistFmmOptions {
    /// Expansion order `p`.
    pub order: usize,
    /// Potentials, or potentials and gradients (or Hessians).
    pub mode: EvalMode,
    /// What each source carries: charges, dipoles or both
    /// ([`Kernel::values_per_source`] values per point in the charge
    /// vectors).
    pub sources: SourceKind,
    /// Directory of the on-disk operator cache (`None`: no cache). With a
    /// cache, rank 0 builds (or loads) the operators first and the other
    /// ranks load what it wrote: one precomputation instead of `R`
    /// competing for the cores of a node. A directory local to each node
    /// works too (one rank per node then computes). The command
    /// `ferrofmm-mpi` passes the default folder
    /// ([`CacheSetting::resolve`](ferrofmm_field::CacheSetting::resolve)).
    pub cache_dir: Option<PathBuf>,
    /// Most bytes of cache files kept in `cache_dir` (least recently used
    /// deleted first; `None`: no cap).
    pub cache_size_limit: Option<u64>,
}

impl DistFmmOptions {
    /// Order `order`, charges, `mode`, no cache.
    pub fn new(order: usize, mode: EvalMode) -> Self {
        DistFmmOptions {
            order,
            mode,
            sources: SourceKind::Charge,
            cache_dir: None,
            cache_size_limit: None,
        }
    }
}

/// One rank's part of a distributed FMM, built once for fixed points and
/// evaluated for any number of charge vectors (see the [module docs](self)).
pub struct DistributedFmm<T: Real, K: Kernel, S: M2lScheme<T>> {
    fmm: TreeFmm<T, K, S>,
    plan: GhostPlan,
    coarse_plan: CoarsePlan,
    route: Route,
    /// The routing of the values when the targets are not the points
    /// (`None`: `route`).
    target_route: Option<Route>,
    /// Merged source position of each of this rank's points (tree order).
    own_pos: Vec<usize>,
    /// Merged source position of each ghost point.
    ghost_pos: Vec<usize>,
    /// Indices of the coarse boxes in the local tree, in key order (the
    /// same sequence on every rank).
    coarse: Vec<usize>,
    n_owned: usize,
    /// This rank's targets in the tree (its points, without separate
    /// targets).
    n_targets: usize,
    /// Values per point in the charge vectors (`c` per charge, `3 c` per
    /// dipole for a kernel with `c` components).
    nq: usize,
    setup: SetupStats,
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> DistributedFmm<T, K, S> {
    /// Builds the FMM on a distributed tree (a collective): the ghost
    /// points and exchange plans, the routing of charges and values, this
    /// rank's locally essential tree, and the operators of the global tree
    /// (every rank precomputes the same ones: the same domain, depth and
    /// transfer vectors, agreed by two `all_reduce`s).
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: options that differ between
    /// ranks, or an FMM setup error on any rank (order out of range,
    /// ill-conditioned operators, not enough memory).
    pub fn build<C: Communicator>(
        comm: &C,
        dtree: &DistributedTree,
        kernel: K,
        config: &S::Config,
        options: &DistFmmOptions,
    ) -> Result<Self, DistError> {
        let me = comm.rank() as usize;
        let mut setup = SetupStats::default();
        let nq = kernel.values_per_source(options.sources);
        let mine = [
            options.order as u64,
            kernel.values_per_target(options.mode) as u64,
            nq as u64,
            kernel.components() as u64,
        ];
        let mut all = vec![0u64; mine.len() * comm.size() as usize];
        comm.all_gather_into(&mine[..], &mut all[..]);
        let mismatch = all.chunks_exact(mine.len()).position(|o| o != mine);
        agree(
            comm,
            mismatch.map_or(Ok(()), |_| Err(InputProblem::MismatchedOptions)),
        )?;

        let t = Instant::now();
        let kinds = local_tree::kinds(dtree);
        let plan = GhostPlan::make(comm, dtree, &kinds);
        let route = Route::make(comm, &dtree.points.ids, &dtree.input_counts);
        let target_route = dtree
            .targets
            .as_ref()
            .map(|t| Route::make(comm, &t.points.ids, &t.input_counts));
        let targets = dtree.targets.as_ref().map_or(&dtree.points, |t| &t.points);
        let plan = agree_message(comm, plan)?;
        setup.bytes_sent = plan.setup_bytes
            + route.setup_bytes
            + target_route.as_ref().map_or(0, |r| r.setup_bytes);
        setup.ghost_points = plan.n_points();
        (setup.send_partners, setup.recv_partners) = plan.partners();
        setup.seconds[0] = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let lists = local_tree::rows(dtree, &kinds, me);
        let own_codes = &dtree.points.codes;
        let (codes, own_pos, ghost_pos) = local_tree::merge(own_codes, &plan.codes);
        // This rank's FMM (its points and ghost points as sources, its
        // targets) refused on every rank, before it is allocated, when
        // some rank's is predicted not to fit.
        check_rank_memory::<C, T>(
            comm,
            &ferrofmm_fmm::RunSize {
                n_sources: codes.len(),
                n_targets: Some(targets.len()),
                values_per_source: nq,
                values_per_target: kernel.values_per_target(options.mode),
                n_vectors: 1,
            },
            "the distributed FMM",
        )?;
        let tree = local_tree::octree(dtree, lists, &codes, &targets.codes);
        let tree = agree_message(comm, tree)?;
        let mut sources = vec![0.0; 3 * codes.len()];
        for (k, &p) in own_pos.iter().enumerate() {
            sources[3 * p..3 * p + 3].copy_from_slice(&dtree.points.coords[3 * k..3 * k + 3]);
        }
        for (g, &p) in ghost_pos.iter().enumerate() {
            sources[3 * p..3 * p + 3].copy_from_slice(&plan.coords[3 * g..3 * g + 3]);
        }
        let coarse: Vec<usize> = (0..kinds.len())
            .filter(|&b| kinds[b] == Kind::Coarse)
            .collect();
        setup.boxes = tree.n_boxes();
        setup.seconds[1] = t.elapsed().as_secs_f64();

        // The global tree's depth and M2L usage: every rank builds the
        // operators of the whole tree.
        let t = Instant::now();
        let (depth, usage) = global_usage(comm, &tree);
        let mut params = OperatorParams::new(options.order);
        params.cache_dir.clone_from(&options.cache_dir);
        params.cache_size_limit = options.cache_size_limit;
        let local = LocalTree {
            tree,
            sources: &sources,
            targets: Some(&targets.coords),
            depth,
            usage: &usage,
        };
        let make = || {
            TreeFmm::new(kernel, options.mode, &params, config, local)
                .map(|f| f.with_source_kind(options.sources))
        };
        let fmm = if options.cache_dir.is_some() && comm.size() > 1 {
            // Rank 0 fills the cache; the others then read it.
            if me == 0 {
                let f = make();
                comm.barrier();
                f
            } else {
                comm.barrier();
                make()
            }
        } else {
            make()
        };
        let fmm = agree_message(comm, fmm.map_err(|e| e.to_string()))?;
        let (active, n_active) = active_boxes(fmm.tree(), &kinds);
        setup.active_boxes = n_active;
        let coarse_plan = CoarsePlan::make(comm, &dtree.cuts, fmm.tree(), &coarse, &active);
        let coarse_plan = agree_message(comm, coarse_plan)?;
        setup.bytes_sent += coarse_plan.setup_bytes;
        (setup.coarse_send_partners, setup.coarse_recv_partners) = coarse_plan.partners();
        let fmm = fmm.with_active_boxes(active).map_err(|e| DistError::Fmm {
            rank: comm.rank(),
            message: e.to_string(),
        })?;
        setup.seconds[2] = t.elapsed().as_secs_f64();
        Ok(DistributedFmm {
            fmm,
            plan,
            coarse_plan,
            route,
            target_route,
            own_pos,
            ghost_pos,
            coarse,
            n_owned: dtree.points.len(),
            n_targets: targets.len(),
            nq,
            setup,
        })
    }

    /// Potentials (and gradients) at this rank's input points, in its input
    /// order, for the densities of its input points (a collective: every
    /// rank passes its own): [`Kernel::values_per_source`] values per
    /// point (one charge for a scalar kernel; `[re, im]` for Helmholtz; a
    /// force for Stokes), [`Kernel::values_per_target`] values out per
    /// point, interleaved, as [`ferrofmm_fmm::Fmm::evaluate`].
    ///
    /// On a tree built with separate targets
    /// ([`DistributedTree::build_with_targets`]), the densities are those
    /// of this rank's input sources, in its input order, and the values
    /// those at its input targets, in its input order of targets
    /// ([`DistributedFmm::n_input_targets`] of them; none on a rank that
    /// gave no target).
    ///
    /// # Errors
    /// [`DistError::BadInput`] with [`InputProblem::BadCharges`] on every
    /// rank when some rank's charges are not that many finite values per
    /// input point.
    pub fn evaluate<C: Communicator>(
        &self,
        comm: &C,
        charges: &[T],
    ) -> Result<(Vec<T>, EvalStats), DistError> {
        agree_on_charges(comm, charges, self.nq * self.route.n_input)?;
        let mut stats = EvalStats::default();
        let t = Instant::now();
        let (own, bytes) = self.route.charges_in(comm, charges, self.nq, self.n_owned);
        stats.add(0, t, bytes);
        let (values, inner) = self.evaluate_sorted_unchecked(comm, &own);
        stats.merge(&inner);
        let t = Instant::now();
        let w = self.fmm.kernel().values_per_target(self.fmm.mode());
        let route = self.target_route.as_ref().unwrap_or(&self.route);
        let (out, bytes) = route.values_out(comm, &values, w);
        stats.add(7, t, bytes);
        Ok((out, stats))
    }

    /// As [`DistributedFmm::evaluate`] with charges and values in the
    /// order of this rank's points in the tree (`dtree.points`; with
    /// separate targets, the values in the order of `dtree.targets`'
    /// points): no routing,
    /// only the FMM's own communication (what an iterative solver that keeps
    /// its vectors distributed along the tree needs).
    ///
    /// # Errors
    /// As [`DistributedFmm::evaluate`], for the densities of the tree
    /// points.
    pub fn evaluate_sorted<C: Communicator>(
        &self,
        comm: &C,
        charges: &[T],
    ) -> Result<(Vec<T>, EvalStats), DistError> {
        agree_on_charges(comm, charges, self.nq * self.n_owned)?;
        Ok(self.evaluate_sorted_unchecked(comm, charges))
    }

    fn evaluate_sorted_unchecked<C: Communicator>(
        &self,
        comm: &C,
        own: &[T],
    ) -> (Vec<T>, EvalStats) {
        let mut stats = EvalStats::default();
        let n = self.fmm.n_surface();
        let nq = self.nq;
        let mut q = vec![T::ZERO; nq * (self.own_pos.len() + self.ghost_pos.len())];
        for (&p, x) in self.own_pos.iter().zip(own.chunks_exact(nq)) {
            q[nq * p..nq * (p + 1)].copy_from_slice(x);
        }
        let mut timings = EvalTimings::default();
        let t = Instant::now();
        let c = stats::cpu_seconds();
        let mut multipoles = self
            .fmm
            .upward(&q, &mut timings)
            .expect("charge vector sized for the local tree");
        stats.add(1, t, 0);
        stats.compute_cpu_seconds += stats::cpu_seconds() - c;

        let t = Instant::now();
        let mut ghost_q = vec![T::ZERO; nq * self.ghost_pos.len()];
        let bytes = self
            .plan
            .exchange(comm, n, nq, &mut multipoles, own, &mut ghost_q);
        for (&p, x) in self.ghost_pos.iter().zip(ghost_q.chunks_exact(nq)) {
            q[nq * p..nq * (p + 1)].copy_from_slice(x);
        }
        stats.add(2, t, bytes);

        let t = Instant::now();
        let bytes = self
            .coarse_plan
            .sum_multipoles(comm, n, &self.coarse, &mut multipoles);
        stats.add(3, t, bytes);

        let t = Instant::now();
        let c = stats::cpu_seconds();
        let mut coarse_cpu = 0.0;
        let mut coarse_seconds = 0.0;
        let mut coarse_bytes = 0;
        let locals = self
            .fmm
            .downward(&q, &multipoles, &mut timings, |level, range, checks| {
                let t = Instant::now();
                let c = stats::cpu_seconds();
                coarse_bytes +=
                    self.coarse_plan
                        .sum_checks(comm, n, level, &self.coarse, range.start, checks);
                coarse_seconds += t.elapsed().as_secs_f64();
                coarse_cpu += stats::cpu_seconds() - c;
            })
            .expect("vectors sized for the local tree");
        stats.seconds[4] += t.elapsed().as_secs_f64() - coarse_seconds;
        stats.compute_cpu_seconds += stats::cpu_seconds() - c - coarse_cpu;
        stats.seconds[5] += coarse_seconds;
        stats.bytes_sent[5] += coarse_bytes;

        let t = Instant::now();
        let c = stats::cpu_seconds();
        let values = self
            .fmm
            .leaf_passes(&q, &multipoles, &locals, &mut timings)
            .expect("vectors sized for the local tree");
        stats.add(6, t, 0);
        stats.compute_cpu_seconds += stats::cpu_seconds() - c;
        stats.passes = timings;
        (values, stats)
    }

    /// Setup figures of this rank.
    pub fn setup_stats(&self) -> &SetupStats {
        &self.setup
    }

    /// The single-machine passes and operators this rank runs.
    pub fn local(&self) -> &TreeFmm<T, K, S> {
        &self.fmm
    }

    /// Number of points (sources) this rank holds in the tree.
    pub fn n_owned(&self) -> usize {
        self.n_owned
    }

    /// Number of targets this rank holds in the tree (the length of
    /// [`DistributedFmm::evaluate_sorted`]'s result, per value): its
    /// points, unless the tree was built with separate targets.
    pub fn n_targets(&self) -> usize {
        self.n_targets
    }

    /// Number of targets this rank gave the tree build (the length of
    /// [`DistributedFmm::evaluate`]'s result, per value): its input points,
    /// unless the tree was built with separate targets.
    pub fn n_input_targets(&self) -> usize {
        self.target_route.as_ref().unwrap_or(&self.route).n_input
    }

    /// Values per point in the charge vectors
    /// ([`Kernel::values_per_source`] of the source kind).
    pub fn values_per_source(&self) -> usize {
        self.nq
    }

    /// Values per point in the results ([`Kernel::values_per_target`] of
    /// the mode).
    pub fn values_per_target(&self) -> usize {
        self.fmm.kernel().values_per_target(self.fmm.mode())
    }
}

/// The boxes whose expansions this rank needs: its own boxes and the
/// coarse boxes above them (a coarse box away from the rank's range gets
/// no multipole from it and its local is not needed here; ghost boxes get
/// their multipoles from their owners and need no locals). Returns the
/// flags and how many are set.
fn active_boxes(tree: &ferrofmm_tree::Octree, kinds: &[Kind]) -> (Vec<bool>, usize) {
    let mut active = vec![false; kinds.len()];
    for b in 0..kinds.len() {
        if kinds[b] != Kind::Own {
            continue;
        }
        active[b] = true;
        let mut up = tree.parent(b);
        while let Some(p) = up {
            if active[p] {
                break;
            }
            active[p] = true;
            up = tree.parent(p);
        }
    }
    let n = active.iter().filter(|&&a| a).count();
    (active, n)
}

/// The global tree's depth and the union of all ranks' M2L usage.
fn global_usage<C: Communicator>(comm: &C, tree: &ferrofmm_tree::Octree) -> (u32, M2lUsage) {
    let mut depth = 0u32;
    comm.all_reduce_into(&tree.depth(), &mut depth, SystemOperation::max());
    let local = m2l_usage(tree);
    let levels = depth as usize + 1;
    let flags: Vec<u8> = (0..levels)
        .flat_map(|l| (0..N_TRANSFER_VECTORS).map(move |v| (l, v)))
        .map(|(l, v)| u8::from(local.is_used(l as u32, v)))
        .collect();
    let mut all = vec![0u8; flags.len()];
    comm.all_reduce_into(&flags[..], &mut all[..], SystemOperation::max());
    let mut usage = M2lUsage::none();
    for (i, &f) in all.iter().enumerate() {
        if f != 0 {
            usage.mark((i / N_TRANSFER_VECTORS) as u32, i % N_TRANSFER_VECTORS);
        }
    }
    (depth, usage)
}

/// One charge per point (`expected` of them), all finite, on every rank:
/// agreed across ranks, so that bad charges on one rank are
/// [`InputProblem::BadCharges`] on all of them and no rank goes on alone.
fn agree_on_charges<C: Communicator, T: Real>(
    comm: &C,
    charges: &[T],
    expected: usize,
) -> Result<(), DistError> {
    let ok = charges.len() == expected && charges.iter().all(|q| q.is_finite());
    agree(
        comm,
        if ok {
            Ok(())
        } else {
            Err(InputProblem::BadCharges)
        },
    )
}
