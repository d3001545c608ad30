//! Splitting a point set into well-separated clusters: the roots of a forest.
//!
//! One octree over a set with a far outlier wastes its levels: with a point
//! `D` cloud-widths away, the cloud sits in one box of width
//! `D / 2^l` at level `l`, and below [`DEEPEST_LEVEL`](crate::DEEPEST_LEVEL)
//! the whole cloud may end up in one leaf (quadratic near field). Far apart
//! groups of points are better served by one tree each, coupled through
//! their roots' expansions.
//!
//! [`separated_clusters`] finds such groups in two steps.
//!
//! **Cutting.** Project a set on axis `a`; two consecutive groups of points
//! `A` and `B` with a gap `g` between them along `a` are cut apart when
//!
//! ```text
//! g >= ratio * max(d(A), d(B)),    d(G) = max(e_a(G), w(G) / (2 ratio), E_a / n),
//! ```
//!
//! where `e_a` is a group's extent along `a`, `w` its largest extent
//! over the three axes, and `E_a / n` the mean spacing of the `n` points
//! of the piece being cut (`E_a` its extent along `a`): groups far apart
//! for their size along the cut (the gain: levels of one tree that the
//! cloud would lose). The spacing floor keeps sparse sets whole: points
//! spread evenly or at random, each alone in a cell, are gaps of about the
//! mean spacing apart, and a tree serves them well (an outlier `D` away
//! from `n` points still comes off once `n >= ratio`). The floor
//! `w / (2 ratio)` keeps flat groups together: the planes of a lattice
//! have no extent along their normal but are not far apart; a cloud that
//! still holds an outlier along another axis, `D2` away, lets one along
//! `a`, `D1` away, come off when `D1 >= D2 / 2` (and the farther one comes
//! off first otherwise). Only neighbours are tested, so outliers on opposite sides come
//! off together, and those along other axes come off when their piece is
//! examined again. Growing a group only makes a cut harder, so the cuts
//! that hold form a unique largest set: scan the groups along the axis with
//! a stack, merging the top with the group below while their cut fails.
//! The groups start as the runs of occupied cells of a histogram of
//! `B = 256` cells along the axis (one linear pass, no sort), so gaps
//! narrower than `2 e_a / B` are not seen at this step; each piece is
//! examined again, along every axis and at its own finer resolution,
//! until none splits.
//!
//! **Checking.** Root expansions couple two clusters accurately only when
//! they are far apart in all three dimensions: their bounding boxes must be
//! apart along some axis by at least `s * max(w(A), w(B))`, with `w` the
//! largest extent over the three axes and `s = min(ratio, 4)` (box centres
//! at least five widths apart, against two for a V-list pair of the tree).
//! Clusters that fail this against each other are merged until every pair
//! passes (a dense lattice, whose planes the cutting separates, comes back
//! together here).
//!
//! **Limits.** The clusters are coupled pair by pair, each through its
//! points or, when it has more, its root's expansion surfaces: about
//! `(sum_i min(n_i, 512))^2` point pairs. A split that needs more than
//! [`MAX_COUPLING_WORK`], or cutting that makes more than [`MAX_PIECES`]
//! pieces (contrived sets: thousands of far groups, points spread
//! geometrically along all three axes), is not made: the set is returned
//! as one cluster and gets one tree.
//!
//! What is not split: a chain of points whose spacings grow geometrically
//! by less than `ratio` per step (1, 100, 10^4, ...) has no valid gap; such
//! a set still gets one tree, as deep as its extent demands.
//!
//! The modules: `cutting` (the histogram, the stack scan, the best axis),
//! `checking` (the 3D separation test and the merging); both measure with
//! the bounding boxes of `crate::bounds`.

mod checking;
mod cutting;

use checking::{coupling_work, merge_close};
use cutting::split_once;

/// The separation ratio used by the FMM driver: a group is cut off when
/// its gap to its neighbour is at least 16 times the larger one's size
/// along the cut. A gap below this costs one tree at most `log2(16) = 4`
/// levels; a larger ratio would leave outliers at mixed distances (1e6 on
/// one side, 1e7 on another with a point between) in the cloud's tree.
pub const DEFAULT_SEPARATION: f64 = 16.0;

/// Most pieces the cutting may produce before [`separated_clusters`] gives
/// up and returns the set whole (see the [module documentation](self)).
pub const MAX_PIECES: usize = 4096;

/// Most coupling work (point-pair interactions, see the [module
/// documentation](self)) that the returned clusters may need; a split that
/// needs more is not made.
pub const MAX_COUPLING_WORK: f64 = 2.5e8;

/// The separation, in units of the wider cluster's width, that every pair
/// of returned clusters keeps in all three dimensions (at most `ratio`).
const COUPLING_SEPARATION: f64 = 4.0;

/// One well-separated group: indices into the caller's sources and targets,
/// ascending.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Cluster {
    /// Indices of the sources in this group.
    pub sources: Vec<usize>,
    /// Indices of the targets in this group (equal to `sources` when the
    /// targets are the sources).
    pub targets: Vec<usize>,
}

impl Cluster {
    /// `max(#sources, #targets)`: the size that decides how it is treated.
    pub fn size(&self) -> usize {
        self.sources.len().max(self.targets.len())
    }
}

/// Splits `sources` (and `targets`, `None` meaning the targets are the
/// sources) into clusters separated by gaps of at least `ratio` times the
/// wider side (see the [module documentation](self)). The result is in a
/// deterministic order (by each cluster's first point); a set without such
/// gaps gives one cluster holding everything.
///
/// Coordinates must be finite (validate first; non-finite coordinates are
/// never split off). `ratio` below 1 is treated as 1.
///
/// ```
/// use ferrofmm_tree::clusters::separated_clusters;
/// // A unit cloud and one point a million units away.
/// let mut pts: Vec<f64> = (0..100).flat_map(|i| {
///     let t = i as f64 / 100.0;
///     [t, (3.0 * t) % 1.0, (7.0 * t) % 1.0]
/// }).collect();
/// pts.extend([1e6, 1e6, 1e6]);
/// let c = separated_clusters(&pts, None, ferrofmm_tree::DEFAULT_SEPARATION);
/// assert_eq!(c.len(), 2);
/// assert_eq!(c[0].sources.len(), 100);
/// assert_eq!(c[1].sources, vec![100]);
/// ```
pub fn separated_clusters(sources: &[f64], targets: Option<&[f64]>, ratio: f64) -> Vec<Cluster> {
    let ratio = ratio.max(1.0);
    let n_src = sources.len() / 3;
    let n_tgt = targets.map_or(0, |t| t.len() / 3);
    let point = |i: usize| -> [f64; 3] {
        let (p, k) = if i < n_src {
            (sources, i)
        } else {
            (targets.unwrap_or(sources), i - n_src)
        };
        [p[3 * k], p[3 * k + 1], p[3 * k + 2]]
    };
    let all: Vec<usize> = (0..n_src + n_tgt).collect();
    let mut done: Vec<Vec<usize>> = Vec::new();
    let mut stack = vec![all];
    while let Some(set) = stack.pop() {
        match split_once(&set, &point, ratio) {
            Some(pieces) => stack.extend(pieces),
            None => done.push(set),
        }
        if done.len() + stack.len() > MAX_PIECES {
            return vec![whole(n_src, n_tgt, targets.is_some())];
        }
    }
    let done = merge_close(done, &point, ratio.min(COUPLING_SEPARATION));
    if done.len() > 1 && coupling_work(&done) > MAX_COUPLING_WORK {
        return vec![whole(n_src, n_tgt, targets.is_some())];
    }
    let mut clusters: Vec<Cluster> = done
        .into_iter()
        .filter_map(|mut items| {
            items.sort_unstable();
            let split = items.partition_point(|&i| i < n_src);
            let sources = items[..split].to_vec();
            let targets = match targets {
                Some(_) => items[split..].iter().map(|&i| i - n_src).collect(),
                None => sources.clone(),
            };
            (!sources.is_empty() || !targets.is_empty()).then_some(Cluster { sources, targets })
        })
        .collect();
    clusters.sort_by_key(|c| {
        let s = c.sources.first().copied().unwrap_or(usize::MAX);
        let t = c.targets.first().copied().unwrap_or(usize::MAX);
        (s, t)
    });
    clusters
}

/// One cluster holding every source and target.
fn whole(n_src: usize, n_tgt: usize, separate_targets: bool) -> Cluster {
    let sources: Vec<usize> = (0..n_src).collect();
    let targets = if separate_targets {
        (0..n_tgt).collect()
    } else {
        sources.clone()
    };
    Cluster { sources, targets }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bounds::{Bounds, bounds};
    use checking::separated;

    fn cloud(n: usize, offset: [f64; 3], size: f64, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .flat_map(|_| std::array::from_fn::<f64, 3, _>(|a| offset[a] + size * next()))
            .collect()
    }

    #[test]
    fn a_compact_cloud_stays_whole() {
        let p = cloud(5000, [0.0; 3], 1.0, 1);
        let c = separated_clusters(&p, None, DEFAULT_SEPARATION);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].sources, (0..5000).collect::<Vec<_>>());
        assert_eq!(c[0].targets, c[0].sources);
    }

    #[test]
    fn outliers_on_several_sides_split_off() {
        let mut p = cloud(3000, [0.0; 3], 1.0, 2);
        for o in [
            [1e6, 0.5, 0.5],
            [-1e9, 0.2, 0.1],
            [0.5, 1e12, 0.5],
            [0.1, 0.1, -1e15],
        ] {
            p.extend(o);
        }
        let c = separated_clusters(&p, None, DEFAULT_SEPARATION);
        assert_eq!(c.len(), 5);
        assert_eq!(c[0].sources.len(), 3000);
        let singles: Vec<usize> = c[1..].iter().map(|c| c.sources[0]).collect();
        assert_eq!(singles, vec![3000, 3001, 3002, 3003]);
    }

    #[test]
    fn two_far_clouds_and_separate_targets() {
        let s = [cloud(400, [0.0; 3], 1.0, 3), cloud(600, [1e8; 3], 2.0, 4)].concat();
        let t = [cloud(50, [1e8; 3], 2.0, 5), cloud(70, [0.0; 3], 1.0, 6)].concat();
        let c = separated_clusters(&s, Some(&t), DEFAULT_SEPARATION);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].sources, (0..400).collect::<Vec<_>>());
        assert_eq!(c[0].targets, (50..120).collect::<Vec<_>>());
        assert_eq!(c[1].sources, (400..1000).collect::<Vec<_>>());
        assert_eq!(c[1].targets, (0..50).collect::<Vec<_>>());
    }

    fn boxes_of(c: &[Cluster], p: &[f64]) -> Vec<Bounds> {
        c.iter()
            .map(|c| bounds(&c.sources, &|i| [p[3 * i], p[3 * i + 1], p[3 * i + 2]]))
            .collect()
    }

    /// A gap is cut when it is `ratio` times the sides' extents along its
    /// axis, and every two clusters end up four widths apart in 3D.
    #[test]
    fn clusters_are_separated_by_the_ratio() {
        let ratio = 16.0;
        let mut p = cloud(500, [0.0; 3], 1.0, 7);
        p.extend(cloud(200, [0.0, 1.5, 0.0], 1.0, 9)); // y gap 0.5: stays
        p.extend(cloud(300, [60.0, 0.0, 0.0], 1.0, 8)); // x gap 59 >= 16 x 1
        p.extend(cloud(100, [1.0, 0.0, -38.0], 1.0, 10)); // z gap 37 >= 16 x 1
        p.extend(cloud(50, [0.5, -6.0, 0.5], 1.0, 11)); // y gap 5 < 16: stays
        let c = separated_clusters(&p, None, ratio);
        let sizes: Vec<usize> = c.iter().map(|c| c.sources.len()).collect();
        assert_eq!(sizes, vec![750, 300, 100]);
        assert_eq!(c[1].sources, (700..1000).collect::<Vec<_>>());
        let boxes = boxes_of(&c, &p);
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                assert!(separated(&boxes[i], &boxes[j], COUPLING_SEPARATION));
            }
        }
    }

    /// A small cloud below a long thin one: the cut along z is valid (the
    /// slab is thin in z) but the two are not apart in 3D, so they merge.
    #[test]
    fn clusters_too_close_in_3d_merge() {
        let mut p: Vec<f64> = (0..400)
            .flat_map(|i| [i as f64 / 4.0, (i % 7) as f64 * 0.01, (i % 5) as f64 * 0.02])
            .collect();
        p.extend(cloud(100, [50.0, 0.0, -20.0], 1.0, 12));
        assert_eq!(separated_clusters(&p, None, 16.0).len(), 1);
        // Far enough in 3D (gap 500 >= 4 x 100): two.
        let n = p.len();
        for z in p[3 * 400..].iter_mut().skip(2).step_by(3) {
            *z -= 480.0;
        }
        assert_eq!(p.len(), n);
        assert_eq!(separated_clusters(&p, None, 16.0).len(), 2);
    }

    /// Far clouds on a geometric grid: 2 x 2 x 2 of them split into eight
    /// clusters; 4 x 4 x 4 would need more coupling work than allowed and
    /// come back as one.
    #[test]
    fn coupling_work_limits_the_split() {
        let grid = |k: i32| -> Vec<f64> {
            let mut p = Vec::new();
            for i in 0..k {
                for j in 0..k {
                    for l in 0..k {
                        let at = [1e4f64.powi(i), 1e4f64.powi(j), 1e4f64.powi(l)];
                        p.extend(cloud(300, at, 1.0, (i * 16 + j * 4 + l) as u64));
                    }
                }
            }
            p
        };
        let c = separated_clusters(&grid(2), None, DEFAULT_SEPARATION);
        assert_eq!(c.len(), 8);
        assert!(c.iter().all(|c| c.sources.len() == 300));
        assert!((64.0 * 300.0f64).powi(2) > MAX_COUPLING_WORK);
        let c = separated_clusters(&grid(4), None, DEFAULT_SEPARATION);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].sources.len(), 64 * 300);
    }

    /// A regular lattice has no far groups: its planes are too close for
    /// their width.
    /// Points each alone in a histogram cell (evenly spaced on a line or a
    /// curve, or a coarse grid) are not singled out: their gaps are about
    /// the mean spacing. One of them moved far away still comes off.
    #[test]
    fn evenly_spaced_points_stay_whole() {
        for n in [20, 100, 1000, 5000] {
            let line: Vec<f64> = (0..n)
                .flat_map(|i| {
                    let t = i as f64 / n as f64;
                    [t, (3.0 * t) % 1.0, (7.0 * t) % 1.0]
                })
                .collect();
            assert_eq!(
                separated_clusters(&line, None, DEFAULT_SEPARATION).len(),
                1,
                "n = {n}"
            );
            let mut far = line.clone();
            far[3 * n - 3..].copy_from_slice(&[1e6; 3]);
            let c = separated_clusters(&far, None, DEFAULT_SEPARATION);
            assert_eq!(c.len(), 2, "n = {n}");
            assert_eq!(c[1].sources, vec![n - 1]);
        }
        let grid: Vec<f64> = (0..512)
            .flat_map(|i| [(i % 8) as f64, ((i / 8) % 8) as f64, (i / 64) as f64].map(|x| 1e3 * x))
            .collect();
        assert_eq!(separated_clusters(&grid, None, DEFAULT_SEPARATION).len(), 1);
    }

    #[test]
    fn a_lattice_stays_whole() {
        for k in [4usize, 5, 12, 20] {
            let p: Vec<f64> = (0..k * k * k)
                .flat_map(|i| [(i % k) as f64, ((i / k) % k) as f64, (i / (k * k)) as f64])
                .collect();
            assert_eq!(
                separated_clusters(&p, None, DEFAULT_SEPARATION).len(),
                1,
                "k = {k}"
            );
        }
    }

    /// A sparse random cloud does not shatter into its points.
    #[test]
    fn a_sparse_cloud_stays_whole() {
        for n in [20, 100, 700] {
            let p = cloud(n, [0.0; 3], 1.0, n as u64);
            for ratio in [4.0, DEFAULT_SEPARATION, 256.0] {
                assert_eq!(separated_clusters(&p, None, ratio).len(), 1, "n = {n}");
            }
        }
    }

    /// Any two clusters are apart in 3D by `min(ratio, 4)` times the wider,
    /// for random clouds and outliers at random scales.
    #[test]
    fn every_pair_is_separated() {
        let mut s = 99u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for trial in 0..30 {
            let mut p = cloud(300 + 50 * trial, [0.0; 3], 1.0, trial as u64);
            for _ in 0..(trial % 7) {
                let scale = 10f64.powf(1.0 + 14.0 * next());
                let size = if next() < 0.5 {
                    0.0
                } else {
                    scale * 1e-3 * next()
                };
                let at = [0, 1, 2].map(|_| scale * (2.0 * next() - 1.0));
                p.extend(cloud(
                    1 + (next() * 40.0) as usize,
                    at,
                    size,
                    trial as u64 + 7,
                ));
            }
            let ratio = [4.0, DEFAULT_SEPARATION, 256.0][trial % 3];
            let c = separated_clusters(&p, None, ratio);
            let mut seen: Vec<usize> = c.iter().flat_map(|c| c.sources.clone()).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..p.len() / 3).collect::<Vec<_>>());
            let boxes = boxes_of(&c, &p);
            for i in 0..boxes.len() {
                for j in i + 1..boxes.len() {
                    assert!(separated(
                        &boxes[i],
                        &boxes[j],
                        ratio.min(COUPLING_SEPARATION)
                    ));
                }
            }
        }
    }

    #[test]
    fn coincident_and_tiny_sets() {
        assert!(separated_clusters(&[], None, 256.0).is_empty());
        let one = separated_clusters(&[1.0, 2.0, 3.0], None, 256.0);
        assert_eq!(one.len(), 1);
        let same = separated_clusters(&[1.0, 2.0, 3.0, 1.0, 2.0, 3.0], None, 256.0);
        assert_eq!(same.len(), 1);
        let two = separated_clusters(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], None, 256.0);
        // Two points: each side is as wide as the mean spacing (the gap), so
        // no ratio above 1 separates them; one tree serves them.
        assert_eq!(two.len(), 1);
    }
}
