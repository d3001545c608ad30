//! The operators of a tree, before the passes run: which M2L operators
//! the tree needs ([`m2l_usage`], from [`first_far_level`] down), whether
//! their predicted memory fits ([`check_memory`]), their precomputation
//! (`build_operators`, `operators_for`: the check-to-equivalent and
//! parent/child operators and the M2L scheme) and each level's V-list
//! pairs grouped for M2L (`level_interactions`). [`crate::Fmm`] and
//! [`crate::TreeFmm`] both build their trees' operators here.

use std::time::Instant;

use ferrofmm_field::{
    AMPLIFICATION_WARNING, FieldError, M2lInteractions, M2lScheme, M2lUsage, OperatorParams,
    Operators, PrecomputeEstimate, transfer_vector_index,
};
use ferrofmm_kernels::{Kernel, Real};
use ferrofmm_tree::Octree;

use crate::FmmError;
use crate::part::shift_at;
use crate::timings::SetupTimings;
use crate::validate::check_wavenumber;

/// The transfer vectors each level's V lists use (none when the tree has
/// no V list, e.g. a single leaf level at depth 0 or 1): what the M2L
/// operators are precomputed for. Read from a tree that still has its V
/// lists: an [`crate::Fmm`]'s own tree has handed them over to its M2L
/// interactions ([`Octree::take_v_lists`]). Pieces of one tree (the processes of a
/// distributed FMM) mark the union of their pieces' usages to get the
/// operators of the whole tree.
pub fn m2l_usage(tree: &Octree) -> M2lUsage {
    let mut usage = M2lUsage::none();
    for level in 0..=tree.depth() {
        for b in tree.level_range(level) {
            for (_, v) in v_entries(tree, b) {
                if let Some(v) = transfer_vector_index(v) {
                    usage.mark(level, v);
                }
            }
        }
    }
    usage
}

/// The V entries of box `b` with their transfer vectors (source centre
/// minus target centre, in box widths of `b`'s level), the image shift of
/// a periodic tree included: the entry `(a, s)` is box `a` moved by `s`
/// cells, `2^level s` boxes.
pub(crate) fn v_entries(tree: &Octree, b: usize) -> impl Iterator<Item = (usize, [i32; 3])> + '_ {
    let key = tree.key(b);
    let shifts = tree.v_shifts(b);
    tree.v_list(b).iter().enumerate().map(move |(k, &a)| {
        (
            a,
            key.shifted_transfer_vector(tree.key(a), shift_at(shifts, k)),
        )
    })
}

/// The shallowest level with far-field work: a box with a V or X list
/// (its downward check potential), or a box in a V or W list (its
/// multipole). Levels above it need no operators of their own: their
/// multipoles are never read, their local expansions stay zero (unless
/// the root is coupled to other parts). `depth + 1` for a tree without
/// far field. Like [`m2l_usage`], for a tree that still has its V lists.
pub fn first_far_level(tree: &Octree) -> u32 {
    let mut first = tree.depth() + 1;
    for level in 0..=tree.depth() {
        if level >= first {
            break;
        }
        for b in tree.level_range(level) {
            if !tree.v_list(b).is_empty() || !tree.x_list(b).is_empty() {
                first = first.min(level);
            }
            for &a in tree.v_list(b).iter().chain(tree.w_list(b)) {
                first = first.min(tree.level(a));
            }
        }
    }
    first
}

/// Predict the precomputation of `S` for `usage` and refuse it with
/// [`FmmError::PrecomputeMemory`] when its peak memory exceeds the limit of
/// `params` ([`ferrofmm_field::MemoryLimit`]).
pub(crate) fn check_memory<T: Real, K: Kernel, S: M2lScheme<T>>(
    kernel: &K,
    params: &OperatorParams,
    config: &S::Config,
    depth: u32,
    usage: &M2lUsage,
) -> Result<PrecomputeEstimate, FmmError> {
    let estimate = S::estimate(kernel, params, config, depth, usage);
    if let Some(limit) = params.memory_limit.resolve()?
        && estimate.peak_bytes > limit
    {
        return Err(FmmError::PrecomputeMemory {
            estimate_bytes: estimate.peak_bytes,
            limit_bytes: limit,
            seconds: estimate.seconds,
            order: params.order,
            matrices: estimate.matrices,
        });
    }
    Ok(estimate)
}

/// `bytes` in MiB or GiB, for messages.
pub(crate) fn human_bytes(bytes: &u64) -> String {
    let b = *bytes as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else {
        format!("{:.1} MiB", b / (1u64 << 20) as f64)
    }
}

/// What a tree needs operators for: the transfer vectors its V lists use
/// ([`m2l_usage`]) and the first level that needs operators of its own.
/// Read from the tree's V lists once, when the tree is built, and kept:
/// a rebuild at another order (verification) reuses it after the FMM has
/// handed the V lists over to its M2L interactions
/// ([`Octree::take_v_lists`]).
#[derive(Clone, Debug)]
pub(crate) struct OperatorNeeds {
    pub(crate) usage: M2lUsage,
    pub(crate) first_level: u32,
}

impl OperatorNeeds {
    /// The needs of `tree`. `coupled`: the tree's root expansions couple
    /// it to other parts (far clusters, a periodic cell's images), so every
    /// level needs its operators; otherwise only the levels from the first
    /// with far-field work down ([`first_far_level`]).
    pub(crate) fn of(tree: &Octree, coupled: bool) -> Self {
        OperatorNeeds {
            usage: m2l_usage(tree),
            first_level: if coupled { 0 } else { first_far_level(tree) },
        }
    }
}

/// The check-to-equivalent and parent/child operators and the M2L scheme
/// for `params` on `tree`, for its `needs` (their times written into
/// `setup`).
pub(crate) fn build_operators<T: Real, K: Kernel, S: M2lScheme<T>>(
    kernel: &K,
    params: &OperatorParams,
    config: &S::Config,
    tree: &Octree,
    needs: &OperatorNeeds,
    setup: &mut SetupTimings,
) -> Result<(Operators<T>, S), FmmError> {
    // Only what the tree needs, and only when it fits (issue 18).
    operators_for(
        kernel,
        params,
        config,
        tree.domain().width,
        tree.depth(),
        needs.first_level,
        &needs.usage,
        setup,
    )
}

/// [`build_operators`] for a domain `width`, levels `first_level..=depth`
/// (see [`Operators::from_level`]) and the transfer vectors `usage` (which
/// may come from more than one tree).
#[allow(clippy::too_many_arguments)]
pub(crate) fn operators_for<T: Real, K: Kernel, S: M2lScheme<T>>(
    kernel: &K,
    params: &OperatorParams,
    config: &S::Config,
    width: f64,
    depth: u32,
    first_level: u32,
    usage: &M2lUsage,
    setup: &mut SetupTimings,
) -> Result<(Operators<T>, S), FmmError> {
    check_wavenumber(kernel, width)?;
    let t = Instant::now();
    check_memory::<T, K, S>(kernel, params, config, depth, usage)?;
    let operators = Operators::<T>::from_level(kernel, params, width, depth, first_level)?;
    let diagnostics = operators.diagnostics();
    if diagnostics.rounding_amplification > AMPLIFICATION_WARNING {
        return Err(FmmError::IllConditioned {
            order: params.order,
            rcond: diagnostics.rcond,
            amplification: diagnostics.rounding_amplification,
            limit: AMPLIFICATION_WARNING,
            precision: T::PRECISION.name(),
        });
    }
    setup.operators = t.elapsed();
    let t = Instant::now();
    let m2l = S::precompute_for(kernel, params, config, width, depth, usage)?;
    setup.m2l_precompute = t.elapsed();
    Ok((operators, m2l))
}

/// The V-list pairs of a level (`(target column, source column, transfer
/// vector)`, columns counted from the level's first box), grouped for M2L.
pub(crate) fn level_interactions(tree: &Octree, level: u32) -> Result<M2lInteractions, FieldError> {
    let range = tree.level_range(level);
    let start = range.start;
    let chunk = M2lInteractions::default_chunk_size(range.len());
    let inter = M2lInteractions::from_targets(range.len(), range.len(), chunk, |t| {
        v_entries(tree, start + t).map(move |(a, v)| (a - start, v))
    })?;
    if level == 0 {
        return Ok(inter);
    }
    // Sibling slot of each box: 8 (parent's index on its level) + octant
    // (increasing with the Morton order), so that schemes that treat
    // siblings together find them although empty boxes are left out.
    let parents = tree.level_range(level - 1).start;
    let slots: Vec<u32> = range
        .map(|b| {
            let parent = tree.parent(b).expect("a box below the root has a parent");
            (8 * (parent - parents) + tree.key(b).octant()) as u32
        })
        .collect();
    inter.with_sibling_slots(slots.clone(), slots)
}
