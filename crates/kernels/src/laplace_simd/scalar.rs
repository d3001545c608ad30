//! Portable Laplace P2P: the same target-lane blocking as the SIMD paths,
//! written as plain loops over `[T; L]` arrays so that the compiler can
//! vectorise the lane loop for whatever the baseline target offers (SSE2 on
//! x86-64, NEON on aarch64). Exact `sqrt` and division.

use crate::Real;

/// Accumulate into `out` (1 or 4 values per target, `GRAD`), `L` targets at
/// a time. Lengths are validated by the caller; mismatched lengths only
/// truncate the loops (no panic, no out-of-bounds access).
pub(super) fn p2p<T: Real, const L: usize, const GRAD: bool>(
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let w = if GRAD { 4 } else { 1 };
    for (tb, ob) in targets.chunks(3 * L).zip(out.chunks_mut(w * L)) {
        let mut tx = [T::ZERO; L];
        let mut ty = [T::ZERO; L];
        let mut tz = [T::ZERO; L];
        for (l, p) in tb.chunks_exact(3).enumerate() {
            tx[l] = p[0];
            ty[l] = p[1];
            tz[l] = p[2];
        }
        let mut phi = [T::ZERO; L];
        let mut gx = [T::ZERO; L];
        let mut gy = [T::ZERO; L];
        let mut gz = [T::ZERO; L];
        for (s, &q) in sources.chunks_exact(3).zip(charges) {
            let (sx, sy, sz) = (s[0], s[1], s[2]);
            for l in 0..L {
                let dx = sx - tx[l];
                let dy = sy - ty[l];
                let dz = sz - tz[l];
                let r2 = dx * dx + dy * dy + dz * dz;
                // Coincident: r2 below the smallest normal number (as in the
                // SIMD paths; also maps NaN to 0 like their ordered compares).
                let rinv = if r2 >= T::MIN_POSITIVE {
                    T::ONE / r2.sqrt()
                } else {
                    T::ZERO
                };
                let qr = q * rinv;
                phi[l] += qr;
                if GRAD {
                    // grad = sum q rinv^3 (x - y)
                    let qr3 = qr * (rinv * rinv);
                    gx[l] += qr3 * dx;
                    gy[l] += qr3 * dy;
                    gz[l] += qr3 * dz;
                }
            }
        }
        for (l, o) in ob.chunks_exact_mut(w).enumerate() {
            o[0] += phi[l] * T::INV_4PI;
            if GRAD {
                o[1] += gx[l] * T::INV_4PI;
                o[2] += gy[l] * T::INV_4PI;
                o[3] += gz[l] * T::INV_4PI;
            }
        }
    }
}
