//! Typed errors returned by domain and tree construction.
//!
//! Nothing in this crate panics on bad *user data* (coordinates, sizes,
//! options): every such problem is reported as a [`TreeError`]. Panics are
//! reserved for programming errors on [`MortonKey`](crate::MortonKey)
//! methods (asking for the parent of the root, for example), and those are
//! documented on each method.

use std::fmt;

/// Names the point set an error refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointSet {
    /// The source points given to [`Octree::new`](crate::Octree::new).
    Sources,
    /// The target points given to [`Octree::new`](crate::Octree::new).
    Targets,
    /// The point set at this position in the slice given to
    /// [`Domain::from_points`](crate::Domain::from_points).
    Set(usize),
}

impl fmt::Display for PointSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PointSet::Sources => f.write_str("sources"),
            PointSet::Targets => f.write_str("targets"),
            PointSet::Set(i) => write!(f, "point set {i}"),
        }
    }
}

/// Everything that can go wrong when building a [`Domain`](crate::Domain)
/// or an [`Octree`](crate::Octree).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TreeError {
    /// A coordinate array whose length is not a multiple of 3. Points are
    /// stored interleaved: `[x0, y0, z0, x1, y1, z1, ...]`.
    #[error("{set}: length {len} is not a multiple of 3 (points are interleaved x, y, z)")]
    BadLength {
        /// The offending point set.
        set: PointSet,
        /// Its length in `f64`s.
        len: usize,
    },
    /// A NaN or infinite coordinate.
    #[error("{set}: point {index} has a non-finite coordinate {point:?}")]
    NonFinite {
        /// The offending point set.
        set: PointSet,
        /// Index of the point (not of the coordinate) in that set.
        index: usize,
        /// The point as given.
        point: [f64; 3],
    },
    /// A point set that must not be empty holds no points.
    #[error("{set}: no points")]
    Empty {
        /// The empty point set.
        set: PointSet,
    },
    /// [`Domain::from_points`](crate::Domain::from_points) was given no
    /// points at all.
    #[error("no points to bound")]
    NoPoints,
    /// `leaf_size == 0` in [`TreeOptions`](crate::TreeOptions).
    #[error("leaf_size must be at least 1")]
    ZeroLeafSize,
    /// A level deeper than [`DEEPEST_LEVEL`](crate::DEEPEST_LEVEL) was asked
    /// for (`max_level` or `uniform_depth`).
    #[error(
        "level {level} is deeper than the deepest level a key can hold ({})",
        crate::DEEPEST_LEVEL
    )]
    LevelTooDeep {
        /// The requested level.
        level: u32,
    },
    /// A domain whose origin is not finite, whose width is not finite and
    /// positive, or whose width is too small to be resolved next to its
    /// origin in `f64` (or too small to be scaled to the finest grid).
    #[error("invalid domain: origin {origin:?}, width {width}")]
    InvalidDomain {
        /// Lower corner as given.
        origin: [f64; 3],
        /// Width as given.
        width: f64,
    },
    /// Parts given to [`Octree::from_parts`](crate::Octree::from_parts)
    /// that do not form a tree.
    #[error("invalid tree parts: {reason}")]
    InvalidParts {
        /// What is wrong.
        reason: &'static str,
    },
    /// A finest-level Morton code outside the grid (`>= 8^D`), given to
    /// [`MortonCodes::from_codes`](crate::MortonCodes::from_codes).
    #[error("code {index} ({code:#x}) is not a finest-level Morton code")]
    InvalidCode {
        /// Position of the code.
        index: usize,
        /// The code.
        code: u64,
    },
    /// A point outside a user-given domain (the closed cube
    /// `[origin, origin + width]^3`).
    #[error("{set}: point {index} {point:?} lies outside the given domain")]
    OutsideDomain {
        /// The offending point set.
        set: PointSet,
        /// Index of the point in that set.
        index: usize,
        /// The point.
        point: [f64; 3],
    },
    /// Periodic axes ([`TreeOptions::periodic`](crate::TreeOptions::periodic))
    /// without a given domain: the periodic cell must be given, it is the
    /// root box.
    #[error("periodic axes need a given domain (the periodic cell): set TreeOptions::domain")]
    PeriodicWithoutDomain,
    /// A point on the upper face `origin + width` of a periodic axis: the
    /// cell is half-open along periodic axes, wrap the point to the lower
    /// face (`origin`) first.
    #[error(
        "{set}: point {index} {point:?} lies on the upper face of periodic axis {axis} \
         (the periodic cell is half-open: wrap it to the lower face)"
    )]
    OnPeriodicFace {
        /// The offending point set.
        set: PointSet,
        /// Index of the point in that set.
        index: usize,
        /// The point.
        point: [f64; 3],
        /// The axis (0 for x, 1 for y, 2 for z).
        axis: usize,
    },
}
