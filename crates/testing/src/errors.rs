//! Error norms of a computed vector against a reference.

use std::ops::Range;

/// Relative L2 error `||got - want||_2 / ||want||_2`.
///
/// # Panics
/// If the lengths differ.
pub fn relative_l2(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len(), "relative_l2: lengths differ");
    let num: f64 = got.iter().zip(want).map(|(a, b)| (a - b) * (a - b)).sum();
    (num / want.iter().map(|b| b * b).sum::<f64>()).sqrt()
}

/// Relative L2 error over columns `cols` of rows of `width` values (for
/// interleaved outputs such as `[phi, dphi/dx, dphi/dy, dphi/dz]` per
/// target): `sqrt(sum_j sum_{c in cols} (got_jc - want_jc)^2 /
/// sum_j sum_{c in cols} want_jc^2)`.
///
/// # Panics
/// If the lengths differ or are not a multiple of `width`, or `cols` is not
/// within `0..width`.
pub fn relative_l2_columns(got: &[f64], want: &[f64], width: usize, cols: Range<usize>) -> f64 {
    assert_eq!(got.len(), want.len(), "relative_l2_columns: lengths differ");
    assert!(width > 0 && got.len().is_multiple_of(width) && cols.end <= width);
    let (mut num, mut den) = (0.0, 0.0);
    for (g, w) in got.chunks_exact(width).zip(want.chunks_exact(width)) {
        for c in cols.clone() {
            num += (g[c] - w[c]).powi(2);
            den += w[c].powi(2);
        }
    }
    (num / den).sqrt()
}

/// Max-norm relative difference `max |a - b| / max |b|` (the plain
/// `max |a - b|` where `b` is all zeros).
///
/// # Panics
/// If the lengths differ.
pub fn max_relative_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "max_relative_diff: lengths differ");
    let scale = b.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    if scale > 0.0 { diff / scale } else { diff }
}

/// Euclidean norm `||v||_2`.
pub fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn norms() {
        let want = [3.0, 4.0];
        assert_eq!(norm2(&want), 5.0);
        assert!((relative_l2(&[3.0, 4.5], &want) - 0.1).abs() < 1e-15);
        // Rows of width 2: column 1 only.
        let got = [0.0, 4.4, 9.0, 3.0];
        let w = [1.0, 4.0, 1.0, 3.0];
        assert!((relative_l2_columns(&got, &w, 2, 1..2) - 0.08).abs() < 1e-15);
        assert_eq!(max_relative_diff(&[1.0, 2.5], &[1.0, 2.0]), 0.25);
        assert_eq!(max_relative_diff(&[0.5], &[0.0]), 0.5);
    }
}
