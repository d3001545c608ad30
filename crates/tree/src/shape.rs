//! The shape of an adaptive tree without the tree: which boxes exist, how
//! many points each holds, and which are leaves, for any leaf size, at a
//! fraction of the cost of [`Octree::new`](crate::Octree::new).
//!
//! An [`Octree`](crate::Octree) sorts the points (coordinates and the
//! permutation), refines, balances, numbers the boxes and builds the
//! interaction lists. Choosing a leaf size needs only the second and third
//! steps, repeated for several sizes. [`MortonCodes`] holds the sorted
//! finest-level Morton codes of the sources and targets (one sort, no
//! coordinates); [`MortonCodes::refine`] runs the **same** top-down
//! refinement as the tree builder on them and [`TreeShape::balance`] the
//! **same** 2:1 balance ([`balance`](crate::balance)), so a shape has exactly
//! the boxes, point counts and leaves of the octree built from the same
//! points, domain, leaf size and deepest level.
//!
//! A box of level `l` covers the codes `m .. m + 8^(D - l)` (`D` =
//! [`DEEPEST_LEVEL`]), so its points are one range of
//! the sorted codes, found by binary search: refining a box costs
//! `O(log n)` per child, independent of how many points it holds.
//!
//! ```
//! use ferrofmm_tree::{Domain, MortonCodes, Octree, TreeOptions};
//! let pts: Vec<f64> = (0..5000)
//!     .flat_map(|i| {
//!         let t = i as f64 * 0.618;
//!         [t.fract(), (3.7 * t).fract(), (7.1 * t).fract()]
//!     })
//!     .collect();
//! let domain = Domain::from_points(&[&pts]).unwrap();
//! let codes = MortonCodes::new(&pts, None, domain).unwrap();
//! let mut shape = codes.refine(40, ferrofmm_tree::DEEPEST_LEVEL);
//! shape.balance(&codes);
//! let tree = Octree::new(&pts, None, &TreeOptions::adaptive(40)).unwrap();
//! assert_eq!(shape.n_boxes(), tree.n_boxes());
//! assert_eq!(shape.n_leaves(), tree.leaves().len());
//! ```

use rayon::prelude::*;

use crate::balance::balance;
use crate::build::{Node, PointKeys, Refinement, refine, refine_from, sort_points};
use crate::domain::{Domain, check_inside, validate_points, validate_sets};
use crate::error::{PointSet, TreeError};
use crate::morton::{DEEPEST_LEVEL, MortonKey};

/// Sorts interleaved `xyz` points along the Morton curve of `domain` with
/// the tree builder's own sort (see [`Octree::new`](crate::Octree::new)):
/// returns the finest-level codes, ascending, and the permutation (`perm[k]`
/// is the index of the point at sorted position `k`; ties keep index order).
///
/// # Errors
/// A length that is not a multiple of 3, a NaN or infinite coordinate, a
/// point outside `domain` (empty input is allowed).
///
/// ```
/// use ferrofmm_tree::{Domain, shape::morton_order};
/// let d = Domain::new([0.0; 3], 1.0).unwrap();
/// let (codes, perm) = morton_order(&[0.9, 0.9, 0.9, 0.1, 0.1, 0.1], &d).unwrap();
/// assert_eq!(perm, [1, 0]);
/// assert!(codes[0] < codes[1]);
/// ```
pub fn morton_order(points: &[f64], domain: &Domain) -> Result<(Vec<u64>, Vec<usize>), TreeError> {
    validate_points(PointSet::Sources, points)?;
    check_inside(PointSet::Sources, points, domain)?;
    let sorted = sort_points(points, domain);
    Ok((sorted.keys, sorted.perm))
}

/// One box of a [`TreeShape`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShapeBox {
    /// The box.
    pub key: MortonKey,
    /// Its sources: a range of [`MortonCodes::sources`].
    pub sources: [usize; 2],
    /// Its targets: a range of [`MortonCodes::targets`].
    pub targets: [usize; 2],
    /// Whether it is a leaf.
    pub leaf: bool,
}

impl ShapeBox {
    /// Number of sources in the box.
    pub fn n_sources(&self) -> usize {
        self.sources[1] - self.sources[0]
    }

    /// Number of targets in the box.
    pub fn n_targets(&self) -> usize {
        self.targets[1] - self.targets[0]
    }
}

/// The sorted finest-level Morton codes of the sources and (when they are
/// another set) the targets in a domain: what [`MortonCodes::refine`] needs.
pub struct MortonCodes {
    domain: Domain,
    sources: Vec<u64>,
    targets: Option<Vec<u64>>,
}

impl MortonCodes {
    /// Codes of interleaved `xyz` points (`targets` `None` when they are the
    /// sources), sorted, in `domain`.
    ///
    /// # Errors
    /// As [`Octree::new`](crate::Octree::new): a length that is not a
    /// multiple of 3, a NaN or infinite coordinate, no sources or no
    /// targets, a point outside `domain`.
    pub fn new(
        sources: &[f64],
        targets: Option<&[f64]>,
        domain: Domain,
    ) -> Result<Self, TreeError> {
        for (set, p) in validate_sets(sources, targets)? {
            check_inside(set, p, &domain)?;
        }
        let codes = |p: &[f64]| {
            let mut c: Vec<u64> = p
                .par_chunks_exact(3)
                .map(|x| domain.finest_morton([x[0], x[1], x[2]]))
                .collect();
            c.par_sort_unstable();
            c
        };
        let (sources, targets) = rayon::join(|| codes(sources), || targets.map(codes));
        Ok(MortonCodes {
            domain,
            sources,
            targets,
        })
    }

    /// Codes already computed (for instance received from other processes)
    /// as the sources, the targets being the sources. They are sorted here
    /// (linear time when they already are).
    ///
    /// # Errors
    /// [`TreeError::InvalidCode`] for a code `>= 8^D` (`D` =
    /// [`DEEPEST_LEVEL`]), which no box holds.
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, MortonCodes};
    /// let d = Domain::new([0.0; 3], 1.0).unwrap();
    /// let codes = MortonCodes::from_codes(d, vec![7, 3, 3]).unwrap();
    /// assert_eq!(codes.sources(), &[3, 3, 7]);
    /// assert!(MortonCodes::from_codes(d, vec![u64::MAX]).is_err());
    /// ```
    pub fn from_codes(domain: Domain, codes: Vec<u64>) -> Result<Self, TreeError> {
        Self::from_code_sets(domain, codes, None)
    }

    /// As [`MortonCodes::from_codes`] with the codes of the sources and,
    /// when they are another set, of the targets (either may be empty: a
    /// process of a distributed build may hold no source or no target).
    /// The refinement then splits a box while `max(#sources, #targets)`
    /// exceeds the leaf size, as [`Octree::new`](crate::Octree::new) with
    /// targets does.
    ///
    /// # Errors
    /// [`TreeError::InvalidCode`] for a code `>= 8^D` in either set (the
    /// index counts the sources first, then the targets).
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, MortonCodes};
    /// let d = Domain::new([0.0; 3], 1.0).unwrap();
    /// let codes = MortonCodes::from_code_sets(d, vec![7, 3], Some(vec![5])).unwrap();
    /// assert_eq!((codes.sources(), codes.targets()), (&[3, 7][..], &[5][..]));
    /// let none = MortonCodes::from_code_sets(d, Vec::new(), Some(vec![2])).unwrap();
    /// assert_eq!(none.n_sources(), 0);
    /// ```
    pub fn from_code_sets(
        domain: Domain,
        mut sources: Vec<u64>,
        mut targets: Option<Vec<u64>>,
    ) -> Result<Self, TreeError> {
        let limit = MortonKey::ROOT.morton_range().end;
        let all = sources.iter().chain(targets.iter().flatten());
        if let Some((index, &code)) = all.enumerate().find(|&(_, &c)| c >= limit) {
            return Err(TreeError::InvalidCode { index, code });
        }
        sources.par_sort_unstable();
        if let Some(t) = targets.as_mut() {
            t.par_sort_unstable();
        }
        Ok(MortonCodes {
            domain,
            sources,
            targets,
        })
    }

    /// The domain of the codes.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// Sorted codes of the sources.
    pub fn sources(&self) -> &[u64] {
        &self.sources
    }

    /// Sorted codes of the targets (the sources' when they are one set).
    pub fn targets(&self) -> &[u64] {
        self.targets.as_deref().unwrap_or(&self.sources)
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.sources.len()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.targets().len()
    }

    fn keys(&self) -> PointKeys<'_> {
        PointKeys {
            src: &self.sources,
            tgt: self.targets(),
            same: self.targets.is_none(),
        }
    }

    /// The adaptive refinement of [`Octree::new`](crate::Octree::new): a box
    /// is split while `max(#sources, #targets) > leaf_size` and its level is
    /// below `max_level`; only non-empty children exist. Not yet balanced
    /// (see [`TreeShape::balance`]).
    pub fn refine(&self, leaf_size: usize, max_level: u32) -> TreeShape {
        let rule = Refinement::Adaptive {
            leaf_size: leaf_size.max(1),
            max_level: max_level.min(crate::DEEPEST_LEVEL),
        };
        TreeShape {
            levels: refine(&self.keys(), rule),
        }
    }
}

impl MortonCodes {
    /// The adaptive refinement (as [`MortonCodes::refine`]) of the subtrees
    /// rooted at `roots` only, with the codes inside each root; the strict
    /// ancestors of the roots are added as internal boxes (holding the codes
    /// of this set inside them). Roots holding no code are left out.
    ///
    /// `roots` must be disjoint (none contains another). This is the piece
    /// of a larger tree held by one process of a distributed build: when
    /// every strict ancestor of a root is split in the refinement of all the
    /// points and each root holds all its points here, the boxes at or below
    /// the roots are exactly those of [`MortonCodes::refine`] on all the
    /// points, because refining a box looks only at its own points.
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, MortonCodes, MortonKey, DEEPEST_LEVEL};
    /// let d = Domain::new([0.0; 3], 1.0).unwrap();
    /// let pts: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.618_034).fract()).collect();
    /// let codes = MortonCodes::new(&pts, None, d).unwrap();
    /// let whole = codes.refine(10, DEEPEST_LEVEL);
    /// let roots = MortonKey::ROOT.children();
    /// let part = codes.refine_below(&roots, 10, DEEPEST_LEVEL);
    /// assert_eq!(part.n_boxes(), whole.n_boxes());
    /// ```
    pub fn refine_below(&self, roots: &[MortonKey], leaf_size: usize, max_level: u32) -> TreeShape {
        let rule = Refinement::Adaptive {
            leaf_size: leaf_size.max(1),
            max_level: max_level.min(DEEPEST_LEVEL),
        };
        let nodes: Vec<Node> = roots
            .iter()
            .map(|&key| self.node(key, true))
            .filter(|n| n.src[0] < n.src[1] || n.tgt[0] < n.tgt[1])
            .collect();
        let ancestors: Vec<MortonKey> = nodes
            .iter()
            .filter(|n| n.key.level() > 0)
            .map(|n| n.key.parent())
            .collect();
        let mut shape = TreeShape {
            levels: refine_from(&self.keys(), rule, nodes),
        };
        shape.insert_internal(self, &ancestors);
        shape
    }

    /// The box `key` with the ranges of the codes inside it.
    fn node(&self, key: MortonKey, leaf: bool) -> Node {
        let r = key.morton_range();
        let range = |c: &[u64]| {
            let lo = c.partition_point(|&x| x < r.start);
            [lo, lo + c[lo..].partition_point(|&x| x < r.end)]
        };
        Node {
            key,
            src: range(&self.sources),
            tgt: range(self.targets()),
            leaf,
        }
    }
}

/// The boxes of an adaptive tree, level by level in Morton order (see the
/// [module docs](self)).
#[derive(Clone, Debug)]
pub struct TreeShape {
    levels: Vec<Vec<Node>>,
}

impl TreeShape {
    /// 2:1-balance the shape with the tree builder's algorithm
    /// ([`balance`](crate::balance)); `codes` must be the ones it was
    /// refined from.
    pub fn balance(&mut self, codes: &MortonCodes) {
        balance(&mut self.levels, &codes.keys(), [false; 3]);
    }

    /// Adds `keys` and all their ancestors as **internal** boxes, where a
    /// box of that key does not exist yet (existing boxes are unchanged),
    /// each holding the codes of `codes` inside it (none, for a box held by
    /// another process).
    ///
    /// These are boxes known to be split in a larger tree of which this
    /// shape is a piece (in a distributed build: boxes of other processes).
    /// [`TreeShape::balance`] then splits the leaves of this shape that are
    /// adjacent to them as the balance of the whole tree would, and never
    /// splits them. Empty levels are appended so that the balance sees two
    /// levels below every inserted box.
    pub fn insert_internal(&mut self, codes: &MortonCodes, keys: &[MortonKey]) {
        let mut new: Vec<MortonKey> = Vec::new();
        for &key in keys {
            let mut k = key;
            loop {
                if self.find(k).is_some() {
                    break;
                }
                new.push(k);
                if k.level() == 0 {
                    break;
                }
                k = k.parent();
            }
        }
        new.sort_unstable();
        new.dedup();
        let deepest = keys.iter().map(|k| k.level() as usize).max();
        if let Some(d) = deepest {
            while self.levels.len() < d + 2 {
                self.levels.push(Vec::new());
            }
        }
        let mut touched = vec![false; self.levels.len()];
        for key in new {
            let l = key.level() as usize;
            self.levels[l].push(codes.node(key, false));
            touched[l] = true;
        }
        for (lv, t) in self.levels.iter_mut().zip(touched) {
            if t {
                lv.sort_unstable_by_key(|n| n.key);
            }
        }
    }

    /// Number of levels (the depth plus one).
    pub fn n_levels(&self) -> usize {
        self.levels.len()
    }

    /// Boxes on each level.
    pub fn boxes_per_level(&self) -> Vec<usize> {
        self.levels.iter().map(Vec::len).collect()
    }

    /// Total number of boxes.
    pub fn n_boxes(&self) -> usize {
        self.levels.iter().map(Vec::len).sum()
    }

    /// Number of leaves.
    pub fn n_leaves(&self) -> usize {
        self.levels.iter().flatten().filter(|n| n.leaf).count()
    }

    /// Number of boxes of `level` (0 beyond the deepest level).
    pub fn level_len(&self, level: usize) -> usize {
        self.levels.get(level).map_or(0, Vec::len)
    }

    /// Box `i` of `level`.
    ///
    /// # Panics
    /// When there is no such box.
    pub fn get(&self, level: usize, i: usize) -> ShapeBox {
        let n = &self.levels[level][i];
        ShapeBox {
            key: n.key,
            sources: n.src,
            targets: n.tgt,
            leaf: n.leaf,
        }
    }

    /// The boxes of `level`, in Morton order.
    pub fn level(&self, level: usize) -> impl ExactSizeIterator<Item = ShapeBox> + '_ {
        (0..self.level_len(level)).map(move |i| self.get(level, i))
    }

    /// Index of `key` among the boxes of its level, if it exists (binary
    /// search).
    pub fn find(&self, key: MortonKey) -> Option<usize> {
        self.levels
            .get(key.level() as usize)?
            .binary_search_by_key(&key, |n| n.key)
            .ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Octree, TreeOptions};

    fn clustered(n: usize) -> Vec<f64> {
        (0..n)
            .flat_map(|i| {
                let t = i as f64 * 0.618_034;
                let s = if i % 3 == 0 { 1.0 } else { 1e-3 };
                [s * t.fract(), s * (3.7 * t).fract(), s * (7.1 * t).fract()]
            })
            .collect()
    }

    #[test]
    fn shape_equals_the_octree() {
        let src = clustered(6000);
        let tgt: Vec<f64> = clustered(2500).iter().map(|x| 0.9 * x + 0.05).collect();
        for targets in [None, Some(&tgt[..])] {
            let mut sets: Vec<&[f64]> = vec![&src];
            sets.extend(targets);
            let domain = Domain::from_points(&sets).unwrap();
            let codes = MortonCodes::new(&src, targets, domain).unwrap();
            for leaf in [8, 40, 300] {
                let mut shape = codes.refine(leaf, crate::DEEPEST_LEVEL);
                shape.balance(&codes);
                let tree = Octree::new(&src, targets, &TreeOptions::adaptive(leaf)).unwrap();
                assert_eq!(shape.n_boxes(), tree.n_boxes());
                for b in 0..tree.n_boxes() {
                    let key = tree.key(b);
                    let i = shape.find(key).expect("box of the tree in the shape");
                    let s = shape.get(key.level() as usize, i);
                    assert_eq!(s.leaf, tree.is_leaf(b), "{key:?}");
                    assert_eq!(s.n_sources(), tree.source_range(b).len());
                    assert_eq!(s.n_targets(), tree.target_range(b).len());
                }
            }
        }
    }

    #[test]
    fn bad_points_are_errors() {
        let domain = Domain::from_points(&[&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]]).unwrap();
        assert!(MortonCodes::new(&[0.0, f64::NAN, 0.0], None, domain).is_err());
        assert!(MortonCodes::new(&[0.0, 0.0], None, domain).is_err());
        assert!(MortonCodes::new(&[], None, domain).is_err());
        assert!(MortonCodes::new(&[5.0, 0.0, 0.0], None, domain).is_err());
        assert!(MortonCodes::new(&[0.5; 3], Some(&[]), domain).is_err());
    }

    /// Two halves of the code range, each refined below its own maximal
    /// boxes and balanced with the other half's internal boxes inserted,
    /// until neither changes: together the balanced shape of all the codes.
    #[test]
    fn pieces_balanced_with_foreign_internal_boxes_equal_the_whole() {
        let pts = clustered(8000);
        let domain = Domain::from_points(&[&pts]).unwrap();
        let all = MortonCodes::new(&pts, None, domain).unwrap();
        for leaf in [5, 40] {
            let mut whole = all.refine(leaf, crate::DEEPEST_LEVEL);
            whole.balance(&all);
            // Cut at the start of the leaf holding the median code.
            let mid = all.sources()[all.n_sources() / 2];
            let unbalanced = all.refine(leaf, crate::DEEPEST_LEVEL);
            let cut = (0..unbalanced.n_levels())
                .flat_map(|l| unbalanced.level(l))
                .find(|b| b.leaf && b.key.morton_range().contains(&mid))
                .unwrap()
                .key
                .morton();
            let roots = |lo: u64, hi: u64| -> Vec<MortonKey> {
                let mut out = Vec::new();
                let mut c = lo;
                while c < hi {
                    let mut l = 0;
                    loop {
                        let k = MortonKey::from_morton(c, l);
                        let r = k.morton_range();
                        if r.start == c && r.end <= hi {
                            out.push(k);
                            c = r.end;
                            break;
                        }
                        l += 1;
                    }
                }
                out
            };
            let end = MortonKey::ROOT.morton_range().end;
            let pieces: Vec<MortonCodes> = [(0, cut), (cut, end)]
                .iter()
                .map(|&(lo, hi)| {
                    let c = all.sources().iter().copied().filter(|&x| lo <= x && x < hi);
                    MortonCodes::from_codes(domain, c.collect()).unwrap()
                })
                .collect();
            let mut shapes: Vec<TreeShape> = [(0, cut), (cut, end)]
                .iter()
                .zip(&pieces)
                .map(|(&(lo, hi), c)| c.refine_below(&roots(lo, hi), leaf, crate::DEEPEST_LEVEL))
                .collect();
            let internal = |s: &TreeShape| -> Vec<MortonKey> {
                (0..s.n_levels())
                    .flat_map(|l| s.level(l))
                    .filter(|b| !b.leaf)
                    .map(|b| b.key)
                    .collect()
            };
            loop {
                let before: Vec<usize> = shapes.iter().map(TreeShape::n_boxes).collect();
                let foreign = [internal(&shapes[1]), internal(&shapes[0])];
                for ((s, c), f) in shapes.iter_mut().zip(&pieces).zip(&foreign) {
                    s.insert_internal(c, f);
                    s.balance(c);
                }
                let after: Vec<usize> = shapes.iter().map(TreeShape::n_boxes).collect();
                if before == after {
                    break;
                }
            }
            // Every box of the whole shape is in the piece holding its
            // points, with the same leaf flag and count.
            for l in 0..whole.n_levels() {
                for b in whole.level(l) {
                    let r = b.key.morton_range();
                    let p = usize::from(r.start >= cut);
                    if r.start < cut && r.end > cut {
                        continue;
                    }
                    let i = shapes[p].find(b.key).expect("box in its piece");
                    let s = shapes[p].get(l, i);
                    assert_eq!(
                        (s.leaf, s.n_sources()),
                        (b.leaf, b.n_sources()),
                        "{:?}",
                        b.key
                    );
                }
            }
            let leaves: usize = shapes
                .iter()
                .map(|s| {
                    (0..s.n_levels())
                        .flat_map(|l| s.level(l))
                        .filter(|b| b.leaf)
                        .count()
                })
                .sum();
            assert_eq!(leaves, whole.n_leaves());
        }
    }
}
