//! Sequential dense matrix products on plain column-major slices, dispatched
//! to faer for the concrete float type.

use faer::traits::ComplexField;
use faer::{Accum, MatMut, MatRef, Par};
use ferrofmm_kernels::Real;

/// What a product does with the values already in its output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Update {
    /// `c = a b`: the old contents (even NaN) are ignored.
    Overwrite,
    /// `c += a b`.
    Accumulate,
}

/// `c (m x n) = [c +] a (m x k) * b (k x n)`, all column-major and
/// contiguous (`a.len() == m k`, `b.len() == k n`, `c.len() == m n`).
///
/// Runs sequentially (`faer::Par::Seq`), so it is safe and efficient inside
/// rayon tasks; parallelise over column blocks of `b`/`c` outside. With
/// [`Update::Overwrite`] `c` is overwritten (its old contents, even NaN,
/// are ignored), with [`Update::Accumulate`] the product is added.
///
/// # Panics
/// When a slice length disagrees with the dimensions.
///
/// ```
/// use ferrofmm_field::{Update, gemm};
/// // [1 3; 2 4] * [1; 1] = [4; 6]
/// let a = [1.0f64, 2.0, 3.0, 4.0];
/// let b = [1.0, 1.0];
/// let mut c = [10.0, 10.0];
/// gemm(2, 1, 2, &a, &b, &mut c, Update::Accumulate);
/// assert_eq!(c, [14.0, 16.0]);
/// gemm(2, 1, 2, &a, &b, &mut c, Update::Overwrite);
/// assert_eq!(c, [4.0, 6.0]);
/// ```
pub fn gemm<T: Real>(m: usize, n: usize, k: usize, a: &[T], b: &[T], c: &mut [T], update: Update) {
    gemm_scaled(m, n, k, 1.0, a, b, c, update);
}

/// `c = [c +] alpha * a * b`: [`gemm`] with a scale factor (used to apply
/// the homogeneous level scaling for free).
///
/// # Panics
/// When a slice length disagrees with the dimensions.
///
/// ```
/// use ferrofmm_field::{Update, gemm_scaled};
/// let a = [2.0f32];
/// let b = [3.0f32];
/// let mut c = [1.0f32];
/// gemm_scaled(1, 1, 1, 0.5, &a, &b, &mut c, Update::Accumulate);
/// assert_eq!(c, [4.0]);
/// ```
#[allow(clippy::too_many_arguments)]
pub fn gemm_scaled<T: Real>(
    m: usize,
    n: usize,
    k: usize,
    alpha: f64,
    a: &[T],
    b: &[T],
    c: &mut [T],
    update: Update,
) {
    assert_eq!(
        a.len(),
        m * k,
        "gemm: a has {} values, expected {m} x {k}",
        a.len()
    );
    assert_eq!(
        b.len(),
        k * n,
        "gemm: b has {} values, expected {k} x {n}",
        b.len()
    );
    assert_eq!(
        c.len(),
        m * n,
        "gemm: c has {} values, expected {m} x {n}",
        c.len()
    );
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if update == Update::Overwrite {
            c.fill(T::ZERO);
        }
        return;
    }
    let accum = match update {
        Update::Accumulate => Accum::Add,
        Update::Overwrite => Accum::Replace,
    };
    if let (Some(a), Some(b), Some(c)) = (
        T::as_f64_slice(a),
        T::as_f64_slice(b),
        T::as_f64_slice_mut(c),
    ) {
        faer_gemm(m, n, k, alpha, a, b, c, accum);
    } else if let (Some(a), Some(b), Some(c)) = (
        T::as_f32_slice(a),
        T::as_f32_slice(b),
        T::as_f32_slice_mut(c),
    ) {
        faer_gemm(m, n, k, alpha as f32, a, b, c, accum);
    } else {
        unreachable!("Real is implemented for f32 and f64 only")
    }
}

/// `c = [c +] alpha a b` in faer, for the concrete float type `E` behind
/// `T` (sequential).
#[allow(clippy::too_many_arguments)]
fn faer_gemm<E: ComplexField>(
    m: usize,
    n: usize,
    k: usize,
    alpha: E,
    a: &[E],
    b: &[E],
    c: &mut [E],
    accum: Accum,
) {
    faer::linalg::matmul::matmul(
        MatMut::from_column_major_slice_mut(c, m, n),
        accum,
        MatRef::from_column_major_slice(a, m, k),
        MatRef::from_column_major_slice(b, k, n),
        alpha,
        Par::Seq,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(m: usize, n: usize, k: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut c = vec![0.0; m * n];
        for j in 0..n {
            for i in 0..m {
                for l in 0..k {
                    c[j * m + i] += a[l * m + i] * b[j * k + l];
                }
            }
        }
        c
    }

    #[test]
    fn matches_naive_both_types() {
        let (m, n, k) = (7, 5, 3);
        let a: Vec<f64> = (0..m * k).map(|i| (i as f64 * 0.37).sin()).collect();
        let b: Vec<f64> = (0..k * n).map(|i| (i as f64 * 0.71).cos()).collect();
        let want = naive(m, n, k, &a, &b);
        let mut c = vec![f64::NAN; m * n];
        gemm(m, n, k, &a, &b, &mut c, Update::Overwrite);
        for (x, y) in c.iter().zip(&want) {
            assert!((x - y).abs() < 1e-14);
        }
        let a32: Vec<f32> = a.iter().map(|&x| x as f32).collect();
        let b32: Vec<f32> = b.iter().map(|&x| x as f32).collect();
        let mut c32 = vec![1.0f32; m * n];
        gemm_scaled(m, n, k, 2.0, &a32, &b32, &mut c32, Update::Accumulate);
        for (x, y) in c32.iter().zip(&want) {
            assert!((*x as f64 - (1.0 + 2.0 * y)).abs() < 1e-5);
        }
        let mut z = vec![f64::NAN; m * n];
        gemm(m, n, 0, &[], &[], &mut z, Update::Overwrite);
        assert!(z.iter().all(|&x| x == 0.0));
    }
}
