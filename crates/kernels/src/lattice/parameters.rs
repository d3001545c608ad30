//! The periodic cell, the options of an Ewald sum and the choice of the
//! splitting parameter and cut-offs from a tolerance.

use crate::KernelError;
use std::f64::consts::PI;

/// An orthorhombic, fully periodic cell: the box `origin + [0, L_x) x [0,
/// L_y) x [0, L_z)` repeated along x, y and z (cubic when the three lengths
/// are equal). Lattice vectors are `n∘L = (n_x L_x, n_y L_y, n_z L_z)`.
///
/// ```
/// use ferrofmm_kernels::PeriodicCell;
/// let cell = PeriodicCell::new([0.0; 3], [1.0, 2.0, 3.0]).unwrap();
/// assert_eq!(cell.volume(), 6.0);
/// assert!(PeriodicCell::new([0.0; 3], [1.0, 0.0, 1.0]).is_err());
/// assert_eq!(cell.wrap([1.25, -0.5, 3.0]), [0.25, 1.5, 0.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodicCell {
    origin: [f64; 3],
    lengths: [f64; 3],
}

impl PeriodicCell {
    /// The cell with corner `origin` and side `lengths`.
    ///
    /// # Errors
    /// [`KernelError::InvalidCell`] when a coordinate of `origin` is not
    /// finite or a length is not finite and positive.
    pub fn new(origin: [f64; 3], lengths: [f64; 3]) -> Result<Self, KernelError> {
        for axis in 0..3 {
            if !origin[axis].is_finite() {
                return Err(KernelError::InvalidCell {
                    what: "origin",
                    axis,
                    value: origin[axis],
                    expected: "finite",
                });
            }
            let l = lengths[axis];
            if !(l.is_finite() && l > 0.0) {
                return Err(KernelError::InvalidCell {
                    what: "lengths",
                    axis,
                    value: l,
                    expected: "finite and > 0",
                });
            }
        }
        Ok(Self { origin, lengths })
    }

    /// The cubic cell `origin + [0, length)^3`.
    ///
    /// # Errors
    /// As [`PeriodicCell::new`].
    pub fn cubic(origin: [f64; 3], length: f64) -> Result<Self, KernelError> {
        Self::new(origin, [length; 3])
    }

    /// The corner of the cell.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// The side lengths `[L_x, L_y, L_z]`.
    pub fn lengths(&self) -> [f64; 3] {
        self.lengths
    }

    /// `V = L_x L_y L_z`.
    pub fn volume(&self) -> f64 {
        self.lengths[0] * self.lengths[1] * self.lengths[2]
    }

    /// The image of `x` in the cell, relative to the origin: `(x - origin)
    /// mod L` per axis, in `[0, L)`.
    pub fn wrap_relative(&self, x: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for d in 0..3 {
            let l = self.lengths[d];
            let mut v = (x[d] - self.origin[d]).rem_euclid(l);
            if v >= l {
                // rem_euclid can round up to `l` for tiny negative inputs.
                v = 0.0;
            }
            out[d] = v;
        }
        out
    }

    /// The image of `x` in the cell, `origin + ((x - origin) mod L)`.
    pub fn wrap(&self, x: [f64; 3]) -> [f64; 3] {
        let r = self.wrap_relative(x);
        [
            self.origin[0] + r[0],
            self.origin[1] + r[1],
            self.origin[2] + r[2],
        ]
    }

    /// The nearest image of a displacement: `r - L round(r / L)` per axis,
    /// in `[-L/2, L/2]`.
    pub fn nearest_image(&self, r: [f64; 3]) -> [f64; 3] {
        let mut out = r;
        for d in 0..3 {
            out[d] -= self.lengths[d] * (r[d] / self.lengths[d]).round();
        }
        out
    }
}

/// Options of an [`EwaldSum`](crate::EwaldSum): the tolerance, the
/// number of targets the sum will be evaluated at (which tunes `alpha`),
/// and the screening wavenumber `kappa` (`0`, the default, for the Laplace
/// kernel `1 / (4 pi r)`; `kappa > 0` for the modified Helmholtz (Yukawa)
/// kernel `e^{-kappa r} / (4 pi r)`).
///
/// ```
/// use ferrofmm_kernels::EwaldOptions;
/// let opts = EwaldOptions::new(1e-12).expected_targets(500).screening(2.0);
/// assert_eq!(opts.tolerance, 1e-12);
/// assert_eq!(opts.screening, 2.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct EwaldOptions {
    /// Relative truncation tolerance, in `(0, 1)`; values below `1e-16` act
    /// as `1e-16` (see [`EwaldParameters`]).
    pub tolerance: f64,
    /// How many targets the sum will be evaluated at; `None` means all the
    /// sources. Few targets make the real-space sum cheaper per source and
    /// the structure factors relatively dearer, so `alpha` is smaller.
    pub expected_targets: Option<usize>,
    /// The screening wavenumber `kappa >= 0` (inverse length) of the kernel
    /// `e^{-kappa r} / (4 pi r)`; `0` is Laplace.
    pub screening: f64,
    /// Forces the splitting parameter (tests of `alpha` independence).
    #[doc(hidden)]
    pub alpha: Option<f64>,
}

impl EwaldOptions {
    /// Options with `tolerance`, all sources as targets, `alpha` chosen.
    pub fn new(tolerance: f64) -> Self {
        Self {
            tolerance,
            expected_targets: None,
            screening: 0.0,
            alpha: None,
        }
    }

    /// The same options for the screened kernel `e^{-kappa r} / (4 pi r)`
    /// (the modified Helmholtz kernel of
    /// [`ModifiedHelmholtz3d`](crate::ModifiedHelmholtz3d) with `k =
    /// kappa`).
    pub fn screening(mut self, kappa: f64) -> Self {
        self.screening = kappa;
        self
    }

    /// The same options, tuned for about `n` targets.
    pub fn expected_targets(mut self, n: usize) -> Self {
        self.expected_targets = Some(n);
        self
    }

    /// The same options with a forced splitting parameter (testing only).
    #[doc(hidden)]
    pub fn with_alpha(mut self, alpha: f64) -> Self {
        self.alpha = Some(alpha);
        self
    }
}

/// The splitting parameter and cut-offs of an Ewald sum.
///
/// # Rule
/// With `tol` the tolerance (clamped to `[1e-16, 0.5]`), let `s =
/// sqrt(ln(1/tol))`. Then
///
/// * real space: pairs (with their images) closer than `r_c = s / alpha`;
///   every dropped term `erfc(alpha r) / r` is below `erfc(s) / r_c <=
///   tol / (s sqrt(pi) r_c)`, i.e. below `tol` relative to the size `1/r_c`
///   of the terms kept at the cut-off, and the tail decays like a Gaussian;
/// * reciprocal space: wave vectors with `|k| <= k_c = 2 alpha s`, every
///   dropped term carrying `exp(-k^2/(4 alpha^2)) <= exp(-s^2) = tol` times
///   `4 pi / (V k^2) < 4 pi / (V k_c^2)`.
///
/// The errors measured (tests) are below `tol` relative to the root mean
/// square of the potentials (and of the gradients) for `tol` from `1e-3` to
/// `1e-14`; the floor is rounding, a few `1e-15` relative.
///
/// `alpha` balances the costs: with `N` sources, `N_t` targets and `V` the
/// volume, the real-space work is `~ c_r N_t (N/V) (4 pi/3) r_c^3` and the
/// reciprocal work (structure factors and evaluation) `~ c_k (N + N_t)
/// (4 pi/3) k_c^3 V / (2 (2 pi)^3)`, both `proportional to s^3`; equating
/// them gives
///
/// ```text
/// alpha^6 = 2 pi^3 (c_r / c_k) N N_t / ((N + N_t) V^2)
/// ```
///
/// and a total cost `O(N^1.5 s^3)` for `N_t = N`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EwaldParameters {
    /// The splitting parameter `alpha` (inverse length).
    pub alpha: f64,
    /// `s = sqrt(ln(1/tol))`, the reduced cut-off `alpha r_c = k_c / (2
    /// alpha)`.
    pub s: f64,
    /// Real-space cut-off radius `r_c = s / alpha`.
    pub r_cut: f64,
    /// Reciprocal-space cut-off `k_c = 2 alpha s`.
    pub k_cut: f64,
    /// The largest `|m_d|` of a wave vector `k = 2 pi m_d / L_d` per axis,
    /// `floor(k_c L_d / (2 pi))`.
    pub kmax: [usize; 3],
}

/// Cost of one real-space pair (an `erfc`, a `sqrt`, a division, with the
/// cell list's wasted pairs) relative to one wave vector at one point (a
/// complex multiply-add), measured on x86-64.
pub(crate) const COST_RATIO: f64 = 12.0;

impl EwaldParameters {
    /// Parameters for `tolerance` in `cell`, with `alpha` given.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] when the tolerance is not in `(0,
    /// 1)` or `alpha` is not finite and positive.
    pub fn with_alpha(
        cell: &PeriodicCell,
        tolerance: f64,
        alpha: f64,
    ) -> Result<Self, KernelError> {
        let s = reduced_cutoff(tolerance)?;
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(KernelError::InvalidParameter {
                name: "alpha",
                value: alpha,
                expected: "finite and > 0",
            });
        }
        let k_cut = 2.0 * alpha * s;
        let l = cell.lengths();
        let kmax = [0, 1, 2].map(|d| (k_cut * l[d] / (2.0 * PI)).floor() as usize);
        Ok(Self {
            alpha,
            s,
            r_cut: s / alpha,
            k_cut,
            kmax,
        })
    }

    /// Parameters balancing the real- and reciprocal-space costs for
    /// `n_sources` sources and `n_targets` targets (see the rule above).
    ///
    /// # Errors
    /// As [`EwaldParameters::with_alpha`].
    pub fn balanced(
        cell: &PeriodicCell,
        tolerance: f64,
        n_sources: usize,
        n_targets: usize,
    ) -> Result<Self, KernelError> {
        let n = n_sources.max(1) as f64;
        let nt = n_targets.max(1) as f64;
        let v = cell.volume();
        let a6 = 2.0 * PI.powi(3) * COST_RATIO * n * nt / ((n + nt) * v * v);
        // Not below ~2.5 / V^(1/3) (a handful of images in real space).
        let alpha = a6.powf(1.0 / 6.0).max(2.5 / v.cbrt());
        Self::with_alpha(cell, tolerance, alpha)
    }
}

/// `s = sqrt(ln(1/tol))` for a tolerance in `(0, 1)`, clamped to
/// `[1e-16, 0.5]`.
///
/// # Errors
/// [`KernelError::InvalidParameter`] otherwise.
pub(crate) fn reduced_cutoff(tolerance: f64) -> Result<f64, KernelError> {
    if !(tolerance.is_finite() && tolerance > 0.0 && tolerance < 1.0) {
        return Err(KernelError::InvalidParameter {
            name: "tolerance",
            value: tolerance,
            expected: "finite, > 0 and < 1",
        });
    }
    let t = tolerance.clamp(1e-16, 0.5);
    Ok((1.0 / t).ln().sqrt())
}
