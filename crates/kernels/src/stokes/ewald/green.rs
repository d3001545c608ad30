//! [`PeriodicStokeslet`]: the periodic Stokeslet of a cell pair by pair,
//! whole or without its 27 nearest images.

use super::split::{Block, HasimotoSplit};
use super::sum::TOLERANCE_MARGIN;
use crate::KernelError;
use crate::lattice::{
    Octant, PeriodicCell, check_points, for_images, image_range, phase_table, reduced_cutoff,
};
use rayon::prelude::*;
use std::f64::consts::PI;

/// `alpha V^(1/3)`, as for [`PeriodicGreen`](crate::PeriodicGreen).
const GREEN_ALPHA_SCALE: f64 = 7.0;

/// Per octant wave vector: `w`, then `w k_x^2/k^2`, `w k_y^2/k^2`, `w
/// k_z^2/k^2`, `w k_x k_y/k^2`, `w k_x k_z/k^2`, `w k_y k_z/k^2`, with `w`
/// the weight of the projector and the octant's multiplicity.
const WEIGHTS: usize = 7;

/// The periodic Stokeslet `G_per(r)` of a cell (Hasimoto: zero mean
/// velocity, a net force balanced by a uniform pressure gradient; see the
/// [module docs](super)) and `G_per` without its 27 nearest images, as `3
/// x 3` blocks, pair by pair:
///
/// * [`velocity`](Self::velocity): `G_per(r)`, every image, periodic;
/// * [`far_images`](Self::far_images): `F(r) = G_per(r) - sum_{n in
///   {-1,0,1}^3} G(r - n∘L)`, smooth where the 27 images are the nearest
///   ones (in particular for `|r_d| < 1.5 L_d`), not periodic.
///
/// Both by Hasimoto's split, the real-space sum over every image within
/// `r_c` of `r`, and the Fourier sum folded onto the octant `m_d >= 0`
/// (diagonal entries `sum w (1 - k_a^2/k^2) prod_d cos(k_d r_d)`,
/// off-diagonal `sum w (k_a k_b / k^2) sin(k_a r_a) sin(k_b r_b) cos(k_c
/// r_c)`, cosines and sines by recurrence per axis).
///
/// ```
/// use ferrofmm_kernels::{PeriodicCell, PeriodicStokeslet};
/// let cell = PeriodicCell::cubic([0.0; 3], 1.0).unwrap();
/// let g = PeriodicStokeslet::new(cell, 1.0, 1e-14).unwrap();
/// let r = [0.3, -0.2, 0.1];
/// let (whole, far) = (g.velocity(r), g.far_images(r));
/// // Periodic, and the far images are the whole less the 27 nearest.
/// let shifted = g.velocity([1.3, 0.8, -2.9]);
/// assert!((whole[0][1] - shifted[0][1]).abs() < 1e-13);
/// assert!((whole[2][2] - far[2][2]).abs() > 0.01);
/// ```
#[derive(Clone, Debug)]
pub struct PeriodicStokeslet {
    cell: PeriodicCell,
    viscosity: f64,
    split: HasimotoSplit,
    r_cut: f64,
    /// The wave vectors: a column's `m_z < len` at
    /// `weights[WEIGHTS * (offset + m_z)..]`.
    octant: Octant,
    weights: Vec<f64>,
}

impl PeriodicStokeslet {
    /// The periodic Stokeslet of `cell` for `viscosity`, to `tolerance`
    /// (relative to the size `1 / (8 pi mu L)` of `G`), with `alpha = 7 /
    /// V^(1/3)`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a tolerance outside `(0, 1)`
    /// or a viscosity that is not finite and positive.
    pub fn new(cell: PeriodicCell, viscosity: f64, tolerance: f64) -> Result<Self, KernelError> {
        let viscosity = crate::Stokes3d::new(viscosity)?.viscosity;
        reduced_cutoff(tolerance)?;
        let s = reduced_cutoff((tolerance * TOLERANCE_MARGIN).max(1e-300))?;
        let volume = cell.volume();
        let alpha = GREEN_ALPHA_SCALE / volume.cbrt();
        let split = HasimotoSplit::new(alpha);
        let octant = Octant::new(cell.lengths(), 2.0 * alpha * s);
        let scale = 1.0 / (8.0 * PI * viscosity * volume);
        let mut weights = Vec::new();
        octant.for_each(|[kx, ky, kz], mult| {
            let k2 = kx * kx + ky * ky + kz * kz;
            if k2 == 0.0 {
                weights.extend([0.0; WEIGHTS]);
                return;
            }
            let w = mult * scale * split.fourier(k2);
            let u = w / k2;
            weights.extend([
                w,
                u * kx * kx,
                u * ky * ky,
                u * kz * kz,
                u * kx * ky,
                u * kx * kz,
                u * ky * kz,
            ]);
        });
        Ok(Self {
            cell,
            viscosity,
            split,
            r_cut: s / alpha,
            octant,
            weights,
        })
    }

    /// The cell.
    pub fn cell(&self) -> &PeriodicCell {
        &self.cell
    }

    /// The viscosity `mu`.
    pub fn viscosity(&self) -> f64 {
        self.viscosity
    }

    /// `G_per(r)`: the periodic velocity at displacement `r` (target minus
    /// source) of a unit force along each axis (column `b` for force
    /// `e_b`), with all its images. Infinite at the lattice points.
    pub fn velocity(&self, r: [f64; 3]) -> [[f64; 3]; 3] {
        let r = self.cell.nearest_image(r);
        let mut real = [[0.0; 3]; 3];
        let mut at_lattice_point = false;
        let (lo, hi) = self.image_range(r, false);
        for_images(r, self.cell.lengths(), lo, hi, |n, rho| {
            if rho < self.r_cut {
                at_lattice_point |= rho == 0.0;
                if rho > 0.0 {
                    add_block(
                        &mut real,
                        &self.split.short(rho, false),
                        shifted(r, n, self.cell.lengths()),
                        1.0,
                    );
                }
            }
        });
        if at_lattice_point {
            return [[f64::INFINITY; 3]; 3];
        }
        self.finish(real, r)
    }

    /// `F(r) = G_per(r) - sum_{n in {-1,0,1}^3} G(r - n∘L)` (`r` as given,
    /// not wrapped; finite everywhere).
    pub fn far_images(&self, r: [f64; 3]) -> [[f64; 3]; 3] {
        let l = self.cell.lengths();
        let mut real = [[0.0; 3]; 3];
        let (lo, hi) = self.image_range(r, true);
        for_images(r, l, lo, hi, |n, rho| {
            let d = shifted(r, n, l);
            if n.iter().all(|c| c.abs() <= 1) {
                add_block(&mut real, &self.split.long(rho), d, -1.0);
            } else if rho < self.r_cut {
                add_block(&mut real, &self.split.short(rho, false), d, 1.0);
            }
        });
        self.finish(real, r)
    }

    /// `M[(3 i + a) * 3 n_s + 3 j + b] = F_ab(t_i - s_j)`
    /// ([`far_images`](Self::far_images)) for interleaved `targets` and
    /// `sources`: the layout of [`Kernel::assemble`](crate::Kernel::assemble)
    /// for [`Stokes3d`](crate::Stokes3d); parallel over targets.
    ///
    /// # Errors
    /// [`KernelError::NotMultipleOf3`] or [`KernelError::NonFinite`] for
    /// bad points.
    pub fn far_images_matrix(
        &self,
        targets: &[f64],
        sources: &[f64],
    ) -> Result<Vec<f64>, KernelError> {
        check_points("targets", targets)?;
        check_points("sources", sources)?;
        let cols = sources.len();
        let mut out = vec![0.0; targets.len() * cols];
        if cols == 0 {
            return Ok(out);
        }
        out.par_chunks_mut(3 * cols)
            .enumerate()
            .for_each(|(i, rows)| {
                let t = &targets[3 * i..3 * i + 3];
                for (j, s) in sources.chunks_exact(3).enumerate() {
                    let f = self.far_images([t[0] - s[0], t[1] - s[1], t[2] - s[2]]);
                    for a in 0..3 {
                        for b in 0..3 {
                            rows[a * cols + 3 * j + b] = f[a][b];
                        }
                    }
                }
            });
        Ok(out)
    }

    /// The real-space part (without `1 / (8 pi mu)`) plus the Fourier part.
    fn finish(&self, real: [[f64; 3]; 3], r: [f64; 3]) -> [[f64; 3]; 3] {
        let inv = 1.0 / (8.0 * PI * self.viscosity);
        let mut out = self.fourier(r);
        for a in 0..3 {
            for b in 0..3 {
                out[a][b] += inv * real[a][b];
            }
        }
        out
    }

    /// [`image_range`] for this cell and cut-off.
    fn image_range(&self, r: [f64; 3], near: bool) -> ([i64; 3], [i64; 3]) {
        image_range(self.cell.lengths(), self.r_cut, r, near)
    }

    /// The Fourier part of `G_per(r)`, folded onto the octant.
    fn fourier(&self, r: [f64; 3]) -> [[f64; 3]; 3] {
        let [mx, my, mz] = self.octant.kmax;
        let mut cos = [vec![0.0; mx + 1], vec![0.0; my + 1], vec![0.0; mz + 1]];
        let mut sin = [vec![0.0; mx + 1], vec![0.0; my + 1], vec![0.0; mz + 1]];
        for d in 0..3 {
            phase_table(self.octant.k0[d] * r[d], &mut cos[d], &mut sin[d]);
        }
        // Diagonal: sum cx cy (t_w - t_aa); off-diagonal as in the docs.
        let mut acc = [0.0f64; 6];
        for &(ix, iy, offset, len) in &self.octant.columns {
            let w = &self.weights[WEIGHTS * offset..WEIGHTS * (offset + len)];
            let (cz, sz) = (&cos[2][..len], &sin[2][..len]);
            let mut t = [0.0f64; WEIGHTS];
            for k in 0..len {
                let q = &w[WEIGHTS * k..WEIGHTS * k + WEIGHTS];
                let (c, s) = (cz[k], sz[k]);
                t[0] += q[0] * c;
                t[1] += q[1] * c;
                t[2] += q[2] * c;
                t[3] += q[3] * c;
                t[4] += q[4] * c;
                t[5] += q[5] * s;
                t[6] += q[6] * s;
            }
            let (cx, sx, cy, sy) = (cos[0][ix], sin[0][ix], cos[1][iy], sin[1][iy]);
            let cc = cx * cy;
            acc[0] += cc * (t[0] - t[1]);
            acc[1] += cc * (t[0] - t[2]);
            acc[2] += cc * (t[0] - t[3]);
            acc[3] += sx * sy * t[4];
            acc[4] += sx * cy * t[5];
            acc[5] += cx * sy * t[6];
        }
        [
            [acc[0], acc[3], acc[4]],
            [acc[3], acc[1], acc[5]],
            [acc[4], acc[5], acc[2]],
        ]
    }
}

/// `r + n∘L`.
fn shifted(r: [f64; 3], n: [i64; 3], l: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|d| r[d] + n[d] as f64 * l[d])
}

/// `m += sign (a I + b d d^T)`.
fn add_block(m: &mut [[f64; 3]; 3], block: &Block, d: [f64; 3], sign: f64) {
    for a in 0..3 {
        for b in 0..3 {
            let delta = if a == b { block.a } else { 0.0 };
            m[a][b] += sign * (delta + block.b * d[a] * d[b]);
        }
    }
}
