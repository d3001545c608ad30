//! Outliers and extreme spreads (issue 18, row 1).
//!
//! A distant point no longer costs the rest of the cloud its digits: the
//! coordinates the passes see are relative to an origin for which the
//! subtraction is exact (`coordinate_origin`). (Before: 2.1e-5 at D = 1e12
//! and 2.3e-2 at D = 1e15 in f64.) Nor does it pile the cloud into one
//! deep leaf: far-separated clusters get a tree each, coupled through their
//! roots' expansions, so the near field stays linear. Every case is held to
//! at most 3x the error of the same cloud without the outliers, on
//! zero-mean and positive charges.

use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real};
use ferrofmm_tree::Octree;

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

/// Source-target pairs summed directly by a tree's near field (P2P over
/// each leaf's U list and itself).
fn near_pairs(tree: &Octree) -> usize {
    tree.leaves()
        .iter()
        .map(|&b| {
            let near: usize = tree
                .u_list(b)
                .iter()
                .map(|&u| tree.source_range(u).len())
                .sum();
            tree.target_range(b).len() * (near + tree.source_range(b).len())
        })
        .sum()
}

/// Result of one run: worst relative error (potential or gradient) over
/// sampled targets, near-field pairs of the main tree, number of clusters.
struct Run {
    error: f64,
    near_pairs: usize,
    clusters: usize,
}

fn run<T: Real>(sources: &[f64], targets: Option<&[f64]>, kind: Charges) -> Run {
    let s: Vec<T> = sources.iter().map(|&x| T::from_f64(x)).collect();
    let t: Option<Vec<T>> = targets.map(|t| t.iter().map(|&x| T::from_f64(x)).collect());
    let n = s.len() / 3;
    let q: Vec<T> = kind.generate(n, 11);
    let mode = EvalMode::PotentialGradient;
    let mut builder = FmmBuilder::new(&s)
        .cache_dir(crate::ops_cache())
        .order(6)
        .leaf_size(40)
        .mode(mode);
    if let Some(t) = &t {
        builder = builder.targets(t);
    }
    let fmm = builder.build_svd().unwrap();
    let v = fmm.evaluate(&q).unwrap();
    let tg = t.as_deref().unwrap_or(&s);
    let m = tg.len() / 3;
    let e = relative_errors(&Laplace3d, mode, &s, &q, tg, &v, &sample_indices(m, 400));
    Run {
        error: e.worst(),
        near_pairs: near_pairs(fmm.tree()),
        clusters: fmm.n_clusters(),
    }
}

const N: usize = 3000;

fn cloud(n: usize, seed: u64) -> Vec<f64> {
    Geometry::Cube.points(n, seed)
}

/// Checks a case against the clean cloud: error at most 3x, near field no
/// larger than 1.5x (it is the quadratic pile-up that this catches).
fn check<T: Real>(label: &str, clean: &[f64], case: &[f64], clusters: usize) {
    for kind in Charges::ALL {
        let reference = run::<T>(clean, None, kind);
        let r = run::<T>(case, None, kind);
        eprintln!(
            "{label} ({kind:?}, {}): error {:.2e} (clean {:.2e}), near pairs {} (clean {}), clusters {}",
            T::PRECISION.name(),
            r.error,
            reference.error,
            r.near_pairs,
            reference.near_pairs,
            r.clusters
        );
        assert!(
            r.error <= 3.0 * reference.error,
            "{label}: error {:.3e} vs {:.3e}",
            r.error,
            reference.error
        );
        assert!(
            2 * r.near_pairs <= 3 * reference.near_pairs,
            "{label}: {} near pairs vs {}",
            r.near_pairs,
            reference.near_pairs
        );
        assert_eq!(r.clusters, clusters, "{label}");
    }
}

#[test]
fn one_distant_point_keeps_the_near_field_linear() {
    let clean = cloud(N, 5);
    for d in [1e6, 1e12, 1e15] {
        let mut p = clean.clone();
        p[3 * N - 3..].copy_from_slice(&[d; 3]);
        check::<f64>(&format!("one point at {d:e}"), &clean, &p, 2);
    }
    let mut p = clean.clone();
    p[3 * N - 3..].copy_from_slice(&[1e4; 3]);
    check::<f32>("f32, one point at 1e4", &clean, &p, 2);
}

#[test]
fn outliers_on_several_sides() {
    let clean = cloud(N, 6);
    let mut p = clean.clone();
    let outliers = [
        [1e6, 0.5, 0.5],
        [-1e6, 0.3, 0.7],
        [0.5, 1e7, 0.5],
        [0.2, 0.5, -1e9],
        [3e5, -2e5, 1e5],
        [-4e12, 2e12, 0.5],
    ];
    for (i, o) in outliers.iter().enumerate() {
        p[3 * (N - 1 - i)..3 * (N - i)].copy_from_slice(o);
    }
    check::<f64>("six outliers on several sides", &clean, &p, 7);
}

#[test]
fn two_clouds_far_apart() {
    let clean = cloud(N, 7);
    let mut p = clean.clone();
    for x in p[3 * (N / 2)..].iter_mut().step_by(3) {
        *x += 1e8;
    }
    // Each cloud's tree holds half the points: its near field is at most
    // the clean cloud's.
    check::<f64>("two clouds 1e8 apart", &clean, &p, 2);
}

#[test]
fn a_cloud_far_from_the_origin() {
    let clean = cloud(N, 8);
    let p: Vec<f64> = clean.iter().map(|&x| x + 1e9).collect();
    check::<f64>("unit cloud at 1e9", &clean, &p, 1);
}

/// Targets in two far groups, sources in one: the far targets form a
/// target-only cluster that receives the sources' root expansion.
#[test]
fn far_targets_of_a_compact_source_cloud() {
    let sources = cloud(N, 9);
    let clean_targets = cloud(N / 2, 10);
    let mut targets = clean_targets.clone();
    for x in targets[..3 * (N / 4)].iter_mut().step_by(3) {
        *x += 1e6;
    }
    for kind in Charges::ALL {
        let reference = run::<f64>(&sources, Some(&clean_targets), kind);
        let r = run::<f64>(&sources, Some(&targets), kind);
        eprintln!(
            "far targets ({kind:?}): {:.2e} (clean {:.2e})",
            r.error, reference.error
        );
        assert!(r.error <= 3.0 * reference.error);
        assert_eq!(r.clusters, 2);
    }
}
