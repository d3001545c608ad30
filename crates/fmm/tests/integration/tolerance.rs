//! `FmmBuilder::tolerance`: the achieved relative L2 error (potential, and
//! gradient when evaluated) is at most the tolerance asked for, on seven
//! very different point sets (a plane, a curve and a thin closed surface
//! with a hole among them), for zero-mean and all-positive charges, in f64
//! and (where it can promise it) f32, with the after-the-fact verification
//! on; unreachable tolerances are refused by name; the chosen parameters
//! are reported and reproduce the result.

use ferrofmm_field::{SvdConfig, SvdM2l};
use ferrofmm_fmm::tuning::{self, ErrorModel};
use ferrofmm_fmm::{
    Charges, FmmBuilder, FmmError, Geometry, charges, f32_reaches, relative_errors, sample_indices,
};
use ferrofmm_kernels::{EvalMode, Laplace3d, Precision, Real};

const N: usize = 12_000;
/// Prime, so that the evenly spaced sample holds odd and even indices
/// (`Geometry::TwoClusters` alternates between its clusters).
const SAMPLE: usize = 997;

fn cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tolerance-operators")
}

/// Build for `eps` in `mode`, evaluate both kinds of charges with
/// verification, and check every output against direct summation.
fn check<T: Real>(g: Geometry, mode: EvalMode, eps: f64) -> Result<(), FmmError> {
    let points: Vec<T> = g.points(N, 7);
    // The FMM itself at every tolerance, never the direct sum the chooser
    // would take for 12,000 points at tight ones (tested in `defaults`).
    let mut fmm = FmmBuilder::new(&points)
        .tolerance(eps)
        .allow_direct(false)
        .mode(mode)
        .cache_dir(cache())
        .build_svd()?;
    // Every target: the relative L2 error the tolerance is about. A
    // sample's own denominators overstate the gradient's error of
    // same-sign charges in a volume (its norm is carried by a few targets
    // with a close neighbour) by up to 1.2x at 1000 targets.
    let sample: Vec<usize> = (0..N).collect();
    for kind in Charges::ALL {
        let q: Vec<T> = kind.generate(N, 11);
        let out = fmm.evaluate_verified(&q)?;
        let v = out.verification.expect("verification is on by default");
        let e = relative_errors(&Laplace3d, mode, &points, &q, &points, &out.values, &sample);
        let c = fmm.chosen_parameters().unwrap();
        eprintln!(
            "{} {:13} {:8} {} eps {eps:.0e}: pot {:.2e} grad {:?} (estimated {:.2e}, predicted {:.1e}) p {} leaf {} attempts {}",
            T::PRECISION.name(),
            g.name(),
            kind.name(),
            mode.values_per_target(),
            e.potential,
            e.gradient,
            v.measured().worst(),
            c.predicted_error,
            c.order,
            c.leaf_size,
            v.attempts.len()
        );
        if !v.met {
            // Only f32 may fall short (its rounding floor; f32 on a plane
            // is a known case, docs/stability.md), and then it says so: the
            // estimate and the real error are both above the tolerance.
            assert_eq!(
                T::PRECISION,
                Precision::F32,
                "{g:?} {kind:?} {eps:e}: {v:?}"
            );
            assert!(v.measured().worst() > eps);
            assert!(
                e.potential.max(e.gradient.unwrap_or(0.0)) > 0.5 * eps,
                "{e:?}"
            );
            continue;
        }
        assert!(
            e.potential <= eps,
            "{g:?} {kind:?}: tolerance {eps:e} not met by the potential: {e:?} with {c:?}"
        );
        if let Some(grad) = e.gradient {
            assert!(
                grad <= eps,
                "{g:?} {kind:?}: tolerance {eps:e} not met by the gradient: {e:?} with {c:?}"
            );
        }
        assert_eq!(c.precision, T::PRECISION.name());
        assert_eq!(fmm.summary().verification.as_ref(), Some(&v));
    }
    Ok(())
}

/// Per geometry: f64 with gradients at three tolerances six digits apart
/// (orders from about 3 to 12), f64 potentials at one more, f32 at two.
/// (Until this stop also 1e-7 with gradients and 1e-3 for potentials: they
/// passed, and cost a third of this file's 12 minutes in a cold CI run,
/// where every SVD is computed afresh.)
fn check_geometry(g: Geometry) {
    for eps in [1e-3, 1e-6, 1e-9] {
        check::<f64>(g, EvalMode::PotentialGradient, eps).unwrap();
    }
    check::<f64>(g, EvalMode::Potential, 1e-5).unwrap();
    for eps in [1e-3, 1e-5] {
        for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
            match check::<f32>(g, mode, eps) {
                Ok(()) => {}
                // f32 cannot resolve the cluster of size 1e-4 at (1, 1, 1)
                // to 1e-5; `--precision auto` takes f64 there.
                Err(FmmError::ToleranceBeyondPrecision { precision, .. })
                    if g == Geometry::TwoClusters
                        || (eps < 1e-4 && mode != EvalMode::Potential) =>
                {
                    assert_eq!(precision, "f32");
                    let points: Vec<f64> = g.points(N, 7);
                    assert_eq!(
                        tuning::choose_precision(eps, mode, &points, None).unwrap(),
                        Precision::F64
                    );
                }
                Err(e) => panic!("f32 {g:?} {eps:e}: {e}"),
            }
        }
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
fn meets_tolerance_on_plane() {
    check_geometry(Geometry::Plane);
}

#[test]
fn meets_tolerance_on_curve() {
    check_geometry(Geometry::Curve);
}

#[test]
fn meets_tolerance_on_torus() {
    check_geometry(Geometry::Torus);
}

#[test]
fn f32_limit_is_what_it_promises() {
    let smallest = tuning::smallest_tolerance(Precision::F32);
    assert!(f32_reaches(smallest) && !f32_reaches(0.5 * smallest));
    assert!(f32_reaches(1e-5));
}

#[test]
fn verification_can_be_switched_off_and_says_so() {
    let points: Vec<f64> = Geometry::Cube.points(3000, 1);
    let q: Vec<f64> = charges(3000, 2);
    let mut fmm = FmmBuilder::new(&points)
        .tolerance(1e-4)
        .verify(false)
        .cache_dir(cache())
        .build_svd()
        .unwrap();
    let out = fmm.evaluate_verified(&q).unwrap();
    assert!(out.verification.is_none());
    assert!(fmm.summary().verification.is_none());
    assert_eq!(out.values, fmm.evaluate(&q).unwrap());
    // Without a tolerance there is nothing to verify either.
    let mut plain = FmmBuilder::new(&points).order(4).build_svd().unwrap();
    assert!(plain.evaluate_verified(&q).unwrap().verification.is_none());
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
            assert!(limit > 1e-14 && limit < 1e-9);
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
    // A leaf size given: a tree (8000 points would be a direct sum) whose
    // order and SVD tolerance are chosen.
    let points: Vec<f64> = Geometry::Plummer.points(8000, 3);
    let q: Vec<f64> = charges(8000, 4);
    let tuned = FmmBuilder::new(&points)
        .leaf_size(96)
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
    let direct = tuning::Tuner::new(ferrofmm_kernels::Precision::F64)
        .with_leaf_size(96)
        .choose(1e-6, &points, None, None, ferrofmm_tree::DEEPEST_LEVEL)
        .unwrap();
    assert_eq!((direct.order, direct.leaf_size), (c.order, c.leaf_size));
    assert_eq!(direct.svd_tolerance, c.svd_tolerance);
    assert!(!c.direct);
    // An order and a leaf size given with the tolerance are kept; only the
    // SVD tolerance is chosen (and verification may raise the order).
    let fixed = FmmBuilder::new(&points)
        .order(5)
        .leaf_size(96)
        .tolerance(1e-3)
        .cache_dir(cache())
        .build_svd()
        .unwrap();
    assert_eq!((fixed.order(), fixed.leaf_size()), (5, 96));
    assert_eq!(fixed.chosen_parameters().unwrap().order, 5);
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

/// A kernel written outside the crates (`1 / (2 pi r)`, twice Laplace's,
/// homogeneous so that its operators are computed once): the default model
/// is Laplace's, reported as borrowed; the tolerance is still met, because
/// the verification measures whatever the kernel.
#[derive(Clone, Copy, Debug)]
struct TwiceLaplace;

impl ferrofmm_kernels::Kernel for TwiceLaplace {
    fn name(&self) -> String {
        "twice-laplace".into()
    }
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if r2 == T::ZERO {
            return T::ZERO;
        }
        T::from_f64(0.5 / std::f64::consts::PI) / r2.sqrt()
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if r2 == T::ZERO {
            return [T::ZERO; 3];
        }
        let f = -T::from_f64(0.5 / std::f64::consts::PI) / (r2 * r2.sqrt());
        [f * d[0], f * d[1], f * d[2]]
    }
}

#[test]
fn models_are_keyed_on_the_kernel_and_can_be_replaced() {
    use std::sync::Arc;
    use tuning::{CostModel, M2lCostShape, TuningModel};
    let n = 6000;
    let points: Vec<f64> = Geometry::Sphere.points(n, 3);
    let q: Vec<f64> = charges(n, 5);
    let eps = 1e-5;

    // Laplace: the measured model.
    // Leaf sizes given throughout: trees whose order the models choose
    // (6000 points would otherwise be a direct sum).
    let laplace = FmmBuilder::new(&points)
        .tolerance(eps)
        .leaf_size(64)
        .build_svd()
        .unwrap();
    let c = laplace.chosen_parameters().unwrap();
    assert_eq!(c.model, "laplace");
    assert!(c.model_measured);

    // Modified Helmholtz: Laplace's tables, measured to bound it, and a
    // dearer kernel in the cost model.
    let yukawa = ferrofmm_kernels::ModifiedHelmholtz3d::new(3.0).unwrap();
    let fmm = FmmBuilder::new(&points)
        .kernel(yukawa)
        .tolerance(eps)
        .leaf_size(64)
        .build_svd()
        .unwrap();
    let c = fmm.chosen_parameters().unwrap();
    assert!(c.model.starts_with("modified-helmholtz"), "{}", c.model);
    assert!(c.model_measured);

    // A user kernel: borrowed, and the verification still holds it to eps.
    let mut fmm = FmmBuilder::new(&points)
        .kernel(TwiceLaplace)
        .tolerance(eps)
        .leaf_size(64)
        .build_svd()
        .unwrap();
    let c = fmm.chosen_parameters().unwrap().clone();
    assert_eq!(c.model, "laplace tables for twice-laplace");
    assert!(!c.model_measured);
    let out = fmm.evaluate_verified(&q).unwrap();
    assert!(out.verification.unwrap().met);
    let sample = sample_indices(n, SAMPLE);
    let e = relative_errors(
        &TwiceLaplace,
        EvalMode::Potential,
        &points,
        &q,
        &points,
        &out.values,
        &sample,
    );
    assert!(e.potential <= eps, "{e:?}");

    // A model of one's own: errors ten times smaller than Laplace's at
    // every order let the chooser take a lower order.
    #[derive(Debug)]
    struct Tenfold;
    impl TuningModel for Tenfold {
        fn name(&self) -> String {
            "tenfold".into()
        }
        fn error_model(&self, p: Precision, mode: EvalMode, _: M2lCostShape) -> ErrorModel {
            let mut m = ErrorModel::laplace_for(p, mode);
            m.order_errors.iter_mut().for_each(|(_, e)| *e *= 0.01);
            m
        }
        fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
            CostModel::default().for_mode(mode)
        }
    }
    let fmm = FmmBuilder::new(&points)
        .tolerance(eps)
        .leaf_size(64)
        .tuning_model(Tenfold)
        .verify(false)
        .build_svd()
        .unwrap();
    let own = fmm.chosen_parameters().unwrap();
    assert_eq!(own.model, "tenfold");
    let base = laplace.chosen_parameters().unwrap();
    assert!(own.order < base.order, "{} vs {}", own.order, base.order);
    // The tuner asks the model again for another mode or scheme.
    let t = tuning::Tuner::new(Precision::F64).with_model(Arc::new(Tenfold));
    let g = t.clone().for_mode(EvalMode::PotentialGradient);
    assert_eq!(
        g.error,
        Tenfold.error_model(
            Precision::F64,
            EvalMode::PotentialGradient,
            M2lCostShape::Compressed
        )
    );
    assert_eq!(
        g.cost,
        CostModel::default().for_mode(EvalMode::PotentialGradient)
    );
}

#[test]
fn only_the_svd_scheme_loosens_its_compression() {
    let points: Vec<f64> = Geometry::Cube.points(20_000, 3);
    let occ = tuning::Occupancy::new(&points, None, None, 19).unwrap();
    let eps = 1e-5;
    let svd = tuning::Tuner::new(Precision::F64)
        .choose_with(eps, &occ)
        .unwrap();
    let fft = tuning::Tuner::new(Precision::F64)
        .for_scheme(tuning::M2lCostShape::Fft)
        .choose_with(eps, &occ)
        .unwrap();
    let base = |p| ferrofmm_field::default_svd_tolerance(Precision::F64, p);
    assert!(svd.svd_tolerance >= base(svd.order));
    assert_eq!(fft.svd_tolerance, base(fft.order));
    assert_eq!(fft.m2l_cost, "fft");
}
