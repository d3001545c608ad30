//! Loops over the periodic images of a displacement.

/// Integer image ranges per axis covering every `n` with `|r + n∘L| <
/// r_cut` in a cell of sides `l`, and `{-1, 0, 1}` when `near`.
pub(crate) fn image_range(
    l: [f64; 3],
    r_cut: f64,
    r: [f64; 3],
    near: bool,
) -> ([i64; 3], [i64; 3]) {
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for d in 0..3 {
        lo[d] = ((-r[d] - r_cut) / l[d]).floor() as i64;
        hi[d] = ((-r[d] + r_cut) / l[d]).ceil() as i64;
        if near {
            lo[d] = lo[d].min(-1);
            hi[d] = hi[d].max(1);
        }
    }
    (lo, hi)
}

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
