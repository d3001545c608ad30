//! Axis-aligned bounding boxes of point sets (the domain's extent, the
//! clusters' groups and separation tests): a box `[lo, hi]` grows by a point (`lo = min(lo, p)`,
//! `hi = max(hi, p)` per axis) and by another box (the same with its
//! corners), starts empty (`lo = +inf`, `hi = -inf`), and has the width
//! `w = max_a (hi_a - lo_a)`, its largest extent over the three axes.

use rayon::prelude::*;

/// A bounding box (in the clustering also a run of points along an axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Bounds {
    /// Smallest coordinate per axis.
    pub(crate) lo: [f64; 3],
    /// Largest coordinate per axis.
    pub(crate) hi: [f64; 3],
}

impl Bounds {
    /// The empty box (holds no point).
    pub(crate) const EMPTY: Bounds = Bounds {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    /// Grow to hold `p`.
    pub(crate) fn add(&mut self, p: [f64; 3]) {
        for (a, &x) in p.iter().enumerate() {
            self.lo[a] = self.lo[a].min(x);
            self.hi[a] = self.hi[a].max(x);
        }
    }

    /// Grow to hold `other`.
    pub(crate) fn merge(&mut self, other: &Bounds) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(other.lo[a]);
            self.hi[a] = self.hi[a].max(other.hi[a]);
        }
    }

    /// Whether no point was added.
    pub(crate) fn is_empty(&self) -> bool {
        self.lo[0] > self.hi[0]
    }

    /// Largest extent over the three axes.
    pub(crate) fn width(&self) -> f64 {
        (0..3).map(|a| self.hi[a] - self.lo[a]).fold(0.0, f64::max)
    }
}

/// Bounding box of `items` (in parallel for large sets).
pub(crate) fn bounds(items: &[usize], point: &(impl Fn(usize) -> [f64; 3] + Sync)) -> Bounds {
    items
        .par_iter()
        .with_min_len(1 << 14)
        .fold(
            || Bounds::EMPTY,
            |mut acc, &i| {
                acc.add(point(i));
                acc
            },
        )
        .reduce(
            || Bounds::EMPTY,
            |mut a, b| {
                a.merge(&b);
                a
            },
        )
}
