//! Seeded point sets, interleaved `[x0, y0, z0, x1, ...]`.
//!
//! Every generator is a pure function of its arguments (seed included), so
//! a failing test reproduces exactly.

use rand::RngExt;

use crate::rng::{SplitMix64, seeded};

/// `n` points uniform in the cube `[lo, lo + width)^3`, drawn from
/// [`seeded`]`(seed)` coordinate by coordinate.
pub fn uniform_cube(n: usize, lo: f64, width: f64, seed: u64) -> Vec<f64> {
    let mut rng = seeded(seed);
    (0..3 * n)
        .map(|_| lo + width * rng.random::<f64>())
        .collect()
}

/// `count` points uniform in the box `|x - center|_inf < half_width`.
pub fn in_box(rng: &mut SplitMix64, count: usize, center: [f64; 3], half_width: f64) -> Vec<f64> {
    (0..3 * count)
        .map(|i| center[i % 3] + rng.range(-half_width, half_width))
        .collect()
}

/// `count` points uniform in the cube shell
/// `inner <= |x - center|_inf < outer` (by rejection from the outer cube).
///
/// # Panics
/// If `inner >= outer` (the shell is empty and rejection would not end).
pub fn in_shell(
    rng: &mut SplitMix64,
    count: usize,
    center: [f64; 3],
    inner: f64,
    outer: f64,
) -> Vec<f64> {
    assert!(inner < outer, "empty shell: inner {inner} >= outer {outer}");
    let mut out = Vec::with_capacity(3 * count);
    while out.len() < 3 * count {
        let p = [
            rng.range(-outer, outer),
            rng.range(-outer, outer),
            rng.range(-outer, outer),
        ];
        if p.iter().map(|c| c.abs()).fold(0.0, f64::max) >= inner {
            out.extend([center[0] + p[0], center[1] + p[1], center[2] + p[2]]);
        }
    }
    out
}

/// `n` points in `clusters` clusters inside the unit cube: each cluster has
/// a random centre and size `10^-u` with `u` uniform in `[0, max_exp)`, and
/// one in four is flattened to a plane, one in four to a line; 5% of the
/// points are background, uniform in the unit cube. Sizes spanning many
/// decades make deep, strongly adaptive trees.
pub fn clustered(n: usize, clusters: usize, max_exp: f64, seed: u64) -> Vec<f64> {
    let mut r = seeded(seed);
    let specs: Vec<([f64; 3], [f64; 3])> = (0..clusters.max(1))
        .map(|_| {
            let c = [r.random::<f64>(), r.random::<f64>(), r.random::<f64>()];
            let s = 10f64.powf(-r.random_range(0.0..max_exp));
            let mut scale = [s; 3];
            match r.random_range(0..4) {
                0 => scale[r.random_range(0..3)] = 0.0,
                1 => {
                    let keep = r.random_range(0..3);
                    for (i, v) in scale.iter_mut().enumerate() {
                        if i != keep {
                            *v = 0.0;
                        }
                    }
                }
                _ => {}
            }
            (c, scale)
        })
        .collect();
    let mut out = Vec::with_capacity(3 * n);
    for _ in 0..n {
        if r.random::<f64>() < 0.05 {
            out.extend((0..3).map(|_| r.random::<f64>()));
            continue;
        }
        let (c, s) = specs[r.random_range(0..specs.len())];
        for d in 0..3 {
            out.push(c[d] + s[d] * (r.random::<f64>() - 0.5));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_stay_in_their_regions() {
        let p = uniform_cube(500, -1.0, 2.0, 3);
        assert_eq!(p.len(), 1500);
        assert!(p.iter().all(|x| (-1.0..1.0).contains(x)));
        assert_eq!(p, uniform_cube(500, -1.0, 2.0, 3));

        let mut rng = SplitMix64(5);
        let c = [1.0, 2.0, 3.0];
        let b = in_box(&mut rng, 200, c, 0.25);
        assert!(
            b.chunks(3)
                .all(|x| (0..3).all(|d| (x[d] - c[d]).abs() <= 0.25))
        );
        let s = in_shell(&mut rng, 200, c, 0.5, 0.6);
        for x in s.chunks(3) {
            let r = (0..3).map(|d| (x[d] - c[d]).abs()).fold(0.0, f64::max);
            assert!((0.5..=0.6).contains(&r), "{r}");
        }

        let k = clustered(1000, 4, 6.0, 9);
        assert_eq!(k.len(), 3000);
        assert!(k.iter().all(|x| (-0.5..1.5).contains(x)));
    }
}
