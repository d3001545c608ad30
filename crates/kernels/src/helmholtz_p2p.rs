//! Modified Helmholtz (Yukawa) P2P: a portable lane-chunked loop with a
//! vectorisable `exp` ([`crate::fast_exp`]), compiled for each
//! [`SimdLevel`] and picked at run time.

use crate::fast_exp::FastExp;
use crate::{EvalMode, Real, SimdLevel};

/// Targets per block of the lane loop.
const LANES: usize = 64;

/// Accumulate the modified Helmholtz potential (and gradient) with
/// wavenumber `k >= 0` using instruction-set `level` (clamped to what the CPU
/// supports):
///
/// ```text
/// phi(y_j)   += sum_i q_i exp(-k r_ij) / (4 pi r_ij)
/// grad phi_j += sum_i -q_i exp(-k r_ij) (1 + k r_ij) (y_j - x_i) / (4 pi r_ij^3)
/// ```
///
/// Layout, accumulation and the coincidence rule (`r^2` below the smallest
/// normal number contributes exactly zero) are those of
/// [`laplace_p2p_with`](crate::laplace_p2p_with). `exp` is evaluated with a
/// polynomial accurate to a few ulps, and returns 0 once `exp(-k r)` drops
/// below the smallest normal number. This is what
/// [`ModifiedHelmholtz3d`](crate::ModifiedHelmholtz3d)'s `evaluate` calls at
/// [`SimdLevel::active`].
///
/// # Panics
/// When lengths are inconsistent, or `k` is negative or not finite.
///
/// ```
/// use ferrofmm_kernels::{modified_helmholtz_p2p_with, EvalMode, SimdLevel};
/// let mut phi = [0.0f64];
/// modified_helmholtz_p2p_with(SimdLevel::detected(), 2.0, EvalMode::Potential,
///     &[0.0, 0.0, 0.0], &[1.0], &[0.5, 0.0, 0.0], &mut phi);
/// let expected = (-1.0f64).exp() / (4.0 * std::f64::consts::PI * 0.5);
/// assert!((phi[0] - expected).abs() < 1e-15);
/// ```
#[allow(clippy::too_many_arguments)]
pub fn modified_helmholtz_p2p_with<T: Real>(
    level: SimdLevel,
    k: f64,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    assert!(
        k.is_finite() && k >= 0.0,
        "modified_helmholtz_p2p: k = {k} must be finite and >= 0"
    );
    let w = mode.values_per_target();
    assert!(
        sources.len().is_multiple_of(3) && targets.len().is_multiple_of(3),
        "modified_helmholtz_p2p: coordinate slices must hold interleaved xyz triples"
    );
    assert_eq!(
        charges.len(),
        sources.len() / 3,
        "modified_helmholtz_p2p: one charge per source"
    );
    assert_eq!(
        out.len(),
        w * (targets.len() / 3),
        "modified_helmholtz_p2p: output length"
    );
    if sources.is_empty() || targets.is_empty() {
        return;
    }
    let level = level.clamp_supported();
    let grad = mode == EvalMode::PotentialGradient;
    if let (Some(s), Some(q), Some(t)) = (
        T::as_f64_slice(sources),
        T::as_f64_slice(charges),
        T::as_f64_slice(targets),
    ) {
        let o = T::as_f64_slice_mut(out).expect("same type as the inputs");
        dispatch(level, grad, k, s, q, t, o);
    } else if let (Some(s), Some(q), Some(t)) = (
        T::as_f32_slice(sources),
        T::as_f32_slice(charges),
        T::as_f32_slice(targets),
    ) {
        let o = T::as_f32_slice_mut(out).expect("same type as the inputs");
        dispatch(level, grad, k as f32, s, q, t, o);
    } else {
        // Some other `Real`: the pairwise reference with libm `exp`.
        let kernel = crate::ModifiedHelmholtz3d { k };
        crate::reference::evaluate_pairwise(&kernel, mode, sources, charges, targets, out);
    }
}

/// `level` must be supported by the CPU (the caller clamps it).
fn dispatch<T: Real + FastExp>(
    level: SimdLevel,
    grad: bool,
    k: T,
    s: &[T],
    q: &[T],
    t: &[T],
    o: &mut [T],
) {
    match (level, grad) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `level` was clamped to `SimdLevel::detected()`: the CPU
        // supports avx512f.
        (SimdLevel::Avx512, true) => unsafe { p2p_avx512::<T, true>(k, s, q, t, o) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        (SimdLevel::Avx512, false) => unsafe { p2p_avx512::<T, false>(k, s, q, t, o) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `level` was clamped to `SimdLevel::detected()`: the CPU
        // supports avx2 and fma.
        (SimdLevel::Avx2, true) => unsafe { p2p_avx2::<T, true>(k, s, q, t, o) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        (SimdLevel::Avx2, false) => unsafe { p2p_avx2::<T, false>(k, s, q, t, o) },
        (_, true) => p2p::<T, true>(k, s, q, t, o),
        (_, false) => p2p::<T, false>(k, s, q, t, o),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn p2p_avx512<T: Real + FastExp, const GRAD: bool>(k: T, s: &[T], q: &[T], t: &[T], o: &mut [T]) {
    p2p::<T, GRAD>(k, s, q, t, o);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn p2p_avx2<T: Real + FastExp, const GRAD: bool>(k: T, s: &[T], q: &[T], t: &[T], o: &mut [T]) {
    p2p::<T, GRAD>(k, s, q, t, o);
}

/// The lane loop; inlined into each `target_feature` wrapper so that it is
/// vectorised for it. Mismatched lengths only truncate the loops.
#[inline(always)]
fn p2p<T: Real + FastExp, const GRAD: bool>(
    k: T,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let w = if GRAD { 4 } else { 1 };
    for (tb, ob) in targets.chunks(3 * LANES).zip(out.chunks_mut(w * LANES)) {
        let mut tx = [T::ZERO; LANES];
        let mut ty = [T::ZERO; LANES];
        let mut tz = [T::ZERO; LANES];
        for (l, p) in tb.chunks_exact(3).enumerate() {
            tx[l] = p[0];
            ty[l] = p[1];
            tz[l] = p[2];
        }
        let mut phi = [T::ZERO; LANES];
        let mut gx = [T::ZERO; LANES];
        let mut gy = [T::ZERO; LANES];
        let mut gz = [T::ZERO; LANES];
        for (s, &q) in sources.chunks_exact(3).zip(charges) {
            let (sx, sy, sz) = (s[0], s[1], s[2]);
            for l in 0..LANES {
                let dx = sx - tx[l];
                let dy = sy - ty[l];
                let dz = sz - tz[l];
                let r2 = dx * dx + dy * dy + dz * dz;
                let valid = r2 >= T::MIN_POSITIVE;
                let r2 = if valid { r2 } else { T::ONE };
                // Correctly rounded r: exp(-k r) amplifies its error by k r.
                let r = r2.sqrt();
                let rinv = T::ONE / r;
                let kr = k * r;
                let qer = if valid {
                    q * T::fast_exp(-kr) * rinv
                } else {
                    T::ZERO
                };
                phi[l] += qer;
                if GRAD {
                    // grad = sum q e^{-kr} (1 + kr) rinv^3 (x - y)
                    let c = qer * (T::ONE + kr) * (rinv * rinv);
                    gx[l] += c * dx;
                    gy[l] += c * dy;
                    gz[l] += c * dz;
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
