//! `f64` dense building blocks of the precomputation: kernel matrices,
//! SVD, and an R-only Householder QR for tall stacks.
//!
//! Uses [`FieldError`] and the thread policy of `crate::threads` only.
//!
//! Everything here is `f64`; operators are rounded to the working type only
//! once they are complete.

use faer::{Accum, Mat, MatMut, MatRef, Par};
use ferrofmm_kernels::{Kernel, Real};

use crate::FieldError;
use crate::threads::nested_par;

/// Column-major kernel matrix `A[j, i] = K(x_i, y_j)` (`n_targets x
/// n_sources`) between interleaved `f64` point sets; `c n_targets x c
/// n_sources` blocks for a kernel with `c` [components](Kernel::components)
/// (see [`Kernel::assemble`]).
pub(crate) fn kernel_matrix<K: Kernel>(
    kernel: &K,
    sources: &[f64],
    targets: &[f64],
    what: &str,
) -> Result<Mat<f64>, FieldError> {
    let c = kernel.components();
    let ns = c * (sources.len() / 3);
    let nt = c * (targets.len() / 3);
    let mut row_major = vec![0.0f64; ns * nt];
    kernel.assemble::<f64>(sources, targets, &mut row_major);
    if row_major.iter().any(|x| !x.is_finite()) {
        return Err(FieldError::NonFiniteKernel {
            kernel: kernel.name(),
            what: what.to_string(),
        });
    }
    Ok(Mat::from_fn(nt, ns, |j, i| row_major[j * ns + i]))
}

/// A thin SVD `A = U diag(s) V^T` with `s` non-increasing.
pub(crate) struct SvdF64 {
    pub u: Mat<f64>,
    pub s: Vec<f64>,
    pub v: Mat<f64>,
}

/// Thin SVD of `a` (faer, parallelism from [`nested_par`]).
pub(crate) fn svd(a: MatRef<'_, f64>, what: &str) -> Result<SvdF64, FieldError> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::svd::{ComputeSvdVectors, svd as svd_into, svd_scratch};
    let (m, n) = a.shape();
    let size = m.min(n);
    let par = nested_par();
    let failed = || FieldError::SvdFailed {
        what: what.to_string(),
    };
    let mut u = Mat::<f64>::zeros(m, size);
    let mut v = Mat::<f64>::zeros(n, size);
    let mut sv = faer::diag::Diag::<f64>::zeros(size);
    let mut mem = MemBuffer::try_new(svd_scratch::<f64>(
        m,
        n,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::Thin,
        par,
        Default::default(),
    ))
    .map_err(|_| failed())?;
    svd_into(
        a,
        sv.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|_| failed())?;
    let s: Vec<f64> = (0..size).map(|i| sv[i]).collect();
    if s.iter().any(|x| !x.is_finite()) {
        return Err(FieldError::SvdFailed {
            what: format!("{what} (non-finite singular values)"),
        });
    }
    Ok(SvdF64 { u, s, v })
}

/// The `n x n` upper-triangular factor `R` of `A = Q R` for a column-major
/// `m x n` matrix with `m >= n` (destroyed). Blocked Householder QR
/// (LAPACK `dgeqrf`/`dlarft` conventions) without any rank-revealing
/// shortcuts: faer's QR skips columns whose residual falls below `16 m eps`
/// of their norm, which for the strongly decaying M2L stacks would silently
/// lose the small singular values we want to resolve.
#[cfg(test)]
pub(crate) fn householder_r(a: &mut [f64], m: usize, n: usize, par: Par) -> Mat<f64> {
    householder_r_until(a, m, n, par, &|| false)
}

/// [`householder_r`] that gives up between column panels once `stop()`
/// returns true (the result is then meaningless; the caller checks `stop`
/// again). Lets a cancelled precomputation end within a fraction of a
/// second even in the middle of a large factorisation.
pub(crate) fn householder_r_until(
    a: &mut [f64],
    m: usize,
    n: usize,
    par: Par,
    stop: &(dyn Fn() -> bool + Sync),
) -> Mat<f64> {
    assert!(m >= n && a.len() == m * n);
    let mut taus = vec![0.0f64; n];
    factor_columns(a, m, 0, n, &mut taus, 64, par, stop);
    Mat::from_fn(n, n, |i, j| if i <= j { a[j * m + i] } else { 0.0 })
}

/// Householder-factorise columns `j0..j1` of the column-major `m`-row
/// matrix `a` (earlier columns already factorised and applied), in blocks
/// of `nb` columns: each block is factorised recursively with blocks of
/// `nb / 4` (unblocked below 8 columns, so the BLAS-2 work stays on panels
/// that fit in cache), then applied to the remaining columns of `j0..j1`
/// as one compact-WY update (`A2 -= V T^T V^T A2`, three GEMMs).
#[allow(clippy::too_many_arguments)]
fn factor_columns(
    a: &mut [f64],
    m: usize,
    j0: usize,
    j1: usize,
    taus: &mut [f64],
    nb: usize,
    par: Par,
    stop: &(dyn Fn() -> bool + Sync),
) {
    if nb <= 8 || j1 - j0 <= 8 {
        factor_unblocked(a, m, j0, j1, taus);
        return;
    }
    let mut jb = j0;
    while jb < j1 {
        if stop() {
            return;
        }
        let b = nb.min(j1 - jb);
        factor_columns(a, m, jb, jb + b, taus, nb / 4, par, stop);
        let nc = j1 - jb - b;
        if nc > 0 {
            apply_block(a, m, jb, b, jb + b, nc, taus, par);
        }
        jb += b;
    }
}

/// Unblocked Householder QR of columns `j0..j1` (each reflector applied to
/// the following columns of the range only).
fn factor_unblocked(a: &mut [f64], m: usize, j0: usize, j1: usize, taus: &mut [f64]) {
    for j in j0..j1.min(m) {
        let (head, tail) = a.split_at_mut((j + 1) * m);
        let v = &mut head[j * m + j..(j + 1) * m];
        taus[j] = make_householder(v);
        let tau = taus[j];
        if tau != 0.0 {
            for c in j + 1..j1 {
                let off = (c - j - 1) * m;
                let col = &mut tail[off + j..off + m];
                let w = tau * (col[0] + dot(&v[1..], &col[1..]));
                col[0] -= w;
                for (y, x) in col[1..].iter_mut().zip(&v[1..]) {
                    *y -= w * x;
                }
            }
        }
    }
}

/// Apply the `b` reflectors stored in columns `jb..jb+b` (rows `jb..m`) to
/// columns `c0..c0+nc`: `A2 <- (I - V T V^T)^T A2`.
#[allow(clippy::too_many_arguments)]
fn apply_block(
    a: &mut [f64],
    m: usize,
    jb: usize,
    b: usize,
    c0: usize,
    nc: usize,
    taus: &[f64],
    par: Par,
) {
    let rows = m - jb;
    // Explicit V (rows x b), unit lower trapezoidal.
    let mut vmat = Mat::<f64>::zeros(rows, b);
    for jj in 0..b {
        let j = jb + jj;
        vmat[(jj, jj)] = 1.0;
        for i in jj + 1..rows {
            vmat[(i, jj)] = a[j * m + jb + i];
        }
    }
    // T (b x b) upper triangular with H_1 ... H_b = I - V T V^T (dlarft):
    // T[i, i] = tau_i, T[0..i, i] = -tau_i T[0..i, 0..i] Z[0..i, i], Z = V^T V.
    let z = product(vmat.transpose(), vmat.as_ref(), 1.0, par);
    let mut t = Mat::<f64>::zeros(b, b);
    for i in 0..b {
        let tau = taus[jb + i];
        t[(i, i)] = tau;
        for r in 0..i {
            let mut s = 0.0;
            for kk in r..i {
                s += t[(r, kk)] * z[(kk, i)];
            }
            t[(r, i)] = -tau * s;
        }
    }
    let amat = MatMut::from_column_major_slice_mut(&mut a[..m * (c0 + nc)], m, c0 + nc);
    let mut a2 = amat.submatrix_mut(jb, c0, rows, nc);
    let w = product(vmat.transpose(), a2.as_ref(), 1.0, par);
    let w2 = product(t.transpose(), w.as_ref(), 1.0, par);
    faer::linalg::matmul::matmul(
        a2.as_mut(),
        Accum::Add,
        vmat.as_ref(),
        w2.as_ref(),
        -1.0,
        par,
    );
}

/// Dot product with independent partial sums (vectorises).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// Householder reflector for `x` (in place, `dlarfg`): afterwards `x[0] =
/// beta`, `x[1..]` holds `v[1..]` (`v[0] = 1`), and `(I - tau v v^T) x_old =
/// beta e_1`. Returns `tau` (0 when `x[1..]` is already zero).
fn make_householder(x: &mut [f64]) -> f64 {
    let x0 = x[0];
    let tail = dot(&x[1..], &x[1..]);
    if tail == 0.0 {
        return 0.0;
    }
    // Entries are kernel values of moderate size: no over/underflow guard.
    let norm = (x0 * x0 + tail).sqrt();
    let beta = if x0 >= 0.0 { -norm } else { norm };
    let tau = (beta - x0) / beta;
    let scale = 1.0 / (x0 - beta);
    for v in &mut x[1..] {
        *v *= scale;
    }
    x[0] = beta;
    tau
}

/// `alpha a b` as a new matrix (faer, parallelism `par`).
pub(crate) fn product(a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64, par: Par) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(out.as_mut(), Accum::Replace, a, b, alpha, par);
    out
}

/// Round an `f64` slice to the working type.
pub(crate) fn round_to<T: Real>(x: &[f64]) -> Vec<T> {
    x.iter().map(|&v| T::from_f64(v)).collect()
}

/// Column-major contents of a faer matrix.
pub(crate) fn col_major(m: MatRef<'_, f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(m.nrows() * m.ncols());
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            out.push(m[(i, j)]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn householder_r_reproduces_gram() {
        for &(m, n) in &[
            (5usize, 3usize),
            (70, 45),
            (130, 64),
            (40, 40),
            (700, 150),
            (300, 300),
        ] {
            let a: Vec<f64> = (0..m * n)
                .map(|i| {
                    ((i * 7919 % 1013) as f64 / 1013.0 - 0.5)
                        + if i % (m + 1) == 0 { 1.0 } else { 0.0 }
                })
                .collect();
            let amat = MatRef::from_column_major_slice(&a, m, n).to_owned();
            let mut work = a.clone();
            let r = householder_r(&mut work, m, n, Par::Seq);
            // A^T A == R^T R
            let g1 = amat.transpose() * &amat;
            let g2 = r.transpose() * &r;
            let err = (&g1 - &g2).norm_l2() / g1.norm_l2();
            assert!(err < 1e-13, "{m}x{n}: {err}");
            // singular values agree
            let s1 = amat.singular_values().unwrap();
            let s2 = r.singular_values().unwrap();
            for (x, y) in s1.iter().zip(&s2) {
                assert!((x - y).abs() <= 1e-12 * s1[0]);
            }
        }
    }

    #[test]
    #[ignore]
    fn householder_r_speed() {
        let (m, n) = (16 * 488, 488);
        let a: Vec<f64> = (0..m * n)
            .map(|i| (i * 7919 % 1013) as f64 / 1013.0 - 0.5)
            .collect();
        let mut w = a.clone();
        let t = std::time::Instant::now();
        householder_r(&mut w, m, n, Par::Seq);
        let dt = t.elapsed().as_secs_f64();
        let flops = 2.0 * (m * n * n) as f64 - 2.0 / 3.0 * (n * n * n) as f64;
        println!(
            "householder_r {m}x{n}: {dt:.3} s, {:.1} GFLOP/s",
            flops / dt / 1e9
        );
        let mut w = a.clone();
        let t = std::time::Instant::now();
        let amat = MatMut::from_column_major_slice_mut(&mut w, m, n);
        let bs = faer::linalg::qr::no_pivoting::factor::recommended_block_size::<f64>(m, n);
        let mut h = Mat::<f64>::zeros(bs, n);
        let req = faer::linalg::qr::no_pivoting::factor::qr_in_place_scratch::<f64>(
            m,
            n,
            bs,
            Par::Seq,
            Default::default(),
        );
        let mut buf = faer::dyn_stack::MemBuffer::new(req);
        faer::linalg::qr::no_pivoting::factor::qr_in_place(
            amat,
            h.as_mut(),
            Par::Seq,
            faer::dyn_stack::MemStack::new(&mut buf),
            Default::default(),
        );
        let dt = t.elapsed().as_secs_f64();
        println!(
            "faer qr_in_place {m}x{n}: {dt:.3} s, {:.1} GFLOP/s",
            flops / dt / 1e9
        );
    }

    #[test]
    fn householder_r_keeps_tiny_singular_values() {
        // Stack of a graded matrix: singular values 10^0 .. 10^-14.
        let n = 40;
        let m = 8 * n;
        let q = Mat::<f64>::from_fn(m, n, |i, j| ((i * 31 + j * 17) as f64 * 0.7).sin());
        let qr = q.qr();
        let qm = qr.compute_thin_Q();
        let d = Mat::<f64>::from_fn(n, n, |i, j| {
            if i == j {
                10f64.powf(-14.0 * i as f64 / (n - 1) as f64)
            } else {
                0.0
            }
        });
        let w = Mat::<f64>::from_fn(n, n, |i, j| ((i * 13 + j * 29) as f64 * 0.37).cos())
            .qr()
            .compute_thin_Q();
        let a = &qm * &d * w.transpose();
        let mut work = col_major(a.as_ref());
        let r = householder_r(&mut work, m, n, Par::Seq);
        let s = r.singular_values().unwrap();
        let last = s[n - 1];
        assert!(
            (last / 1e-14 - 1.0).abs() < 1e-2,
            "smallest singular value {last}"
        );
    }
}
