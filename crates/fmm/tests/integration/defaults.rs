//! Right-sized by default (issue 31, items 1 and 2): the simplest builder
//! call is chosen for the default tolerance, an order alone gets its leaf
//! size from the cost model, a direct sum is a candidate where it is
//! cheaper, and every run meets what it promises against direct
//! summation.

use ferrofmm_fmm::{
    Charges, DEFAULT_TOLERANCE, FmmBuilder, Geometry, relative_errors, sample_indices,
};
use ferrofmm_kernels::{EvalMode, Helmholtz3d, Laplace3d};

const GRAD: EvalMode = EvalMode::PotentialGradient;

/// Worst relative error of potential and gradient of `values` on a sample.
fn worst_error(points: &[f64], q: &[f64], values: &[f64]) -> f64 {
    let n = points.len() / 3;
    relative_errors(
        &Laplace3d,
        GRAD,
        points,
        q,
        points,
        values,
        &sample_indices(n, 300),
    )
    .worst()
}

#[test]
fn small_problems_are_direct_sums_and_large_ones_are_trees_both_verified() {
    for (n, expect_direct) in [(2_000, true), (60_000, false)] {
        for charges in [Charges::Signed, Charges::Positive] {
            let points: Vec<f64> = Geometry::Cube.points(n, 3);
            let q = charges.generate(n, 4);
            // The FFT scheme: operators in a fraction of a second cold
            // (the SVD scheme's take seconds, and its cold first run is
            // rightly a direct sum up to larger N).
            let mut fmm = FmmBuilder::new(&points)
                .mode(GRAD)
                .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
                .unwrap();
            let chosen = fmm.chosen_parameters().unwrap().clone();
            assert_eq!(chosen.tolerance, DEFAULT_TOLERANCE);
            assert_eq!(chosen.direct, expect_direct, "n = {n}: {chosen:?}");
            let direct_s = chosen.direct_seconds.expect("a candidate");
            if expect_direct {
                assert!(direct_s < chosen.predicted_seconds + chosen.precompute_seconds);
                assert_eq!(fmm.summary().depth, 0);
            } else {
                assert!(direct_s >= chosen.predicted_seconds + chosen.precompute_seconds);
                assert!(fmm.summary().depth >= 2);
            }
            let out = fmm.evaluate_verified(&q).unwrap();
            let v = out.verification.expect("the default tolerance is verified");
            assert!(v.met, "n = {n} {charges:?}: {v:?}");
            let e = worst_error(&points, &q, &out.values);
            if expect_direct {
                // Exact to rounding.
                assert!(e < 1e-12, "direct sum off by {e:e}");
            } else {
                assert!(e <= DEFAULT_TOLERANCE, "n = {n} {charges:?}: {e:e}");
            }
        }
    }
}

#[test]
fn an_order_alone_gets_its_leaf_size_and_is_not_verified() {
    let n = 100_000;
    let points: Vec<f64> = Geometry::Sphere.points(n, 5);
    let q = Charges::Signed.generate(n, 6);
    let at = |p: usize| {
        FmmBuilder::new(&points)
            .order(p)
            .mode(GRAD)
            .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
            .unwrap()
    };
    let (low, high) = (at(4), at(8));
    for f in [&low, &high] {
        let c = f.chosen_parameters().unwrap();
        assert!(c.tolerance.is_nan(), "no tolerance: {}", c.tolerance);
        assert!(!c.direct);
    }
    assert_eq!((low.order(), high.order()), (4, 8));
    // Higher orders make M2L dearer against P2P: leaves at least as large.
    assert!(
        high.leaf_size() >= low.leaf_size(),
        "p 4: leaf {}, p 8: leaf {}",
        low.leaf_size(),
        high.leaf_size()
    );
    let mut high = high;
    let out = high.evaluate_verified(&q).unwrap();
    assert!(out.verification.is_none(), "nothing to verify against");
    // Order 8 is good to about 1e-7 on a sphere (docs/tolerance.md).
    assert!(worst_error(&points, &q, &out.values) < 1e-6);
}

#[test]
fn given_settings_win() {
    let n = 3_000;
    let points: Vec<f64> = Geometry::Plummer.points(n, 7);
    // Both given: no choice at all.
    let fmm = FmmBuilder::new(&points)
        .order(5)
        .leaf_size(50)
        .build_svd()
        .unwrap();
    assert!(fmm.chosen_parameters().is_none());
    assert_eq!((fmm.order(), fmm.leaf_size()), (5, 50));
    // A leaf size given: a tree of that leaf size, never a direct sum.
    let fmm = FmmBuilder::new(&points)
        .leaf_size(50)
        .tolerance(1e-5)
        .build_svd()
        .unwrap();
    let c = fmm.chosen_parameters().unwrap();
    assert!(!c.direct && c.direct_seconds.is_none());
    assert_eq!(fmm.leaf_size(), 50);
    assert!(fmm.summary().depth >= 2);
}

#[test]
fn costly_operators_tip_small_helmholtz_runs_to_a_direct_sum() {
    // 8,000 points, k = 5 at 1e-8: per-level operators of order 10 and
    // more cost seconds, a direct sum milliseconds (issue 31's figure).
    let n = 8_000;
    let points: Vec<f64> = Geometry::Cube.points(n, 9);
    let q = Charges::Signed.generate(2 * n, 10);
    let kernel = Helmholtz3d::new(5.0).unwrap();
    let mut fmm = FmmBuilder::new(&points)
        .kernel(kernel)
        .tolerance(1e-8)
        .mode(GRAD)
        .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
        .unwrap();
    let c = fmm.chosen_parameters().unwrap().clone();
    assert!(c.direct, "{c:?}");
    assert!(c.precompute_seconds > c.direct_seconds.unwrap());
    let out = fmm.evaluate_verified(&q).unwrap();
    assert!(out.verification.unwrap().met);
}
