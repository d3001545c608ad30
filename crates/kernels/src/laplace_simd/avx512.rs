//! AVX-512F Laplace P2P: 8 `f64` / 16 `f32` target lanes per register, two
//! register chunks per block, `vrsqrt14` refined to full precision, coincident
//! pairs masked with `k` registers.
//!
//! Every function here is compiled with `avx512f` enabled and must only be
//! called after [`SimdLevel`](crate::SimdLevel) detection confirmed it.

use std::arch::x86_64::*;

use crate::Real;

const L64: usize = 8;
const L32: usize = 16;
/// Target chunks (registers) per block.
const NC: usize = 2;

/// `1/sqrt(r2)` to `f64` precision: `vrsqrt14pd` (rel. error `< 2^-14`) and
/// the series `y (1 + e/2 + 3e^2/8 + 5e^3/16)`, `e = 1 - r2 y^2`
/// (truncation `< 4.4 * 2^-56`). Lanes not in `nonzero` start from `y = 0`
/// and come out exactly 0 (`e = 1`, `y e p = 0`).
#[inline]
#[target_feature(enable = "avx512f")]
fn rsqrt_f64(r2: __m512d, nonzero: __mmask8) -> __m512d {
    let y = _mm512_maskz_rsqrt14_pd(nonzero, r2);
    let ry = _mm512_mul_pd(r2, y);
    let e = _mm512_fnmadd_pd(ry, y, _mm512_set1_pd(1.0));
    let p = _mm512_fmadd_pd(_mm512_set1_pd(5.0 / 16.0), e, _mm512_set1_pd(3.0 / 8.0));
    let p = _mm512_fmadd_pd(p, e, _mm512_set1_pd(0.5));
    let ye = _mm512_mul_pd(y, e);
    _mm512_fmadd_pd(ye, p, y)
}

/// `1/sqrt(r2)` to `f32` precision: `vrsqrt14ps` and one Newton step
/// `y (1 + e/2)` (truncation `< 1.5 * 2^-28`). Lanes not in `nonzero` come
/// out exactly 0.
#[inline]
#[target_feature(enable = "avx512f")]
fn rsqrt_f32(r2: __m512, nonzero: __mmask16) -> __m512 {
    let y = _mm512_maskz_rsqrt14_ps(nonzero, r2);
    let ry = _mm512_mul_ps(r2, y);
    let e = _mm512_fnmadd_ps(ry, y, _mm512_set1_ps(1.0));
    let ye = _mm512_mul_ps(y, e);
    _mm512_fmadd_ps(ye, _mm512_set1_ps(0.5), y)
}

#[inline]
#[target_feature(enable = "avx512f")]
fn load_f64(a: &[f64; L64]) -> __m512d {
    // SAFETY: `a` is 8 initialised, contiguous f64 = one 64-byte unaligned load.
    unsafe { _mm512_loadu_pd(a.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx512f")]
fn store_f64(v: __m512d) -> [f64; L64] {
    let mut a = [0.0; L64];
    // SAFETY: `a` is 8 writable, contiguous f64 = one 64-byte unaligned store.
    unsafe { _mm512_storeu_pd(a.as_mut_ptr(), v) };
    a
}

#[inline]
#[target_feature(enable = "avx512f")]
fn load_f32(a: &[f32; L32]) -> __m512 {
    // SAFETY: `a` is 16 initialised, contiguous f32 = one 64-byte unaligned load.
    unsafe { _mm512_loadu_ps(a.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx512f")]
fn store_f32(v: __m512) -> [f32; L32] {
    let mut a = [0.0; L32];
    // SAFETY: `a` is 16 writable, contiguous f32 = one 64-byte unaligned store.
    unsafe { _mm512_storeu_ps(a.as_mut_ptr(), v) };
    a
}

/// `f64` P2P over all targets, `NC * 8` at a time (`GRAD`: 4 values per
/// target, else 1). Mismatched lengths only truncate the loops.
#[target_feature(enable = "avx512f")]
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

/// Up to `C * 8` targets (`tb`, interleaved) against all sources.
#[inline]
#[target_feature(enable = "avx512f")]
fn block_f64<const C: usize, const GRAD: bool>(
    sources: &[f64],
    charges: &[f64],
    tb: &[f64],
    ob: &mut [f64],
) {
    // De-interleave the block's targets into lanes, zero-padded.
    let mut buf = [[[0.0f64; L64]; C]; 3];
    for (k, p) in tb.chunks_exact(3).enumerate() {
        buf[0][k / L64][k % L64] = p[0];
        buf[1][k / L64][k % L64] = p[1];
        buf[2][k / L64][k % L64] = p[2];
    }
    let zero = _mm512_setzero_pd();
    let tiny = _mm512_set1_pd(f64::MIN_POSITIVE);
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
        let sx = _mm512_set1_pd(s[0]);
        let sy = _mm512_set1_pd(s[1]);
        let sz = _mm512_set1_pd(s[2]);
        let vq = _mm512_set1_pd(q);
        for c in 0..C {
            // Source minus target: grad = sum q rinv^3 (x - y), no negation.
            let dx = _mm512_sub_pd(sx, tx[c]);
            let dy = _mm512_sub_pd(sy, ty[c]);
            let dz = _mm512_sub_pd(sz, tz[c]);
            let r2 = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dx, dx)));
            // Coincident lanes (r2 below the smallest normal number) get
            // y = 0 from the masked estimate, and the refinement maps 0 to
            // exactly 0: they contribute nothing.
            let nonzero = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(r2, tiny);
            let rinv = rsqrt_f64(r2, nonzero);
            let qr = _mm512_mul_pd(vq, rinv);
            phi[c] = _mm512_add_pd(phi[c], qr);
            if GRAD {
                let qr3 = _mm512_mul_pd(qr, _mm512_mul_pd(rinv, rinv));
                gx[c] = _mm512_fmadd_pd(qr3, dx, gx[c]);
                gy[c] = _mm512_fmadd_pd(qr3, dy, gy[c]);
                gz[c] = _mm512_fmadd_pd(qr3, dz, gz[c]);
            }
        }
    }
    let k = _mm512_set1_pd(<f64 as Real>::INV_4PI);
    let mut res = [[[0.0f64; L64]; C]; 4];
    for c in 0..C {
        res[0][c] = store_f64(_mm512_mul_pd(phi[c], k));
        if GRAD {
            res[1][c] = store_f64(_mm512_mul_pd(gx[c], k));
            res[2][c] = store_f64(_mm512_mul_pd(gy[c], k));
            res[3][c] = store_f64(_mm512_mul_pd(gz[c], k));
        }
    }
    let w = if GRAD { 4 } else { 1 };
    for (j, o) in ob.chunks_exact_mut(w).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j / L64][j % L64];
        }
    }
}

/// `f32` P2P over all targets, `NC * 16` at a time.
#[target_feature(enable = "avx512f")]
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

/// Up to `C * 16` targets against all sources.
#[inline]
#[target_feature(enable = "avx512f")]
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
    let zero = _mm512_setzero_ps();
    let tiny = _mm512_set1_ps(f32::MIN_POSITIVE);
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
        let sx = _mm512_set1_ps(s[0]);
        let sy = _mm512_set1_ps(s[1]);
        let sz = _mm512_set1_ps(s[2]);
        let vq = _mm512_set1_ps(q);
        for c in 0..C {
            // Source minus target: grad = sum q rinv^3 (x - y), no negation.
            let dx = _mm512_sub_ps(sx, tx[c]);
            let dy = _mm512_sub_ps(sy, ty[c]);
            let dz = _mm512_sub_ps(sz, tz[c]);
            let r2 = _mm512_fmadd_ps(dz, dz, _mm512_fmadd_ps(dy, dy, _mm512_mul_ps(dx, dx)));
            // Coincident lanes (r2 below the smallest normal number) get
            // y = 0 from the masked estimate, and the refinement maps 0 to
            // exactly 0: they contribute nothing.
            let nonzero = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(r2, tiny);
            let rinv = rsqrt_f32(r2, nonzero);
            let qr = _mm512_mul_ps(vq, rinv);
            phi[c] = _mm512_add_ps(phi[c], qr);
            if GRAD {
                let qr3 = _mm512_mul_ps(qr, _mm512_mul_ps(rinv, rinv));
                gx[c] = _mm512_fmadd_ps(qr3, dx, gx[c]);
                gy[c] = _mm512_fmadd_ps(qr3, dy, gy[c]);
                gz[c] = _mm512_fmadd_ps(qr3, dz, gz[c]);
            }
        }
    }
    let k = _mm512_set1_ps(<f32 as Real>::INV_4PI);
    let mut res = [[[0.0f32; L32]; C]; 4];
    for c in 0..C {
        res[0][c] = store_f32(_mm512_mul_ps(phi[c], k));
        if GRAD {
            res[1][c] = store_f32(_mm512_mul_ps(gx[c], k));
            res[2][c] = store_f32(_mm512_mul_ps(gy[c], k));
            res[3][c] = store_f32(_mm512_mul_ps(gz[c], k));
        }
    }
    let w = if GRAD { 4 } else { 1 };
    for (j, o) in ob.chunks_exact_mut(w).enumerate() {
        for (v, r) in o.iter_mut().zip(&res) {
            *v += r[j / L32][j % L32];
        }
    }
}
