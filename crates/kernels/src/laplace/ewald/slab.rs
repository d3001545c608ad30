//! [`SlabGreen`]: the Green's function of a slab (periodic in `x` and `y`,
//! free space in `z`), pair by pair, whole or without its 9 nearest
//! images: Parry's two-dimensional Ewald sum.
//!
//! # Maths
//! For the kernel `K(r) = e^{-kappa r} / (4 pi r)` (`kappa >= 0`; Laplace
//! at `kappa = 0`), cell sides `L_x, L_y`, area `A = L_x L_y`, in-plane
//! lattice vectors `n = (n_x L_x, n_y L_y, 0)` and wave vectors `k = 2 pi
//! (m_x / L_x, m_y / L_y)`, the splitting of [`Split`] (`psi` the
//! short-range part) gives, for `r = (rho, z)`,
//!
//! ```text
//! G(r) = 1/(4 pi) sum_n psi(|r + n|)
//!      + 1/A sum_{k != 0} cos(k . rho) T(s_k, z) / (4 s_k)      s_k = sqrt(k^2 + kappa^2)
//!      + G_0(z)
//! T(s, z) = e^{s z} erfc(alpha z + s / (2 alpha)) + e^{-s z} erfc(-alpha z + s / (2 alpha))
//! ```
//!
//! the in-plane transform of the long-range part `4 pi e^{-(K^2 + kappa^2)
//! / (4 alpha^2)} / (K^2 + kappa^2)` integrated over `K_z` in closed form.
//! The `k = 0` term is `G_0(z) = T(kappa, z) / (4 A kappa)` when screened;
//! at `kappa = 0` its divergent constant `1 / (2 A s)` is dropped (it
//! cancels in a neutral cell) and the limit is
//!
//! ```text
//! G_0(z) = -(1 / (2 A)) [ z erf(alpha z) + e^{-alpha^2 z^2} / (alpha sqrt(pi)) ]
//! ```
//!
//! (far from the plane `-|z| / (2 A)`, the potential of a charged sheet).
//! The gradients follow term by term; in `z` the Gaussian parts of `T'`
//! cancel: `dT/dz = s [ e^{s z} erfc(alpha z + s/(2 alpha)) - e^{-s z}
//! erfc(-alpha z + s/(2 alpha)) ]`, and `dG_0/dz = -erf(alpha z) / (2 A)`
//! for Laplace. `G` does not depend on `alpha`; a neutral set of charges
//! sums to the limit of expanding, centrally symmetric image shells
//! (`-Delta G = sum_n delta(r + n)`: no background).

use super::pairwise::PairGreen;
use super::screening::{Split, grow};
use crate::lattice::{PeriodicCell, phase_table, reduced_cutoff};
use crate::{EvalMode, INV_4PI, KernelError};

/// `alpha sqrt(A)` of a [`SlabGreen`]: balances the ~35 in-plane images
/// (an `erfc` each) against the ~35 wave vectors (two `erfc` each) at
/// tolerance `1e-15`.
const SLAB_ALPHA_SCALE: f64 = 1.8;

/// One wave vector of the quadrant `m_x, m_y >= 0` (not both zero).
#[derive(Clone, Copy, Debug)]
struct Mode {
    m: [usize; 2],
    /// `s_k`.
    s: f64,
    /// `multiplicity / (4 A s)` (the cosines of `+-m_x, +-m_y` folded).
    weight: f64,
}

/// The periodic Green's function of a slab (periodic in `x` and `y`, free
/// space in `z`) of the Laplace kernel `1 / (4 pi r)`, or of the screened
/// kernel `e^{-kappa r} / (4 pi r)`, pair by pair (see the module docs of
/// `slab.rs` for the maths): Parry's Ewald sum.
///
/// * [`potential`](Self::potential): `G(r)` and its gradient, every image
///   `n = (n_x L_x, n_y L_y, 0)`; for Laplace defined up to a constant
///   (dropped; it cancels for a neutral cell);
/// * [`far_images`](Self::far_images): `G(r)` without the 9 nearest images
///   (`|n_x|, |n_y| <= 1`): smooth where those are the nearest;
/// * [`self_potential`](Self::self_potential): `lim_{r -> 0} (G(r) -
///   K(r))`.
///
/// ```
/// use ferrofmm_kernels::{PeriodicCell, SlabGreen, INV_4PI};
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// // Screened strongly: a few rings of images converge.
/// let kappa = 8.0;
/// let g = SlabGreen::screened(cell, kappa, 1e-15).unwrap();
/// let r = [0.3, -0.2, 0.4];
/// let mut sum = 0.0;
/// for nx in -8i32..=8 { for ny in -8i32..=8 {
///     let d = [r[0] + nx as f64, r[1] + ny as f64, r[2]];
///     let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
///     sum += INV_4PI * (-kappa * rho).exp() / rho;
/// }}
/// assert!((g.potential(r)[0] - sum).abs() < 1e-14 * sum);
/// ```
#[derive(Clone, Debug)]
pub struct SlabGreen {
    cell: PeriodicCell,
    tolerance: f64,
    lengths: [f64; 2],
    alpha: f64,
    split: Split,
    r_cut: f64,
    modes: Vec<Mode>,
    m_max: [usize; 2],
    area: f64,
    self_potential: f64,
}

impl SlabGreen {
    /// The Laplace slab Green's function of `cell` (its `x` and `y` sides;
    /// the `z` side is not used) to `tolerance` relative to its size.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`.
    pub fn new(cell: PeriodicCell, tolerance: f64) -> Result<Self, KernelError> {
        Self::screened(cell, 0.0, tolerance)
    }

    /// The same for the screened kernel `e^{-kappa r} / (4 pi r)`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`
    /// or a `kappa` that is negative or not finite.
    pub fn screened(cell: PeriodicCell, kappa: f64, tolerance: f64) -> Result<Self, KernelError> {
        let alpha = SLAB_ALPHA_SCALE / (cell.lengths()[0] * cell.lengths()[1]).sqrt();
        Self::with_alpha(cell, kappa, tolerance, alpha)
    }

    /// The same with the splitting parameter `alpha` (the result does not
    /// depend on it, to the tolerance; for tests and tuning).
    ///
    /// # Errors
    /// As [`SlabGreen::screened`], and for `alpha` not finite and positive.
    pub fn with_alpha(
        cell: PeriodicCell,
        kappa: f64,
        tolerance: f64,
        alpha: f64,
    ) -> Result<Self, KernelError> {
        let kappa = crate::error::check_wavenumber(kappa)?;
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(KernelError::InvalidParameter {
                name: "alpha",
                value: alpha,
                expected: "finite and > 0",
            });
        }
        let s_red = reduced_cutoff(tolerance)?;
        let [lx, ly, _] = cell.lengths();
        let area = lx * ly;
        let split = Split::new(alpha, kappa);
        // `T(s, z) <~ 2 e^{-s^2 / (4 alpha^2)}`: wave vectors up to `2 alpha
        // s_red`, with half a unit of margin for the `1/s` and `e^{s|z|}`
        // factors.
        let k_cut = 2.0 * alpha * (s_red + 0.5);
        let k0 = [
            2.0 * std::f64::consts::PI / lx,
            2.0 * std::f64::consts::PI / ly,
        ];
        let m_max = [0, 1].map(|a| (k_cut / k0[a]).floor() as usize);
        let mut modes = Vec::new();
        for mx in 0..=m_max[0] {
            for my in 0..=m_max[1] {
                if mx == 0 && my == 0 {
                    continue;
                }
                let k2 = (mx as f64 * k0[0]).powi(2) + (my as f64 * k0[1]).powi(2);
                if k2 > k_cut * k_cut {
                    continue;
                }
                let s = (k2 + kappa * kappa).sqrt();
                let mult = if mx > 0 && my > 0 { 4.0 } else { 2.0 };
                modes.push(Mode {
                    m: [mx, my],
                    s,
                    weight: mult / (4.0 * area * s),
                });
            }
        }
        let mut g = SlabGreen {
            cell,
            tolerance,
            lengths: [lx, ly],
            alpha,
            split,
            r_cut: s_red / alpha,
            modes,
            m_max,
            area,
            self_potential: 0.0,
        };
        let mut xi = g.far_images([0.0; 3]);
        for nx in -1i64..=1 {
            for ny in -1i64..=1 {
                if (nx, ny) != (0, 0) {
                    let rho = ((nx as f64 * lx).powi(2) + (ny as f64 * ly).powi(2)).sqrt();
                    xi += INV_4PI * (-kappa * rho).exp() / rho;
                }
            }
        }
        g.self_potential = xi;
        Ok(g)
    }

    /// The splitting parameter `alpha`.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// The screening `kappa` (`0`: Laplace).
    pub fn screening(&self) -> f64 {
        self.split.kappa()
    }

    /// `[G, dG/dx, dG/dy, dG/dz]` at displacement `r` (target minus
    /// source), every image; `+inf` at an image of the source.
    pub fn potential(&self, r: [f64; 3]) -> [f64; 4] {
        let r = self.nearest(r);
        let mut out = self.smooth(r);
        let mut hit = false;
        self.for_images(r, None, |_, d, rho| {
            if rho == 0.0 {
                hit = true;
            } else if rho < self.r_cut {
                add_short(&self.split, d, rho, &mut out);
            }
        });
        if hit {
            return [f64::INFINITY, 0.0, 0.0, 0.0];
        }
        out
    }

    /// `G(r)` without the 9 nearest images of the source (`r` as given,
    /// not wrapped; smooth for `|r_x| < 1.5 L_x`, `|r_y| < 1.5 L_y`, any
    /// `z`).
    pub fn far_images(&self, r: [f64; 3]) -> f64 {
        self.far_with(r, 1, false)[0]
    }

    /// `G(r)` and its gradient without the images `|n_a| <= m` along the
    /// repeating axes (the gradient only when `grad`).
    fn far_with(&self, r: [f64; 3], m: i64, grad: bool) -> [f64; 4] {
        let real = super::pairwise::far_real(&self.split, self.r_cut, grad, |f| {
            self.for_images(r, Some(m), f)
        });
        let mut out = self.smooth(r);
        for a in 0..4 {
            out[a] += real[a];
        }
        out
    }

    /// `lim_{r -> 0} (G(r) - K(r))`: the potential at a unit source of its
    /// own images.
    pub fn self_potential(&self) -> f64 {
        self.self_potential
    }

    /// `M[i * n_sources + j] = far_images(t_i - s_j)`, row-major, parallel
    /// over rows.
    ///
    /// # Errors
    /// [`KernelError::NotMultipleOf3`] or [`KernelError::NonFinite`] for
    /// bad points.
    pub fn far_images_matrix(
        &self,
        targets: &[f64],
        sources: &[f64],
    ) -> Result<Vec<f64>, KernelError> {
        super::pairwise::far_matrix(targets, sources, |r| self.far_images(r))
    }

    /// The potentials (and gradients, per `mode`: `1` or `4` values a
    /// target) at `targets` of the charges `charges` at `sources`, every
    /// image included: `sum_j q_j G(t - x_j)`, by pairs (`O(N M)`,
    /// parallel over targets).
    ///
    /// # Errors
    /// Bad points, `charges` not one per source, or Hessians.
    pub fn sum_at_points(
        &self,
        sources: &[f64],
        charges: &[f64],
        targets: &[f64],
        mode: EvalMode,
    ) -> Result<Vec<f64>, KernelError> {
        super::pairwise::at_points(self, sources, charges, targets, mode)
    }

    /// The same at the sources `indices`, each leaving out only itself
    /// (its own images included).
    ///
    /// # Errors
    /// As [`SlabGreen::sum_at_points`], and an index out of range.
    pub fn sum_at_sources(
        &self,
        sources: &[f64],
        charges: &[f64],
        indices: &[usize],
        mode: EvalMode,
    ) -> Result<Vec<f64>, KernelError> {
        super::pairwise::at_sources(self, sources, charges, indices, mode)
    }

    /// `r` moved by in-plane lattice vectors to `|r_x| <= L_x / 2`, `|r_y|
    /// <= L_y / 2`.
    fn nearest(&self, r: [f64; 3]) -> [f64; 3] {
        let [lx, ly] = self.lengths;
        [
            r[0] - lx * (r[0] / lx).round(),
            r[1] - ly * (r[1] / ly).round(),
            r[2],
        ]
    }

    /// Calls `f(near, d, |d|)` for the in-plane images `d = r + n` within
    /// the cut-off, and for the 9 nearest (`near`) when `with_near`.
    fn for_images(&self, r: [f64; 3], near: Option<i64>, mut f: impl FnMut(bool, [f64; 3], f64)) {
        let [lx, ly] = self.lengths;
        let range = |x: f64, l: f64| {
            let mut lo = ((-x - self.r_cut) / l).floor() as i64;
            let mut hi = ((-x + self.r_cut) / l).ceil() as i64;
            if let Some(m) = near {
                lo = lo.min(-m);
                hi = hi.max(m);
            }
            (lo, hi)
        };
        let (x0, x1) = range(r[0], lx);
        let (y0, y1) = range(r[1], ly);
        for ny in y0..=y1 {
            for nx in x0..=x1 {
                let d = [r[0] + nx as f64 * lx, r[1] + ny as f64 * ly, r[2]];
                let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                f(near.is_some_and(|m| nx.abs() <= m && ny.abs() <= m), d, rho);
            }
        }
    }

    /// The reciprocal sum and the `k = 0` term, with gradients.
    fn smooth(&self, r: [f64; 3]) -> [f64; 4] {
        let z = r[2];
        let a = self.alpha;
        let mut out = [0.0; 4];
        // `k = 0`.
        let kappa = self.split.kappa();
        if kappa == 0.0 {
            let az = a * z;
            let erf = libm::erf(az);
            out[0] = -(z * erf + (-az * az).exp() / (a * std::f64::consts::PI.sqrt()))
                / (2.0 * self.area);
            out[3] = -erf / (2.0 * self.area);
        } else {
            let (t, dt) = t_pair(kappa, a, z);
            out[0] = t / (4.0 * self.area * kappa);
            out[3] = dt / (4.0 * self.area * kappa);
        }
        if self.modes.is_empty() {
            return out;
        }
        let [mx, my] = self.m_max;
        let mut cx = vec![0.0; mx + 1];
        let mut sx = vec![0.0; mx + 1];
        let mut cy = vec![0.0; my + 1];
        let mut sy = vec![0.0; my + 1];
        let k0 = [0, 1].map(|d| 2.0 * std::f64::consts::PI / self.lengths[d]);
        phase_table(k0[0] * r[0], &mut cx, &mut sx);
        phase_table(k0[1] * r[1], &mut cy, &mut sy);
        for mode in &self.modes {
            let [ix, iy] = mode.m;
            let (t, dt) = t_pair(mode.s, a, z);
            let w = mode.weight;
            let (c, s) = (cx[ix] * cy[iy], [sx[ix] * cy[iy], cx[ix] * sy[iy]]);
            out[0] += w * c * t;
            out[1] -= w * ix as f64 * k0[0] * s[0] * t;
            out[2] -= w * iy as f64 * k0[1] * s[1] * t;
            out[3] += w * c * dt;
        }
        out
    }
}

/// `(T(s, z), dT/dz)` of the module docs.
fn t_pair(s: f64, alpha: f64, z: f64) -> (f64, f64) {
    let c = s / (2.0 * alpha);
    let up = grow(s * z, libm::erfc(alpha * z + c));
    let down = grow(-s * z, libm::erfc(-alpha * z + c));
    (up + down, s * (up - down))
}

/// Adds the short-range part of one image at `d`, `|d| = rho > 0`.
fn add_short(split: &Split, d: [f64; 3], rho: f64, out: &mut [f64; 4]) {
    let (psi, g) = split.short(rho, true);
    out[0] += INV_4PI * psi;
    for a in 0..3 {
        out[1 + a] -= INV_4PI * g * d[a];
    }
}

impl PairGreen for SlabGreen {
    fn value(&self, r: [f64; 3]) -> [f64; 4] {
        self.potential(r)
    }

    fn far(&self, r: [f64; 3], m: i64) -> [f64; 4] {
        self.far_with(r, m, true)
    }

    fn kappa(&self) -> f64 {
        self.split.kappa()
    }

    fn cell(&self) -> (&PeriodicCell, [bool; 3], f64) {
        (&self.cell, [true, true, false], self.tolerance)
    }

    fn self_potential(&self) -> f64 {
        self.self_potential
    }

    fn name(&self) -> &'static str {
        "slab Ewald sum"
    }
}
