//! The computational domain: one cube shared by sources and targets.
//!
//! A [`Domain`] is the half-open cube `[origin, origin + width)^3`. Box
//! geometry follows from it: a box of level `l` is `width / 2^l` wide, and a
//! point `p` falls in the finest cell `floor((p - origin) / width * 2^D)`
//! (`D` = [`DEEPEST_LEVEL`](crate::DEEPEST_LEVEL)), clamped into the grid.
//!
//! [`Domain::from_points`] computes the bounding cube of several point sets:
//! the cube is centred on their bounding box and its width is the largest
//! extent, enlarged by a relative `2^-20` plus a few units in the last place
//! of the coordinates' magnitude, so that points on the upper faces fall
//! strictly inside (the enlargement is doubled until they provably do). A
//! set with zero extent (a single point, or all points coincident) gets the
//! width `max(|coordinate|, 1)`.

use rayon::prelude::*;

use crate::bounds::Bounds;
use crate::error::{PointSet, TreeError};
use crate::morton::{FINEST_GRID, encode};

/// A cube `[origin, origin + width)^3`: the root box of an octree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Domain {
    /// Lower corner.
    pub origin: [f64; 3],
    /// Edge length (positive).
    pub width: f64,
}

impl Domain {
    /// A domain with the given lower corner and width.
    ///
    /// # Errors
    /// [`TreeError::InvalidDomain`] if a coordinate of `origin` is not finite,
    /// `width` is not finite and positive, `origin + width` is not finite or
    /// not larger than `origin` in `f64`, or `width` is too small to be
    /// scaled to the finest grid.
    ///
    /// ```
    /// use ferrofmm_tree::Domain;
    /// let d = Domain::new([-1.0; 3], 2.0).unwrap();
    /// assert_eq!(d.center(), [0.0; 3]);
    /// assert!(Domain::new([0.0; 3], 0.0).is_err());
    /// ```
    pub fn new(origin: [f64; 3], width: f64) -> Result<Self, TreeError> {
        let err = TreeError::InvalidDomain { origin, width };
        let scale = FINEST_GRID as f64 / width;
        if !(width.is_finite() && width > 0.0 && scale.is_finite()) {
            return Err(err);
        }
        for &o in &origin {
            let hi = o + width;
            if !(o.is_finite() && hi.is_finite() && hi > o) {
                return Err(err);
            }
        }
        Ok(Domain { origin, width })
    }

    /// The bounding cube of several interleaved `xyz` point sets together
    /// (see the [module documentation](self) for how it is enlarged). Empty
    /// sets are allowed as long as one set holds a point.
    ///
    /// # Errors
    /// [`TreeError::BadLength`] or [`TreeError::NonFinite`] (naming the set by
    /// its position, [`PointSet::Set`]), [`TreeError::NoPoints`] if all sets
    /// are empty, [`TreeError::InvalidDomain`] if the extent overflows `f64`.
    ///
    /// ```
    /// use ferrofmm_tree::Domain;
    /// let sources = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    /// let targets = [2.0, 0.5, 0.5];
    /// let d = Domain::from_points(&[&sources, &targets]).unwrap();
    /// assert!(d.width > 2.0 && d.contains([2.0, 0.5, 0.5]));
    /// ```
    pub fn from_points(points: &[&[f64]]) -> Result<Self, TreeError> {
        let sets: Vec<(PointSet, &[f64])> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| (PointSet::Set(i), p))
            .collect();
        for &(set, p) in &sets {
            validate_points(set, p)?;
        }
        Self::bounding(&sets)
    }

    /// Bounding cube of already validated point sets.
    pub(crate) fn bounding(sets: &[(PointSet, &[f64])]) -> Result<Self, TreeError> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &(_, p) in sets {
            let (l, h) = bounds(p);
            for i in 0..3 {
                lo[i] = lo[i].min(l[i]);
                hi[i] = hi[i].max(h[i]);
            }
        }
        if lo[0] > hi[0] {
            return Err(TreeError::NoPoints);
        }
        let mut extent = 0.0f64;
        let mut magnitude = 0.0f64;
        let mut center = [0.0; 3];
        for i in 0..3 {
            extent = extent.max(hi[i] - lo[i]);
            magnitude = magnitude.max(lo[i].abs()).max(hi[i].abs());
            center[i] = 0.5 * lo[i] + 0.5 * hi[i];
        }
        let invalid = TreeError::InvalidDomain {
            origin: lo,
            width: extent,
        };
        if !extent.is_finite() {
            return Err(invalid);
        }
        let base = if extent > 0.0 {
            extent
        } else {
            magnitude.max(1.0)
        };
        let mut pad = base * (1.0 / (1u64 << 20) as f64) + 8.0 * f64::EPSILON * magnitude;
        for _ in 0..64 {
            let width = base + pad;
            let origin: [f64; 3] = std::array::from_fn(|i| center[i] - 0.5 * width);
            let inside = (0..3).all(|i| origin[i] <= lo[i] && hi[i] < origin[i] + width);
            if inside && let Ok(d) = Domain::new(origin, width) {
                return Ok(d);
            }
            pad *= 2.0;
        }
        Err(invalid)
    }

    /// Centre of the cube.
    pub fn center(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.origin[i] + 0.5 * self.width)
    }

    /// `true` if `p` lies in the **closed** cube `[origin, origin + width]^3`
    /// (points on the upper faces are accepted and assigned to the last box).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|i| p[i] >= self.origin[i] && p[i] <= self.origin[i] + self.width)
    }

    /// The finest cell containing `p`, `floor((p - origin) / width * 2^D)`
    /// clamped to `0 ..= 2^D - 1` on each axis (NaN maps to 0).
    #[inline]
    pub fn finest_cell(&self, p: [f64; 3]) -> [u32; 3] {
        let scale = FINEST_GRID as f64 / self.width;
        // `as u32` saturates: negative -> 0, NaN -> 0, huge -> u32::MAX.
        std::array::from_fn(|i| {
            (((p[i] - self.origin[i]) * scale).floor() as u32).min(FINEST_GRID - 1)
        })
    }

    /// Morton code of the finest cell containing `p`.
    #[inline]
    pub(crate) fn finest_morton(&self, p: [f64; 3]) -> u64 {
        encode(self.finest_cell(p))
    }
}

/// Points per parallel work item in validation and bounds.
const BLOCK: usize = 1 << 14;

/// The sources and (when given) the targets, each checked to be a
/// non-empty list of finite points.
pub(crate) fn validate_sets<'a>(
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
) -> Result<Vec<(PointSet, &'a [f64])>, TreeError> {
    let mut sets = vec![(PointSet::Sources, sources)];
    sets.extend(targets.map(|t| (PointSet::Targets, t)));
    for &(set, p) in &sets {
        validate_points(set, p)?;
        if p.is_empty() {
            return Err(TreeError::Empty { set });
        }
    }
    Ok(sets)
}

/// Checks that `p` is a list of finite points.
pub(crate) fn validate_points(set: PointSet, p: &[f64]) -> Result<(), TreeError> {
    if !p.len().is_multiple_of(3) {
        return Err(TreeError::BadLength { set, len: p.len() });
    }
    let bad = p
        .par_chunks(3 * BLOCK)
        .position_first(|c| c.iter().any(|x| !x.is_finite()))
        .map(|block| {
            let c = &p[3 * BLOCK * block..];
            block * BLOCK
                + c.chunks_exact(3)
                    .position(|q| q.iter().any(|x| !x.is_finite()))
                    .unwrap_or(0)
        });
    reject(set, p, bad, |set, index, point| TreeError::NonFinite {
        set,
        index,
        point,
    })
}

/// Per-axis minimum and maximum of finite interleaved points (`+inf/-inf`
/// for an empty set).
fn bounds(p: &[f64]) -> ([f64; 3], [f64; 3]) {
    let b = p
        .par_chunks(3 * BLOCK)
        .map(|block| {
            let mut b = Bounds::EMPTY;
            for c in block.chunks_exact(3) {
                b.add(point_at(c, 0));
            }
            b
        })
        .reduce(
            || Bounds::EMPTY,
            |mut a, b| {
                a.merge(&b);
                a
            },
        );
    (b.lo, b.hi)
}

/// `Err(error(set, index, point))` for the first bad point `index` of `p`
/// (none: `Ok`).
fn reject(
    set: PointSet,
    p: &[f64],
    bad: Option<usize>,
    error: fn(PointSet, usize, [f64; 3]) -> TreeError,
) -> Result<(), TreeError> {
    bad.map_or(Ok(()), |index| Err(error(set, index, point_at(p, index))))
}

/// Point `index` of interleaved coordinates.
fn point_at(p: &[f64], index: usize) -> [f64; 3] {
    [p[3 * index], p[3 * index + 1], p[3 * index + 2]]
}

/// Checks that every point of `p` lies in the closed cube of `d`.
pub(crate) fn check_inside(set: PointSet, p: &[f64], d: &Domain) -> Result<(), TreeError> {
    let bad = p
        .par_chunks_exact(3)
        .position_first(|c| !d.contains([c[0], c[1], c[2]]));
    reject(set, p, bad, |set, index, point| TreeError::OutsideDomain {
        set,
        index,
        point,
    })
}

/// Checks that no point of `p` lies on the upper face of a periodic axis
/// (the points are known to lie in the closed cube of `d`).
pub(crate) fn check_periodic_faces(
    set: PointSet,
    p: &[f64],
    d: &Domain,
    periodic: [bool; 3],
) -> Result<(), TreeError> {
    let upper: [f64; 3] = std::array::from_fn(|a| d.origin[a] + d.width);
    let on_face = |c: &[f64]| (0..3).find(|&a| periodic[a] && c[a] >= upper[a]);
    let Some(index) = p
        .par_chunks_exact(3)
        .position_first(|c| on_face(c).is_some())
    else {
        return Ok(());
    };
    let point = point_at(p, index);
    Err(TreeError::OnPeriodicFace {
        set,
        index,
        point,
        axis: on_face(&point).unwrap_or(0),
    })
}
