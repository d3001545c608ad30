//! AVX2 + FMA Laplace P2P: 4 `f64` / 8 `f32` target lanes per register, two
//! register chunks per block. `f64` uses exact `sqrt` and division (AVX2 has
//! no `f64` reciprocal square root estimate); `f32` uses `vrsqrtps` refined to
//! full precision. Coincident pairs are zeroed with a compare mask.
//!
//! Every function here is compiled with `avx2,fma` enabled and must only be
//! called after [`SimdLevel`](crate::SimdLevel) detection confirmed them.

use std::arch::x86_64::*;

use crate::Real;

const L64: usize = 4;
const L32: usize = 8;
/// Target chunks (registers) per block.
const NC: usize = 2;

/// `1/sqrt(r2)` to `f32` precision: `vrsqrtps` (rel. error `< 1.5 * 2^-12`)
/// and the series `y (1 + e/2 + 3e^2/8)`, `e = 1 - r2 y^2` (truncation
/// `< 1.3e-10`). Lanes with `r2 == 0` must be masked by the caller.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn rsqrt_f32(r2: __m256) -> __m256 {
    let y = _mm256_rsqrt_ps(r2);
    let ry = _mm256_mul_ps(r2, y);
    let e = _mm256_fnmadd_ps(ry, y, _mm256_set1_ps(1.0));
    let p = _mm256_fmadd_ps(_mm256_set1_ps(3.0 / 8.0), e, _mm256_set1_ps(0.5));
    let ye = _mm256_mul_ps(y, e);
    _mm256_fmadd_ps(ye, p, y)
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn load_f64(a: &[f64; L64]) -> __m256d {
    // SAFETY: `a` is 4 initialised, contiguous f64 = one 32-byte unaligned load.
    unsafe { _mm256_loadu_pd(a.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn store_f64(v: __m256d) -> [f64; L64] {
    let mut a = [0.0; L64];
    // SAFETY: `a` is 4 writable, contiguous f64 = one 32-byte unaligned store.
    unsafe { _mm256_storeu_pd(a.as_mut_ptr(), v) };
    a
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn load_f32(a: &[f32; L32]) -> __m256 {
    // SAFETY: `a` is 8 initialised, contiguous f32 = one 32-byte unaligned load.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn store_f32(v: __m256) -> [f32; L32] {
    let mut a = [0.0; L32];
    // SAFETY: `a` is 8 writable, contiguous f32 = one 32-byte unaligned store.
    unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
    a
}

/// `f64` P2P over all targets, `NC * 4` at a time.
#[target_feature(enable = "avx2,fma")]
pub(super) fn p2p_f64<const GRAD: bool>(
    sources: &[f64],
    charges: &[f64],
    targets: &[f64],
    out: &mut [f64],
) {
    let w = if GRAD { 4 } else { 1 };
    for (tb, ob) in targets
        .chunks(3 * NC * L64)
        .zip(out.chunks_mut(w * NC * L64))
    {
        if tb.len() > 3 * L64 {
            block_f64::<NC, GRAD>(sources, charges, tb, ob);
        } else {
            block_f64::<1, GRAD>(sources, charges, tb, ob);
        }
    }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn block_f64<const C: usize, const GRAD: bool>(
    sources: &[f64],
    charges: &[f64],
    tb: &[f64],
    ob: &mut [f64],
) {
    let mut buf = [[[0.0f64; L64]; C]; 3];
    for (k, p) in tb.chunks_exact(3).enumerate() {
        buf[0][k / L64][k % L64] = p[0];
        buf[1][k / L64][k % L64] = p[1];
        buf[2][k / L64][k % L64] = p[2];
    }
    let zero = _mm256_setzero_pd();
    let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
    let one = _mm256_set1_pd(1.0);
    let mut tx = [zero; C];
    let mut ty = [zero; C];
    let mut tz = [zero; C];
    for c in 0..C {
        tx[c] = load_f64(&buf[0][c]);
        ty[c] = load_f64(&buf[1][c]);
        tz[c] = load_f64(&buf[2][c]);
    }
    let mut phi = [zero; C];
    let mut gx = [zero; C];
    let mut gy = [zero; C];
    let mut gz = [zero; C];
    for (s, &q) in sources.chunks_exact(3).zip(charges) {
        let sx = _mm256_set1_pd(s[0]);
        let sy = _mm256_set1_pd(s[1]);
        let sz = _mm256_set1_pd(s[2]);
        let vq = _mm256_set1_pd(q);
        for c in 0..C {
            // Source minus target: grad = sum q rinv^3 (x - y), no negation.
            let dx = _mm256_sub_pd(sx, tx[c]);
            let dy = _mm256_sub_pd(sy, ty[c]);
            let dz = _mm256_sub_pd(sz, tz[c]);
            let r2 = _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dy, dy, _mm256_mul_pd(dx, dx)));
            let nonzero = _mm256_cmp_pd::<_CMP_GE_OQ>(r2, tiny);
            // 1/0 = Inf in coincident lanes (r2 below the smallest normal
            // number); the mask turns it into exactly 0.
            let rinv = _mm256_and_pd(nonzero, _mm256_div_pd(one, _mm256_sqrt_pd(r2)));
            let qr = _mm256_mul_pd(vq, rinv);
            phi[c] = _mm256_add_pd(phi[c], qr);
            if GRAD {
                let qr3 = _mm256_mul_pd(qr, _mm256_mul_pd(rinv, rinv));
                gx[c] = _mm256_fmadd_pd(qr3, dx, gx[c]);
                gy[c] = _mm256_fmadd_pd(qr3, dy, gy[c]);
                gz[c] = _mm256_fmadd_pd(qr3, dz, gz[c]);
            }
        }
    }
    let k = _mm256_set1_pd(<f64 as Real>::INV_4PI);
    let mut res = [[[0.0f64; L64]; C]; 4];
    for c in 0..C {
        res[0][c] = store_f64(_mm256_mul_pd(phi[c], k));
        if GRAD {
            res[1][c] = store_f64(_mm256_mul_pd(gx[c], k));
            res[2][c] = store_f64(_mm256_mul_pd(gy[c], k));
            res[3][c] = store_f64(_mm256_mul_pd(gz[c], k));
        }
    }
    let w = if GRAD { 4 } else { 1 };
    for (j, o) in ob.chunks_exact_mut(w).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j / L64][j % L64];
        }
    }
}

/// `f32` P2P over all targets, `NC * 8` at a time.
#[target_feature(enable = "avx2,fma")]
pub(super) fn p2p_f32<const GRAD: bool>(
    sources: &[f32],
    charges: &[f32],
    targets: &[f32],
    out: &mut [f32],
) {
    let w = if GRAD { 4 } else { 1 };
    for (tb, ob) in targets
        .chunks(3 * NC * L32)
        .zip(out.chunks_mut(w * NC * L32))
    {
        if tb.len() > 3 * L32 {
            block_f32::<NC, GRAD>(sources, charges, tb, ob);
        } else {
            block_f32::<1, GRAD>(sources, charges, tb, ob);
        }
    }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn block_f32<const C: usize, const GRAD: bool>(
    sources: &[f32],
    charges: &[f32],
    tb: &[f32],
    ob: &mut [f32],
) {
    let mut buf = [[[0.0f32; L32]; C]; 3];
    for (k, p) in tb.chunks_exact(3).enumerate() {
        buf[0][k / L32][k % L32] = p[0];
        buf[1][k / L32][k % L32] = p[1];
        buf[2][k / L32][k % L32] = p[2];
    }
    let zero = _mm256_setzero_ps();
    let tiny = _mm256_set1_ps(f32::MIN_POSITIVE);
    let mut tx = [zero; C];
    let mut ty = [zero; C];
    let mut tz = [zero; C];
    for c in 0..C {
        tx[c] = load_f32(&buf[0][c]);
        ty[c] = load_f32(&buf[1][c]);
        tz[c] = load_f32(&buf[2][c]);
    }
    let mut phi = [zero; C];
    let mut gx = [zero; C];
    let mut gy = [zero; C];
    let mut gz = [zero; C];
    for (s, &q) in sources.chunks_exact(3).zip(charges) {
        let sx = _mm256_set1_ps(s[0]);
        let sy = _mm256_set1_ps(s[1]);
        let sz = _mm256_set1_ps(s[2]);
        let vq = _mm256_set1_ps(q);
        for c in 0..C {
            // Source minus target: grad = sum q rinv^3 (x - y), no negation.
            let dx = _mm256_sub_ps(sx, tx[c]);
            let dy = _mm256_sub_ps(sy, ty[c]);
            let dz = _mm256_sub_ps(sz, tz[c]);
            let r2 = _mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dx, dx)));
            let nonzero = _mm256_cmp_ps::<_CMP_GE_OQ>(r2, tiny);
            // rsqrt(0) = Inf (vrsqrtps also flushes subnormal input to 0)
            // and the refinement gives NaN; the mask (r2 below the smallest
            // normal f32 counts as coincident) zeroes it.
            let rinv = _mm256_and_ps(nonzero, rsqrt_f32(r2));
            let qr = _mm256_mul_ps(vq, rinv);
            phi[c] = _mm256_add_ps(phi[c], qr);
            if GRAD {
                let qr3 = _mm256_mul_ps(qr, _mm256_mul_ps(rinv, rinv));
                gx[c] = _mm256_fmadd_ps(qr3, dx, gx[c]);
                gy[c] = _mm256_fmadd_ps(qr3, dy, gy[c]);
                gz[c] = _mm256_fmadd_ps(qr3, dz, gz[c]);
            }
        }
    }
    let k = _mm256_set1_ps(<f32 as Real>::INV_4PI);
    let mut res = [[[0.0f32; L32]; C]; 4];
    for c in 0..C {
        res[0][c] = store_f32(_mm256_mul_ps(phi[c], k));
        if GRAD {
            res[1][c] = store_f32(_mm256_mul_ps(gx[c], k));
            res[2][c] = store_f32(_mm256_mul_ps(gy[c], k));
            res[3][c] = store_f32(_mm256_mul_ps(gz[c], k));
        }
    }
    let w = if GRAD { 4 } else { 1 };
    for (j, o) in ob.chunks_exact_mut(w).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j / L32][j % L32];
        }
    }
}
