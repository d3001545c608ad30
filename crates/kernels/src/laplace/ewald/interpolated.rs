//! Slab and rod sums of many sources: the nearest images directly, the
//! rest through a Chebyshev grid, which costs `O(N (25 + g) )` a target
//! instead of `O(N)` evaluations of the Green's function.
//!
//! # Maths
//! Split `G = N_2 + F_2` with `N_2(r) = sum_{|n_a| <= 2} K(r + n)` the
//! images within two cells along the repeating axes (25 for a slab, 5 for
//! a rod) and `F_2` the rest. With the sources and targets wrapped into
//! the cell along the repeating axes, `F_2(t - y)` is, for every target
//! `t`, smooth in `y` over the sources' box (its singularities are two
//! cells away along a repeating axis, or two cells off the real line
//! along an open one), so it is interpolated in `y` on a tensor grid of
//! Chebyshev points `y_c` of the sources' box with Lagrange polynomials
//! `l_c`:
//!
//! ```text
//! sum_j q_j F_2(t - x_j) ~ sum_c W_c F_2(t - y_c),   W_c = sum_j q_j l_c(x_j)
//! ```
//!
//! The error falls as `rho^{-g}` with `g` points an axis and `rho >= 8`
//! (the Bernstein ellipse through the nearest singularity); `g =
//! ceil(log_8(10 / tol)) + 1`. A source's own `n = 0` term is left out of
//! `N_2` at that source (its images and `F_2` stay: the Ewald
//! convention). Used when there are at least [`MIN_SOURCES`] sources and
//! their extent along every open axis is at most the cell's side; the
//! pairwise sum otherwise.

use rayon::prelude::*;

use super::pairwise::PairGreen;
use crate::INV_4PI;

/// Fewest sources for which the grid pays.
const MIN_SOURCES: usize = 2000;

/// Fewest targets for which the grid pays.
const MIN_TARGETS: usize = 4;

/// Chebyshev points and barycentric weights of one axis over `[lo, hi]`
/// (one point at `lo` for a degenerate axis).
struct Axis {
    nodes: Vec<f64>,
    weights: Vec<f64>,
}

impl Axis {
    fn new(lo: f64, hi: f64, g: usize) -> Self {
        if hi - lo <= 0.0 {
            return Axis {
                nodes: vec![lo],
                weights: vec![1.0],
            };
        }
        let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let theta = |k: usize| std::f64::consts::PI * (2 * k + 1) as f64 / (2 * g) as f64;
        Axis {
            nodes: (0..g).map(|k| mid + half * theta(k).cos()).collect(),
            weights: (0..g)
                .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 } * theta(k).sin())
                .collect(),
        }
    }

    /// `l_c(x)` for every node `c` into `out`.
    fn basis(&self, x: f64, out: &mut [f64]) {
        if let Some(k) = self.nodes.iter().position(|&y| y == x) {
            out.iter_mut().for_each(|v| *v = 0.0);
            out[k] = 1.0;
            return;
        }
        let mut total = 0.0;
        for ((o, &y), &w) in out.iter_mut().zip(&self.nodes).zip(&self.weights) {
            *o = w / (x - y);
            total += *o;
        }
        out.iter_mut().for_each(|v| *v /= total);
    }
}

/// `x` wrapped into `[o, o + l)`.
fn wrap(x: f64, o: f64, l: f64) -> f64 {
    let t = (x - o).rem_euclid(l);
    if t >= l { o } else { o + t }
}

/// The sum of [`super::pairwise`] through the grid, or `None` where the
/// pairwise sum serves (few sources or targets, or sources wider than the
/// cell along an open axis). `w` values a target (1 or 4).
pub(crate) fn sum(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    targets: &[[f64; 3]],
    own: Option<&[usize]>,
    w: usize,
) -> Option<Vec<f64>> {
    let n = charges.len();
    if n < MIN_SOURCES || targets.len() < MIN_TARGETS {
        return None;
    }
    let (cell, mask, tol) = green.cell();
    let (o, l) = (cell.origin(), cell.lengths());
    let place = |p: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|a| {
            if mask[a] {
                wrap(p[a], o[a], l[a])
            } else {
                p[a]
            }
        })
    };
    let x: Vec<[f64; 3]> = sources
        .chunks_exact(3)
        .map(|p| place([p[0], p[1], p[2]]))
        .collect();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &x {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    if (0..3).any(|a| !mask[a] && hi[a] - lo[a] > l[a]) {
        return None;
    }
    let g = ((10.0 / tol).ln() / 8f64.ln()).ceil() as usize + 1;
    let axes: [Axis; 3] = std::array::from_fn(|a| Axis::new(lo[a], hi[a], g));
    let dims = axes.each_ref().map(|a| a.nodes.len());
    let cells = dims[0] * dims[1] * dims[2];
    // W_c = sum_j q_j l_c(x_j), in parallel chunks.
    let weights = x
        .par_chunks(1024)
        .zip(charges.par_chunks(1024))
        .fold(
            || vec![0.0f64; cells],
            |mut acc, (xs, qs)| {
                let mut b: [Vec<f64>; 3] = dims.map(|d| vec![0.0; d]);
                for (p, &q) in xs.iter().zip(qs) {
                    for a in 0..3 {
                        axes[a].basis(p[a], &mut b[a]);
                    }
                    let mut c = 0;
                    for &bz in &b[2] {
                        for &by in &b[1] {
                            let qyz = q * by * bz;
                            for &bx in &b[0] {
                                acc[c] += qyz * bx;
                                c += 1;
                            }
                        }
                    }
                }
                acc
            },
        )
        .reduce(
            || vec![0.0f64; cells],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                a
            },
        );
    let mut nodes = Vec::with_capacity(cells);
    for &z in &axes[2].nodes {
        for &y in &axes[1].nodes {
            for &xx in &axes[0].nodes {
                nodes.push([xx, y, z]);
            }
        }
    }
    // The near images' shifts.
    let range = |a: usize| if mask[a] { -2i64..=2 } else { 0..=0 };
    let mut shifts = Vec::new();
    for nz in range(2) {
        for ny in range(1) {
            for nx in range(0) {
                shifts.push([nx as f64 * l[0], ny as f64 * l[1], nz as f64 * l[2]]);
            }
        }
    }
    let kappa = green.kappa();
    let mut out = vec![0.0; w * targets.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(i, o)| {
        let t = place(targets[i]);
        let me = own.map(|own| own[i]);
        let mut acc = [0.0f64; 4];
        for (c, y) in nodes.iter().enumerate() {
            let f = green.far2([t[0] - y[0], t[1] - y[1], t[2] - y[2]]);
            for a in 0..w {
                acc[a] += weights[c] * f[a];
            }
        }
        for (j, (p, &q)) in x.iter().zip(charges).enumerate() {
            for s in &shifts {
                let d = [t[0] - p[0] - s[0], t[1] - p[1] - s[1], t[2] - p[2] - s[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if r2 == 0.0 && Some(j) == me {
                    continue;
                }
                let r = r2.sqrt();
                let k = INV_4PI * q * (-kappa * r).exp() / r;
                acc[0] += k;
                if w == 4 {
                    let dk = -k * (kappa + 1.0 / r) / r;
                    for a in 0..3 {
                        acc[1 + a] += dk * d[a];
                    }
                }
            }
        }
        o.copy_from_slice(&acc[..w]);
    });
    Some(out)
}
