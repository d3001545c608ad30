//! Hostile inputs that once gave silent wrong answers: `f32` runs on points
//! far from the origin (rounded before centring, a unit cube at 1e8 became
//! one point) and densities whose sums overflow the float type (NaN and
//! infinity returned as a result).

use ferrofmm_fmm::{FmmBuilder, FmmError, Geometry, check_finite_output};
use ferrofmm_kernels::{EvalMode, Laplace3d, direct_sum};
use ferrofmm_testing::{charges::uniform_in, errors::relative_l2_columns};

/// Relative L2 errors (potential, gradient) of `got` (4 values a target)
/// against the f64 direct sum at `points`.
fn errors(points: &[f64], q: &[f64], got: &[f64]) -> (f64, f64) {
    let mut want = vec![0.0; got.len()];
    direct_sum(
        &Laplace3d,
        EvalMode::PotentialGradient,
        points,
        q,
        points,
        &mut want,
    );
    (
        relative_l2_columns(got, &want, 4, 0..1),
        relative_l2_columns(got, &want, 4, 1..4),
    )
}

/// An f32 run on f64 points keeps its accuracy wherever the points lie:
/// the same cube at the origin and shifted by up to 1e8 gives errors of
/// the same size against the f64 truth of the shifted coordinates.
#[test]
fn f32_on_offset_points_matches_the_f64_truth() {
    let n = 3000;
    let cube: Vec<f64> = Geometry::Cube.points(n, 7);
    let q = uniform_in(n, -0.5, 0.5, 8);
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    let run = |shift: [f64; 3]| {
        let p: Vec<f64> = cube
            .iter()
            .enumerate()
            .map(|(i, x)| x + shift[i % 3])
            .collect();
        let fmm = FmmBuilder::<f32, _>::from_f64(&p)
            .order(5)
            .leaf_size(64)
            .mode(EvalMode::PotentialGradient)
            .build_svd()
            .unwrap();
        let got: Vec<f64> = fmm
            .evaluate(&q32)
            .unwrap()
            .iter()
            .map(|&v| v as f64)
            .collect();
        errors(&p, &q, &got)
    };
    let (p0, g0) = run([0.0; 3]);
    assert!(p0 < 1e-3 && g0 < 1e-3, "at the origin: {p0:e} {g0:e}");
    for shift in [[1e4, 1e4, 1e4], [1e8, -1e8, 3.5e7], [-2.5e6, 0.0, 1e-3]] {
        let (p, g) = run(shift);
        assert!(
            p <= 2.0 * p0 + 2e-6 && g <= 2.0 * g0 + 2e-6,
            "shift {shift:?}: errors {p:e} / {g:e} against {p0:e} / {g0:e} at the origin"
        );
    }
}

/// Separate f64 targets far from the origin, and a verified tolerance: the
/// check compares with the f64 truth, and is met.
#[test]
fn f32_tolerance_on_offset_points_is_verified_against_the_truth() {
    let n = 2000;
    let src: Vec<f64> = Geometry::Sphere
        .points::<f64>(n, 3)
        .iter()
        .map(|x| x + 1e6)
        .collect();
    let tgt: Vec<f64> = Geometry::Cube
        .points::<f64>(500, 4)
        .iter()
        .map(|x| x * 0.5 + 1e6)
        .collect();
    let q = uniform_in(n, -0.5, 0.5, 5);
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    let eps = 1e-4;
    let mut fmm = FmmBuilder::<f32, _>::from_f64(&src)
        .targets_f64(&tgt)
        .tolerance(eps)
        .build_svd()
        .unwrap();
    let out = fmm.evaluate_verified(&q32).unwrap();
    let v = out.verification.expect("verified");
    assert!(v.met, "{v:?}");
    let mut want = vec![0.0; 500];
    direct_sum(&Laplace3d, EvalMode::Potential, &src, &q, &tgt, &mut want);
    let got: Vec<f64> = out.values.iter().map(|&x| x as f64).collect();
    let e = ferrofmm_testing::errors::relative_l2(&got, &want);
    assert!(e <= eps, "true error {e:e} above the tolerance {eps:e}");
}

/// Densities near the float type's largest value: the sums overflow and
/// the evaluation fails naming it, in f64 and f32, for one vector and
/// several; no NaN or infinity is ever returned as a result.
#[test]
fn overflowing_sums_are_an_error_not_a_result() {
    let n = 1500;
    let p: Vec<f64> = Geometry::Cube.points(n, 1);
    let fmm = FmmBuilder::new(&p)
        .order(4)
        .leaf_size(64)
        .build_svd()
        .unwrap();
    let huge: Vec<f64> = uniform_in(n, 0.5, 1.0, 2)
        .iter()
        .map(|x| x * 1e307)
        .collect();
    let e = fmm.evaluate(&huge).unwrap_err();
    assert!(
        matches!(
            e,
            FmmError::NonFiniteResult {
                precision: "f64",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("overflowed"), "{e}");
    // Fine once rescaled, and the check passes through finite results.
    let ok: Vec<f64> = huge.iter().map(|x| x * 1e-300).collect();
    assert!(fmm.evaluate(&ok).unwrap().iter().all(|v| v.is_finite()));
    let two = [ok.clone(), huge].concat();
    let e = fmm.evaluate_many(&two, 2).unwrap_err();
    assert!(
        matches!(e, FmmError::NonFiniteResult { target, .. } if target < n),
        "{e:?}"
    );

    let p32: Vec<f32> = p.iter().map(|&x| x as f32).collect();
    let fmm32 = FmmBuilder::new(&p32)
        .order(4)
        .leaf_size(64)
        .mode(EvalMode::PotentialGradient)
        .build_svd()
        .unwrap();
    let huge32: Vec<f32> = vec![3e37; n];
    let e = fmm32.evaluate(&huge32).unwrap_err();
    assert!(
        matches!(
            e,
            FmmError::NonFiniteResult {
                precision: "f32",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("or use f64"), "{e}");
}

#[test]
fn finite_output_check_names_the_first_bad_value() {
    let v = [1.0, 2.0, 3.0, 4.0, 5.0, f64::NAN, 7.0, f64::INFINITY];
    match check_finite_output(&v, 4, &[-3.0, 2.0]) {
        Err(FmmError::NonFiniteResult {
            target,
            component,
            largest_density,
            ..
        }) => assert_eq!((target, component, largest_density), (1, 1, 3.0)),
        other => panic!("{other:?}"),
    }
    assert!(check_finite_output(&v[..5], 4, &[1.0]).is_ok());
}
