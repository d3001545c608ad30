//! The caller's points, in the run's float type `T` or in `f64`.
//!
//! A run in `f32` on points the caller holds in `f64` must not round the
//! absolute coordinates: at `|x| = 1e4` neighbouring `f32` values are
//! `2^-10 ~ 1e-3` apart, at `1e8` they are 8 apart, so a unit cube shifted
//! there loses three digits or collapses to a point. The FMM therefore
//! keeps the `f64` coordinates until the tree is built and only rounds the
//! differences `x - c` to the tree's coordinate origin `c` (a point near
//! the domain, see `fmm::coordinate_origin`): the rounding then moves a
//! point by at most `u |x - c| <= 2.5 u W` (`u` the unit roundoff of `T`,
//! `W` the domain's width), whatever the offset of the domain.

use std::borrow::Cow;

use ferrofmm_kernels::Real;

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
    /// [`crate::builder::check_points`]).
    pub(crate) fn check(&self, what: &'static str) -> Result<(), crate::FmmError> {
        match self {
            Coordinates::Native(p) => crate::builder::check_points(what, p),
            Coordinates::Wide(p) => crate::builder::check_points(what, p),
        }
    }
}
