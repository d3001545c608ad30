//! Whole-FMM benchmarks: evaluation (and setup) time of the Laplace FMM on
//! the benchmark everyone quotes — uniform points in the unit cube, charges
//! in [0, 1), potential + gradient — comparing M2L schemes and precisions
//! on the same tree at the same order.
//!
//! `cargo bench --bench fmm` ; ids read
//! `fmm/evaluate/<precision>/<scheme>/p=<order>/cube/n=<N>`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use ferrofmm::field::M2lScheme;
use ferrofmm::fmm::{FmmBuilder, Geometry, charges};
use ferrofmm::kernels::{EvalMode, Real};
use ferrofmm::prelude::{DenseM2l, SvdM2l};

const N: usize = 100_000;

fn bench_case<T: Real, S: M2lScheme<T>>(c: &mut Criterion, order: usize) {
    let points: Vec<T> = Geometry::Cube.points(N, 1);
    let q: Vec<T> = charges(N, 2);
    let builder = FmmBuilder::new(&points)
        .order(order)
        .mode(EvalMode::PotentialGradient);
    let fmm = builder.clone().build_with::<S>(Default::default()).unwrap();
    let id = format!(
        "{}/{}/p={order}/cube/n=1e5",
        T::PRECISION.name(),
        fmm.m2l_scheme().name()
    );
    let mut group = c.benchmark_group("fmm");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    group.bench_function(BenchmarkId::new("evaluate", &id), |b| {
        b.iter(|| black_box(fmm.evaluate(black_box(&q)).unwrap()))
    });
    group.bench_function(BenchmarkId::new("setup", &id), |b| {
        b.iter(|| black_box(builder.clone().build_with::<S>(Default::default()).unwrap()))
    });
    group.finish();
}

fn fmm(c: &mut Criterion) {
    for order in [4, 6, 8] {
        bench_case::<f64, SvdM2l<f64>>(c, order);
    }
    bench_case::<f64, DenseM2l<f64>>(c, 6);
    bench_case::<f32, SvdM2l<f32>>(c, 6);
}

criterion_group!(benches, fmm);
criterion_main!(benches);
