//! Tree construction: sort + refine + 2:1 balance + U/V/W/X lists, for
//! uniform points in the unit cube and on the unit sphere surface, leaf size
//! 150, N = 1e5 and 1e6.
//!
//! Ids: `tree/build+balance+lists/{uniform_cube,sphere_surface}/n={1e5,1e6}`.
//!
//! ```text
//! cargo bench --bench tree -j 2
//! ```

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ferrofmm::tree::{Octree, TreeOptions};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, UnitSphere};

fn uniform_cube(n: usize, rng: &mut StdRng) -> Vec<f64> {
    (0..3 * n).map(|_| rng.random::<f64>()).collect()
}

fn sphere_surface(n: usize, rng: &mut StdRng) -> Vec<f64> {
    (0..n)
        .flat_map(|_| {
            let p: [f64; 3] = UnitSphere.sample(rng);
            p
        })
        .collect()
}

fn bench_tree(c: &mut Criterion) {
    let mut rng = StdRng::seed_from_u64(42);
    let options = TreeOptions::adaptive(150);
    let mut group = c.benchmark_group("tree");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    type Generator = fn(usize, &mut StdRng) -> Vec<f64>;
    let shapes: [(&str, Generator); 2] = [
        ("uniform_cube", uniform_cube),
        ("sphere_surface", sphere_surface),
    ];
    for (shape, generate) in shapes {
        for (label, n) in [("1e5", 100_000usize), ("1e6", 1_000_000)] {
            let points = generate(n, &mut rng);
            group.throughput(Throughput::Elements(n as u64));
            group.bench_with_input(
                BenchmarkId::new(format!("build+balance+lists/{shape}"), format!("n={label}")),
                &points,
                |b, points| {
                    b.iter(|| Octree::new(black_box(points), None, black_box(&options)).unwrap())
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench_tree);
criterion_main!(benches);
