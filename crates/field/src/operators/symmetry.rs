//! The symmetries of the surfaces that let the operators be permuted
//! instead of recomputed.
//!
//! The surface grid of order `p` is symmetric under the reflection of any
//! set of axes (`mask`, bit 0: x): [`reflection`] gives the permutation
//! `sigma` of the (component-expanded) surface indices. A kernel matrix
//! `A` is invariant under it when `A[sigma(j), sigma(i)] = A[j, i]`
//! ([`is_permuted`]); then so is its (unique) truncated pseudo-inverse, and
//! the octant-`o` translation is octant 0's permuted ([`permute`]). A
//! kernel symmetric up to signs gives `A_d = D A_u^T D` with `D = diag(d)`,
//! `d_i = ±1` ([`transpose_signs`]). All tests hold to
//! [`SYMMETRY_TOLERANCE`] of the largest entry.

use faer::MatRef;

/// Relative agreement (to the largest entry) at which two kernel matrices
/// count as equal up to a symmetry: far below any truncation, far above the
/// rounding of surface points that are mirror images of each other.
const SYMMETRY_TOLERANCE: f64 = 1e-12;

/// Per index of a surface expanded to `c` components per point (point
/// major, as [`Kernel::assemble`] writes them), the index of its mirror
/// image under the reflection of the axes set in `mask` (bit 0: x).
pub(super) fn reflection(order: usize, mask: usize, c: usize) -> Vec<usize> {
    let unit = crate::surface::unit_surface(order);
    let last = (order - 1) as i64;
    let grid = |u: &[f64; 3]| u.map(|x| ((x + 1.0) * 0.5 * last as f64).round() as i64);
    let index: std::collections::HashMap<[i64; 3], usize> =
        unit.iter().enumerate().map(|(i, u)| (grid(u), i)).collect();
    let mut out = Vec::with_capacity(c * unit.len());
    for u in &unit {
        let mut k = grid(u);
        for (d, k) in k.iter_mut().enumerate() {
            if mask >> d & 1 == 1 {
                *k = last - *k;
            }
        }
        let j = index[&k];
        out.extend((0..c).map(|a| c * j + a));
    }
    out
}

/// Largest absolute entry.
fn max_abs(a: MatRef<'_, f64>) -> f64 {
    let mut m: f64 = 0.0;
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            m = m.max(a[(i, j)].abs());
        }
    }
    m
}

/// Whether `b[sigma(j), sigma(i)] = a[j, i]` for every entry (square
/// matrices, to [`SYMMETRY_TOLERANCE`] of the largest entry of `a`).
pub(super) fn is_permuted(a: MatRef<'_, f64>, b: MatRef<'_, f64>, sigma: &[usize]) -> bool {
    let n = a.nrows();
    if a.shape() != (n, n) || b.shape() != (n, n) || sigma.len() != n {
        return false;
    }
    let scale = max_abs(a);
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    let tol = SYMMETRY_TOLERANCE * scale;
    (0..n).all(|i| (0..n).all(|j| (b[(sigma[j], sigma[i])] - a[(j, i)]).abs() <= tol))
}

/// `out[sigma(j), sigma(i)] = a[j, i]` for a column-major `n x n` matrix.
pub(super) fn permute(a: &[f64], n: usize, sigma: &[usize]) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            out[sigma[i] * n + sigma[j]] = a[i * n + j];
        }
    }
    out
}

/// The signs `d` with `b = D a^T D` (`D = diag(d)`, `d_0 = 1`) when `b` is
/// of that form to [`SYMMETRY_TOLERANCE`]; `None` otherwise (including
/// when a sign cannot be read off the first row and column).
pub(super) fn transpose_signs(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let n = a.nrows();
    if n == 0 || a.shape() != (n, n) || b.shape() != (n, n) {
        return None;
    }
    let scale = max_abs(a);
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let tol = SYMMETRY_TOLERANCE * scale;
    let mut d = vec![1.0; n];
    for (i, di) in d.iter_mut().enumerate().skip(1) {
        let (x, y) = (b[(0, i)], a[(i, 0)]);
        if x.abs() <= tol || y.abs() <= tol {
            return None;
        }
        *di = if (x > 0.0) == (y > 0.0) { 1.0 } else { -1.0 };
    }
    let ok = (0..n).all(|i| (0..n).all(|j| (b[(j, i)] - d[j] * d[i] * a[(i, j)]).abs() <= tol));
    ok.then_some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Surfaces map onto themselves under every reflection, components
    /// kept together.
    #[test]
    fn reflections_are_permutations() {
        for (order, c) in [(2, 1), (5, 2), (6, 3)] {
            let n = c * crate::n_surface_points(order);
            for mask in 0..8 {
                let sigma = reflection(order, mask, c);
                let mut seen = vec![false; n];
                for (i, &j) in sigma.iter().enumerate() {
                    assert_eq!(i % c, j % c);
                    seen[j] = true;
                }
                assert!(seen.iter().all(|&s| s));
                let twice: Vec<usize> = sigma.iter().map(|&j| sigma[j]).collect();
                assert_eq!(
                    twice,
                    (0..n).collect::<Vec<_>>(),
                    "a reflection is an involution"
                );
            }
        }
    }
}
