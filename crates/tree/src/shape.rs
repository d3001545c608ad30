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
//! [`DEEPEST_LEVEL`](crate::DEEPEST_LEVEL)), so its points are one range of
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
use crate::build::{Node, PointKeys, Refinement, refine};
use crate::domain::{Domain, check_inside, validate_points};
use crate::error::{PointSet, TreeError};
use crate::morton::MortonKey;

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
        let mut sets = vec![(PointSet::Sources, sources)];
        if let Some(t) = targets {
            sets.push((PointSet::Targets, t));
        }
        for &(set, p) in &sets {
            validate_points(set, p)?;
            if p.is_empty() {
                return Err(TreeError::Empty { set });
            }
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
        balance(&mut self.levels, &codes.keys());
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
}
