//! [`PeriodicGreen`]: the periodic Green's function of a cell pair by pair,
//! whole or without its 27 nearest images.

use super::screening::Split;
use crate::lattice::{
    Octant, PeriodicCell, for_images, image_range, near_images, norm, phase_table, reduced_cutoff,
};
use crate::{INV_4PI, KernelError};

/// `alpha V^(1/3)` of a [`PeriodicGreen`]: the balance of ~30-60 images
/// in real space (`erf`/`erfc` each) against ~1,200 wave vectors of the
/// positive octant (one multiply-add each) at `tol = 1e-15`.
const GREEN_ALPHA_SCALE: f64 = 7.0;

/// The periodic Green's function `G(r)` of the Laplace kernel `1/(4 pi r)`
/// in a cell (tin-foil, zero mean: see the [module docs](crate::ewald)), or
/// of the screened kernel `e^{-kappa r} / (4 pi r)`, and `G` without the 27
/// nearest images, pair by pair.
///
/// * [`potential`](Self::potential): `G(r)`, every image, periodic;
/// * [`far_images`](Self::far_images): `F(r) = G(r) - sum_{n in {-1,0,1}^3}
///   K(r - n∘L)`, i.e. the sum over every image outside the `3 x 3 x 3`
///   block around `r` plus the background; smooth (harmonic up to the
///   constant `-1/V` source: `-Delta F = -1/V`) wherever the 27 images are
///   the nearest ones, in particular for `|r_d| < 1.5 L_d`, and not
///   periodic;
/// * [`self_potential`](Self::self_potential): `xi = lim_{r->0} (G(r) -
///   K(r)) = F(0) + sum_{n != 0 in {-1,0,1}^3} K(n∘L)`.
///
/// All are evaluated by Ewald splitting, with the real-space lattice sum
/// over every image within `r_c` of `r` (not a minimum-image convention):
///
/// ```text
/// F(r) = 1/(4 pi) [ - sum_{n in {-1,0,1}^3} erf(alpha rho_n) / rho_n
///                   + sum_{n outside, rho_n < r_c} erfc(alpha rho_n) / rho_n ]
///      + sum_{m >= 0, m != 0, |k| <= k_c} 2^{nz(m)} (1/V) exp(-k^2/(4 alpha^2)) / k^2
///                 cos(k_x r_x) cos(k_y r_y) cos(k_z r_z)
///      - 1 / (4 alpha^2 V)
/// ```
///
/// with `rho_n = |r + n∘L|`, `erf(alpha rho)/rho -> 2 alpha / sqrt(pi)` at
/// `rho = 0`, and the reciprocal sum folded onto the octant `m_d >= 0`
/// (`nz(m)` nonzero components; `sum_signs cos(a +- b +- c) = 4 cos a cos b
/// cos c`), with the cosines by recurrence per axis. No cancellation of
/// singular terms: accurate to a few `1e-16 / L` absolute at tolerance
/// `1e-15`. Precomputed once: the wave-vector coefficients; per pair: three
/// short phase tables, one multiply-add per octant wave vector and
/// `~30-60` `erf`/`erfc`.
///
/// ```
/// use ferrofmm_kernels::{PeriodicCell, PeriodicGreen, INV_4PI};
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// let g = PeriodicGreen::new(cell, 1e-15).unwrap();
/// let r = [0.3, -0.2, 0.1];
/// let mut near = 0.0;
/// for nx in -1..=1 { for ny in -1..=1 { for nz in -1..=1 {
///     let d = [r[0] - nx as f64, r[1] - ny as f64, r[2] - nz as f64];
///     near += INV_4PI / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
/// }}}
/// assert!((g.potential(r) - (g.far_images(r) + near)).abs() < 1e-14);
/// // Periodic:
/// assert!((g.potential(r) - g.potential([1.3, 0.8, -2.9])).abs() < 1e-14);
/// ```
///
/// # Screened kernel
/// [`PeriodicGreen::screened`] gives the same for the modified Helmholtz
/// (Yukawa) kernel `K(r) = e^{-kappa r} / (4 pi r)`, whose lattice sum
/// converges absolutely: no background, `(-Delta + kappa^2) F = 0` where
/// the 27 images are the nearest, and the Ewald split of the module's
/// `screening.rs` (`erfc(alpha rho) / rho` becomes the screened
/// short-range kernel `psi(rho)`, `erf(alpha rho) / rho` its long-range
/// part `l(rho)`, and the reciprocal coefficients `exp(-(k^2 + kappa^2) /
/// (4 alpha^2)) / (k^2 + kappa^2)`, the `k = 0` one included).
///
/// ```
/// use ferrofmm_kernels::{PeriodicCell, PeriodicGreen, INV_4PI};
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// let kappa = 6.0;
/// let g = PeriodicGreen::screened(cell, kappa, 1e-15).unwrap();
/// // Screened strongly enough that a few shells of images converge.
/// let r = [0.3, -0.2, 0.1];
/// let mut sum = 0.0;
/// for nx in -8i32..=8 { for ny in -8i32..=8 { for nz in -8i32..=8 {
///     let d = [r[0] - nx as f64, r[1] - ny as f64, r[2] - nz as f64];
///     let rho = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
///     sum += INV_4PI * (-kappa * rho).exp() / rho;
/// }}}
/// assert!((g.potential(r) - sum).abs() < 1e-14 * sum);
/// ```
#[derive(Clone, Debug)]
pub struct PeriodicGreen {
    cell: PeriodicCell,
    alpha: f64,
    split: Split,
    r_cut: f64,
    /// The wave vectors, `coef[offset + m_z]` for a column's `m_z < len`.
    octant: Octant,
    coef: Vec<f64>,
    background: f64,
    self_potential: f64,
}

impl PeriodicGreen {
    /// The Green's function of `cell` to `tolerance` (relative to the size
    /// `1/L` of `G`; see [`EwaldParameters`](crate::EwaldParameters) for the
    /// cut-off rule), with `alpha = 7 / V^(1/3)`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`.
    pub fn new(cell: PeriodicCell, tolerance: f64) -> Result<Self, KernelError> {
        Self::screened(cell, 0.0, tolerance)
    }

    /// The Green's function of the screened kernel `e^{-kappa r} / (4 pi
    /// r)` in `cell` (see [Screened kernel](#screened-kernel)); `kappa = 0`
    /// is [`PeriodicGreen::new`]. `alpha = 7 / V^(1/3)`, as for Laplace.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`,
    /// or a `kappa` that is negative or not finite.
    pub fn screened(cell: PeriodicCell, kappa: f64, tolerance: f64) -> Result<Self, KernelError> {
        let kappa = crate::error::check_wavenumber(kappa)?;
        let s = reduced_cutoff(tolerance)?;
        let volume = cell.volume();
        let alpha = GREEN_ALPHA_SCALE / volume.cbrt();
        let split = Split::new(alpha, kappa);
        let l = cell.lengths();
        let octant = Octant::new(l, 2.0 * alpha * s);
        let mut coef = Vec::new();
        octant.for_each(|k, mult| {
            let k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
            coef.push(if k2 == 0.0 {
                0.0
            } else {
                mult / volume * split.fourier(k2)
            });
        });
        let mut g = Self {
            cell,
            alpha,
            split,
            r_cut: s / alpha,
            octant,
            coef,
            background: split.k_zero(volume),
            self_potential: 0.0,
        };
        let mut xi = g.far_images([0.0; 3]);
        for n in near_images() {
            if n != [0, 0, 0] {
                let rho = norm([0, 1, 2].map(|a| n[a] as f64 * l[a]));
                xi += INV_4PI * (-kappa * rho).exp() / rho;
            }
        }
        g.self_potential = xi;
        Ok(g)
    }

    /// The cell.
    pub fn cell(&self) -> &PeriodicCell {
        &self.cell
    }

    /// The screening wavenumber `kappa` (`0`: Laplace).
    pub fn screening(&self) -> f64 {
        self.split.kappa()
    }

    /// The splitting parameter `alpha`.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// `G(r)`: the periodic potential at displacement `r` (target minus
    /// source) of a unit charge and all its images, with a uniform
    /// background `-1/V` (tin-foil, zero mean over the cell). `+inf` at the
    /// lattice points.
    pub fn potential(&self, r: [f64; 3]) -> f64 {
        let r = self.cell.nearest_image(r);
        let l = self.cell.lengths();
        let (lo, hi) = self.image_range(r, false);
        let mut real = 0.0;
        let mut at_lattice_point = false;
        for_images(r, l, lo, hi, |_, rho| {
            if rho < self.r_cut {
                at_lattice_point |= rho == 0.0;
                if rho > 0.0 {
                    real += self.split.short(rho, false).0;
                }
            }
        });
        if at_lattice_point {
            return f64::INFINITY;
        }
        INV_4PI * real + self.reciprocal(r) + self.background
    }

    /// `F(r) = G(r) - sum_{n in {-1,0,1}^3} K(r - n∘L)`: the periodic
    /// potential without the 27 nearest images of the source (`r` as given,
    /// not wrapped; smooth for `|r_d| < 1.5 L_d`, finite everywhere).
    pub fn far_images(&self, r: [f64; 3]) -> f64 {
        let l = self.cell.lengths();
        let (lo, hi) = self.image_range(r, true);
        let mut real = 0.0;
        for_images(r, l, lo, hi, |n, rho| {
            if n.iter().all(|c| c.abs() <= 1) {
                real -= self.split.long(rho);
            } else if rho < self.r_cut {
                real += self.split.short(rho, false).0;
            }
        });
        INV_4PI * real + self.reciprocal(r) + self.background
    }

    /// `xi = lim_{r -> 0} (G(r) - K(r))`: the potential at a unit source of
    /// its own images and background.
    pub fn self_potential(&self) -> f64 {
        self.self_potential
    }

    /// `M[i * n_sources + j] = F(t_i - s_j)` ([`far_images`](Self::far_images))
    /// for interleaved `targets` and `sources`, row-major, parallel over
    /// rows.
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

    /// [`image_range`] for this cell and cut-off.
    fn image_range(&self, r: [f64; 3], near: bool) -> ([i64; 3], [i64; 3]) {
        image_range(self.cell.lengths(), self.r_cut, r, near)
    }

    /// `sum_{m in octant} c_m cos(k_x r_x) cos(k_y r_y) cos(k_z r_z)`.
    fn reciprocal(&self, r: [f64; 3]) -> f64 {
        const STACK: usize = 64;
        let [mx, my, mz] = self.octant.kmax;
        if mx.max(my).max(mz) >= STACK {
            let mut c = [vec![0.0; mx + 1], vec![0.0; my + 1], vec![0.0; mz + 1]];
            let mut s = [vec![0.0; mx + 1], vec![0.0; my + 1], vec![0.0; mz + 1]];
            for d in 0..3 {
                phase_table(self.octant.k0[d] * r[d], &mut c[d], &mut s[d]);
            }
            return self.octant_sum(&c[0], &c[1], &c[2]);
        }
        let mut c = [[0.0; STACK]; 3];
        let mut s = [0.0; STACK];
        for d in 0..3 {
            let m = self.octant.kmax[d] + 1;
            phase_table(self.octant.k0[d] * r[d], &mut c[d][..m], &mut s[..m]);
        }
        self.octant_sum(&c[0][..=mx], &c[1][..=my], &c[2][..=mz])
    }

    fn octant_sum(&self, cx: &[f64], cy: &[f64], cz: &[f64]) -> f64 {
        let mut total = 0.0;
        for &(mx, my, offset, len) in &self.octant.columns {
            let c = &self.coef[offset..offset + len];
            let z = &cz[..len];
            let mut t = 0.0;
            for k in 0..len {
                t += c[k] * z[k];
            }
            total += cx[mx] * cy[my] * t;
        }
        total
    }
}
