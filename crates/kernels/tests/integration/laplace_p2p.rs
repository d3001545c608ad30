//! The vectorised Laplace P2P at every supported SIMD level against the
//! scalar pairwise reference.

use crate::common;

use common::{laplace_vs_reference, levels, random_points};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real, SimdLevel, laplace_p2p_with, reference};
use proptest::prelude::*;

const MODES: [EvalMode; 2] = [EvalMode::Potential, EvalMode::PotentialGradient];

/// Random sources / charges / targets; `shared` targets are copies of
/// sources (coincident pairs, at varying lanes).
fn problem<T: Real + proptest::arbitrary::Arbitrary>(
    coord: impl Strategy<Value = T> + Clone,
) -> impl Strategy<Value = (Vec<T>, Vec<T>, Vec<T>)> {
    (0usize..40, 0usize..40, 0usize..6).prop_flat_map(move |(ns, nt, shared)| {
        (
            prop::collection::vec(coord.clone(), 3 * ns),
            prop::collection::vec(coord.clone(), ns),
            prop::collection::vec(coord.clone(), 3 * nt),
        )
            .prop_map(move |(s, q, mut t)| {
                let k = shared.min(ns).min(t.len() / 3);
                for i in 0..k {
                    // Target 3i+1 (if any) coincides with source i.
                    let j = (3 * i + 1) % (t.len() / 3);
                    t[3 * j..3 * j + 3].copy_from_slice(&s[3 * i..3 * i + 3]);
                }
                (s, q, t)
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn f64_matches_reference((s, q, t) in problem(-1.0f64..1.0)) {
        for level in levels() {
            for mode in MODES {
                let (err, tol) = laplace_vs_reference(level, mode, &s, &q, &t);
                prop_assert!(err <= tol, "{level} {mode:?}: error {err:e} > {tol:e}");
            }
        }
    }

    #[test]
    fn f32_matches_reference((s, q, t) in problem(-1.0f32..1.0)) {
        for level in levels() {
            for mode in MODES {
                let (err, tol) = laplace_vs_reference(level, mode, &s, &q, &t);
                prop_assert!(err <= tol, "{level} {mode:?}: error {err:e} > {tol:e}");
            }
        }
    }
}

/// Lengths that are not multiples of any lane width, and the empty cases.
#[test]
fn remainders_and_empty() {
    let sizes = [0usize, 1, 7, 8, 9, 15, 16, 17, 33];
    for &ns in &sizes {
        for &nt in &sizes {
            let (s64, q64) = random_points::<f64>(1 + ns as u64, ns);
            let (t64, _) = random_points::<f64>(100 + nt as u64, nt);
            let s32: Vec<f32> = s64.iter().map(|&x| x as f32).collect();
            let q32: Vec<f32> = q64.iter().map(|&x| x as f32).collect();
            let t32: Vec<f32> = t64.iter().map(|&x| x as f32).collect();
            for level in levels() {
                for mode in MODES {
                    let (err, tol) = laplace_vs_reference(level, mode, &s64, &q64, &t64);
                    assert!(err <= tol, "f64 {level} {mode:?} ns={ns} nt={nt}: {err:e}");
                    let (err, tol) = laplace_vs_reference(level, mode, &s32, &q32, &t32);
                    assert!(err <= tol, "f32 {level} {mode:?} ns={ns} nt={nt}: {err:e}");
                    if ns == 0 {
                        // No sources: the output is left exactly as it was.
                        let mut out = vec![1.5f64; mode.values_per_target() * nt];
                        laplace_p2p_with(level, mode, &s64, &q64, &t64, &mut out);
                        assert!(out.iter().all(|&v| v == 1.5));
                    }
                }
            }
        }
    }
}

/// Self-interaction with duplicated points: only exact zeros from
/// coincident pairs, never NaN or Inf, in every lane position.
#[test]
fn coincident_points_contribute_exactly_zero() {
    for level in levels() {
        for mode in MODES {
            let w = mode.values_per_target();
            // All sources at one point, targets there too: output stays 0.
            for n in [1usize, 5, 8, 16, 17, 40] {
                let s = [0.25f64, -0.5, 0.125].repeat(n);
                let q = vec![1.0f64; n];
                let mut out = vec![0.0f64; w * n];
                laplace_p2p_with(level, mode, &s, &q, &s, &mut out);
                assert!(
                    out.iter().all(|&v| v == 0.0),
                    "{level} {mode:?} n={n}: {out:?}"
                );
                let s32: Vec<f32> = s.iter().map(|&x| x as f32).collect();
                let q32 = vec![1.0f32; n];
                let mut out32 = vec![0.0f32; w * n];
                laplace_p2p_with(level, mode, &s32, &q32, &s32, &mut out32);
                assert!(out32.iter().all(|&v| v == 0.0), "{level} {mode:?} n={n}");
            }
            // Self-interaction of random points with duplicates.
            let (mut p, q) = random_points::<f64>(7, 37);
            for i in 0..10 {
                let (a, b) = (3 * i, 3 * (36 - i));
                let src: Vec<f64> = p[a..a + 3].to_vec();
                p[b..b + 3].copy_from_slice(&src);
            }
            let (err, tol) = laplace_vs_reference(level, mode, &p, &q, &p);
            assert!(err <= tol, "{level} {mode:?}: {err:e}");
            let p32: Vec<f32> = p.iter().map(|&x| x as f32).collect();
            let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
            let (err, tol) = laplace_vs_reference(level, mode, &p32, &q32, &p32);
            assert!(err <= tol, "{level} {mode:?} f32: {err:e}");
        }
    }
}

/// `out` is accumulated into: the result is exactly `old + fresh`.
#[test]
fn accumulates_into_output() {
    let (s, q) = random_points::<f64>(3, 29);
    let (t, _) = random_points::<f64>(4, 21);
    for level in levels() {
        for mode in MODES {
            let n = mode.values_per_target() * 21;
            let mut fresh = vec![0.0; n];
            laplace_p2p_with(level, mode, &s, &q, &t, &mut fresh);
            let old: Vec<f64> = (0..n).map(|i| i as f64 - 7.5).collect();
            let mut acc = old.clone();
            laplace_p2p_with(level, mode, &s, &q, &t, &mut acc);
            for i in 0..n {
                assert_eq!(acc[i], old[i] + fresh[i], "{level} {mode:?} index {i}");
            }
            // Two source halves accumulated equal the whole, to rounding.
            let mut halves = vec![0.0; n];
            laplace_p2p_with(level, mode, &s[..42], &q[..14], &t, &mut halves);
            laplace_p2p_with(level, mode, &s[42..], &q[14..], &t, &mut halves);
            for i in 0..n {
                assert!((halves[i] - fresh[i]).abs() <= 1e-13 * (1.0 + fresh[i].abs()));
            }
        }
    }
}

/// One pair at a time, against an independent evaluation: the approximate
/// reciprocal square root plus refinement is as accurate as exact `sqrt` and
/// division (a few ulps of the type for potential and gradient).
#[test]
fn single_pair_accuracy_is_at_type_precision() {
    let (p, _) = random_points::<f64>(11, 4000);
    for level in levels() {
        let mut worst64 = 0.0f64;
        let mut worst32 = 0.0f64;
        for pair in p.chunks_exact(6) {
            // Spread distances over many binades: 1e-3 .. 1e3.
            let scale = 10f64.powf(6.0 * (pair[0] + 1.0) / 2.0 - 3.0);
            let s = [pair[0] * scale, pair[1] * scale, pair[2] * scale];
            let t = [pair[3] * scale, pair[4] * scale, pair[5] * scale];
            let exact = exact_pair(&s, &t);
            let mut out = [0.0f64; 4];
            laplace_p2p_with(level, EvalMode::PotentialGradient, &s, &[1.0], &t, &mut out);
            worst64 = worst64.max(pair_error(&out, &exact));
            let s32 = s.map(|x| x as f32);
            let t32 = t.map(|x| x as f32);
            let exact32 = exact_pair(&s32.map(f64::from), &t32.map(f64::from));
            let mut out32 = [0.0f32; 4];
            laplace_p2p_with(
                level,
                EvalMode::PotentialGradient,
                &s32,
                &[1.0],
                &t32,
                &mut out32,
            );
            worst32 = worst32.max(pair_error(&out32.map(f64::from), &exact32));
        }
        // Each side rounds r2 (2u), 1/sqrt (<= 1.5u incl. the refinement's
        // < u/2 truncation), the cube of rinv and the products with q, d and
        // 1/(4 pi) (<= 3u incl. the rounding of 1/(4 pi)): <= ~6u each, so
        // <= 12u = 6 eps between them (u = eps/2). Observed: 2.7-4.5 eps.
        assert!(
            worst64 <= 6.0 * f64::EPSILON,
            "{level} f64: {:.2} eps",
            worst64 / f64::EPSILON
        );
        assert!(
            worst32 <= 6.0 * f32::EPSILON as f64,
            "{level} f32: {:.2} eps",
            worst32 / f32::EPSILON as f64
        );
        println!(
            "{level}: worst single-pair error {:.2} eps (f64), {:.2} eps (f32)",
            worst64 / f64::EPSILON,
            worst32 / f32::EPSILON as f64
        );
    }
}

/// `[phi, g]` of one unit charge, computed in f64 from f64 inputs.
fn exact_pair(s: &[f64; 3], t: &[f64; 3]) -> [f64; 4] {
    let d = [t[0] - s[0], t[1] - s[1], t[2] - s[2]];
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let k = 1.0 / (4.0 * std::f64::consts::PI);
    let g = -k / (r * r * r);
    [k / r, g * d[0], g * d[1], g * d[2]]
}

/// Relative error of the potential and of the gradient vector (norm-wise).
fn pair_error(out: &[f64; 4], exact: &[f64; 4]) -> f64 {
    let ep = ((out[0] - exact[0]) / exact[0]).abs();
    let gn = (exact[1].powi(2) + exact[2].powi(2) + exact[3].powi(2)).sqrt();
    let eg =
        ((out[1] - exact[1]).powi(2) + (out[2] - exact[2]).powi(2) + (out[3] - exact[3]).powi(2))
            .sqrt()
            / gn;
    ep.max(eg)
}

/// Very small and very large coordinates (within the documented range).
#[test]
fn extreme_scales() {
    for level in levels() {
        for mode in MODES {
            for scale in [1e-100f64, 1e-10, 1e10, 1e100] {
                let (mut s, q) = random_points::<f64>(5, 19);
                let (mut t, _) = random_points::<f64>(6, 23);
                s.iter_mut().chain(t.iter_mut()).for_each(|x| *x *= scale);
                let (err, tol) = laplace_vs_reference(level, mode, &s, &q, &t);
                assert!(err <= tol, "{level} {mode:?} scale {scale:e}: {err:e}");
            }
            for scale in [1e-6f32, 1e6] {
                let (mut s, q) = random_points::<f32>(5, 19);
                let (mut t, _) = random_points::<f32>(6, 23);
                s.iter_mut().chain(t.iter_mut()).for_each(|x| *x *= scale);
                let (err, tol) = laplace_vs_reference(level, mode, &s, &q, &t);
                assert!(err <= tol, "{level} {mode:?} f32 scale {scale:e}: {err:e}");
            }
        }
    }
}

/// Requesting an unsupported level is clamped, never unsafe; the kernel's
/// own `evaluate` agrees with the explicit call.
#[test]
fn levels_are_clamped_and_trait_dispatches() {
    let (s, q) = random_points::<f64>(9, 50);
    let (t, _) = random_points::<f64>(10, 45);
    let mut a = vec![0.0; 45];
    let mut b = vec![0.0; 45];
    laplace_p2p_with(SimdLevel::Avx512, EvalMode::Potential, &s, &q, &t, &mut a);
    laplace_p2p_with(
        SimdLevel::Avx512.clamp_supported(),
        EvalMode::Potential,
        &s,
        &q,
        &t,
        &mut b,
    );
    assert_eq!(a, b);
    let mut c = vec![0.0; 45];
    ferrofmm_kernels::Kernel::evaluate(&Laplace3d, EvalMode::Potential, &s, &q, &t, &mut c);
    let mut r = vec![0.0; 45];
    reference::evaluate_pairwise(&Laplace3d, EvalMode::Potential, &s, &q, &t, &mut r);
    for (x, y) in c.iter().zip(&r) {
        assert!((x - y).abs() <= 1e-13 * y.abs().max(1.0));
    }
}

#[test]
#[should_panic(expected = "P2P: 2 sources but 1 charges")]
fn mismatched_charges_panic() {
    let mut out = [0.0f64; 1];
    laplace_p2p_with(
        SimdLevel::detected(),
        EvalMode::Potential,
        &[0.0; 6],
        &[1.0],
        &[1.0; 3],
        &mut out,
    );
}

/// Pairs closer than the smallest normal `r^2` count as coincident: exactly
/// zero contribution, never NaN or Inf (`vrsqrtps` flushes subnormal input).
#[test]
fn subnormal_separations_count_as_coincident() {
    for level in levels() {
        for mode in MODES {
            let w = mode.values_per_target();
            let s32 = [1e-20f32, 0.0, 0.0, 0.5, 0.5, 0.5];
            let t32 = [2e-20f32, 0.0, 0.0];
            let mut out = vec![0.0f32; w];
            laplace_p2p_with(level, mode, &s32[..3], &[1.0], &t32, &mut out);
            assert!(
                out.iter().all(|&v| v == 0.0),
                "{level} {mode:?} f32: {out:?}"
            );
            // With a regular second source, only that one contributes.
            let mut out2 = vec![0.0f32; w];
            laplace_p2p_with(level, mode, &s32, &[1.0, 1.0], &t32, &mut out2);
            let mut far = vec![0.0f32; w];
            laplace_p2p_with(level, mode, &s32[3..], &[1.0], &t32, &mut far);
            assert_eq!(out2, far, "{level} {mode:?}");
            let s64 = [1e-160f64, 0.0, 0.0];
            let t64 = [3e-160f64, 0.0, 0.0];
            let mut out = vec![0.0f64; w];
            laplace_p2p_with(level, mode, &s64, &[1.0], &t64, &mut out);
            assert!(
                out.iter().all(|&v| v == 0.0),
                "{level} {mode:?} f64: {out:?}"
            );
        }
    }
}
