//! Before the M2L precomputation: which operators the tree needs
//! ([`m2l_usage`]) and whether their predicted memory fits
//! ([`check_memory`]).

use ferrofmm_field::{
    M2lScheme, M2lUsage, OperatorParams, PrecomputeEstimate, transfer_vector_index,
};
use ferrofmm_kernels::{Kernel, Real};
use ferrofmm_tree::Octree;

use crate::FmmError;

/// The transfer vectors each level's V lists use (none when the tree has
/// no V list, e.g. a single leaf level at depth 0 or 1): what the M2L
/// operators are precomputed for. Pieces of one tree (the processes of a
/// distributed FMM) mark the union of their pieces' usages to get the
/// operators of the whole tree.
pub fn m2l_usage(tree: &Octree) -> M2lUsage {
    let mut usage = M2lUsage::none();
    for level in 0..=tree.depth() {
        for b in tree.level_range(level) {
            let key = tree.key(b);
            for &a in tree.v_list(b) {
                if let Some(v) = transfer_vector_index(key.transfer_vector(tree.key(a))) {
                    usage.mark(level, v);
                }
            }
        }
    }
    usage
}

/// The shallowest level with far-field work: a box with a V or X list
/// (its downward check potential), or a box in a V or W list (its
/// multipole). Levels above it need no operators of their own: their
/// multipoles are never read, their local expansions stay zero (unless
/// the root is coupled to other parts). `depth + 1` for a tree without
/// far field.
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
