//! `FmmBuilder::tolerance`: the achieved relative L2 potential error is at
//! most the tolerance asked for, on four very different point sets, in f64
//! and (where it can promise it) f32; unreachable tolerances are refused by
//! name; the chosen parameters are reported and reproduce the result.

use ferrofmm_field::{SvdConfig, SvdM2l};
use ferrofmm_fmm::tuning::{self, ErrorModel, SAFETY_FACTOR};
use ferrofmm_fmm::{
    ChosenParameters, FmmBuilder, FmmError, Geometry, charges, f32_reaches, relative_errors,
    sample_indices,
};
use ferrofmm_kernels::{EvalMode, Laplace3d, Precision, Real};

const N: usize = 20_000;
/// Prime, so that the evenly spaced sample holds odd and even indices
/// (`Geometry::TwoClusters` alternates between its clusters).
const SAMPLE: usize = 997;
const TOLERANCES: [f64; 4] = [1e-3, 1e-5, 1e-7, 1e-9];

fn cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tolerance-operators")
}

/// Build for `eps`, evaluate, and return the error and the chosen parameters.
fn run<T: Real>(points: &[T], eps: f64) -> (f64, ChosenParameters) {
    try_run(points, eps).unwrap_or_else(|e| panic!("build for {eps:e}: {e}"))
}

fn try_run<T: Real>(points: &[T], eps: f64) -> Result<(f64, ChosenParameters), FmmError> {
    let n = points.len() / 3;
    let q: Vec<T> = charges(n, 11);
    let fmm = FmmBuilder::new(points)
        .tolerance(eps)
        .cache_dir(cache())
        .build_svd()?;
    let values = fmm.evaluate(&q).unwrap();
    let e = relative_errors(
        &Laplace3d,
        EvalMode::Potential,
        points,
        &q,
        points,
        &values,
        &sample_indices(n, SAMPLE),
    );
    let chosen = fmm.chosen_parameters().cloned().expect("chosen parameters");
    assert_eq!(fmm.summary().chosen.as_ref(), Some(&chosen));
    Ok((e.potential, chosen))
}

fn check_geometry(g: Geometry) {
    let points: Vec<f64> = g.points(N, 7);
    let mut previous: Option<ChosenParameters> = None;
    for eps in TOLERANCES {
        let (err, c) = run(&points, eps);
        eprintln!(
            "{:13} eps {eps:.0e}: error {err:.2e} (predicted {:.1e}) p {} leaf {} svd {:.1e} rank {:?}",
            g.name(),
            c.predicted_error,
            c.order,
            c.leaf_size,
            c.svd_tolerance,
            c.svd_rank
        );
        assert!(
            err <= eps,
            "{g:?}: tolerance {eps:e} not met: error {err:.3e} with {c:?}"
        );
        assert!(
            SAFETY_FACTOR * c.predicted_error <= eps * (1.0 + 1e-9),
            "{c:?}"
        );
        assert_eq!(c.precision, "f64");
        let rank = c.svd_rank.expect("build_svd reports the rank");
        assert!(rank >= 1 && rank <= ferrofmm_field::n_surface_points(c.order));
        if let Some(p) = &previous {
            // A tighter tolerance never gets a lower order or a coarser SVD.
            assert!(c.order >= p.order, "{p:?} then {c:?}");
            assert!(c.svd_tolerance <= p.svd_tolerance, "{p:?} then {c:?}");
        }
        previous = Some(c);
    }
}

#[test]
fn meets_tolerance_on_uniform_cube() {
    check_geometry(Geometry::Cube);
}

#[test]
fn meets_tolerance_on_sphere_surface() {
    check_geometry(Geometry::Sphere);
}

#[test]
fn meets_tolerance_on_plummer_cluster() {
    check_geometry(Geometry::Plummer);
}

#[test]
fn meets_tolerance_on_two_clusters() {
    check_geometry(Geometry::TwoClusters);
}

#[test]
fn f32_meets_what_it_promises() {
    let smallest = tuning::smallest_tolerance(Precision::F32);
    assert!(f32_reaches(smallest) && !f32_reaches(0.5 * smallest));
    for g in Geometry::ALL {
        let points: Vec<f32> = g.points(N, 7);
        let points64: Vec<f64> = points.iter().map(|&x| x as f64).collect();
        for eps in [1e-3, smallest] {
            match try_run(&points, eps) {
                Ok((err, c)) => {
                    eprintln!(
                        "f32 {:13} eps {eps:.1e}: error {err:.2e} p {}",
                        g.name(),
                        c.order
                    );
                    assert!(
                        err <= eps,
                        "f32 {g:?}: {eps:e} not met: {err:.3e} with {c:?}"
                    );
                    assert_eq!(c.precision, "f32");
                    assert_eq!(
                        tuning::choose_precision(eps, &points64, None).unwrap(),
                        Precision::F32
                    );
                }
                // Only the cluster of size 1e-4 at (1, 1, 1) needs more digits
                // of its coordinates than f32 has; f64 then takes over.
                Err(FmmError::ToleranceBeyondPrecision {
                    precision, limit, ..
                }) => {
                    eprintln!(
                        "f32 {:13} eps {eps:.1e}: refused (limit {limit:.1e})",
                        g.name()
                    );
                    assert_eq!(g, Geometry::TwoClusters, "f32 refused {eps:e} on {g:?}");
                    assert_eq!(precision, "f32");
                    assert!(limit > eps);
                    assert_eq!(
                        tuning::choose_precision(eps, &points64, None).unwrap(),
                        Precision::F64
                    );
                }
                Err(e) => panic!("{g:?} {eps:e}: {e}"),
            }
        }
    }
}

#[test]
fn unreachable_or_invalid_tolerances_are_refused() {
    let points: Vec<f64> = Geometry::Cube.points(1000, 1);
    for eps in [0.0, -1e-6, 1.0, 2.0, f64::NAN, f64::INFINITY] {
        let r = FmmBuilder::new(&points).tolerance(eps).build_svd();
        assert!(
            matches!(r, Err(FmmError::InvalidTolerance(_))),
            "{eps}: {:?}",
            r.err()
        );
    }
    let r = FmmBuilder::new(&points).tolerance(1e-14).build_svd();
    match r {
        Err(FmmError::ToleranceBeyondPrecision {
            precision, limit, ..
        }) => {
            assert_eq!(precision, "f64");
            assert!(limit > 1e-14 && limit < 1e-10);
        }
        other => panic!("expected ToleranceBeyondPrecision, got {:?}", other.err()),
    }
    let points32: Vec<f32> = Geometry::Cube.points(1000, 1);
    assert!(!f32_reaches(1e-7));
    let r = FmmBuilder::new(&points32).tolerance(1e-7).build_svd();
    match r {
        Err(e @ FmmError::ToleranceBeyondPrecision { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("f32") && msg.contains("f64"), "{msg}");
        }
        other => panic!("expected ToleranceBeyondPrecision, got {:?}", other.err()),
    }
    // The same tolerance is fine in f64.
    assert!(FmmBuilder::new(&points).tolerance(1e-7).build_svd().is_ok());
}

#[test]
fn chosen_parameters_reproduce_the_result() {
    let points: Vec<f64> = Geometry::Plummer.points(8000, 3);
    let q: Vec<f64> = charges(8000, 4);
    let tuned = FmmBuilder::new(&points)
        .order(14) // replaced by the tolerance
        .leaf_size(3)
        .tolerance(1e-6)
        .cache_dir(cache())
        .build_svd()
        .unwrap();
    let c = tuned.chosen_parameters().unwrap().clone();
    assert_eq!(tuned.order(), c.order);
    assert_eq!(tuned.leaf_size(), c.leaf_size);
    assert_eq!(tuned.m2l_scheme().rank(), c.svd_rank.unwrap());
    let manual = FmmBuilder::new(&points)
        .order(c.order)
        .leaf_size(c.leaf_size)
        .cache_dir(cache())
        .build_with::<SvdM2l<f64>>(SvdConfig {
            rank: None,
            tolerance: c.svd_tolerance,
        })
        .unwrap();
    assert!(manual.chosen_parameters().is_none());
    assert!(manual.summary().chosen.is_none());
    assert_eq!(tuned.evaluate(&q).unwrap(), manual.evaluate(&q).unwrap());
    // The choice needs no build.
    let direct = tuning::choose_parameters(1e-6, &points, None).unwrap();
    assert_eq!((direct.order, direct.leaf_size), (c.order, c.leaf_size));
    assert_eq!(direct.svd_tolerance, c.svd_tolerance);
}

#[test]
fn separate_targets_and_dense_scheme_meet_tolerance() {
    let sources: Vec<f64> = Geometry::Sphere.points(6000, 1);
    let targets: Vec<f64> = Geometry::Cube
        .points::<f64>(3000, 2)
        .iter()
        .map(|x| 2.0 * x - 1.0)
        .collect();
    let q: Vec<f64> = charges(6000, 3);
    let eps = 1e-5;
    let fmm = FmmBuilder::new(&sources)
        .targets(&targets)
        .tolerance(eps)
        .cache_dir(cache())
        .build_dense()
        .unwrap();
    let c = fmm.chosen_parameters().unwrap();
    assert!(c.svd_rank.is_none(), "no SVD in the dense scheme");
    let v = fmm.evaluate(&q).unwrap();
    let e = relative_errors(
        &Laplace3d,
        EvalMode::Potential,
        &sources,
        &q,
        &targets,
        &v,
        &sample_indices(3000, SAMPLE),
    );
    assert!(e.potential <= eps, "error {:.3e}", e.potential);
}

#[test]
fn error_model_is_consistent() {
    for precision in [Precision::F64, Precision::F32] {
        let m = ErrorModel::laplace(precision);
        let mut last = f64::INFINITY;
        for &(p, e) in &m.order_errors {
            assert!(e > 0.0 && e.is_finite());
            if precision == Precision::F64 {
                assert!(e < last, "E_p must fall with p ({p})");
            }
            last = e;
        }
        for ratio in [0.0, 1e2, 1e5] {
            for eps in [0.5, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10] {
                if let Some(p) = m.smallest_order(eps, ratio) {
                    let tau = m.svd_tolerance(p, eps, ratio);
                    assert!(tau >= m.base_svd_tolerance(p));
                    let predicted = m.predicted_error(p, tau, ratio).unwrap();
                    assert!(
                        m.safety * predicted <= eps * (1.0 + 1e-9),
                        "{eps} {p} {tau}"
                    );
                    if p > m.order_errors[0].0 {
                        assert!(!m.admissible(p - 1, eps, ratio));
                    }
                } else {
                    assert!(eps < m.smallest_reachable(ratio));
                }
            }
        }
        // Boxes far from the origin cost digits.
        assert!(m.smallest_reachable(1e5) > m.smallest_reachable(10.0));
    }
    // A loose tolerance compresses harder than the default.
    let m = ErrorModel::laplace(Precision::F64);
    assert!(m.svd_tolerance(6, 1e-4, 0.0) > 10.0 * m.base_svd_tolerance(6));
}
