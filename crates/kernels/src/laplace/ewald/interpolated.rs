//! Slab and rod sums of many sources: the nearest images directly, the
//! rest through a Chebyshev grid, which costs `O(N (25 + g) )` a target
//! instead of `O(N)` evaluations of the Green's function.
//!
//! # Maths
//! Split `G = N_m + F_m` with `N_m(r) = sum_{|n_a| <= m} K(r + n)` the
//! images within `m` cells along the repeating axes (`(2m + 1)^2` for a
//! slab, `2m + 1` for a rod) and `F_m` the rest. With the sources and
//! targets wrapped into the cell along the repeating axes, `F_m(t - y)` is,
//! for every target `t`, smooth in `y` over the sources' box (its
//! singularities are `m` cells away along a repeating axis, or as far off
//! the real line along an open one), so it is interpolated in `y` on a
//! tensor grid of Chebyshev points `y_c` of the sources' box with Lagrange
//! polynomials `l_c`:
//!
//! ```text
//! sum_j q_j F_m(t - x_j) ~ sum_c W_c F_m(t - y_c),   W_c = sum_j q_j l_c(x_j)
//! ```
//!
//! The error falls as `rho_m^{-g}` with `g` points an axis, `rho_m` the
//! Bernstein ellipse through the nearest singularity for an interval a
//! cell wide: along a repeating axis the singularity is `m` cells beyond
//! the cell (`rho = 2m + 1 + sqrt((2m + 1)^2 - 1)`: 5.8, 9.9), along an
//! open one `m` cells off the real line (`rho = 2m + sqrt(4m^2 + 1)`: 4.2,
//! 8.1), so `rho_1 = 4.2`, `rho_2 = 8`; `g = ceil(log_rho(10 / tol)) + 1`. Per target
//! the grid costs `g^3` evaluations of `F_m` and the near images `(2m +
//! 1)^d N` kernel evaluations: `m` is the cheaper of 1 and 2 for the
//! number of sources. Pairs at zero distance are left out of `N_m`: a
//! source's own `n = 0` term at that source (its images and `F_m` stay:
//! the Ewald convention), and any other source at exactly the target
//! (whose pair sum is infinite). Used when there are at least [`MIN_SOURCES`] sources and
//! their extent along every open axis is at most the cell's side; the
//! pairwise sum otherwise.

use rayon::prelude::*;

use super::pairwise::PairGreen;
use crate::INV_4PI;
use crate::lattice::PeriodicCell;

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

/// `p` wrapped into the cell along the repeating axes `mask`.
fn place(cell: &PeriodicCell, mask: [bool; 3], p: [f64; 3]) -> [f64; 3] {
    let (o, l) = (cell.origin(), cell.lengths());
    std::array::from_fn(|a| {
        if !mask[a] {
            return p[a];
        }
        let t = (p[a] - o[a]).rem_euclid(l[a]);
        if t >= l[a] { o[a] } else { o[a] + t }
    })
}

/// The sum of [`super::pairwise`] through the grid, or `None` where the
/// pairwise sum serves (few sources or targets, or sources wider than the
/// cell along an open axis). `w` values a target (1 or 4).
pub(crate) fn sum(
    green: &impl PairGreen,
    sources: &[f64],
    charges: &[f64],
    targets: &[[f64; 3]],
    w: usize,
) -> Option<Vec<f64>> {
    let n = charges.len();
    if n < MIN_SOURCES || targets.len() < MIN_TARGETS {
        return None;
    }
    let (cell, mask, tol) = green.cell();
    let l = cell.lengths();
    let place = |p| place(cell, mask, p);
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
    // The near radius: `g^3` far evaluations (about 1000 kernel
    // evaluations each) against `(2m + 1)^d N` near ones.
    let periodic = mask.iter().filter(|&&p| p).count() as i32;
    let cost = |m: i64, rho: f64| {
        let g = ((10.0 / tol).ln() / rho.ln()).ceil() + 1.0;
        (
            g,
            1000.0 * g.powi(3) + ((2 * m + 1) as f64).powi(periodic) * n as f64,
        )
    };
    let ((g, _), m) = [(cost(1, 4.2), 1i64), (cost(2, 8.0), 2)]
        .into_iter()
        .min_by(|a, b| a.0.1.total_cmp(&b.0.1))
        .expect("two radii");
    Some(sum_with(
        green,
        &x,
        [lo, hi],
        charges,
        targets,
        w,
        m,
        g as usize,
    ))
}

/// The sum through the grid of `g` points an axis over the box `[lo, hi]`
/// of the wrapped sources `x`, near radius `m`.
#[allow(clippy::too_many_arguments)]
fn sum_with(
    green: &impl PairGreen,
    x: &[[f64; 3]],
    [lo, hi]: [[f64; 3]; 2],
    charges: &[f64],
    targets: &[[f64; 3]],
    w: usize,
    m: i64,
    g: usize,
) -> Vec<f64> {
    let (cell, mask, _) = green.cell();
    let l = cell.lengths();
    let place = |p| place(cell, mask, p);
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
    let range = |a: usize| if mask[a] { -m..=m } else { 0..=0 };
    let mut shifts = Vec::new();
    for nz in range(2) {
        for ny in range(1) {
            for nx in range(0) {
                shifts.push([nx as f64 * l[0], ny as f64 * l[1], nz as f64 * l[2]]);
            }
        }
    }
    let kappa = green.kappa();
    // The sources by coordinate, for a loop the compiler vectorises.
    let coords: [Vec<f64>; 3] = std::array::from_fn(|a| x.iter().map(|p| p[a]).collect());
    let mut out = vec![0.0; w * targets.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(i, o)| {
        let t = place(targets[i]);
        let mut acc = [0.0f64; 4];
        for (c, y) in nodes.iter().enumerate() {
            let f = green.far([t[0] - y[0], t[1] - y[1], t[2] - y[2]], m);
            for a in 0..w {
                acc[a] += weights[c] * f[a];
            }
        }
        for s in &shifts {
            let near = near_images(
                &coords,
                charges,
                [t[0] - s[0], t[1] - s[1], t[2] - s[2]],
                kappa,
                w == 4,
            );
            for a in 0..w {
                acc[a] += near[a];
            }
        }
        o.copy_from_slice(&acc[..w]);
    });
    out
}

/// `sum_j q_j K(t - x_j)` and its gradient, pairs at zero distance left
/// out, `K = e^{-kappa r} / (4 pi r)`.
fn near_images(x: &[Vec<f64>; 3], q: &[f64], t: [f64; 3], kappa: f64, grad: bool) -> [f64; 4] {
    let mut acc = [0.0f64; 4];
    let n = q.len();
    let (xs, ys, zs) = (&x[0][..n], &x[1][..n], &x[2][..n]);
    if kappa == 0.0 {
        for j in 0..n {
            let d = [t[0] - xs[j], t[1] - ys[j], t[2] - zs[j]];
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let inv = if r2 > 0.0 { 1.0 / r2.sqrt() } else { 0.0 };
            let k = q[j] * inv;
            acc[0] += k;
            if grad {
                let dk = k * inv * inv;
                acc[1] -= dk * d[0];
                acc[2] -= dk * d[1];
                acc[3] -= dk * d[2];
            }
        }
    } else {
        for j in 0..n {
            let d = [t[0] - xs[j], t[1] - ys[j], t[2] - zs[j]];
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if r2 == 0.0 {
                continue;
            }
            let r = r2.sqrt();
            let k = q[j] * (-kappa * r).exp() / r;
            acc[0] += k;
            if grad {
                let dk = k * (kappa + 1.0 / r) / r;
                acc[1] -= dk * d[0];
                acc[2] -= dk * d[1];
                acc[3] -= dk * d[2];
            }
        }
    }
    acc.map(|v| INV_4PI * v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PeriodicCell, RodGreen, SlabGreen};

    /// Both near radii give the same sums (the choice between them is a
    /// matter of cost only).
    #[test]
    fn near_radii_agree() {
        let cell = PeriodicCell::new([0.5, -1.0, 2.0], [1.0, 1.2, 1.0]).unwrap();
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 300;
        let x: Vec<[f64; 3]> = (0..n)
            .map(|_| [0.5 + next(), -1.0 + 1.2 * next(), 2.0 + 0.7 * next()])
            .collect();
        let mut q: Vec<f64> = (0..n).map(|_| next() - 0.5).collect();
        let mean = q.iter().sum::<f64>() / n as f64;
        q.iter_mut().for_each(|v| *v -= mean);
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &x {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let targets = [x[3], x[100], [0.9, 0.0, 2.5]];
        let slab = SlabGreen::screened(cell, 0.0, 1e-12).unwrap();
        let rod = RodGreen::screened(cell, 1.0, 1e-12).unwrap();
        let a = sum_with(&slab, &x, [lo, hi], &q, &targets, 4, 1, 22);
        let b = sum_with(&slab, &x, [lo, hi], &q, &targets, 4, 2, 16);
        let c = sum_with(&rod, &x, [lo, hi], &q, &targets, 4, 1, 22);
        let d = sum_with(&rod, &x, [lo, hi], &q, &targets, 4, 2, 16);
        for (u, v) in [(&a, &b), (&c, &d)] {
            let size = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (s, t) in u.iter().zip(v.iter()) {
                assert!((s - t).abs() < 1e-11 * size, "{s} {t}");
            }
        }
    }
}
