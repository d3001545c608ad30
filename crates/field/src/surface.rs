//! Equivalent and check surfaces: the cube-surface grid of order `p` and the
//! radii that scale it to a box.

use ferrofmm_kernels::{Kernel, Real};

/// Number of points of the cube-surface grid of order `p`:
/// `p^3 - (p-2)^3 = 6 (p-1)^2 + 2`.
///
/// This is the number of equivalent (and check) points per box, i.e. the
/// length of one multipole or local expansion.
///
/// # Panics
/// When `order < 2` (such a grid has no interior to surround).
///
/// ```
/// assert_eq!(ferrofmm_field::n_surface_points(2), 8);
/// assert_eq!(ferrofmm_field::n_surface_points(6), 152);
/// assert_eq!(ferrofmm_field::n_surface_points(10), 488);
/// ```
pub fn n_surface_points(order: usize) -> usize {
    assert!(order >= 2, "surface order must be at least 2, got {order}");
    6 * (order - 1) * (order - 1) + 2
}

/// Values in one expansion of `kernel` at `order`: one density per surface
/// point and [component](Kernel::components),
/// `kernel.components() * n_surface_points(order)`. Every operator and M2L
/// matrix is square of this size; expansions are stored point-major
/// (`[c values of point 0, c values of point 1, ...]`), the layout of the
/// kernel's densities.
///
/// ```
/// use ferrofmm_field::{expansion_len, n_surface_points};
/// use ferrofmm_kernels::{Laplace3d, Stokes3d};
/// assert_eq!(expansion_len(&Laplace3d, 4), n_surface_points(4));
/// assert_eq!(expansion_len(&Stokes3d::default(), 4), 3 * n_surface_points(4));
/// ```
pub fn expansion_len<K: Kernel>(kernel: &K, order: usize) -> usize {
    kernel.components() * n_surface_points(order)
}

/// Points of the cube-surface grid of `order`, scaled to a box:
/// `center + radius * half_width * u` for every `u` of the unit grid, where
/// the unit grid is the set of points of `{-1 + 2 i / (p-1) : i = 0..p}^3`
/// with at least one coordinate equal to `±1` (the surface of `[-1, 1]^3`).
///
/// Output is interleaved `[x0, y0, z0, x1, ...]` of length
/// `3 * n_surface_points(order)`. The order of the points is fixed
/// (lexicographic in the grid indices, `x` slowest) and identical for every
/// box, radius and float type, so the `k`-th value of an expansion always
/// belongs to the `k`-th point. Coordinates are computed in `f64` and
/// rounded to `T` once.
///
/// # Panics
/// When `order < 2`.
///
/// ```
/// use ferrofmm_field::{n_surface_points, surface_points};
/// let pts: Vec<f64> = surface_points(4, [0.5, 0.5, 0.5], 0.25, 1.05);
/// assert_eq!(pts.len(), 3 * n_surface_points(4));
/// // every point lies on the cube of half-width 1.05 * 0.25 around the center
/// for p in pts.chunks(3) {
///     let m = p.iter().map(|x| (x - 0.5).abs()).fold(0.0f64, f64::max);
///     assert!((m - 1.05 * 0.25).abs() < 1e-12);
/// }
/// ```
pub fn surface_points<T: Real>(
    order: usize,
    center: [f64; 3],
    half_width: f64,
    radius: f64,
) -> Vec<T> {
    let n = n_surface_points(order);
    let scale = radius * half_width;
    let mut out = Vec::with_capacity(3 * n);
    for u in unit_surface(order) {
        for d in 0..3 {
            out.push(T::from_f64(center[d] + scale * u[d]));
        }
    }
    debug_assert_eq!(out.len(), 3 * n);
    out
}

/// The unit grid (on the surface of `[-1, 1]^3`) in the fixed point order.
pub(crate) fn unit_surface(order: usize) -> Vec<[f64; 3]> {
    let p = order;
    let coord = |i: usize| -1.0 + 2.0 * i as f64 / (p - 1) as f64;
    let mut out = Vec::with_capacity(n_surface_points(order));
    for i in 0..p {
        for j in 0..p {
            for k in 0..p {
                let on_face = i == 0 || i == p - 1 || j == 0 || j == p - 1 || k == 0 || k == p - 1;
                if on_face {
                    out.push([coord(i), coord(j), coord(k)]);
                }
            }
        }
    }
    out
}

/// Radii of the four KIFMM surfaces of a box, as multiples of the box
/// half-width `h` (a radius `r` means the cube of half-width `r h` around the
/// box center).
///
/// * upward equivalent `r_ue` (encloses the box's sources, `r_ue > 1`) and
///   upward check `r_uc` (`r_ue < r_uc <= 3`: between the equivalent surface
///   and the far field, which starts 3 half-widths from the center);
/// * downward equivalent `r_de` (encloses the box's targets and the
///   downward check surface, `r_dc < r_de <= 3`) and downward check `r_dc`
///   (`1 <= r_dc`).
///
/// The default `1.05 / 2.95 / 2.95 / 1.05` (ExaFMM-T's choice) was kept after
/// the radius sweep recorded in `docs/algorithms.md`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceRadii {
    /// Upward equivalent surface radius `r_ue` (multiple of the half-width).
    pub upward_equivalent: f64,
    /// Upward check surface radius `r_uc`.
    pub upward_check: f64,
    /// Downward equivalent surface radius `r_de`.
    pub downward_equivalent: f64,
    /// Downward check surface radius `r_dc`.
    pub downward_check: f64,
}

impl Default for SurfaceRadii {
    fn default() -> Self {
        SurfaceRadii {
            upward_equivalent: 1.05,
            upward_check: 2.95,
            downward_equivalent: 2.95,
            downward_check: 1.05,
        }
    }
}

impl SurfaceRadii {
    /// The radius of one surface.
    ///
    /// ```
    /// use ferrofmm_field::{SurfaceKind, SurfaceRadii};
    /// let r = SurfaceRadii::default();
    /// assert_eq!(r.radius(SurfaceKind::UpwardCheck), r.upward_check);
    /// ```
    pub fn radius(&self, kind: SurfaceKind) -> f64 {
        match kind {
            SurfaceKind::UpwardEquivalent => self.upward_equivalent,
            SurfaceKind::UpwardCheck => self.upward_check,
            SurfaceKind::DownwardEquivalent => self.downward_equivalent,
            SurfaceKind::DownwardCheck => self.downward_check,
        }
    }

    /// The four radii as `[r_ue, r_uc, r_de, r_dc]`.
    pub fn to_array(&self) -> [f64; 4] {
        [
            self.upward_equivalent,
            self.upward_check,
            self.downward_equivalent,
            self.downward_check,
        ]
    }
}

/// Which of a box's four surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SurfaceKind {
    /// Carries the multipole (upward equivalent density `phi`).
    UpwardEquivalent,
    /// Where the potential of the box's sources is matched (P2M, M2M).
    UpwardCheck,
    /// Carries the local expansion (downward equivalent density `psi`).
    DownwardEquivalent,
    /// Where the potential of far sources is matched (M2L, P2L, L2L).
    DownwardCheck,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_geometry() {
        for p in 2..=12 {
            let u = unit_surface(p);
            assert_eq!(u.len(), n_surface_points(p));
            assert_eq!(u.len(), p * p * p - (p - 2) * (p - 2) * (p - 2));
            for x in &u {
                let m = x.iter().map(|c| c.abs()).fold(0.0, f64::max);
                assert!((m - 1.0).abs() < 1e-15);
            }
            // no duplicates
            let mut keys: Vec<_> = u
                .iter()
                .map(|x| x.map(|c| ((c + 1.0) * (p - 1) as f64 / 2.0).round() as i64))
                .collect();
            keys.sort();
            keys.dedup();
            assert_eq!(keys.len(), u.len());
            // symmetric about the center
            let s: [f64; 3] = u
                .iter()
                .fold([0.0; 3], |a, x| [a[0] + x[0], a[1] + x[1], a[2] + x[2]]);
            assert!(s.iter().all(|c| c.abs() < 1e-10));
        }
    }

    #[test]
    fn scaled_points() {
        let p: Vec<f32> = surface_points(3, [1.0, 2.0, 3.0], 0.5, 2.0);
        assert_eq!(p.len(), 3 * 26);
        assert_eq!(&p[0..3], &[0.0, 1.0, 2.0]);
    }

    #[test]
    #[should_panic]
    fn order_one_panics() {
        n_surface_points(1);
    }
}
