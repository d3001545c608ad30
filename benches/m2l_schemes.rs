//! M2L application per scheme on a realistic level: all 4096 boxes of level
//! 4 of a uniform octree with their full V lists (built here from integer
//! box coordinates), random multipoles. Criterion's throughput is the
//! scheme's own flop count (`M2lScheme::flops`), so `thrpt` reads GFLOP/s.
//!
//! Ids: `m2l/<scheme>/<precision>/p=<order>/level4_4096boxes`.
//!
//! ```text
//! cargo bench --bench m2l_schemes
//! cargo bench --bench m2l_schemes -- 'p=6'
//! ```

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ferrofmm::field::plumbing::conformance::full_level_pairs;
use ferrofmm::field::{
    DenseConfig, DenseM2l, FftConfig, FftM2l, M2lInteractions, M2lScheme, OperatorParams,
    SvdConfig, SvdM2l, n_surface_points,
};
use ferrofmm::kernels::{Laplace3d, Real};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

const LEVEL: u32 = 4;
const SIDE: i32 = 16;

fn bench_scheme<T: Real, S: M2lScheme<T>>(
    c: &mut Criterion,
    order: usize,
    config: S::Config,
    inter: &M2lInteractions,
) {
    let params = OperatorParams::new(order);
    let t0 = Instant::now();
    let scheme = S::precompute(&Laplace3d, &params, &config, 1.0, LEVEL).unwrap();
    let setup = t0.elapsed();
    let n = n_surface_points(order);
    let nb = inter.n_target_cols();
    let mut rng = StdRng::seed_from_u64(7);
    let multipoles: Vec<T> = (0..n * nb)
        .map(|_| T::from_f64(rng.random::<f64>() - 0.5))
        .collect();
    let mut check = vec![T::ZERO; n * nb];
    let flops = scheme.flops(inter);
    // One timed application outside criterion for the summary line.
    let t0 = Instant::now();
    scheme.apply(LEVEL, inter, &multipoles, &mut check);
    let once = t0.elapsed().as_secs_f64();
    println!(
        "m2l/{}/{}/p={order}: n={n}, {} pairs, {:.3e} flop, memory {:.1} MB, precompute {:.2} s, \
         one apply {:.3} s = {:.1} GFLOP/s",
        scheme.name(),
        T::PRECISION.name(),
        inter.len(),
        flops,
        scheme.memory_bytes() as f64 / 1e6,
        setup.as_secs_f64(),
        once,
        flops / once / 1e9
    );
    let mut group = c.benchmark_group("m2l");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
        .throughput(Throughput::Elements(flops as u64));
    let id = BenchmarkId::new(
        format!("{}/{}/p={order}", scheme.name(), T::PRECISION.name()),
        "level4_4096boxes",
    );
    group.bench_function(id, |b| {
        b.iter(|| {
            scheme.apply(
                LEVEL,
                black_box(inter),
                black_box(&multipoles),
                black_box(&mut check),
            )
        })
    });
    group.finish();
}

fn m2l(c: &mut Criterion) {
    let pairs = full_level_pairs(LEVEL);
    let nb = (SIDE * SIDE * SIDE) as usize;
    let inter = M2lInteractions::new(nb, nb, &pairs);
    println!(
        "level {LEVEL}: {nb} boxes, {} V-list pairs ({:.1} per box), {} chunks, {} GEMMs per apply",
        inter.len(),
        inter.len() as f64 / nb as f64,
        inter.n_chunks(),
        inter.n_groups()
    );
    for order in [4, 6, 8, 10] {
        bench_scheme::<f64, DenseM2l<f64>>(c, order, DenseConfig, &inter);
        bench_scheme::<f64, SvdM2l<f64>>(c, order, SvdConfig::default(), &inter);
        bench_scheme::<f64, FftM2l<f64>>(c, order, FftConfig, &inter);
    }
    bench_scheme::<f32, DenseM2l<f32>>(c, 6, DenseConfig, &inter);
    bench_scheme::<f32, SvdM2l<f32>>(c, 6, SvdConfig::default(), &inter);
}

criterion_group!(benches, m2l);
criterion_main!(benches);
