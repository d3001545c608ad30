use super::*;

/// The check with progress gives the same errors, bit for bit, and
/// reports its direct sums block by block, never going back, ending
/// at its total (sources times sampled targets).
#[test]
fn progress_reports_the_direct_sums_and_changes_nothing() {
    use std::sync::Mutex;
    let pts: Vec<f64> = crate::Geometry::Cube.points(10_000, 3);
    let q: Vec<f64> = (0..10_000)
        .map(|i| ((i * 37) % 101) as f64 / 50.0 - 1.0)
        .collect();
    let values: Vec<f64> = (0..40_000).map(|i| (i % 7) as f64).collect();
    let sample: Vec<usize> = (0..10_000).step_by(97).collect();
    let (k, kind, mode) = (
        &ferrofmm_kernels::Laplace3d,
        SourceKind::Charge,
        EvalMode::PotentialGradient,
    );
    let plain = relative_errors_sources(k, kind, mode, &pts, &q, &pts, &values, &sample);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let log = seen.clone();
    let progress: Arc<ProgressFn> = Arc::new(move |p| log.lock().unwrap().push(p));
    let with = relative_errors_sources_with_progress(
        k, kind, mode, &pts, &q, &pts, &values, &sample, &progress,
    );
    assert_eq!(plain, with);
    let seen = seen.lock().unwrap();
    let total = 10_000 * sample.len() as u64;
    assert!(seen.len() >= 3, "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0].done <= w[1].done));
    assert!(seen.iter().all(|p| p.total == total));
    assert_eq!(seen.last().unwrap().done, total);
}
use ferrofmm_kernels::{Laplace3d, direct_sum};

fn problem(n: usize) -> (Vec<f64>, Vec<f64>) {
    let points: Vec<f64> = crate::Geometry::Cube.points(n, 3);
    let q: Vec<f64> = crate::charges(n, 4);
    (points, q)
}

#[test]
fn reference_matches_direct_sum_for_any_charge_scale() {
    let (points, q) = problem(9000);
    let mode = EvalMode::PotentialGradient;
    let mut exact = vec![0.0; 4 * 9000];
    direct_sum(&Laplace3d, mode, &points, &q, &points, &mut exact);
    // A perturbation of relative size 1e-6 everywhere.
    let perturbed: Vec<f64> = exact
        .iter()
        .enumerate()
        .map(|(i, v)| v * (1.0 + 1e-6 * if i % 2 == 0 { 1.0 } else { -1.0 }))
        .collect();
    let sample = sample_indices(9000, 101);
    for s in [1.0, 1e200, 1e-300] {
        let qs: Vec<f64> = q.iter().map(|x| x * s).collect();
        let vs: Vec<f64> = perturbed.iter().map(|x| x * s).collect();
        let e = relative_errors(&Laplace3d, mode, &points, &qs, &points, &vs, &sample);
        assert!(
            (e.potential / 1e-6 - 1.0).abs() < 1e-3,
            "scale {s:e}: {e:?}"
        );
        assert!((e.gradient.unwrap() / 1e-6 - 1.0).abs() < 1e-3, "{e:?}");
    }
}

#[test]
fn estimate_respects_the_sample_bounds() {
    let (points, q) = problem(5000);
    let mode = EvalMode::Potential;
    let mut exact = vec![0.0; 5000];
    direct_sum(&Laplace3d, mode, &points, &q, &points, &mut exact);
    let noisy: Vec<f64> = exact.iter().map(|v| v * (1.0 + 1e-4)).collect();
    let estimate = |budget| {
        estimate_errors(
            &Laplace3d,
            SourceKind::Charge,
            mode,
            &points,
            &q,
            &points,
            &noisy,
            budget,
            40,
            200,
        )
    };
    let e = estimate(Duration::ZERO);
    assert_eq!(e.n_sampled, 40);
    assert!((e.potential / 1e-4 - 1.0).abs() < 1e-6, "{e:?}");
    let e = estimate(Duration::from_secs(60));
    assert_eq!(e.n_sampled, 200);
}

#[test]
fn random_sample_is_distinct_and_deterministic() {
    let a = random_sample(1000, 300);
    let b = random_sample(1000, 300);
    assert_eq!(a, b);
    let set: std::collections::HashSet<_> = a.iter().collect();
    assert_eq!(set.len(), 300);
    assert!(a.iter().all(|&j| j < 1000));
    assert_eq!(random_sample(10, 20), (0..10).collect::<Vec<_>>());
    // Both parities appear (two-cluster inputs alternate by index).
    assert!(a.iter().any(|j| j % 2 == 0) && a.iter().any(|j| j % 2 == 1));
}
