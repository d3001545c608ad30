//! Loops over the periodic images of a displacement.

/// `{-1, 0, 1}^3`.
pub(crate) fn near_images() -> impl Iterator<Item = [i64; 3]> {
    (0..27).map(|i| [i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1])
}

pub(crate) fn norm(d: [f64; 3]) -> f64 {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Calls `f(n, |r + n L|)` for every image `n` in `lo..=hi` (per axis).
pub(crate) fn for_images(
    r: [f64; 3],
    l: [f64; 3],
    lo: [i64; 3],
    hi: [i64; 3],
    mut f: impl FnMut([i64; 3], f64),
) {
    for nz in lo[2]..=hi[2] {
        for ny in lo[1]..=hi[1] {
            for nx in lo[0]..=hi[0] {
                let d = [
                    r[0] + nx as f64 * l[0],
                    r[1] + ny as f64 * l[1],
                    r[2] + nz as f64 * l[2],
                ];
                f([nx, ny, nz], norm(d));
            }
        }
    }
}
