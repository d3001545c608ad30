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
