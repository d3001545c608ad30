//! The distributed build, step by step (see the [crate docs](crate)).

use ferrofmm_tree::{DEEPEST_LEVEL, Domain, MortonCodes, MortonKey, TreeShape};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::balance::balance_distributed;
use crate::error::{DistError, InputProblem, agree, problem_of};
use crate::ghosts::{GhostLayer, exchange_ghosts, own_boxes};
use crate::partition::{covering_boxes, find_cuts, redistribute, straddling};
use crate::sort::{LocalPoints, sample_sort};
use crate::stats::{BuildStats, Timer};

/// Options of a distributed build; every rank must pass the same.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DistOptions {
    /// A box is split while it holds more than `leaf_size` points.
    pub leaf_size: usize,
    /// Boxes are not split below this level (at most
    /// [`DEEPEST_LEVEL`]).
    pub max_level: u32,
}

impl DistOptions {
    /// Adaptive refinement to `leaf_size` points per leaf, as
    /// [`TreeOptions::adaptive`](ferrofmm_tree::TreeOptions::adaptive).
    pub fn adaptive(leaf_size: usize) -> Self {
        DistOptions {
            leaf_size,
            max_level: DEEPEST_LEVEL,
        }
    }
}

/// One rank's piece of a distributed adaptive, 2:1-balanced octree.
pub struct DistributedTree {
    /// The domain (the bounding cube of all points, as
    /// [`Domain::from_points`] computes it for all of them).
    pub domain: Domain,
    /// `cuts[r] .. cuts[r + 1]`: the finest codes of rank `r`.
    pub cuts: Vec<u64>,
    /// This rank's points, sorted along the Morton curve.
    pub points: LocalPoints,
    /// This rank's boxes (inside its range): key, leaf flag, point count,
    /// sorted by key.
    pub boxes: Vec<(MortonKey, bool, usize)>,
    /// The coarse tree: boxes straddling a cut (internal, on every rank).
    pub coarse: Vec<MortonKey>,
    /// Ghost boxes and the lists of this rank's boxes.
    pub ghosts: GhostLayer,
    /// Phase times and bytes sent.
    pub stats: BuildStats,
    /// The number of points every rank passed to the build (rank order):
    /// global id `i` is point `i - sum(input_counts[..r])` of rank `r`'s
    /// input.
    pub input_counts: Vec<u64>,
    shape: TreeShape,
    rank: usize,
}

impl DistributedTree {
    /// Builds the tree from the interleaved `xyz` `points` each rank holds
    /// (any share, possibly none). A collective: every rank calls it.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: bad input on any rank
    /// (length, NaN or infinity, zero leaf size, options differing between
    /// ranks), or no point on any rank.
    pub fn build<C: Communicator>(
        comm: &C,
        points: &[f64],
        options: &DistOptions,
    ) -> Result<Self, DistError> {
        Self::build_weighted(comm, points, None, options)
    }

    /// [`DistributedTree::build`] with a weight per point (for instance an
    /// estimate of its work): ranks get contiguous ranges of about equal
    /// total weight instead of equal point counts.
    ///
    /// # Errors
    /// As [`DistributedTree::build`], and weights that are not one finite,
    /// non-negative value per point, or that sum to zero.
    pub fn build_weighted<C: Communicator>(
        comm: &C,
        points: &[f64],
        weights: Option<&[f64]>,
        options: &DistOptions,
    ) -> Result<Self, DistError> {
        let mut stats = BuildStats::default();
        let me = comm.rank() as usize;
        let size = comm.size() as usize;
        let t = Timer::start();

        // 0. Validation, then the same options everywhere.
        let local = validate(points, weights, options);
        agree(comm, local)?;
        let mine = [
            options.leaf_size as u64,
            options.max_level as u64,
            u64::from(weights.is_some()),
        ];
        let mut all_o = vec![0u64; 3 * size];
        comm.all_gather_into(&mine[..], &mut all_o[..]);
        if let Some(r) = all_o.chunks_exact(3).position(|o| o != &all_o[..3]) {
            return Err(DistError::BadInput {
                rank: r as i32,
                problem: InputProblem::MismatchedOptions,
            });
        }

        // 1. Global bounding box and domain.
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in points.chunks_exact(3) {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let (mut glo, mut ghi) = ([0.0f64; 3], [0.0f64; 3]);
        comm.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
        comm.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
        if glo[0] > ghi[0] {
            return Err(DistError::NoPoints);
        }
        // The bounding cube depends only on the extremes, so the cube of
        // two corner points is that of all the points.
        let corners = [glo[0], glo[1], glo[2], ghi[0], ghi[1], ghi[2]];
        let domain = Domain::from_points(&[&corners]).map_err(|source| DistError::Tree {
            rank: me as i32,
            source,
        })?;
        let n_local = (points.len() / 3) as u64;
        let mut counts = vec![0u64; size];
        comm.all_gather_into(&n_local, &mut counts[..]);
        let first_id: u64 = counts[..me].iter().sum();
        let total_w = weights.map_or(1.0, |w| w.iter().sum::<f64>());
        let mut all_w = 0.0;
        comm.all_reduce_into(&total_w, &mut all_w, SystemOperation::sum());
        if weights.is_some() && all_w <= 0.0 {
            return Err(DistError::BadInput {
                rank: 0,
                problem: InputProblem::BadWeights,
            });
        }
        t.stop(&mut stats, 0);

        // 2. Local sort (the tree crate's), then the sample sort.
        let t = Timer::start();
        let sorted = LocalPoints::sorted_local(points, weights, &domain, first_id);
        let (sorted, bytes) = sample_sort(comm, sorted);
        stats.bytes_sent[1] = bytes;
        t.stop(&mut stats, 1);

        // 3. Box-aligned cuts balanced by weight; move the points there.
        let t = Timer::start();
        let cuts = find_cuts(comm, &sorted, options.leaf_size, options.max_level);
        let (pts, bytes) = redistribute(comm, sorted, &cuts);
        stats.bytes_sent[2] = bytes;
        t.stop(&mut stats, 2);

        // 4. Local refinement below the coarsest boxes of the range, with
        // the coarse tree (boxes straddling cuts) as internal boxes.
        let t = Timer::start();
        let (lo, hi) = (cuts[me], cuts[me + 1]);
        let codes = MortonCodes::from_codes(domain, pts.codes.clone()).map_err(|source| {
            DistError::Tree {
                rank: me as i32,
                source,
            }
        })?;
        let mut shape = codes.refine_below(
            &covering_boxes(lo, hi),
            options.leaf_size,
            options.max_level,
        );
        let mut coarse: Vec<MortonKey> =
            cuts[1..size].iter().flat_map(|&c| straddling(c)).collect();
        coarse.sort_unstable();
        coarse.dedup();
        shape.insert_internal(&codes, &coarse);
        t.stop(&mut stats, 3);

        // 5. Distributed 2:1 balance.
        let t = Timer::start();
        let (rounds, bytes) = balance_distributed(comm, &mut shape, &codes, &cuts);
        stats.balance_rounds = rounds;
        stats.bytes_sent[4] = bytes;
        t.stop(&mut stats, 4);

        // 6. Ghosts.
        let t = Timer::start();
        let boxes = own_boxes(&shape, lo, hi);
        let (ghosts, bytes) = exchange_ghosts(comm, &boxes, &coarse, &cuts);
        stats.bytes_sent[5] = bytes;
        t.stop(&mut stats, 5);

        Ok(DistributedTree {
            domain,
            cuts,
            points: pts,
            boxes,
            coarse,
            ghosts,
            stats,
            input_counts: counts,
            shape,
            rank: me,
        })
    }

    /// This rank's number in the communicator the tree was built on.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// This rank's leaves (keys, sorted).
    pub fn leaves(&self) -> impl Iterator<Item = MortonKey> + '_ {
        self.boxes.iter().filter(|b| b.1).map(|b| b.0)
    }

    /// A work estimate per point of this rank, from the interaction lists,
    /// for [`DistributedTree::build_weighted`]: a leaf `B` with `n_B`
    /// points costs `n_B * sum(n_A, A in U(B))` pair interactions (P2P)
    /// plus `far_cost` for each entry of its V, W and X lists (any box's V
    /// and X entries likewise); a box's cost is spread evenly over its
    /// points, and a point sums the costs of its boxes. A crude model:
    /// `far_cost` is the cost
    /// of one far-field translation in pair interactions (of the order of
    /// the square of the number of equivalent points for dense M2L).
    pub fn work_weights(&self, far_cost: f64) -> Vec<f64> {
        let g = &self.ghosts;
        let (lo, hi) = (self.cuts[self.rank], self.cuts[self.rank + 1]);
        let count = |k: MortonKey| -> usize {
            if crate::ghosts::inside(k, lo, hi) {
                self.boxes
                    .binary_search_by_key(&k, |b| b.0)
                    .map_or(0, |i| self.boxes[i].2)
            } else {
                g.ghosts
                    .binary_search_by_key(&k, |x| x.key)
                    .map_or(0, |i| g.ghosts[i].points)
            }
        };
        let mut w = vec![0.0; self.points.len()];
        for (s, &key) in g.skeleton.iter().enumerate() {
            if !crate::ghosts::inside(key, lo, hi) {
                continue;
            }
            let n_b = count(key);
            if n_b == 0 {
                continue;
            }
            let near: usize = g.lists.u.get(s).iter().map(|&a| count(g.skeleton[a])).sum();
            let far = g.lists.v.get(s).len() + g.lists.w.get(s).len() + g.lists.x.get(s).len();
            let per_point = near as f64 + far_cost * far as f64 / n_b as f64;
            let r = key.morton_range();
            let first = self.points.codes.partition_point(|&c| c < r.start);
            let last = self.points.codes.partition_point(|&c| c < r.end);
            for x in &mut w[first..last] {
                *x += per_point;
            }
        }
        w
    }

    /// The rank's piece of the tree as built (its boxes, the coarse tree and
    /// the internal boxes received during the balance).
    pub fn shape(&self) -> &TreeShape {
        &self.shape
    }
}

/// Local checks of one rank's input.
fn validate(
    points: &[f64],
    weights: Option<&[f64]>,
    options: &DistOptions,
) -> Result<(), InputProblem> {
    if options.leaf_size == 0 {
        return Err(InputProblem::ZeroLeafSize);
    }
    if options.max_level > DEEPEST_LEVEL {
        return Err(InputProblem::Other);
    }
    if !points.len().is_multiple_of(3) {
        return Err(InputProblem::BadLength);
    }
    if !points.is_empty() {
        Domain::from_points(&[points]).map_err(|e| problem_of(&e))?;
    }
    if let Some(w) = weights
        && (w.len() != points.len() / 3 || w.iter().any(|&x| !(x.is_finite() && x >= 0.0)))
    {
        return Err(InputProblem::BadWeights);
    }
    Ok(())
}
