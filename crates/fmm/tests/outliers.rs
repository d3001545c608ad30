//! A distant point no longer costs the rest of the cloud its digits: the
//! coordinates the passes see are relative to an origin for which the
//! subtraction is exact (`coordinate_origin`), so a cloud that shares one
//! deep leaf keeps its exact separations. (Before: 2.1e-5 at D = 1e12 and
//! 2.3e-2 at D = 1e15 in f64.) The P2P cost of such a leaf is the part of
//! issue 18 still open.

use ferrofmm_fmm::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real};

fn error_with_outlier<T: Real>(n: usize, d: f64) -> f64 {
    let mut points: Vec<T> = Geometry::Cube.points(n, 3);
    let last = points.len() - 3;
    for c in 0..3 {
        points[last + c] = T::from_f64(d);
    }
    let q: Vec<T> = charges(n, 4);
    let mode = EvalMode::PotentialGradient;
    let fmm = FmmBuilder::new(&points)
        .order(6)
        .mode(mode)
        .build_svd()
        .unwrap();
    let v = fmm.evaluate(&q).unwrap();
    relative_errors(
        &Laplace3d,
        mode,
        &points,
        &q,
        &points,
        &v,
        &sample_indices(n, 499),
    )
    .worst()
}

#[test]
fn one_distant_point_keeps_f64_accuracy() {
    for d in [1e6, 1e12, 1e15] {
        let e = error_with_outlier::<f64>(1500, d);
        eprintln!("f64, outlier at {d:e}: {e:.2e}");
        assert!(e < 1e-9, "outlier at {d:e}: error {e:.3e}");
    }
}

#[test]
fn one_distant_point_keeps_f32_accuracy() {
    for d in [1e3, 1e5] {
        let e = error_with_outlier::<f32>(1500, d);
        eprintln!("f32, outlier at {d:e}: {e:.2e}");
        assert!(e < 1e-5, "outlier at {d:e}: error {e:.3e}");
    }
}

/// `--precision auto --tolerance 1e-5` with a point at 1e6: whichever
/// float type is chosen reaches the tolerance (f32 was chosen and gave
/// 1.1e-2 before the exact coordinate origin).
#[test]
fn auto_precision_with_an_outlier_meets_the_tolerance() {
    use ferrofmm_fmm::tuning::choose_precision;
    use ferrofmm_kernels::Precision;
    let n = 1000;
    let mut points: Vec<f64> = Geometry::Cube.points(n, 3);
    points[3 * n - 3..].copy_from_slice(&[1e6; 3]);
    let eps = 1e-5;
    let mode = EvalMode::Potential;
    let check = |values: &[f64], q: &[f64]| {
        relative_errors(
            &Laplace3d,
            mode,
            &points,
            q,
            &points,
            values,
            &sample_indices(n, 499),
        )
        .potential
    };
    let q: Vec<f64> = charges(n, 4);
    let e = match choose_precision(eps, mode, &points, None).unwrap() {
        Precision::F32 => {
            let p32: Vec<f32> = points.iter().map(|&x| x as f32).collect();
            let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
            let mut fmm = FmmBuilder::new(&p32).tolerance(eps).build_svd().unwrap();
            let out = fmm.evaluate_verified(&q32).unwrap();
            assert!(out.verification.unwrap().met);
            let v: Vec<f64> = out.values.iter().map(|&x| x as f64).collect();
            check(&v, &q)
        }
        Precision::F64 => {
            let mut fmm = FmmBuilder::new(&points).tolerance(eps).build_svd().unwrap();
            check(&fmm.evaluate_verified(&q).unwrap().values, &q)
        }
    };
    assert!(e <= eps, "error {e:.3e}");
}
