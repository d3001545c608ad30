//! Dipole sources and Hessians through the FMM, against direct summation.
//!
//! Bounds follow the order: the relative L2 errors fall about 6x per order
//! (measured with `examples/sources_sweep.rs` on the cube at N = 2e4, worst
//! of potential, gradient and Hessian over the source kinds: 6.0e-4,
//! 1.0e-5, 2.9e-7, 7.2e-9 at p = 4, 6, 8, 10; the dipole potential's error
//! is about 5x the charge potential's, as the dipole field of zero-mean
//! densities is smaller). Each bound is `AT4 * 6^-(p - 4)`, 3-6x above the
//! worst measured case.

use ferrofmm_fmm::{
    Charges, ErrorReport, FmmBuilder, FmmError, Geometry, relative_errors_sources, sample_indices,
};
use ferrofmm_kernels::{
    EvalMode, Kernel, KernelError, Laplace3d, ModifiedHelmholtz3d, Real, SourceKind,
};

const KINDS: [SourceKind; 3] = [
    SourceKind::Charge,
    SourceKind::Dipole,
    SourceKind::ChargeDipole,
];

/// Error bound at order `p` for values whose order-4 error is `at4`.
fn bound(at4: f64, p: usize) -> f64 {
    at4 * 6f64.powi(4 - p as i32)
}

/// One operator cache for the runs of this file: builds that differ only
/// in the source kind or the outputs share their operators (the tests
/// check evaluations, not precomputation).
fn cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("sources-operators")
}

#[allow(clippy::too_many_arguments)]
fn run<T: Real, K: Kernel>(
    kernel: &K,
    geometry: Geometry,
    n: usize,
    order: usize,
    kind: SourceKind,
    mode: EvalMode,
    sign: Charges,
    targets: Option<&[T]>,
) -> (ErrorReport, Vec<T>) {
    let points: Vec<T> = geometry.points(n, 5);
    let densities: Vec<T> = sign.generate(n * kind.values_per_source(), 6);
    let mut builder = FmmBuilder::new(&points)
        .kernel(kernel.clone())
        .order(order)
        .leaf_size(64)
        .mode(mode)
        .source_kind(kind)
        .cache_dir(cache());
    if let Some(t) = targets {
        builder = builder.targets(t);
    }
    let fmm = builder.build_svd().unwrap();
    assert_eq!(fmm.source_kind(), kind);
    let values = fmm.evaluate(&densities).unwrap();
    let at = targets.unwrap_or(&points);
    let sample = sample_indices(at.len() / 3, 400);
    let e = relative_errors_sources(
        kernel, kind, mode, &points, &densities, at, &values, &sample,
    );
    eprintln!(
        "{} {} {} p={order} {} {}: {:.2e} {:?} {:?}",
        kernel.name(),
        geometry.name(),
        sign.name(),
        kind.name(),
        mode.name(),
        e.potential,
        e.gradient,
        e.hessian
    );
    (e, values)
}

fn assert_bounded(label: &str, e: &ErrorReport, order: usize, at4: f64) {
    let b = bound(at4, order);
    assert!(e.worst() <= b, "{label} p={order}: {e:?} above {b:.1e}");
    assert!(
        e.worst() > 0.0,
        "{label}: an exact FMM result means nothing was compared"
    );
}

/// Every kernel x source kind x output, orders 4..10, on the cube with
/// zero-mean densities; one Hessian build covers all three outputs (all
/// kinds at p = 4 and 6, charge + dipole above, to keep the test short).
#[test]
fn every_kernel_kind_and_output_meets_its_order_bound() {
    let yukawa = ModifiedHelmholtz3d::new(5.0).unwrap();
    let mode = EvalMode::PotentialGradientHessian;
    let n = 12_000;
    for order in [4, 6, 8, 10] {
        let kinds: &[SourceKind] = if order <= 6 {
            &KINDS
        } else {
            &[SourceKind::ChargeDipole]
        };
        for &kind in kinds {
            let (e, _) = run::<f64, _>(
                &Laplace3d,
                Geometry::Cube,
                n,
                order,
                kind,
                mode,
                Charges::Signed,
                None,
            );
            assert_bounded("laplace", &e, order, 2e-3);
            if order <= 6 {
                let (e, _) = run::<f64, _>(
                    &yukawa,
                    Geometry::Cube,
                    n,
                    order,
                    kind,
                    mode,
                    Charges::Signed,
                    None,
                );
                assert_bounded("yukawa", &e, order, 2e-3);
            }
        }
    }
}

/// The potential and gradient modes give the leading values of the
/// Hessian mode (the same passes with fewer outputs).
#[test]
fn fewer_outputs_are_the_leading_values() {
    let kind = SourceKind::ChargeDipole;
    let (_, full) = run::<f64, _>(
        &Laplace3d,
        Geometry::Sphere,
        6000,
        5,
        kind,
        EvalMode::PotentialGradientHessian,
        Charges::Signed,
        None,
    );
    for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
        let w = mode.values_per_target();
        let (_, part) = run::<f64, _>(
            &Laplace3d,
            Geometry::Sphere,
            6000,
            5,
            kind,
            mode,
            Charges::Signed,
            None,
        );
        let scale = full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in part.chunks_exact(w).zip(full.chunks_exact(10)) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 1e-12 * scale, "{} {x} vs {y}", mode.name());
            }
        }
    }
}

/// Adaptive (Plummer), thin (plane) and far-separated (two clusters, whose
/// coupling runs outside the trees) inputs with positive and zero-mean
/// dipoles, and separate targets.
#[test]
fn adaptive_thin_and_clustered_inputs_with_dipoles() {
    let mode = EvalMode::PotentialGradientHessian;
    for geometry in [Geometry::Plummer, Geometry::Plane, Geometry::TwoClusters] {
        for sign in Charges::ALL {
            let (e, _) = run::<f64, _>(
                &Laplace3d,
                geometry,
                15_000,
                6,
                SourceKind::ChargeDipole,
                mode,
                sign,
                None,
            );
            assert_bounded(geometry.name(), &e, 6, 2e-3);
        }
    }
    let targets: Vec<f64> = Geometry::Sphere.points(3000, 9);
    let (e, _) = run(
        &Laplace3d,
        Geometry::Cube,
        10_000,
        6,
        SourceKind::Dipole,
        mode,
        Charges::Signed,
        Some(&targets),
    );
    assert_bounded("separate targets", &e, 6, 2e-3);
}

/// A distant point is its own cluster, coupled to the cloud outside the
/// tree (its dipole acts through the cluster coupling, and it receives
/// the cloud's field there): still to the order's accuracy, at the
/// outlier too.
#[test]
fn a_distant_dipole_is_coupled_to_the_accuracy_of_the_order() {
    let n = 8000;
    let mut points: Vec<f64> = Geometry::Cube.points(n, 2);
    points[3 * n - 3..].copy_from_slice(&[1e4, -3e3, 2e4]);
    let kind = SourceKind::ChargeDipole;
    let mode = EvalMode::PotentialGradientHessian;
    let mut d: Vec<f64> = Charges::Signed.generate(4 * n, 3);
    // A strong outlier, so that its field matters in the cloud.
    d[4 * n - 4..].copy_from_slice(&[1e3, 2e6, -1e6, 3e6]);
    let fmm = FmmBuilder::new(&points)
        .source_kind(kind)
        .mode(mode)
        .order(6)
        .build_svd()
        .unwrap();
    assert!(
        fmm.n_clusters() > 1,
        "the outlier should be a cluster of its own"
    );
    let values = fmm.evaluate(&d).unwrap();
    let mut sample = sample_indices(n, 300);
    sample.push(n - 1);
    let e = relative_errors_sources(
        &Laplace3d, kind, mode, &points, &d, &points, &values, &sample,
    );
    assert_bounded("outlier", &e, 6, 2e-3);
    // The outlier alone: its own values against direct summation.
    let e = relative_errors_sources(
        &Laplace3d,
        kind,
        mode,
        &points,
        &d,
        &points,
        &values,
        &[n - 1],
    );
    assert!(e.worst() < 1e-4, "at the outlier: {e:?}");
}

/// f32 reaches its rounding floor with dipoles and Hessians too.
#[test]
fn f32_dipoles_and_hessians() {
    let (e, _) = run::<f32, _>(
        &Laplace3d,
        Geometry::Cube,
        10_000,
        5,
        SourceKind::ChargeDipole,
        EvalMode::PotentialGradientHessian,
        Charges::Signed,
        None,
    );
    assert!(e.worst() < 2e-4, "{e:?}");
}

/// `evaluate_many` runs vector after vector of densities.
#[test]
fn many_density_vectors() {
    let points: Vec<f64> = Geometry::Cube.points(3000, 1);
    let kind = SourceKind::Dipole;
    let fmm = FmmBuilder::new(&points)
        .source_kind(kind)
        .mode(EvalMode::PotentialGradient)
        .order(5)
        .build_svd()
        .unwrap();
    let a: Vec<f64> = Charges::Signed.generate(3 * 3000, 1);
    let b: Vec<f64> = Charges::Signed.generate(3 * 3000, 2);
    let both = fmm
        .evaluate_many(&[a.clone(), b.clone()].concat(), 2)
        .unwrap();
    assert_eq!(both.len(), 2 * 4 * 3000);
    assert_eq!(&both[..4 * 3000], &fmm.evaluate(&a).unwrap()[..]);
    assert_eq!(&both[4 * 3000..], &fmm.evaluate(&b).unwrap()[..]);
}

/// With a tolerance, the verified result meets it for every output.
#[test]
fn tolerance_holds_for_dipoles_and_hessians() {
    let points: Vec<f64> = Geometry::Sphere.points(20_000, 3);
    let kind = SourceKind::ChargeDipole;
    let d: Vec<f64> = Charges::Signed.generate(4 * 20_000, 4);
    for eps in [1e-4, 1e-7] {
        let mut fmm = FmmBuilder::new(&points)
            .source_kind(kind)
            .mode(EvalMode::PotentialGradientHessian)
            .tolerance(eps)
            .build_svd()
            .unwrap();
        let out = fmm.evaluate_verified(&d).unwrap();
        let e = relative_errors_sources(
            &Laplace3d,
            kind,
            EvalMode::PotentialGradientHessian,
            &points,
            &d,
            &points,
            &out.values,
            &sample_indices(20_000, 500),
        );
        assert!(e.worst() <= eps, "eps {eps:e}: {e:?}");
        let v = out.verification.unwrap();
        assert!(v.measured().hessian.is_some());
    }
}

/// A kernel that implements only values and gradients.
#[derive(Clone)]
struct Plain;

impl Kernel for Plain {
    fn name(&self) -> String {
        "plain".into()
    }
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        Laplace3d.kernel_value(d)
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        Laplace3d.kernel_gradient(d)
    }
}

#[test]
fn bad_densities_and_unsupported_kernels_are_errors() {
    let points: Vec<f64> = Geometry::Cube.points(500, 1);
    let fmm = FmmBuilder::new(&points)
        .source_kind(SourceKind::Dipole)
        .order(4)
        .build_svd()
        .unwrap();
    // One value per source is a charge vector, not dipoles.
    let e = fmm.evaluate(&vec![1.0; 500]).unwrap_err();
    assert!(
        matches!(
            e,
            FmmError::DensityCount {
                per_source: 3,
                expected: 1500,
                got: 500,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("dipole"), "{e}");
    let mut d = vec![0.5; 1500];
    d[7] = f64::INFINITY;
    assert!(matches!(
        fmm.evaluate(&d),
        Err(FmmError::NonFiniteCharge { index: 7, .. })
    ));
    for (kind, mode) in [
        (SourceKind::Dipole, EvalMode::Potential),
        (SourceKind::Charge, EvalMode::PotentialGradientHessian),
    ] {
        let e = FmmBuilder::new(&points)
            .kernel(Plain)
            .source_kind(kind)
            .mode(mode)
            .build_svd()
            .err()
            .expect("the plain kernel has no dipoles or Hessians");
        assert!(
            matches!(&e, FmmError::Kernel(KernelError::Unsupported { kernel, .. }) if kernel == "plain"),
            "{e:?}"
        );
    }
}
