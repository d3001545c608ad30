//! What an M2L precomputation must build: the transfer vectors a tree uses
//! per level ([`M2lUsage`]) and, from them, the vectors each operator set
//! gets ([`planned_sets`]).
//!
//! With `V_l` the transfer vectors occurring in the V lists of level `l`,
//! a kernel homogeneous of degree `d` needs one set, `V = U_l V_l` (scaled
//! by `h_l^d` per level), any other kernel one set `V_l` per level
//! `l = 2..=depth` (`K_v(h_l)` for `v in V_l`).
//!
//! Uses: the transfer-vector numbering ([`crate::interactions`]), the first
//! M2L level ([`crate::levels`]) and the cache directory of
//! [`OperatorParams`].

use crate::levels::FIRST_M2L_LEVEL;
use crate::{N_TRANSFER_VECTORS, OperatorParams};

/// Which M2L operators a tree needs: for each level `l`, the set `V_l` of
/// transfer vectors (indices into [`transfer_vectors`](crate::transfer_vectors))
/// that occur in the V lists of its boxes.
///
/// A tree with no V list at all (few points, one leaf level) needs no M2L
/// operator; a large uniform tree needs all 316 vectors at most levels
/// `2..=d`. For a homogeneous
/// kernel one operator set serves every level, so only
/// `V = U_l V_l` ([`M2lUsage::union`]) is computed.
///
/// ```
/// use ferrofmm_field::M2lUsage;
/// let mut usage = M2lUsage::none();
/// assert!(usage.is_empty());
/// usage.mark(3, 17);
/// assert!(usage.is_used(3, 17) && !usage.is_used(2, 17));
/// assert_eq!(usage.levels().collect::<Vec<_>>(), vec![3]);
/// assert_eq!(M2lUsage::all(4).n_used(), 3 * 316);
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct M2lUsage {
    /// Index = level; each entry empty (unused level) or 316 flags.
    used: Vec<Vec<bool>>,
}

impl M2lUsage {
    /// Nothing used (no V list anywhere).
    pub fn none() -> Self {
        M2lUsage::default()
    }

    /// Every transfer vector at every level `2..=depth`: what
    /// [`M2lScheme::precompute`](crate::M2lScheme::precompute) builds.
    pub fn all(depth: u32) -> Self {
        let mut usage = M2lUsage::none();
        for level in FIRST_M2L_LEVEL..=depth {
            for v in 0..N_TRANSFER_VECTORS {
                usage.mark(level, v);
            }
        }
        usage
    }

    /// Mark transfer vector `vector` (an index `< 316`) as used at `level`.
    ///
    /// # Panics
    /// When `vector >= 316`.
    pub fn mark(&mut self, level: u32, vector: usize) {
        assert!(
            vector < N_TRANSFER_VECTORS,
            "transfer vector index {vector} out of range"
        );
        let l = level as usize;
        if self.used.len() <= l {
            self.used.resize(l + 1, Vec::new());
        }
        if self.used[l].is_empty() {
            self.used[l] = vec![false; N_TRANSFER_VECTORS];
        }
        self.used[l][vector] = true;
    }

    /// Whether `vector` is used at `level`.
    pub fn is_used(&self, level: u32, vector: usize) -> bool {
        self.used
            .get(level as usize)
            .and_then(|l| l.get(vector))
            .copied()
            .unwrap_or(false)
    }

    /// True when no level uses any transfer vector.
    pub fn is_empty(&self) -> bool {
        self.used.iter().all(|l| !l.contains(&true))
    }

    /// Levels with at least one used transfer vector, in increasing order.
    pub fn levels(&self) -> impl Iterator<Item = u32> + '_ {
        self.used
            .iter()
            .enumerate()
            .filter(|(_, l)| l.contains(&true))
            .map(|(i, _)| i as u32)
    }

    /// Used transfer vectors of `level` (increasing indices).
    pub fn vectors_at(&self, level: u32) -> Vec<usize> {
        match self.used.get(level as usize) {
            Some(l) => (0..l.len()).filter(|&v| l[v]).collect(),
            None => Vec::new(),
        }
    }

    /// Transfer vectors used at any level (increasing indices).
    pub fn union(&self) -> Vec<usize> {
        (0..N_TRANSFER_VECTORS)
            .filter(|&v| self.used.iter().any(|l| l.get(v) == Some(&true)))
            .collect()
    }

    /// Number of `(level, vector)` pairs used.
    pub fn n_used(&self) -> usize {
        self.used
            .iter()
            .map(|l| l.iter().filter(|&&u| u).count())
            .sum()
    }

    /// Deepest level with a used vector (`None` when empty).
    pub fn deepest_level(&self) -> Option<u32> {
        self.levels().last()
    }

    /// Per operator set (homogeneous kernel: one set, the union; otherwise
    /// one per level `first..=depth`), the used vector indices.
    pub(crate) fn per_set(&self, homogeneous: bool, first: u32, depth: u32) -> Vec<Vec<usize>> {
        if homogeneous {
            vec![self.union()]
        } else {
            (first..=depth).map(|l| self.vectors_at(l)).collect()
        }
    }
}

/// The shallowest level whose M2L operators a tree with `usage` needs:
/// [`FIRST_M2L_LEVEL`] (2), or 1 when V lists reach level 1, which only a
/// periodic tree's wrapped lists do (a level-1 box and the images of its
/// siblings one cell away).
pub fn first_m2l_level(usage: &M2lUsage) -> u32 {
    usage
        .levels()
        .next()
        .map_or(FIRST_M2L_LEVEL, |l| l.min(FIRST_M2L_LEVEL))
}

/// Whether a non-homogeneous kernel's M2L store for `usage` may go through
/// the cache: only when its sets start at [`FIRST_M2L_LEVEL`], the layout
/// cache files have (a periodic tree's extra level-1 set is computed, not
/// cached).
pub(crate) fn cacheable(homogeneous: bool, usage: &M2lUsage) -> bool {
    homogeneous || first_m2l_level(usage) == FIRST_M2L_LEVEL
}

/// The transfer vectors (indices) to compute per operator set for
/// [`M2lScheme::precompute_for`](crate::M2lScheme::precompute_for): nothing for an empty `usage`; all 316 per
/// set with a cache directory (so the file stays complete); otherwise the
/// union of the used vectors (homogeneous kernel, one set) or those of each
/// level [`first_m2l_level`]`..=depth`.
pub fn planned_sets(
    homogeneous: bool,
    params: &OperatorParams,
    depth: u32,
    usage: &M2lUsage,
) -> Vec<Vec<usize>> {
    let first = first_m2l_level(usage);
    let n_sets = if homogeneous {
        1
    } else {
        (depth + 1).saturating_sub(first) as usize
    };
    if usage.is_empty() {
        vec![Vec::new(); n_sets]
    } else if params.cache_dir.is_some() && cacheable(homogeneous, usage) {
        vec![(0..N_TRANSFER_VECTORS).collect(); n_sets]
    } else {
        usage.per_set(homogeneous, first, depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usage_sets() {
        let mut u = M2lUsage::none();
        u.mark(2, 5);
        u.mark(4, 7);
        u.mark(4, 5);
        assert_eq!(u.union(), vec![5, 7]);
        assert_eq!(u.per_set(false, 2, 4), vec![vec![5], vec![], vec![5, 7]]);
        assert_eq!(u.per_set(true, 2, 4), vec![vec![5, 7]]);
        assert_eq!(u.deepest_level(), Some(4));
    }
}
