//! What the chooser sees of a scene before building: how many points, and
//! whether they fill a volume, lie on a surface or along a curve
//! ([`Scene`]).

use ferrofmm_tree::TreeShape;

use super::occupancy::Occupancy;

/// Leaf size of the refinement [`Scene::of`] measures the dimension on:
/// a split box holds more than this many points, so that a child is
/// empty because the points do not reach it, not by chance (64 uniform
/// points leave one of 8 children empty with probability 0.2%).
pub const SCENE_LEAF_SIZE: usize = 64;

/// The scene of a set of points, as the error model reads it
/// ([`ErrorModel::in_scene`](super::ErrorModel::in_scene)).
///
/// The **dimension** `d` is the box-counting dimension of the adaptive
/// tree at leaf size [`SCENE_LEAF_SIZE`]:
///
/// ```text
/// d = log2( sum_b c_b / #{b} )     over split boxes b with c_b >= 2 occupied children
/// ```
///
/// A box cut by a volume of points has 8 occupied children, by a surface
/// about 4, by a curve about 2, so `d` is about 3, 2 and 1. Boxes with a
/// single occupied child are left out: they only descend towards a
/// cluster much smaller than themselves (two clusters 1000x apart in size)
/// and say nothing about its shape. Coarse boxes see a curved surface as
/// a volume (a sphere fills all 8 octants of its bounding box), so `d`
/// reads somewhat above 2 for closed surfaces. Measured (`N` = 1e4, 1e5,
/// 1e6; `examples/scene_sweep.rs`, `docs/tolerance.md`): cube 3.00, 3.00,
/// 3.00; Plummer 2.96, 3.00, 3.00; two clusters 2.98, 2.83, 2.97; sphere
/// 2.55, 2.34, 2.35; torus 2.35, 2.38, 2.24; plane 2.00; trefoil curve
/// 1.51, 1.51, 1.51.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Scene {
    /// Box-counting dimension `d` (1 to 3; 3 when the tree has no split
    /// box with two or more children).
    pub dimension: f64,
    /// Number of sources.
    pub n_sources: usize,
}

impl Scene {
    /// The scene of the points of `occupancy` (one refinement at
    /// [`SCENE_LEAF_SIZE`]: a few milliseconds at a million points).
    ///
    /// ```
    /// use ferrofmm_fmm::Geometry;
    /// use ferrofmm_fmm::tuning::{Occupancy, Scene};
    /// let d = |g: Geometry| {
    ///     let points: Vec<f64> = g.points(20_000, 1);
    ///     Scene::of(&Occupancy::new(&points, None, None, 19).unwrap()).dimension
    /// };
    /// assert!(d(Geometry::Cube) > 2.9);
    /// assert!((d(Geometry::Plane) - 2.0).abs() < 0.1);
    /// assert!(d(Geometry::Curve) < 1.7);
    /// ```
    pub fn of(occupancy: &Occupancy) -> Self {
        Self::of_shape(&occupancy.refine(SCENE_LEAF_SIZE), occupancy.n_sources())
    }

    /// The scene of a refinement `shape` of `n_sources` sources (see the
    /// type's docs for the dimension).
    pub fn of_shape(shape: &TreeShape, n_sources: usize) -> Self {
        let (mut splits, mut children) = (0usize, 0usize);
        for l in 0..shape.n_levels().saturating_sub(1) {
            let mut kids = shape.level(l + 1).map(|b| b.key.parent()).peekable();
            for b in shape.level(l) {
                let mut c = 0;
                while kids.next_if(|&k| k == b.key).is_some() {
                    c += 1;
                }
                if c >= 2 {
                    splits += 1;
                    children += c;
                }
            }
        }
        let dimension = if splits == 0 {
            3.0
        } else {
            (children as f64 / splits as f64).log2().clamp(1.0, 3.0)
        };
        Scene {
            dimension,
            n_sources,
        }
    }
}
