//! The distributed build, step by step (see the [crate docs](crate)).

use ferrofmm_tree::{DEEPEST_LEVEL, Domain, MortonCodes, MortonKey, TreeShape};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::balance::balance_distributed;
use crate::error::{DistError, InputProblem, agree, problem_of};
use crate::ghosts::{GhostLayer, SeparateTargets, exchange_ghosts, own_boxes};
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
    /// This rank's points, sorted along the Morton curve (the sources, in
    /// a tree built with separate targets).
    pub points: LocalPoints,
    /// This rank's boxes (inside its range): key, leaf flag, point
    /// (source) count, sorted by key.
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
    /// The targets, when the tree was built with targets that are not the
    /// points ([`DistributedTree::build_with_targets`]); `None`: the
    /// points are the targets.
    pub targets: Option<DistTargets>,
    shape: TreeShape,
    rank: usize,
}

/// This rank's targets in a tree built with separate targets.
#[derive(Clone, Debug, Default)]
pub struct DistTargets {
    /// The targets in this rank's range, sorted along the Morton curve, with
    /// global ids: the position of the target in the concatenation of all
    /// ranks' target inputs in rank order (weights are 1).
    pub points: LocalPoints,
    /// The number of targets every rank passed (rank order), as
    /// [`DistributedTree::input_counts`] for the points.
    pub input_counts: Vec<u64>,
}

/// The point sets of one rank's input (validated).
#[derive(Clone, Copy)]
struct Input<'a> {
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
    weights: Option<&'a [f64]>,
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
        let input = Input {
            sources: points,
            targets: None,
            weights,
        };
        Self::build_input(comm, input, options)
    }

    /// Builds the tree from each rank's `sources` and its `targets` (both
    /// interleaved `xyz`, any share, either possibly empty on a rank; the
    /// targets need not lie near the sources). A collective.
    ///
    /// The tree is the one [`Octree::new`](ferrofmm_tree::Octree::new)
    /// builds from all sources and all targets: the domain is the bounding
    /// cube of both, a box exists when it holds a source or a target, a box
    /// is split while `max(#sources, #targets) > leaf_size`, and the lists
    /// keep only entries holding sources in rows of boxes holding targets.
    /// The points are sorted and partitioned together (each counts 1 in the
    /// load balance), so a rank's range holds its sources
    /// ([`DistributedTree::points`], with `boxes` counting them) and its
    /// targets ([`DistributedTree::targets`]).
    ///
    /// # Errors
    /// As [`DistributedTree::build`] for the sources
    /// ([`DistError::NoPoints`]: no source on any rank), and
    /// [`InputProblem::BadTargetLength`] or
    /// [`InputProblem::NonFiniteTarget`] for bad targets on any rank, or
    /// [`DistError::NoTargets`] when no rank has a target: the same error
    /// on every rank.
    pub fn build_with_targets<C: Communicator>(
        comm: &C,
        sources: &[f64],
        targets: &[f64],
        options: &DistOptions,
    ) -> Result<Self, DistError> {
        let input = Input {
            sources,
            targets: Some(targets),
            weights: None,
        };
        Self::build_input(comm, input, options)
    }

    fn build_input<C: Communicator>(
        comm: &C,
        input: Input<'_>,
        options: &DistOptions,
    ) -> Result<Self, DistError> {
        let mut stats = BuildStats::default();
        let me = comm.rank() as usize;
        let size = comm.size() as usize;
        let t = Timer::start();
        let Input {
            sources: points,
            targets,
            weights,
        } = input;

        // 0. Validation, then the same options everywhere.
        agree(comm, validate(input, options))?;
        let mine = [
            options.leaf_size as u64,
            options.max_level as u64,
            u64::from(weights.is_some()),
            u64::from(targets.is_some()),
        ];
        let mut all_o = vec![0u64; mine.len() * size];
        comm.all_gather_into(&mine[..], &mut all_o[..]);
        if let Some(r) = all_o
            .chunks_exact(mine.len())
            .position(|o| o != &all_o[..mine.len()])
        {
            return Err(DistError::BadInput {
                rank: r as i32,
                problem: InputProblem::MismatchedOptions,
            });
        }

        // 1. Counts, global bounding box and domain.
        let counts = gather_counts(comm, points);
        let target_counts = targets.map(|t| gather_counts(comm, t));
        if counts.iter().sum::<u64>() == 0 {
            return Err(DistError::NoPoints);
        }
        let n_sources: u64 = counts.iter().sum();
        if target_counts
            .as_ref()
            .is_some_and(|c| c.iter().sum::<u64>() == 0)
        {
            return Err(DistError::NoTargets);
        }
        let domain = global_domain(comm, &[Some(points), targets])?;
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

        // 2. Local sort (the tree crate's), then the sample sort. Targets
        // travel with the sources, numbered after all of them.
        let t = Timer::start();
        let sorted = match (targets, &target_counts) {
            (Some(tp), Some(tc)) => {
                let n_src = points.len() / 3;
                let first_target = n_sources + tc[..me].iter().sum::<u64>();
                let both = [points, tp].concat();
                LocalPoints::sorted_local(&both, None, &domain, |i| match i < n_src {
                    true => first_id + i as u64,
                    false => first_target + (i - n_src) as u64,
                })
            }
            _ => LocalPoints::sorted_local(points, weights, &domain, |i| first_id + i as u64),
        };
        let (sorted, bytes) = sample_sort(comm, sorted);
        stats.bytes_sent[1] = bytes;
        t.stop(&mut stats, 1);

        // 3. Box-aligned cuts balanced by weight; move the points there.
        let t = Timer::start();
        let first_target = targets.map(|_| n_sources);
        let cuts = find_cuts(
            comm,
            &sorted,
            first_target,
            options.leaf_size,
            options.max_level,
        );
        let (pts, bytes) = redistribute(comm, sorted, &cuts);
        let (pts, tgt) = match first_target {
            Some(first) => {
                let (s, t) = pts.split_targets(first);
                (s, Some(t))
            }
            None => (pts, None),
        };
        stats.bytes_sent[2] = bytes;
        t.stop(&mut stats, 2);

        // 4. Local refinement below the coarsest boxes of the range, with
        // the coarse tree (boxes straddling cuts) as internal boxes.
        let t = Timer::start();
        let (lo, hi) = (cuts[me], cuts[me + 1]);
        let tgt_codes = tgt.as_ref().map(|t| t.codes.clone());
        let codes = MortonCodes::from_code_sets(domain, pts.codes.clone(), tgt_codes).map_err(
            |source| DistError::Tree {
                rank: me as i32,
                source,
            },
        )?;
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

        // 6. Ghosts (with targets, the lists pruned as on one machine: the
        // coarse boxes' source and target counts summed over the ranks).
        let t = Timer::start();
        let (boxes, box_targets) = own_boxes(&shape, lo, hi);
        let coarse_counts = match tgt {
            Some(_) => coarse_counts(comm, &codes, &coarse),
            None => Vec::new(),
        };
        let separate = tgt.as_ref().map(|_| SeparateTargets {
            own: &box_targets,
            coarse: &coarse_counts,
        });
        let (ghosts, bytes) = exchange_ghosts(comm, &boxes, &coarse, &cuts, separate);
        stats.bytes_sent[5] = bytes;
        t.stop(&mut stats, 5);
        let targets = tgt
            .zip(target_counts)
            .map(|(points, input_counts)| DistTargets {
                points,
                input_counts,
            });

        Ok(DistributedTree {
            domain,
            cuts,
            points: pts,
            boxes,
            coarse,
            ghosts,
            stats,
            input_counts: counts,
            targets,
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
fn validate(input: Input<'_>, options: &DistOptions) -> Result<(), InputProblem> {
    let Input {
        sources: points,
        targets,
        weights,
    } = input;
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
    if let Some(t) = targets {
        if !t.len().is_multiple_of(3) {
            return Err(InputProblem::BadTargetLength);
        }
        if t.iter().any(|x| !x.is_finite()) {
            return Err(InputProblem::NonFiniteTarget);
        }
    }
    if let Some(w) = weights
        && (w.len() != points.len() / 3 || w.iter().any(|&x| !(x.is_finite() && x >= 0.0)))
    {
        return Err(InputProblem::BadWeights);
    }
    Ok(())
}

/// The number of points (`xyz` triples of `points`) of every rank.
fn gather_counts<C: Communicator>(comm: &C, points: &[f64]) -> Vec<u64> {
    let mut counts = vec![0u64; comm.size() as usize];
    comm.all_gather_into(&((points.len() / 3) as u64), &mut counts[..]);
    counts
}

/// The bounding cube of the point sets of all ranks (validated, not all
/// empty): an `all_reduce` of the extremes, then the tree crate's cube of
/// the two corners (the cube depends only on the extremes, so it is that
/// of all the points, [`Domain::from_points`] on one machine).
fn global_domain<C: Communicator>(comm: &C, sets: &[Option<&[f64]>]) -> Result<Domain, DistError> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in sets.iter().flatten().flat_map(|s| s.chunks_exact(3)) {
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
    let corners = [glo[0], glo[1], glo[2], ghi[0], ghi[1], ghi[2]];
    Domain::from_points(&[&corners]).map_err(|source| DistError::Tree {
        rank: comm.rank(),
        source,
    })
}

/// The sources and targets of every coarse box, summed over the ranks
/// (one `all_reduce` of two counts a box): each rank counts the codes of
/// its range inside the box.
fn coarse_counts<C: Communicator>(
    comm: &C,
    codes: &MortonCodes,
    coarse: &[MortonKey],
) -> Vec<[u64; 2]> {
    let count = |c: &[u64], k: MortonKey| {
        let r = k.morton_range();
        (c.partition_point(|&x| x < r.end) - c.partition_point(|&x| x < r.start)) as u64
    };
    let local: Vec<u64> = coarse
        .iter()
        .flat_map(|&k| [count(codes.sources(), k), count(codes.targets(), k)])
        .collect();
    let mut global = vec![0u64; local.len()];
    comm.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
    global.chunks_exact(2).map(|c| [c[0], c[1]]).collect()
}
