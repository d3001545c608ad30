//! Operator precomputation time (Laplace, f64) per order: the non-M2L
//! operators (`Operators`: two pseudo-inverses and 16 child operators), the
//! dense M2L (316 kernel matrices) and the SVD M2L (two TSQR + SVD of the
//! stacked operators, 316 projections), each computed and loaded from a
//! warm on-disk cache.
//!
//! Ids: `precompute/<what>/p=<order>` with `what` in `operators`,
//! `dense`, `svd`, and `*-cache-hit`.
//!
//! ```text
//! cargo bench --bench precompute
//! ```

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use ferrofmm::field::{
    DenseConfig, DenseM2l, M2lScheme, OperatorParams, Operators, SvdConfig, SvdM2l,
};
use ferrofmm::kernels::Laplace3d;

const DEPTH: u32 = 5;

fn bench_order(c: &mut Criterion, order: usize, cache: &Path) {
    let plain = OperatorParams::new(order);
    let mut cached = plain.clone();
    cached.cache_dir = Some(cache.to_path_buf());
    let mut group = c.benchmark_group("precompute");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(if order >= 10 { 20 } else { 5 }));
    let p = format!("p={order}");
    group.bench_function(BenchmarkId::new("operators", &p), |b| {
        b.iter(|| black_box(Operators::<f64>::new(&Laplace3d, &plain, 1.0, DEPTH).unwrap()))
    });
    group.bench_function(BenchmarkId::new("dense", &p), |b| {
        b.iter(|| {
            black_box(
                DenseM2l::<f64>::precompute(&Laplace3d, &plain, &DenseConfig, 1.0, DEPTH).unwrap(),
            )
        })
    });
    group.bench_function(BenchmarkId::new("svd", &p), |b| {
        b.iter(|| {
            black_box(
                SvdM2l::<f64>::precompute(&Laplace3d, &plain, &SvdConfig::default(), 1.0, DEPTH)
                    .unwrap(),
            )
        })
    });
    // Warm the cache, then time loading.
    Operators::<f64>::new(&Laplace3d, &cached, 1.0, DEPTH).unwrap();
    DenseM2l::<f64>::precompute(&Laplace3d, &cached, &DenseConfig, 1.0, DEPTH).unwrap();
    SvdM2l::<f64>::precompute(&Laplace3d, &cached, &SvdConfig::default(), 1.0, DEPTH).unwrap();
    group.bench_function(BenchmarkId::new("operators-cache-hit", &p), |b| {
        b.iter(|| {
            let o = Operators::<f64>::new(&Laplace3d, &cached, 1.0, DEPTH).unwrap();
            assert!(o.cache_status().is_hit());
            black_box(o)
        })
    });
    group.bench_function(BenchmarkId::new("dense-cache-hit", &p), |b| {
        b.iter(|| {
            let s =
                DenseM2l::<f64>::precompute(&Laplace3d, &cached, &DenseConfig, 1.0, DEPTH).unwrap();
            assert!(s.cache_status().is_hit());
            black_box(s)
        })
    });
    group.bench_function(BenchmarkId::new("svd-cache-hit", &p), |b| {
        b.iter(|| {
            let s =
                SvdM2l::<f64>::precompute(&Laplace3d, &cached, &SvdConfig::default(), 1.0, DEPTH)
                    .unwrap();
            assert!(s.cache_status().is_hit());
            black_box(s)
        })
    });
    group.finish();
}

fn precompute(c: &mut Criterion) {
    let cache = std::env::temp_dir().join(format!("ferrofmm-bench-cache-{}", std::process::id()));
    for order in [4, 6, 8, 10] {
        bench_order(c, order, &cache);
    }
    let _ = std::fs::remove_dir_all(&cache);
}

criterion_group!(benches, precompute);
criterion_main!(benches);
