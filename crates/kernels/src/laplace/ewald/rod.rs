//! [`RodGreen`]: the Green's function of a rod (periodic in `x`, free
//! space in `y` and `z`), pair by pair, whole or without its 3 nearest
//! images: the one-dimensional Ewald sum.
//!
//! # Maths
//! For the kernel `K(r) = e^{-kappa r} / (4 pi r)` (`kappa >= 0`; Laplace
//! at `kappa = 0`), period `L`, images `n = (n L, 0, 0)` and wave numbers
//! `k_m = 2 pi m / L`, the splitting of [`Split`] (`psi` the short-range
//! part) gives, for `r = (x, rho)` with `rho` the distance from the axis,
//!
//! ```text
//! G(r) = 1/(4 pi) sum_n psi(|r + n|)
//!      + 1/(4 pi L) sum_{m != 0} cos(k_m x) I(s_m^2 / (4 alpha^2), alpha^2 rho^2)     s_m = sqrt(k_m^2 + kappa^2)
//!      + G_0(rho)
//! I(a, b) = int_0^{alpha^2} e^{-s^2 / (4 u) - rho^2 u} du / u
//! ```
//!
//! the transverse transform of the long-range part `4 pi e^{-(K^2 +
//! kappa^2) / (4 alpha^2)} / (K^2 + kappa^2)` integrated over the plane
//! through `e^{-q/(4 alpha^2)} / q = int_{1/(4 alpha^2)}^inf e^{-q t} dt`
//! (`u = 1 / (4 t)`); `I` is an incomplete Bessel function, taken by
//! quadrature (the crate's `lattice/special.rs`). The `m = 0` term is
//! `G_0 = I(kappa^2 / (4 alpha^2), alpha^2 rho^2) / (4 pi L)` when
//! screened; at `kappa = 0` the integral diverges by a constant (dropped:
//! it cancels in a neutral cell), and what is left is
//!
//! ```text
//! G_0(rho) = -Ein(alpha^2 rho^2) / (4 pi L),   Ein(x) = int_0^x (1 - e^{-t}) / t dt
//! ```
//!
//! (far from the axis `-(ln rho) / (2 pi L)` and a constant: a line
//! charge). Gradients term by term: `d I / d rho_a = -2 rho_a alpha^2
//! J(a, b)` with `J = int_{-inf}^0 e^v e^{-a e^{-v} - b e^v} dv`, and `d G_0
//! / d rho_a = -2 rho_a (1 - e^{-alpha^2 rho^2}) / (4 pi L rho^2)` for
//! Laplace. `G` does not depend on `alpha`; a neutral set of charges sums
//! to the limit of symmetric image segments (`-Delta G = sum_n delta(r +
//! n)`: no background).

use super::pairwise::PairGreen;
use super::screening::Split;
use crate::lattice::special::{ein, incomplete_bessel};
use crate::lattice::{PeriodicCell, reduced_cutoff};
use crate::{EvalMode, INV_4PI, KernelError};

/// `alpha L` of a [`RodGreen`]: about 13 images in real space, and one or
/// two wave numbers (a quadrature each) at tolerance `1e-15`.
const ROD_ALPHA_SCALE: f64 = 1.0;

/// The periodic Green's function of a rod (periodic in `x`, free space in
/// `y` and `z`) of the Laplace kernel `1 / (4 pi r)`, or of the screened
/// kernel `e^{-kappa r} / (4 pi r)`, pair by pair (see the module docs of
/// `rod.rs` for the maths).
///
/// * [`potential`](Self::potential): `G(r)` and its gradient, every image
///   `(n L, 0, 0)`; for Laplace defined up to a constant (dropped; it
///   cancels for a neutral cell);
/// * [`far_images`](Self::far_images): `G(r)` without the 3 nearest images
///   (`|n| <= 1`): smooth where those are the nearest;
/// * [`self_potential`](Self::self_potential): `lim_{r -> 0} (G(r) -
///   K(r))`.
///
/// ```
/// use ferrofmm_kernels::{PeriodicCell, RodGreen, INV_4PI};
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// // The alternating chain: Madelung constant 2 ln 2.
/// let g = RodGreen::new(cell, 1e-15).unwrap();
/// let phi = g.self_potential() - g.potential([0.5, 0.0, 0.0])[0];
/// assert!((-phi / INV_4PI * 0.5 - 2.0 * 2f64.ln()).abs() < 1e-13);
/// ```
#[derive(Clone, Debug)]
pub struct RodGreen {
    cell: PeriodicCell,
    tolerance: f64,
    length: f64,
    alpha: f64,
    split: Split,
    r_cut: f64,
    /// `(k_m, a_m = s_m^2 / (4 alpha^2))` for `m >= 1` within the cut-off.
    modes: Vec<(f64, f64)>,
    self_potential: f64,
}

impl RodGreen {
    /// The Laplace rod Green's function of `cell` (its `x` side; the others
    /// are not used) to `tolerance` relative to its size.
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
        Self::with_alpha(cell, kappa, tolerance, ROD_ALPHA_SCALE / cell.lengths()[0])
    }

    /// The same with the splitting parameter `alpha` (the result does not
    /// depend on it, to the tolerance; for tests and tuning).
    ///
    /// # Errors
    /// As [`RodGreen::screened`], and for `alpha` not finite and positive.
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
        let length = cell.lengths()[0];
        // `I(a, b) <= E1(a) < e^{-a} / a`: wave numbers while `a <= (s_red
        // + 0.5)^2`.
        let a_cut = (s_red + 0.5).powi(2);
        let k0 = 2.0 * std::f64::consts::PI / length;
        let modes = (1..)
            .map(|m| {
                let k = m as f64 * k0;
                (k, (k * k + kappa * kappa) / (4.0 * alpha * alpha))
            })
            .take_while(|&(_, a)| a <= a_cut)
            .collect();
        let mut g = RodGreen {
            cell,
            tolerance,
            length,
            alpha,
            split: Split::new(alpha, kappa),
            r_cut: s_red / alpha,
            modes,
            self_potential: 0.0,
        };
        // The images at `+-L` are near ones, left out of `far_images`.
        g.self_potential =
            g.far_images([0.0; 3]) + 2.0 * INV_4PI * (-kappa * length).exp() / length;
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
        let l = self.length;
        let r = [r[0] - l * (r[0] / l).round(), r[1], r[2]];
        let mut out = self.smooth(r);
        let mut hit = false;
        self.for_images(r, None, |_, d, rho| {
            if rho == 0.0 {
                hit = true;
            } else if rho < self.r_cut {
                let (psi, g) = self.split.short(rho, true);
                out[0] += INV_4PI * psi;
                for a in 0..3 {
                    out[1 + a] -= INV_4PI * g * d[a];
                }
            }
        });
        if hit {
            return [f64::INFINITY, 0.0, 0.0, 0.0];
        }
        out
    }

    /// `G(r)` without the 3 nearest images of the source (`r` as given,
    /// not wrapped; smooth for `|r_x| < 1.5 L`, any `y`, `z`).
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
    /// As [`RodGreen::sum_at_points`], and an index out of range.
    pub fn sum_at_sources(
        &self,
        sources: &[f64],
        charges: &[f64],
        indices: &[usize],
        mode: EvalMode,
    ) -> Result<Vec<f64>, KernelError> {
        super::pairwise::at_sources(self, sources, charges, indices, mode)
    }

    /// Calls `f(near, d, |d|)` for the images `d = r + (n L, 0, 0)` within
    /// the cut-off, and for the 3 nearest (`near`) when `with_near`.
    fn for_images(&self, r: [f64; 3], near: Option<i64>, mut f: impl FnMut(bool, [f64; 3], f64)) {
        let l = self.length;
        let mut lo = ((-r[0] - self.r_cut) / l).floor() as i64;
        let mut hi = ((-r[0] + self.r_cut) / l).ceil() as i64;
        if let Some(m) = near {
            lo = lo.min(-m);
            hi = hi.max(m);
        }
        for n in lo..=hi {
            let d = [r[0] + n as f64 * l, r[1], r[2]];
            let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            f(near.is_some_and(|m| n.abs() <= m), d, rho);
        }
    }

    /// The reciprocal sum and the `m = 0` term, with gradients.
    fn smooth(&self, r: [f64; 3]) -> [f64; 4] {
        let a2 = self.alpha * self.alpha;
        let rho2 = r[1] * r[1] + r[2] * r[2];
        let b = a2 * rho2;
        let scale = INV_4PI / self.length;
        let mut out = [0.0; 4];
        // `m = 0`: `G_0` and `-2 rho_a c`.
        let (g0, c) = match self.split.kappa() {
            0.0 => {
                // (1 - e^{-b}) / rho^2 = alpha^2 (1 - e^{-b}) / b.
                let ratio = if b > 1e-300 {
                    -libm::expm1(-b) / b
                } else {
                    1.0
                };
                (-ein(b), a2 * ratio)
            }
            kappa => {
                let (i, j) = incomplete_bessel(kappa * kappa / (4.0 * a2), b);
                (i, a2 * j)
            }
        };
        out[0] = scale * g0;
        out[2] = -2.0 * scale * r[1] * c;
        out[3] = -2.0 * scale * r[2] * c;
        for &(k, a) in &self.modes {
            let (i, j) = incomplete_bessel(a, b);
            let (sin, cos) = (k * r[0]).sin_cos();
            out[0] += 2.0 * scale * cos * i;
            out[1] -= 2.0 * scale * k * sin * i;
            out[2] -= 4.0 * scale * cos * r[1] * a2 * j;
            out[3] -= 4.0 * scale * cos * r[2] * a2 * j;
        }
        out
    }
}

impl PairGreen for RodGreen {
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
        (&self.cell, [true, false, false], self.tolerance)
    }

    fn self_potential(&self) -> f64 {
        self.self_potential
    }

    fn name(&self) -> &'static str {
        "rod Ewald sum"
    }
}
