//! The reciprocal-space part of an Ewald sum: the wave vectors of half of
//! the reciprocal lattice within `k_c`, their structure factors `S(k) =
//! sum_j q_j exp(i k . x_j)` and the evaluation of `sum_k Re(B_k exp(i k .
//! y))` at targets, all through phase tables `exp(i m k0_d y_d)` built by
//! recurrence per axis.

use rayon::prelude::*;
use std::f64::consts::PI;

/// Re-anchor the phase recurrences with an exact `sin_cos` every this many
/// steps, which keeps their error below ~`16 eps`.
const ANCHOR: usize = 16;

/// `exp(i m theta)` for `m = 0..re.len()`, by recurrence.
pub(crate) fn phase_table(theta: f64, re: &mut [f64], im: &mut [f64]) {
    let (s1, c1) = theta.sin_cos();
    for m in 0..re.len() {
        if m.is_multiple_of(ANCHOR) {
            let (s, c) = (m as f64 * theta).sin_cos();
            re[m] = c;
            im[m] = s;
        } else {
            let (pr, pi) = (re[m - 1], im[m - 1]);
            re[m] = pr * c1 - pi * s1;
            im[m] = pr * s1 + pi * c1;
        }
    }
}

/// `exp(i m theta)` for `m = -M..=M` at index `M + m` (`re.len() = 2M + 1`).
fn symmetric_phase_table(theta: f64, re: &mut [f64], im: &mut [f64]) {
    let m = re.len() / 2;
    phase_table(theta, &mut re[m..], &mut im[m..]);
    for j in 1..=m {
        re[m - j] = re[m + j];
        im[m - j] = -im[m + j];
    }
}

/// A run of wave vectors `(m_x, m_y, m_z)` with `m_z` in `lo..=hi`.
#[derive(Clone, Copy, Debug)]
struct Column {
    mx: usize,
    my: i64,
    lo: i64,
    hi: i64,
    offset: usize,
}

/// Half of the reciprocal lattice within `|k| <= k_c` (`m_x > 0`, or `m_x
/// = 0, m_y > 0`, or `m_x = m_y = 0, m_z > 0`; the other half is the
/// complex conjugate), in columns along `m_z`, with the coefficients `a_k =
/// (2 / V) weight(k^2)` of a scalar kernel (for Laplace and Yukawa,
/// `weight = exp(-(k^2 + kappa^2) / (4 alpha^2)) / (k^2 + kappa^2)`: the
/// `1/(4 pi)` of the kernel, the `4 pi / V` of the sum and the factor 2 of
/// the half lattice). The `k = 0` term, a constant, is the caller's; a
/// vector kernel (Stokes) takes the [structure
/// factors](ReciprocalLattice::structure_factors) and makes its own
/// coefficients.
#[derive(Clone, Debug)]
pub(crate) struct ReciprocalLattice {
    k0: [f64; 3],
    kmax: [usize; 3],
    columns: Vec<Column>,
    /// `columns[groups[g]..groups[g + 1]]` have `m_x = g`.
    groups: Vec<usize>,
    coef: Vec<f64>,
    /// `m_z` as `f64` at the index `M_z + m_z` of a z phase table.
    mz: Vec<f64>,
}

/// Per-thread phase tables.
#[derive(Clone, Debug)]
pub(crate) struct Scratch {
    xr: Vec<f64>,
    xi: Vec<f64>,
    yr: Vec<f64>,
    yi: Vec<f64>,
    zr: Vec<f64>,
    zi: Vec<f64>,
}

impl ReciprocalLattice {
    /// The wave vectors of `lengths` within `k_cut`, with at most `kmax[d]`
    /// per axis, with the coefficient `a_k = (2 / V) weight(k^2)`.
    pub(crate) fn new(
        lengths: [f64; 3],
        kmax: [usize; 3],
        k_cut: f64,
        weight: impl Fn(f64) -> f64,
    ) -> Self {
        let k0 = [0, 1, 2].map(|d| 2.0 * PI / lengths[d]);
        let volume = lengths[0] * lengths[1] * lengths[2];
        let kc2 = k_cut * k_cut;
        let mut columns = Vec::new();
        let mut groups = vec![0];
        let mut coef = Vec::new();
        let (mxm, mym, mzm) = (kmax[0], kmax[1] as i64, kmax[2] as i64);
        for mx in 0..=mxm {
            let kx = mx as f64 * k0[0];
            let my_lo = if mx == 0 { 0 } else { -mym };
            for my in my_lo..=mym {
                let ky = my as f64 * k0[1];
                let rem = kc2 - kx * kx - ky * ky;
                if rem < 0.0 {
                    continue;
                }
                let hi = ((rem.sqrt() / k0[2]).floor() as i64).min(mzm);
                let lo = if mx == 0 && my == 0 { 1 } else { -hi };
                if lo > hi {
                    continue;
                }
                columns.push(Column {
                    mx,
                    my,
                    lo,
                    hi,
                    offset: coef.len(),
                });
                for mz in lo..=hi {
                    let kz = mz as f64 * k0[2];
                    let k2 = kx * kx + ky * ky + kz * kz;
                    coef.push(2.0 / volume * weight(k2));
                }
            }
            groups.push(columns.len());
        }
        let mz = (0..=2 * kmax[2])
            .map(|i| i as f64 - kmax[2] as f64)
            .collect();
        Self {
            k0,
            kmax,
            columns,
            groups,
            coef,
            mz,
        }
    }

    /// The number of wave vectors (half lattice).
    pub(crate) fn len(&self) -> usize {
        self.coef.len()
    }

    /// Empty phase tables.
    pub(crate) fn scratch(&self) -> Scratch {
        let [mx, my, mz] = self.kmax;
        Scratch {
            xr: vec![0.0; mx + 1],
            xi: vec![0.0; mx + 1],
            yr: vec![0.0; 2 * my + 1],
            yi: vec![0.0; 2 * my + 1],
            zr: vec![0.0; 2 * mz + 1],
            zi: vec![0.0; 2 * mz + 1],
        }
    }

    /// `B_k = a_k conj(S(k))` as `(re, im)`, with `S(k) = sum_j q_j exp(i k
    /// . x_j)` ([`ReciprocalLattice::structure_factors`]).
    pub(crate) fn coefficients(
        &self,
        positions: &[[f64; 3]],
        charges: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (mut br, mut bi) = self.structure_factors(positions, charges);
        for k in 0..br.len() {
            br[k] *= self.coef[k];
            bi[k] *= -self.coef[k];
        }
        (br, bi)
    }

    /// The wave vectors `k`, in the order of every per-`k` array here.
    pub(crate) fn wave_vectors(&self) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(self.len());
        for c in &self.columns {
            for mz in c.lo..=c.hi {
                out.push([
                    c.mx as f64 * self.k0[0],
                    c.my as f64 * self.k0[1],
                    mz as f64 * self.k0[2],
                ]);
            }
        }
        out
    }

    /// `S(k) = sum_j q_j exp(i k . x_j)` as `(re, im)`; parallel over
    /// `m_x`, each `S(k)` summed in source order (deterministic).
    pub(crate) fn structure_factors(
        &self,
        positions: &[[f64; 3]],
        charges: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let parts: Vec<(Vec<f64>, Vec<f64>)> = (0..self.groups.len() - 1)
            .into_par_iter()
            .map(|g| {
                let cols = &self.columns[self.groups[g]..self.groups[g + 1]];
                let (start, end) = match (cols.first(), cols.last()) {
                    (Some(f), Some(l)) => (f.offset, l.offset + (l.hi - l.lo + 1) as usize),
                    _ => return (Vec::new(), Vec::new()),
                };
                let mut sr = vec![0.0; end - start];
                let mut si = vec![0.0; end - start];
                let mut s = self.scratch();
                let (my0, mz0) = (self.kmax[1] as i64, self.kmax[2] as i64);
                for (p, &q) in positions.iter().zip(charges) {
                    if q == 0.0 {
                        continue;
                    }
                    let (sx, cx) = (g as f64 * self.k0[0] * p[0]).sin_cos();
                    symmetric_phase_table(self.k0[1] * p[1], &mut s.yr, &mut s.yi);
                    symmetric_phase_table(self.k0[2] * p[2], &mut s.zr, &mut s.zi);
                    for c in cols {
                        let (yr, yi) = (s.yr[(my0 + c.my) as usize], s.yi[(my0 + c.my) as usize]);
                        let wr = q * (cx * yr - sx * yi);
                        let wi = q * (cx * yi + sx * yr);
                        let len = (c.hi - c.lo + 1) as usize;
                        let o = c.offset - start;
                        let z0 = (mz0 + c.lo) as usize;
                        let (ar, ai) = (&mut sr[o..o + len], &mut si[o..o + len]);
                        let (zr, zi) = (&s.zr[z0..z0 + len], &s.zi[z0..z0 + len]);
                        for k in 0..len {
                            ar[k] += wr * zr[k] - wi * zi[k];
                            ai[k] += wr * zi[k] + wi * zr[k];
                        }
                    }
                }
                (sr, si)
            })
            .collect();
        let mut br = Vec::with_capacity(self.len());
        let mut bi = Vec::with_capacity(self.len());
        for (sr, si) in parts {
            br.extend(sr);
            bi.extend(si);
        }
        (br, bi)
    }

    /// `[phi, gx, gy, gz]` with `phi = sum_k Re(B_k exp(i k . t))` and its
    /// gradient `-sum_k k Im(B_k exp(i k . t))` (only when `grad`).
    pub(crate) fn evaluate(
        &self,
        br: &[f64],
        bi: &[f64],
        t: [f64; 3],
        grad: bool,
        s: &mut Scratch,
    ) -> [f64; 4] {
        phase_table(self.k0[0] * t[0], &mut s.xr, &mut s.xi);
        symmetric_phase_table(self.k0[1] * t[1], &mut s.yr, &mut s.yi);
        symmetric_phase_table(self.k0[2] * t[2], &mut s.zr, &mut s.zi);
        let (my0, mz0) = (self.kmax[1] as i64, self.kmax[2] as i64);
        let mut acc = [0.0f64; 4];
        for c in &self.columns {
            let (xr, xi) = (s.xr[c.mx], s.xi[c.mx]);
            let (yr, yi) = (s.yr[(my0 + c.my) as usize], s.yi[(my0 + c.my) as usize]);
            let wr = xr * yr - xi * yi;
            let wi = xr * yi + xi * yr;
            let len = (c.hi - c.lo + 1) as usize;
            let z0 = (mz0 + c.lo) as usize;
            let (b_r, b_i) = (&br[c.offset..c.offset + len], &bi[c.offset..c.offset + len]);
            let (zr, zi) = (&s.zr[z0..z0 + len], &s.zi[z0..z0 + len]);
            let (mut tr, mut ti) = (0.0, 0.0);
            if grad {
                let mz = &self.mz[z0..z0 + len];
                let (mut ur, mut ui) = (0.0, 0.0);
                for k in 0..len {
                    let pr = b_r[k] * zr[k] - b_i[k] * zi[k];
                    let pi = b_r[k] * zi[k] + b_i[k] * zr[k];
                    tr += pr;
                    ti += pi;
                    ur += mz[k] * pr;
                    ui += mz[k] * pi;
                }
                let vi = wr * ti + wi * tr;
                acc[1] -= c.mx as f64 * self.k0[0] * vi;
                acc[2] -= c.my as f64 * self.k0[1] * vi;
                acc[3] -= self.k0[2] * (wr * ui + wi * ur);
            } else {
                for k in 0..len {
                    tr += b_r[k] * zr[k] - b_i[k] * zi[k];
                    ti += b_r[k] * zi[k] + b_i[k] * zr[k];
                }
            }
            acc[0] += wr * tr - wi * ti;
        }
        acc
    }
}
