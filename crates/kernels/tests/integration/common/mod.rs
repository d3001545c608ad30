//! Helpers shared by the integration tests.
#![allow(dead_code)]

use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, Real, SimdLevel, laplace_p2p_with, reference};
use ferrofmm_testing::{charges, points};

/// `n` points uniform in `[-1, 1)^3`, interleaved, plus `n` charges in `[-1, 1)`.
pub fn random_points<T: Real>(seed: u64, n: usize) -> (Vec<T>, Vec<T>) {
    let p = points::uniform_cube(n, -1.0, 2.0, seed);
    let q = charges::uniform_in(n, -1.0, 1.0, seed);
    (to_t(&p), to_t(&q))
}

/// `x` converted to `T`.
pub fn to_t<T: Real>(x: &[f64]) -> Vec<T> {
    x.iter().map(|&v| T::from_f64(v)).collect()
}

/// The levels this CPU can run (always includes `Scalar`).
pub fn levels() -> Vec<SimdLevel> {
    SimdLevel::supported()
}

/// Per-target error scales `S_j = sum_i |q_i| |K_ij|` (index 0) and
/// `sum_i |q_i| |grad K_ij|_1` (indices 1..4), computed in `f64`, coincident
/// pairs skipped.
pub fn abs_sums<K: Kernel, T: Real>(
    kernel: &K,
    sources: &[T],
    charges: &[T],
    targets: &[T],
) -> Vec<[f64; 2]> {
    targets
        .chunks_exact(3)
        .map(|t| {
            let mut s = [0.0; 2];
            for (x, q) in sources.chunks_exact(3).zip(charges) {
                let d = [
                    t[0].to_f64() - x[0].to_f64(),
                    t[1].to_f64() - x[1].to_f64(),
                    t[2].to_f64() - x[2].to_f64(),
                ];
                if d == [0.0; 3] {
                    continue;
                }
                let q = q.to_f64().abs();
                s[0] += q * kernel.kernel_value(d).abs();
                let g = kernel.kernel_gradient(d);
                // 1-norm: no overflow / underflow at extreme scales.
                s[1] += q * (g[0].abs() + g[1].abs() + g[2].abs());
            }
            s
        })
        .collect()
}

/// Max over targets and components of `|a - b| / S` with the scales from
/// [`abs_sums`] (0 where the scale is 0 and `a == b`, infinite where `a` or
/// `b` is not finite).
pub fn scaled_error<T: Real>(mode: EvalMode, a: &[T], b: &[T], scales: &[[f64; 2]]) -> f64 {
    let w = mode.values_per_target();
    let mut worst = 0.0f64;
    for (j, s) in scales.iter().enumerate() {
        for c in 0..w {
            let (x, y) = (a[w * j + c].to_f64(), b[w * j + c].to_f64());
            if !x.is_finite() || !y.is_finite() {
                return f64::INFINITY;
            }
            let scale = if c == 0 { s[0] } else { s[1] };
            let diff = (x - y).abs();
            if diff > 0.0 {
                worst = worst.max(if scale > 0.0 {
                    diff / scale
                } else {
                    f64::INFINITY
                });
            }
        }
    }
    worst
}

/// Tolerance for a fast path against the scalar reference, relative to the
/// absolute sum `S`: both sum the sources in the same order, so they differ
/// by a few roundings per term (approximate `rsqrt` refined to < 1/2 ulp,
/// FMA vs separate rounding, `1/(4 pi)` applied per target instead of per
/// term: <= 8 eps per term) plus at most one rounding of the running sum per
/// source (<= n_s eps S). Hence `(n_s + 8) eps`: ~1e-14 in f64 and ~5e-6 in
/// f32 for the sizes used here.
pub fn tolerance<T: Real>(n_sources: usize) -> f64 {
    (n_sources as f64 + 8.0) * T::EPSILON.to_f64()
}

/// Laplace at `level` against the pairwise reference; returns the scaled
/// error and the tolerance.
pub fn laplace_vs_reference<T: Real>(
    level: SimdLevel,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
) -> (f64, f64) {
    let n = mode.values_per_target() * targets.len() / 3;
    let mut fast = vec![T::ZERO; n];
    let mut slow = vec![T::ZERO; n];
    laplace_p2p_with(level, mode, sources, charges, targets, &mut fast);
    reference::evaluate_pairwise(&Laplace3d, mode, sources, charges, targets, &mut slow);
    let scales = abs_sums(&Laplace3d, sources, charges, targets);
    (
        scaled_error(mode, &fast, &slow, &scales),
        tolerance::<T>(sources.len() / 3),
    )
}
