//! The coarse tree's sums (steps 4 and 5 of an evaluation): who holds a
//! share of each coarse box, who needs the sum, and the plans of the
//! sparse exchanges (`dfmm/sparse_sum.rs`) that replace the `all_reduce`s.
//!
//! A coarse box `C` straddles cuts: the ranks whose ranges meet it (its
//! **owners**, a contiguous run of ranks along the Morton curve) each hold
//! part of it. Read off each rank's locally essential tree when the FMM is
//! built:
//!
//! * **multipole** `u_C = sum_r u_C^(r)`: shares on the ranks where `C` is
//!   active (its owners: P2M and M2M run only above their own boxes, so
//!   elsewhere `u_C^(r) = 0`); the sum is needed where the local tree reads
//!   it: an own box with `C` in its V or W row, or `C` in the
//!   coarse-to-coarse part of the V row of a coarse box whose root this
//!   rank is;
//! * **check potential** `c_C`: shares on the ranks with a nonempty V or X
//!   row for `C` (own boxes in `V(C)`, own leaves in `X(C)`, and the root
//!   of `C`, which adds the coarse boxes in `V(C)`); the sum is needed
//!   where `C` is active (its owners, whose own boxes below `C` take their
//!   locals from `d_C = DC2E c_C + L2L d_parent`).
//!
//! The **root** of `C`, which sums it, is its first owner ([`root_of`]),
//! known to every rank from the cuts. A rank is the root of at most one
//! coarse box per level: a box whose first owner is `r` starts in `r`'s
//! range and, straddling a cut, holds `r`'s last code. So a rank sends and
//! receives the few coarse boxes above its range and near it (a few per
//! level), not the whole coarse tree; only the roots of the coarsest boxes
//! talk to many ranks (the owners of a level-`l` box are about `R / 8^l`
//! ranks), see docs/distributed.md.

use ferrofmm_kernels::Real;
use ferrofmm_tree::{MortonKey, Octree};
use mpi::traits::*;

use super::sparse_sum::{Role, SparseSum};
use crate::partition::owners;

/// The rank that sums coarse box `key`: the first rank whose range meets
/// it (the same on every rank: it depends on the cuts alone).
pub(crate) fn root_of(cuts: &[u64], key: MortonKey) -> usize {
    owners(cuts, key.morton_range()).next().unwrap_or(0)
}

/// One rank's plans of the coarse sums of an evaluation.
#[derive(Debug, Default)]
pub(crate) struct CoarsePlan {
    multipoles: SparseSum,
    /// Per level that has coarse boxes this rank sums, sends or needs:
    /// the plan of its check potentials.
    checks: Vec<(u32, SparseSum)>,
    /// Bytes sent while making the plans.
    pub(crate) setup_bytes: u64,
}

/// This rank's roles in the two sums, for every coarse box (`coarse[j]`
/// the index of the `j`-th in `tree`): multipoles, checks.
fn roles(tree: &Octree, coarse: &[usize], active: &[bool]) -> (Vec<Role>, Vec<Role>) {
    let mut read = vec![false; tree.n_boxes()];
    for b in 0..tree.n_boxes() {
        for &a in tree.v_list(b).iter().chain(tree.w_list(b)) {
            read[a] = true;
        }
    }
    let multipoles = coarse
        .iter()
        .map(|&b| Role {
            share: active[b],
            need: read[b],
        })
        .collect();
    let checks = coarse
        .iter()
        .map(|&b| Role {
            share: !tree.v_list(b).is_empty() || !tree.x_list(b).is_empty(),
            need: active[b],
        })
        .collect();
    (multipoles, checks)
}

impl CoarsePlan {
    /// Makes the plans (a collective): `tree` is this rank's locally
    /// essential tree (with the rows its passes follow), `coarse` the
    /// indices of the coarse boxes in it (key order, the same boxes on
    /// every rank), `active` the boxes whose expansions it computes.
    pub(crate) fn make<C: Communicator>(
        comm: &C,
        cuts: &[u64],
        tree: &Octree,
        coarse: &[usize],
        active: &[bool],
    ) -> Result<Self, String> {
        let roots: Vec<usize> = coarse.iter().map(|&b| root_of(cuts, tree.key(b))).collect();
        let (m_roles, c_roles) = roles(tree, coarse, active);
        let (multipoles, b1) = SparseSum::make(comm, &roots, &m_roles);
        let (checks, b2) = SparseSum::make(comm, &roots, &c_roles);
        let (multipoles, checks) = (multipoles?, checks?);
        let mut levels: Vec<u32> = coarse.iter().map(|&b| tree.level(b)).collect();
        levels.dedup();
        let checks = levels
            .into_iter()
            .map(|l| {
                let at_l = |j: usize| coarse.get(j).is_some_and(|&b| tree.level(b) == l);
                (l, checks.restrict(at_l))
            })
            .filter(|(_, plan)| !plan.is_empty())
            .collect();
        Ok(CoarsePlan {
            multipoles,
            checks,
            setup_bytes: b1 + b2,
        })
    }

    /// Sums the coarse boxes' multipoles (`n` values per box of the local
    /// tree in `multipoles`) where they are needed; returns the bytes sent.
    pub(crate) fn sum_multipoles<C: Communicator, T: Real>(
        &self,
        comm: &C,
        n: usize,
        coarse: &[usize],
        multipoles: &mut [T],
    ) -> u64 {
        self.multipoles.sum(comm, n, |j| coarse[j], multipoles)
    }

    /// Sums the check potentials of the coarse boxes of `level` (`checks`
    /// holds the level's boxes from `first`, the index of its first box, `n`
    /// values each) where they are needed; returns the bytes sent.
    pub(crate) fn sum_checks<C: Communicator, T: Real>(
        &self,
        comm: &C,
        n: usize,
        level: u32,
        coarse: &[usize],
        first: usize,
        checks: &mut [T],
    ) -> u64 {
        match self.checks.iter().find(|(l, _)| *l == level) {
            Some((_, plan)) => plan.sum(comm, n, |j| coarse[j] - first, checks),
            None => 0,
        }
    }

    /// Distinct ranks this one sends to and receives from in the coarse
    /// sums of an evaluation.
    pub(crate) fn partners(&self) -> (usize, usize) {
        let (mut to, mut from) = self.multipoles.partners();
        for (_, plan) in &self.checks {
            let (t, f) = plan.partners();
            to.extend(t);
            from.extend(f);
        }
        for v in [&mut to, &mut from] {
            v.sort_unstable();
            v.dedup();
        }
        (to.len(), from.len())
    }
}

#[cfg(test)]
mod tests {
    use super::super::sparse_sum::simulate_plans;
    use super::*;
    use crate::partition::{END, straddling};

    /// `ranks` about equal ranges of the Morton curve (cuts off the box
    /// boundaries) and the coarse tree of their cuts down to level
    /// `deepest`, in level then key order.
    fn layout(ranks: usize, deepest: u32) -> (Vec<u64>, Vec<MortonKey>) {
        let r = ranks as u64;
        let cuts: Vec<u64> = (0..=r)
            .map(|k| if k == r { END } else { k * (END / r) + k * 977 })
            .collect();
        let mut coarse: Vec<MortonKey> = cuts
            .iter()
            .flat_map(|&c| straddling(c))
            .filter(|k| k.level() <= deepest)
            .collect();
        coarse.sort_unstable_by_key(|k| (k.level(), *k));
        coarse.dedup();
        (cuts, coarse)
    }

    #[test]
    fn a_rank_is_the_root_of_at_most_one_coarse_box_per_level() {
        for ranks in [2, 3, 7, 64, 100] {
            let (cuts, coarse) = layout(ranks, 8);
            let mut rooted = std::collections::BTreeSet::new();
            for &c in &coarse {
                let root = root_of(&cuts, c);
                assert_eq!(owners(&cuts, c.morton_range()).next(), Some(root));
                assert!(rooted.insert((root, c.level())), "R = {ranks}, {c:?}");
            }
        }
    }

    /// The checks' plan on 512 ranks: every owner of a coarse box needs its
    /// sum, its root holds the only share (the coarse-to-coarse part; none
    /// above level 2, which has no V or X lists). A rank
    /// receives at most two boxes a level, against the whole coarse tree
    /// that an `all_reduce` gives every rank; only the roots of the coarsest
    /// boxes send to many.
    #[test]
    fn a_rank_receives_a_few_boxes_per_level_not_the_coarse_tree() {
        let (ranks, deepest) = (512, 6);
        let (cuts, coarse) = layout(ranks, deepest);
        let roots: Vec<usize> = coarse.iter().map(|&c| root_of(&cuts, c)).collect();
        let roles: Vec<Vec<Role>> = (0..ranks)
            .map(|r| {
                coarse
                    .iter()
                    .zip(&roots)
                    .map(|(c, &root)| Role {
                        share: root == r && c.level() >= 2,
                        need: owners(&cuts, c.morton_range()).any(|o| o == r),
                    })
                    .collect()
            })
            .collect();
        let plans = simulate_plans(&roots, &roles);
        let levels = deepest as usize + 1;
        for (r, plan) in plans.iter().enumerate() {
            let [shares_out, shares_in, _, sums_in] = plan.box_counts();
            assert!(sums_in <= 2 * levels, "rank {r}");
            assert_eq!(shares_out + shares_in, 0);
        }
        // The coarse tree: all 73 boxes of levels 0-2, then 511 a level.
        assert_eq!(coarse.len(), 73 + 4 * 511);
        // Rank 0 is the root of the first box of every level: it sends the
        // level-2 box to its 512 / 64 - 1 = 7 other owners and, at levels
        // 3-6, the box of its upper cut to rank 1.
        assert_eq!(plans[0].box_counts()[2], 7 + 4);
    }
}

#[cfg(test)]
#[path = "coarse_model.rs"]
mod model;
