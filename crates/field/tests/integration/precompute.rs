//! Issue 18 row 8: M2L operators only for the levels and transfer vectors
//! a tree uses; progress and cancellation of the precomputation.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use ferrofmm_field::{
    CacheStatus, DenseConfig, DenseM2l, FieldError, M2lInteractions, M2lScheme, M2lUsage,
    OperatorParams, PrecomputeMonitor, SvdConfig, SvdM2l, n_surface_points, transfer_vectors,
};
use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d};

const ORDER: usize = 3;

/// One interaction `(0 <- 0, v)` applied to a fixed multipole.
fn apply_one<S: M2lScheme<f64>>(m2l: &S, level: u32, v: [i32; 3]) -> Vec<f64> {
    let n = n_surface_points(ORDER);
    let inter = M2lInteractions::new(1, 1, &[(0, 0, v)]);
    let multipole: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
    let mut check = vec![0.0; n];
    m2l.apply(level, &inter, &multipole, &mut check);
    check
}

fn usage(level: u32, vectors: &[usize]) -> M2lUsage {
    let mut u = M2lUsage::none();
    for &v in vectors {
        u.mark(level, v);
    }
    u
}

const USED: [usize; 4] = [0, 41, 200, 315];

#[test]
fn dense_for_usage_equals_full_on_used_vectors_and_holds_nothing_else() {
    let params = OperatorParams::new(ORDER);
    let full = DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, 1.0, 4).unwrap();
    let part = DenseM2l::<f64>::precompute_for(
        &Laplace3d,
        &params,
        &DenseConfig,
        1.0,
        4,
        &usage(3, &USED),
    )
    .unwrap();
    assert_eq!(full.n_matrices(), 316);
    assert_eq!(part.n_matrices(), USED.len());
    let vectors = transfer_vectors();
    for &v in &USED {
        // Homogeneous kernel: one set serves every level.
        for level in [2, 3, 4] {
            assert!(part.has_vector(level, v));
            assert_eq!(
                apply_one(&part, level, vectors[v]),
                apply_one(&full, level, vectors[v])
            );
        }
    }
    assert!(!part.has_vector(3, 1));
    assert!(part.memory_bytes() * 316 == full.memory_bytes() * USED.len());
}

#[test]
fn non_homogeneous_kernel_gets_only_the_used_levels() {
    let kernel = ModifiedHelmholtz3d::new(2.0).unwrap();
    let params = OperatorParams::new(ORDER);
    let mut u = usage(3, &USED);
    u.mark(4, 7);
    let part = DenseM2l::<f64>::precompute_for(&kernel, &params, &DenseConfig, 1.0, 5, &u).unwrap();
    assert_eq!(part.n_matrices(), USED.len() + 1);
    assert!(part.has_vector(3, 41) && !part.has_vector(4, 41) && part.has_vector(4, 7));
    assert!(!part.has_vector(2, 0) && !part.has_vector(5, 0));
    let full = DenseM2l::<f64>::precompute(&kernel, &params, &DenseConfig, 1.0, 5).unwrap();
    let vectors = transfer_vectors();
    assert_eq!(
        apply_one(&part, 4, vectors[7]),
        apply_one(&full, 4, vectors[7])
    );
}

#[test]
fn empty_usage_computes_nothing() {
    let params = OperatorParams::new(ORDER);
    let none = M2lUsage::none();
    let d =
        DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 1, &none).unwrap();
    assert_eq!((d.n_matrices(), d.memory_bytes()), (0, 0));
    let s =
        SvdM2l::<f64>::precompute_for(&Laplace3d, &params, &SvdConfig::default(), 1.0, 1, &none)
            .unwrap();
    assert_eq!((s.n_vectors(), s.memory_bytes()), (0, 0));
    // An empty level still applies (nothing to do).
    let n = n_surface_points(ORDER);
    let mut check = vec![0.0; n];
    d.apply(
        1,
        &M2lInteractions::new(1, 1, &[]),
        &vec![1.0; n],
        &mut check,
    );
    assert!(check.iter().all(|&x| x == 0.0));
}

#[test]
fn svd_for_usage_compresses_only_the_used_vectors_and_stays_accurate() {
    let params = OperatorParams::new(ORDER);
    let config = SvdConfig {
        rank: None,
        tolerance: 1e-8,
    };
    let dense = DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, 1.0, 4).unwrap();
    let part =
        SvdM2l::<f64>::precompute_for(&Laplace3d, &params, &config, 1.0, 4, &usage(3, &USED))
            .unwrap();
    assert_eq!(part.n_vectors(), USED.len());
    let vectors = transfer_vectors();
    for &v in &USED {
        let a = apply_one(&part, 3, vectors[v]);
        let b = apply_one(&dense, 3, vectors[v]);
        let err = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt();
        let norm = b.iter().map(|y| y * y).sum::<f64>().sqrt();
        assert!(
            err <= 1e-6 * norm,
            "vector {v}: relative error {}",
            err / norm
        );
    }
}

#[test]
fn cancel_flag_stops_with_cancelled() {
    let flag = Arc::new(AtomicBool::new(true));
    let mut params = OperatorParams::new(ORDER);
    params.monitor = PrecomputeMonitor::new().with_cancel_flag(flag.clone());
    let all = M2lUsage::all(3);
    let d = DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 3, &all);
    assert!(matches!(d, Err(FieldError::Cancelled)));
    let s = SvdM2l::<f64>::precompute_for(&Laplace3d, &params, &SvdConfig::default(), 1.0, 3, &all);
    assert!(matches!(s, Err(FieldError::Cancelled)));
    // Set in the middle: the progress callback raises the flag after the
    // first unit of work.
    let flag = Arc::new(AtomicBool::new(false));
    let raise = flag.clone();
    params.monitor = PrecomputeMonitor::new()
        .with_cancel_flag(flag)
        .with_progress(move |p| {
            if p.done > 0 {
                raise.store(true, Ordering::Relaxed);
            }
        });
    let s = SvdM2l::<f64>::precompute_for(&Laplace3d, &params, &SvdConfig::default(), 1.0, 3, &all);
    assert!(matches!(s, Err(FieldError::Cancelled)));
}

#[test]
fn progress_reaches_the_total() {
    let done = Arc::new(AtomicU64::new(0));
    let total = Arc::new(AtomicU64::new(0));
    let (d2, t2) = (done.clone(), total.clone());
    let mut params = OperatorParams::new(ORDER);
    params.monitor = PrecomputeMonitor::new().with_progress(move |p| {
        d2.fetch_max(p.done, Ordering::Relaxed);
        t2.store(p.total, Ordering::Relaxed);
    });
    SvdM2l::<f64>::precompute_for(
        &Laplace3d,
        &params,
        &SvdConfig::default(),
        1.0,
        3,
        &usage(3, &USED),
    )
    .unwrap();
    let total = total.load(Ordering::Relaxed);
    assert!(total > 0);
    assert_eq!(done.load(Ordering::Relaxed), total);
}

#[test]
fn with_a_cache_all_vectors_are_computed_and_the_file_serves_any_tree() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-precompute-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut params = OperatorParams::new(ORDER);
    params.cache_dir = Some(dir.clone());
    let part = DenseM2l::<f64>::precompute_for(
        &Laplace3d,
        &params,
        &DenseConfig,
        1.0,
        4,
        &usage(3, &USED),
    )
    .unwrap();
    assert_eq!(part.n_matrices(), 316);
    assert!(matches!(
        part.cache_status(),
        CacheStatus::Computed {
            write_error: None,
            ..
        }
    ));
    // Another usage, and the full precompute, both hit the same file.
    let other =
        DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 4, &usage(2, &[5]))
            .unwrap();
    assert!(other.cache_status().is_hit());
    let full = DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, 1.0, 4).unwrap();
    assert!(full.cache_status().is_hit());
    let svd = SvdM2l::<f64>::precompute_for(
        &Laplace3d,
        &params,
        &SvdConfig::default(),
        1.0,
        4,
        &usage(3, &USED),
    )
    .unwrap();
    assert_eq!(svd.n_vectors(), 316);
    let again =
        SvdM2l::<f64>::precompute(&Laplace3d, &params, &SvdConfig::default(), 1.0, 4).unwrap();
    assert!(again.cache_status().is_hit());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn estimates_follow_the_usage() {
    let params = OperatorParams::new(6);
    let none = <DenseM2l<f64> as M2lScheme<f64>>::estimate(
        &Laplace3d,
        &params,
        &DenseConfig,
        4,
        &M2lUsage::none(),
    );
    assert_eq!((none.matrices, none.peak_bytes), (0, 0));
    let some = <DenseM2l<f64> as M2lScheme<f64>>::estimate(
        &Laplace3d,
        &params,
        &DenseConfig,
        4,
        &usage(3, &USED),
    );
    let all = <DenseM2l<f64> as M2lScheme<f64>>::estimate(
        &Laplace3d,
        &params,
        &DenseConfig,
        4,
        &M2lUsage::all(4),
    );
    assert_eq!((some.matrices, all.matrices), (USED.len(), 316));
    let n = n_surface_points(6) as u64;
    assert!(all.peak_bytes >= 316 * n * n * 8);
    let svd = <SvdM2l<f64> as M2lScheme<f64>>::estimate(
        &Laplace3d,
        &params,
        &SvdConfig::default(),
        4,
        &M2lUsage::all(4),
    );
    assert!(svd.peak_bytes > 0 && svd.seconds > 0.0);
}

/// The FFT scheme holds nothing for a tree without V pairs (one leaf, or
/// a shallow adaptive tree), and per level only for the levels used (a
/// non-homogeneous kernel); the used levels apply as the full operators do.
#[test]
fn fft_holds_no_slab_for_unused_levels() {
    use ferrofmm_field::{FftConfig, FftM2l};
    let params = OperatorParams::new(ORDER);
    let empty =
        FftM2l::<f64>::precompute_for(&Laplace3d, &params, &FftConfig, 1.0, 0, &M2lUsage::none())
            .unwrap();
    assert_eq!(empty.memory_bytes(), 0);
    let kernel = ModifiedHelmholtz3d::new(2.0).unwrap();
    let one_level =
        FftM2l::<f64>::precompute_for(&kernel, &params, &FftConfig, 1.0, 5, &usage(4, &USED))
            .unwrap();
    let mut u = usage(4, &USED);
    u.mark(2, 0);
    let two_levels =
        FftM2l::<f64>::precompute_for(&kernel, &params, &FftConfig, 1.0, 5, &u).unwrap();
    assert!(one_level.memory_bytes() > 0);
    assert_eq!(two_levels.memory_bytes(), 2 * one_level.memory_bytes());
    let full = FftM2l::<f64>::precompute(&kernel, &params, &FftConfig, 1.0, 5).unwrap();
    let vectors = transfer_vectors();
    for &v in &USED {
        assert_eq!(
            apply_one(&one_level, 4, vectors[v]),
            apply_one(&full, 4, vectors[v])
        );
    }
}
