//! The caller's points, in the run's float type `T` or in `f64`.
//!
//! A run in `f32` on points the caller holds in `f64` must not round the
//! absolute coordinates: at `|x| = 1e4` neighbouring `f32` values are
//! `2^-10 ~ 1e-3` apart, at `1e8` they are 8 apart, so a unit cube shifted
//! there loses three digits or collapses to a point. The FMM therefore
//! keeps the `f64` coordinates until the tree is built and only rounds the
//! differences `x - c` to the tree's coordinate origin `c` (a point near
//! the domain, [`coordinate_origin`]): the rounding then moves a
//! point by at most `u |x - c| <= 2.5 u W` (`u` the unit roundoff of `T`,
//! `W` the domain's width), whatever the offset of the domain.

use std::borrow::Cow;

use ferrofmm_kernels::Real;
use ferrofmm_tree::Domain;

/// Interleaved `x, y, z` coordinates as the caller gave them.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Coordinates<'a, T> {
    /// In the run's float type (`FmmBuilder::new`, `FmmBuilder::targets`).
    Native(&'a [T]),
    /// In `f64`, whatever the run's float type (`FmmBuilder::from_f64`,
    /// `FmmBuilder::targets_f64`).
    Wide(&'a [f64]),
}

impl<'a, T: Real> Coordinates<'a, T> {
    /// Number of values (three per point).
    pub(crate) fn len(&self) -> usize {
        match self {
            Coordinates::Native(p) => p.len(),
            Coordinates::Wide(p) => p.len(),
        }
    }

    /// The coordinates in `f64`: borrowed when given in `f64`, else
    /// converted (exactly).
    pub(crate) fn to_f64(self) -> Cow<'a, [f64]> {
        match self {
            Coordinates::Native(p) => Cow::Owned(p.iter().map(|x| x.to_f64()).collect()),
            Coordinates::Wide(p) => Cow::Borrowed(p),
        }
    }

    /// Non-empty, a multiple of 3, all finite (see
    /// [`crate::validate::check_points`]).
    pub(crate) fn check(&self, what: &'static str) -> Result<(), crate::FmmError> {
        match self {
            Coordinates::Native(p) => crate::validate::check_points(what, p),
            Coordinates::Wide(p) => crate::validate::check_points(what, p),
        }
    }
}

/// The point the stored coordinates are relative to: the domain's centre
/// rounded towards zero to a multiple of `2^k`, the smallest power of two
/// at least the domain's width.
///
/// Subtracting it is **exact** for every coordinate of the domain, in `f32`
/// as in `f64` (a coordinate `x` and this origin `c` have the same sign
/// unless `c = 0`; for `c/2 <= x <= 2c` the difference is exact (Sterbenz),
/// and beyond it `x - c` is a multiple of the coarser of `ulp(x)` and
/// `2^k` no larger than `x`), so two nearby points keep their exact
/// separation: rounding the differences to the centre itself moved points
/// near the origin by up to `u |x - centre|`, which in `f32` cost up to 1e-3
/// of accuracy on a plane through the origin and 1e-2 on a curve whose
/// closest points are 1e-8 apart. The relative coordinates stay within 2.5
/// domain widths of zero.
pub(crate) fn coordinate_origin(domain: &Domain) -> [f64; 3] {
    let step = 2f64.powi(domain.width.log2().ceil() as i32);
    domain.center().map(|c| (c / step).trunc() * step)
}

/// Points relative to `centre`, in the order `perm` gives them
/// (`out[k] = points[perm[k]] - centre`, a tree's sorted order) or, for
/// `None`, in their own order: the difference in `f64`, then rounded to
/// `T`.
pub(crate) fn permute_points<T: Real>(
    points: &[f64],
    perm: Option<&[usize]>,
    centre: [f64; 3],
) -> Vec<T> {
    let point =
        |i: usize| std::array::from_fn::<T, 3, _>(|c| T::from_f64(points[3 * i + c] - centre[c]));
    match perm {
        Some(perm) => perm.iter().flat_map(|&i| point(i)).collect(),
        None => (0..points.len() / 3).flat_map(point).collect(),
    }
}

/// Points already in order (a tree's sorted coordinates, handed over by
/// [`ferrofmm_tree::Octree::take_sorted_points`]) relative to `centre`,
/// rounded to `T`: the same values as [`permute_points`] gives from the
/// caller's points, made in place for `f64` (no second copy).
pub(crate) fn relative_points<T: Real>(points: Vec<f64>, centre: [f64; 3]) -> Vec<T> {
    let any: Box<dyn std::any::Any> = Box::new(points);
    match any.downcast::<Vec<T>>() {
        Ok(same) => {
            let mut same = *same;
            for p in same.chunks_exact_mut(3) {
                for c in 0..3 {
                    p[c] = T::from_f64(p[c].to_f64() - centre[c]);
                }
            }
            same
        }
        Err(any) => {
            let points = any
                .downcast::<Vec<f64>>()
                .expect("the box holds the Vec<f64> it was made from");
            permute_points(&points, None, centre)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::coordinate_origin;
    use ferrofmm_tree::Domain;

    /// `x - origin` is exact in f32 for every f32 coordinate of the domain,
    /// near the origin, straddling it and far from it.
    #[test]
    fn coordinate_origin_makes_differences_exact() {
        let domains = [
            ([0.0, 0.0, -0.5], 1.0),
            ([0.001, -0.3, 0.999], 1.0),
            ([-0.8, -0.2, 3.0], 0.7),
            ([1e4, -1e4, 5e3], 0.37),
            ([1e8, 1.0, -2.0e6], 3.0),
            ([-1e-3, 2e-3, 0.5], 1e-3),
        ];
        for (origin, width) in domains {
            let d = Domain { origin, width };
            let c = coordinate_origin(&d);
            for i in 0..3 {
                for k in 0..=1000 {
                    let x = (origin[i] + width * k as f64 / 1000.0) as f32;
                    let exact = x as f64 - c[i];
                    assert_eq!((exact as f32) as f64, exact, "{d:?} axis {i} x {x}");
                    assert!(exact.abs() <= 2.5 * width + 1e-9, "{d:?} {c:?}");
                }
            }
        }
    }
}
