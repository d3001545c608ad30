//! [`MemoryReport`]: an accounting of the big buffers of an [`Fmm`].
//!
//! Nothing is allocated for empty space: the tree holds only boxes that
//! contain points, expansions are `n` values per existing box, and M2L
//! interactions exist only between existing boxes. So memory grows with the
//! number of occupied boxes (about `N / leaf_size` times a small factor),
//! not with the depth: two clusters 1000x apart in size need a tree 17
//! levels deep, where `8^17` boxes could not be stored, but as many boxes as
//! uniform points of the same `N`.

use std::mem::{size_of, size_of_val};

#[cfg(doc)]
use ferrofmm_field::MemoryLimit;
use ferrofmm_field::{M2lInteractions, M2lScheme};
use ferrofmm_kernels::{Kernel, Real};

use crate::Fmm;
use crate::part::Body;

/// Bytes of the big buffers of an [`Fmm`] (see [`Fmm::memory`]).
///
/// The tree's figures count its arrays from their lengths (keys, parents,
/// children, masks, point ranges, the 27-entry colleague table, the CSR
/// lists, sorted coordinates and permutations); small fixed-size parts
/// are left out. An [`Fmm`]'s tree has handed its V lists over to the M2L
/// interactions (counted there), and its sorted points to the FMM.
///
/// The figures add up buffers that are not all alive at once: the
/// evaluation releases the multipoles after M2P and the locals after L2P,
/// so the outputs (first written by L2P) and both expansions are never
/// resident together, and [`MemoryReport::total`] is above the peak.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MemoryReport {
    /// Boxes the buffers below are sized by.
    pub n_boxes: usize,
    /// Values per expansion (`n = 6 (p - 1)^2 + 2`).
    pub n_surface: usize,
    /// Multipole and local expansions of one evaluation:
    /// `2 n n_boxes size_of::<T>()`.
    pub expansions: usize,
    /// Other buffers of one evaluation: densities in tree order, the outputs (made in tree order and put in
    /// the caller's order in place: one copy) and the M2L scheme's working
    /// memory ([`M2lScheme::apply_scratch_bytes`], the largest level's).
    pub evaluation_scratch: usize,
    /// Points kept by the FMM (sorted, in `T`, relative to the tree's
    /// origin) and the tree's permutations (and sorted `f64` coordinates,
    /// where the tree still holds them: a caller's tree).
    pub points: usize,
    /// Tree structure: per-box arrays, colleague table, U/V/W/X lists.
    pub tree: usize,
    /// M2L interactions of every level: their sibling blocks, with the
    /// grouped pair lists only for a scheme that reads them whole
    /// ([`M2lScheme::reads_pair_lists`](ferrofmm_field::M2lScheme::reads_pair_lists):
    /// none of the built-in ones).
    pub m2l_interactions: usize,
    /// Check-to-equivalent, M2M and L2L operators.
    pub operators: usize,
    /// M2L operators ([`M2lScheme::memory_bytes`]).
    pub m2l: usize,
    /// Everything above.
    pub total: usize,
}

impl MemoryReport {
    pub(crate) fn of<T: Real, K: Kernel, S: M2lScheme<T>>(fmm: &Fmm<T, K, S>) -> Self {
        let t = size_of::<T>();
        let us = size_of::<usize>();
        let n = fmm.expansion_len();
        let w = fmm.kernel.values_per_target(fmm.mode);
        let mut n_boxes = 0;
        let mut points = 0;
        let mut tree_bytes = 0;
        let mut m2l_interactions = 0;
        let mut operators = 0;
        let mut m2l = 0;
        let mut m2l_scratch = 0;
        for part in &fmm.parts {
            // Caller indices of a cluster's points.
            let ids = part.source_ids.as_ref().map_or(0, Vec::len)
                + part.target_ids.as_ref().map_or(0, Vec::len);
            points += ids * us;
            match &part.body {
                Body::Points(p) => {
                    points += (p.sources.len() + p.targets.as_ref().map_or(0, Vec::len)) * t;
                }
                Body::Tree(tp) => {
                    let tree = &tp.tree;
                    n_boxes += tree.n_boxes();
                    let held =
                        |coords: &[f64], perm: &[usize]| size_of_val(coords) + size_of_val(perm);
                    let tree_points = held(tree.sorted_sources(), tree.source_permutation())
                        + if tree.sources_are_targets() {
                            0
                        } else {
                            held(tree.sorted_targets(), tree.target_permutation())
                        };
                    points += (tp.sources.len() + tp.targets.as_ref().map_or(0, Vec::len)) * t
                        + tree_points;
                    // keys, parents, children (2), source and target ranges
                    // (4), two masks, colleague table (27 u32), leaves.
                    let per_box = size_of::<u64>() + us + 2 * us + 4 * us + 2 + 27 * 4;
                    let lists = tree.interaction_lists();
                    let csr = |c: &ferrofmm_tree::Csr| (c.offsets().len() + c.indices().len()) * us;
                    tree_bytes += tree.n_boxes() * per_box
                        + std::mem::size_of_val(tree.leaves())
                        + csr(&lists.u)
                        + csr(&lists.v)
                        + csr(&lists.w)
                        + csr(&lists.x);
                    m2l_interactions += tp
                        .m2l_interactions
                        .iter()
                        .map(M2lInteractions::memory_bytes)
                        .sum::<usize>();
                    operators += tp.operators.memory_bytes();
                    m2l += tp.m2l.memory_bytes();
                    m2l_scratch = tp
                        .m2l_interactions
                        .iter()
                        .map(|i| tp.m2l.apply_scratch_bytes(i))
                        .fold(m2l_scratch, usize::max);
                }
            }
        }
        let expansions = 2 * n * n_boxes * t;
        let nq = fmm.kernel.values_per_source(fmm.source_kind);
        // Check potentials are gathered in the expansions' own columns
        // (`passes::p2m`, `passes::downward`): no buffer of their own.
        let evaluation_scratch = nq * fmm.n_sources * t + w * fmm.n_targets * t + m2l_scratch;
        let total = expansions
            + evaluation_scratch
            + points
            + tree_bytes
            + m2l_interactions
            + operators
            + m2l;
        MemoryReport {
            n_boxes,
            n_surface: n,
            expansions,
            evaluation_scratch,
            points,
            tree: tree_bytes,
            m2l_interactions,
            operators,
            m2l,
            total,
        }
    }
}

/// The sizes a run's point-dependent buffers follow (see
/// [`MemoryReport::predict`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunSize {
    /// Number of sources.
    pub n_sources: usize,
    /// Number of separate targets (`None`: the targets are the sources).
    pub n_targets: Option<usize>,
    /// Values per source of one density vector
    /// ([`Kernel::values_per_source`]).
    pub values_per_source: usize,
    /// Values per target ([`Kernel::values_per_target`]).
    pub values_per_target: usize,
    /// Density vectors evaluated in one call (their results kept).
    pub n_vectors: usize,
}

impl MemoryReport {
    /// Bytes that building an [`Fmm`] in `T` for `size` and evaluating
    /// `size.n_vectors` density vectors need at least: the buffers whose
    /// length follows from the point counts alone, with the same per-point
    /// figures as [`Fmm::memory`]. What the FMM keeps (its sorted points and
    /// the tree's permutation) plus the larger of what the build holds
    /// while it sorts and what the evaluation holds (the densities in tree
    /// order and the outputs of every vector): `kept + max(build,
    /// evaluation)` of [`MemoryReport::predict_points`] and
    /// [`MemoryReport::predict_evaluation`]. Boxes, expansions and
    /// operators are not counted (they depend on the tree), nor the
    /// caller's own inputs, so this is a lower bound of the peak: a run it
    /// puts beyond the memory available cannot fit ([`check_memory`]).
    ///
    /// Saturates at `u64::MAX` instead of overflowing.
    pub fn predict<T: Real>(size: &RunSize) -> u64 {
        let (kept, build) = Self::points_share::<T>(size);
        let evaluation = Self::predict_evaluation::<T>(size);
        kept.saturating_add(build.max(evaluation))
    }

    /// The build's share of [`MemoryReport::predict`], per point (source
    /// or separate target): the sorted points the FMM keeps in `T` and the
    /// tree's permutation (`3 size_of::<T>() + size_of::<usize>()`), and
    /// while the tree sorts, the finest-cell Morton codes before and after
    /// the sort (`16`) and, in `f32`, the sorted `f64` coordinates the
    /// `f32` copy is made from (`24`; in `f64` they become the FMM's).
    pub fn predict_points<T: Real>(size: &RunSize) -> u64 {
        let (kept, build) = Self::points_share::<T>(size);
        kept.saturating_add(build)
    }

    /// What the FMM keeps per point, and what the build holds besides
    /// while it sorts (see [`MemoryReport::predict_points`]).
    fn points_share<T: Real>(size: &RunSize) -> (u64, u64) {
        let t = size_of::<T>() as u128;
        let us = size_of::<usize>() as u128;
        let points = size.n_sources as u128 + size.n_targets.unwrap_or(0) as u128;
        let f64_copy = if t == 8 { 0 } else { 3 * 8 };
        let bytes = |per: u128| u64::try_from(points * per).unwrap_or(u64::MAX);
        (bytes(3 * t + us), bytes(16 + f64_copy))
    }

    /// The evaluation's share of [`MemoryReport::predict`] (of an
    /// [`Fmm`] already built): the densities in tree order and the
    /// outputs of every vector (those of the vector being evaluated are
    /// made in tree order and put in the caller's order in place).
    pub fn predict_evaluation<T: Real>(size: &RunSize) -> u64 {
        let t = size_of::<T>() as u128;
        let n = size.n_sources as u128;
        let m = size.n_targets.unwrap_or(size.n_sources) as u128;
        let (s, w, k) = (
            size.values_per_source as u128,
            size.values_per_target as u128,
            size.n_vectors.max(1) as u128,
        );
        u64::try_from(n * s * t + k * w * m * t).unwrap_or(u64::MAX)
    }
}

/// [`FmmError::RunMemory`](crate::FmmError::RunMemory) when `needed` bytes exceed `limit` (resolved as
/// for the operator precomputation: [`MemoryLimit::Auto`] is
/// `FERROFMM_MEMORY_LIMIT`, else the memory available, which honours
/// `RLIMIT_AS`; see [`ferrofmm_field::available_memory`]). `what` names
/// the run in the message.
pub fn check_memory(
    needed: u64,
    limit: ferrofmm_field::MemoryLimit,
    what: &str,
) -> Result<(), crate::FmmError> {
    match limit.resolve()? {
        Some(limit_bytes) if needed > limit_bytes => Err(crate::FmmError::RunMemory {
            what: what.to_string(),
            estimate_bytes: needed,
            limit_bytes,
        }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_field::MemoryLimit;

    #[test]
    fn predicted_bytes_grow_with_the_points_and_saturate() {
        let size = |n, m| RunSize {
            n_sources: n,
            n_targets: m,
            values_per_source: 1,
            values_per_target: 4,
            n_vectors: 1,
        };
        // Kept 32 bytes a point, then the larger of the sort's 16 and the
        // evaluation's 8 + 32.
        let small = MemoryReport::predict::<f64>(&size(1000, None));
        assert_eq!(small, 1000 * (32 + 40));
        assert_eq!(
            MemoryReport::predict_points::<f64>(&size(1000, None)),
            1000 * (32 + 16)
        );
        assert!(MemoryReport::predict::<f64>(&size(1000, Some(1000))) > small);
        assert!(MemoryReport::predict::<f32>(&size(1000, None)) < small);
        assert_eq!(
            MemoryReport::predict::<f64>(&size(usize::MAX, Some(usize::MAX))),
            u64::MAX
        );
        let big = MemoryReport::predict::<f64>(&size(1_000_000_000, None));
        let err = check_memory(big, MemoryLimit::Bytes(1 << 30), "test").unwrap_err();
        assert!(matches!(err, crate::FmmError::RunMemory { .. }), "{err}");
        assert!(err.to_string().contains("1.0 GiB"), "{err}");
        assert!(check_memory(small, MemoryLimit::Bytes(1 << 30), "test").is_ok());
        assert!(check_memory(big, MemoryLimit::Unlimited, "test").is_ok());
    }
}
