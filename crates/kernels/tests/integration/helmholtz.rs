//! The modified Helmholtz (Yukawa) kernel.

use crate::common;

use common::{abs_sums, levels, random_points, scaled_error, tolerance};
use ferrofmm_kernels::{
    EvalMode, Kernel, KernelError, Laplace3d, ModifiedHelmholtz3d, Real, SimdLevel,
    modified_helmholtz_p2p_with, reference,
};

/// Independent f64 implementation of the Yukawa sums, straight from the
/// formulas `e^{-kr}/(4 pi r)` and `-e^{-kr}(1 + kr) d / (4 pi r^3)`.
fn yukawa_formula(k: f64, mode: EvalMode, s: &[f64], q: &[f64], t: &[f64]) -> Vec<f64> {
    let w = mode.values_per_target();
    let mut out = vec![0.0; w * t.len() / 3];
    for (y, o) in t.chunks_exact(3).zip(out.chunks_exact_mut(w)) {
        for (x, &qi) in s.chunks_exact(3).zip(q) {
            let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if r == 0.0 {
                continue;
            }
            let four_pi = 4.0 * std::f64::consts::PI;
            o[0] += qi * (-k * r).exp() / (four_pi * r);
            if w == 4 {
                let f = -qi * (-k * r).exp() * (1.0 + k * r) / (four_pi * r * r * r);
                for c in 0..3 {
                    o[1 + c] += f * d[c];
                }
            }
        }
    }
    out
}

fn check<T: Real>(k: f64, n: usize) {
    let kernel = ModifiedHelmholtz3d::new(k).unwrap();
    let (s, q) = random_points::<T>(31, n);
    let nt = n + 3;
    let (mut t, _) = random_points::<T>(32, nt);
    // Some coincident pairs.
    t[..3 * n.min(4)].copy_from_slice(&s[..3 * n.min(4)]);
    let to64 = |v: &[T]| v.iter().map(|x| x.to_f64()).collect::<Vec<_>>();
    for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
        let expected: Vec<T> = yukawa_formula(k, mode, &to64(&s), &to64(&q), &to64(&t))
            .into_iter()
            .map(T::from_f64)
            .collect();
        let scales = abs_sums(&kernel, &s, &q, &t);
        // On top of the Laplace analysis: exp itself (a few ulps), and its
        // condition number k r, which amplifies the rounding of r (about
        // 1.5 eps on each side) for separations up to 2 sqrt(3) < 3.5.
        let tol = tolerance::<T>(n) + (4.0 + 3.0 * k * 3.5) * T::EPSILON.to_f64();
        for level in levels() {
            let mut out = vec![T::ZERO; mode.values_per_target() * nt];
            modified_helmholtz_p2p_with(level, k, mode, &s, &q, &t, &mut out);
            let err = scaled_error(mode, &out, &expected, &scales);
            assert!(
                err <= tol,
                "{level} {:?} k={k} n={n} {mode:?}: {err:e} > {tol:e}",
                T::PRECISION
            );
            // And the pairwise reference built from kernel_value/kernel_gradient.
            let mut r = vec![T::ZERO; out.len()];
            reference::evaluate_pairwise(&kernel, mode, &s, &q, &t, &mut r);
            assert!(scaled_error(mode, &out, &r, &scales) <= tol);
        }
        // The trait method dispatches to the active level.
        let mut a = vec![T::ZERO; mode.values_per_target() * nt];
        let mut b = a.clone();
        kernel.evaluate(mode, &s, &q, &t, &mut a);
        modified_helmholtz_p2p_with(SimdLevel::active(), k, mode, &s, &q, &t, &mut b);
        assert_eq!(a, b);
    }
}

#[test]
fn matches_the_formula() {
    for k in [0.0, 0.1, 1.0, 10.0] {
        for n in [0usize, 1, 7, 9, 17, 40, 70] {
            check::<f64>(k, n);
            check::<f32>(k, n);
        }
    }
}

#[test]
fn zero_wavenumber_is_laplace() {
    let (s, q) = random_points::<f64>(41, 30);
    let (t, _) = random_points::<f64>(42, 30);
    let y = ModifiedHelmholtz3d::new(0.0).unwrap();
    let mut a = vec![0.0; 120];
    let mut b = vec![0.0; 120];
    y.evaluate(EvalMode::PotentialGradient, &s, &q, &t, &mut a);
    reference::evaluate_pairwise(&Laplace3d, EvalMode::PotentialGradient, &s, &q, &t, &mut b);
    let scales = abs_sums(&Laplace3d, &s, &q, &t);
    assert!(scaled_error(EvalMode::PotentialGradient, &a, &b, &scales) <= tolerance::<f64>(30));
    assert_eq!(y.homogeneity(), Some(-1.0));
}

#[test]
fn metadata_and_validation() {
    let y = ModifiedHelmholtz3d::new(2.5).unwrap();
    assert_eq!(y.name(), "modified_helmholtz3d");
    assert_eq!(y.parameters(), vec![2.5]);
    assert_eq!(y.homogeneity(), None);
    for bad in [-1.0, f64::NAN, f64::INFINITY, -0.0001] {
        assert!(
            matches!(
                ModifiedHelmholtz3d::new(bad),
                Err(KernelError::InvalidParameter { name: "k", .. })
            ),
            "{bad} accepted"
        );
    }
    // Screening: far away the potential is much smaller than Laplace's.
    let d = [3.0f64, 0.0, 0.0];
    assert!(y.kernel_value(d) < 1e-3 * Laplace3d.kernel_value(d));
}

/// Coincident and subnormal-distance pairs contribute exactly zero; huge
/// `k r` underflows to exactly zero; accumulation into `out`.
#[test]
fn coincident_underflow_and_accumulation() {
    for level in levels() {
        for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
            let w = mode.values_per_target();
            let p = [0.3f64, 0.2, 0.1].repeat(9);
            let mut out = vec![0.0; w * 9];
            modified_helmholtz_p2p_with(level, 1.0, mode, &p, &[1.0; 9], &p, &mut out);
            assert!(out.iter().all(|&v| v == 0.0), "{level} {mode:?}");
            let mut out = vec![0.0f32; w];
            modified_helmholtz_p2p_with(
                level,
                1.0,
                mode,
                &[1e-20f32, 0.0, 0.0],
                &[1.0],
                &[2e-20, 0.0, 0.0],
                &mut out,
            );
            assert!(out.iter().all(|&v| v == 0.0), "{level} {mode:?} f32");
            // exp(-1000) underflows: zero, not NaN.
            let mut out = vec![0.0; w];
            modified_helmholtz_p2p_with(
                level,
                1000.0,
                mode,
                &[0.0; 3],
                &[1.0],
                &[1.0, 0.0, 0.0],
                &mut out,
            );
            assert!(out.iter().all(|&v| v == 0.0), "{level} {mode:?} underflow");
            // Accumulates.
            let mut out = vec![1.0; w];
            modified_helmholtz_p2p_with(
                level,
                1.0,
                mode,
                &[0.0; 3],
                &[1.0],
                &[1.0, 0.0, 0.0],
                &mut out,
            );
            let expected = 1.0 + (-1.0f64).exp() / (4.0 * std::f64::consts::PI);
            assert!((out[0] - expected).abs() < 1e-15, "{level} {mode:?}");
        }
    }
}
