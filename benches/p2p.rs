//! P2P throughput of the Laplace kernel (interactions per second, single
//! thread) for every SIMD level this CPU supports, plus the dense assembly,
//! the modified Helmholtz loop, and every source kind x output of every
//! kernel (`p2p/sources/{laplace,yukawa,helmholtz,stokes}/{charge,dipole,
//! charge+dipole}/{potential,gradient,hessian}/dispatch`, f64, and the same
//! with `f32/` after the kernel's name; the complex
//! Helmholtz kernel at k = 10, the Stokeslet with forces only).
//!
//! Ids: `p2p/laplace/{f64,f32}/{potential,potential+gradient}/{level}/{ns}x{nt}`
//! where `level` is `scalar` (portable code, forced), `avx2` or `avx512`
//! (forced), or `dispatch` (`Laplace3d::evaluate`, i.e. the best level the
//! CPU supports, as the FMM uses it).
//!
//! ```text
//! cargo bench --bench p2p -- --warm-up-time 1 --measurement-time 3
//! ```

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ferrofmm::kernels::{
    EvalMode, Helmholtz3d, Kernel, Laplace3d, ModifiedHelmholtz3d, Real, SimdLevel, SourceKind,
    Stokes3d, laplace_assemble_with, laplace_p2p_with, modified_helmholtz_p2p_with,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// `n` points uniform in the unit cube and `n` charges in `[0, 1)`.
fn points<T: Real>(rng: &mut StdRng, n: usize) -> (Vec<T>, Vec<T>) {
    let p = (0..3 * n)
        .map(|_| T::from_f64(rng.random::<f64>()))
        .collect();
    let q = (0..n).map(|_| T::from_f64(rng.random::<f64>())).collect();
    (p, q)
}

fn bench_laplace<T: Real>(c: &mut Criterion, name: &str) {
    let mut rng = StdRng::seed_from_u64(42);
    let mut group = c.benchmark_group("p2p");
    // In-cache throughput (1024 x 1024) and a realistic leaf-pair size.
    for (ns, nt) in [(1024usize, 1024usize), (256, 256)] {
        let (s, q) = points::<T>(&mut rng, ns);
        let (t, _) = points::<T>(&mut rng, nt);
        group.throughput(Throughput::Elements((ns * nt) as u64));
        for (mode, mode_name) in [
            (EvalMode::Potential, "potential"),
            (EvalMode::PotentialGradient, "potential+gradient"),
        ] {
            let mut out = vec![T::ZERO; mode.values_per_target() * nt];
            // Through the trait, as the FMM calls it (runtime dispatch).
            let id = BenchmarkId::new(
                format!("laplace/{name}/{mode_name}/dispatch"),
                format!("{ns}x{nt}"),
            );
            group.bench_function(id, |b| {
                b.iter(|| {
                    Laplace3d.evaluate(
                        mode,
                        black_box(&s),
                        black_box(&q),
                        black_box(&t),
                        black_box(&mut out),
                    )
                })
            });
            for level in SimdLevel::supported() {
                let id = BenchmarkId::new(
                    format!("laplace/{name}/{mode_name}/{level}"),
                    format!("{ns}x{nt}"),
                );
                group.bench_function(id, |b| {
                    b.iter(|| {
                        laplace_p2p_with(
                            level,
                            mode,
                            black_box(&s),
                            black_box(&q),
                            black_box(&t),
                            black_box(&mut out),
                        )
                    })
                });
            }
        }
    }
    group.finish();
}

fn bench_assemble(c: &mut Criterion) {
    let mut rng = StdRng::seed_from_u64(7);
    let n = 1024;
    let (s, _) = points::<f64>(&mut rng, n);
    let (t, _) = points::<f64>(&mut rng, n);
    let mut m = vec![0.0f64; n * n];
    let mut group = c.benchmark_group("p2p");
    group.throughput(Throughput::Elements((n * n) as u64));
    for level in SimdLevel::supported() {
        let id = BenchmarkId::new(format!("laplace/f64/assemble/{level}"), format!("{n}x{n}"));
        // Assembly of large matrices is row-parallel: run it on one thread
        // so the figure is per core like the others.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        group.bench_function(id, |b| {
            pool.install(|| {
                b.iter(|| {
                    laplace_assemble_with(level, black_box(&s), black_box(&t), black_box(&mut m))
                })
            })
        });
    }
    group.finish();
}

fn bench_yukawa(c: &mut Criterion) {
    let mut rng = StdRng::seed_from_u64(9);
    let n = 1024;
    let (s, q) = points::<f64>(&mut rng, n);
    let (t, _) = points::<f64>(&mut rng, n);
    let kernel = ModifiedHelmholtz3d::new(1.0).unwrap();
    let mut group = c.benchmark_group("p2p");
    group.throughput(Throughput::Elements((n * n) as u64));
    for (mode, mode_name) in [
        (EvalMode::Potential, "potential"),
        (EvalMode::PotentialGradient, "potential+gradient"),
    ] {
        let mut out = vec![0.0f64; mode.values_per_target() * n];
        for level in SimdLevel::supported() {
            let id = BenchmarkId::new(
                format!("modified_helmholtz/f64/{mode_name}/{level}"),
                format!("{n}x{n}"),
            );
            group.bench_function(id, |b| {
                b.iter(|| {
                    modified_helmholtz_p2p_with(
                        level,
                        kernel.k,
                        mode,
                        black_box(&s),
                        black_box(&q),
                        black_box(&t),
                        black_box(&mut out),
                    )
                })
            });
        }
    }
    group.finish();
}

/// Every source kind x output the kernel supports through
/// `Kernel::evaluate_sources`, as the FMM calls it (best level of the CPU),
/// 1024 x 1024 (complex and vector kernels: pairs, not components); `prec`
/// is `""` for f64 (the ids of old) and `"f32/"` for f32.
fn bench_sources<K: Kernel, T: Real>(c: &mut Criterion, kernel: &K, name: &str, prec: &str) {
    let mut rng = StdRng::seed_from_u64(11);
    let n = 1024;
    let (s, _) = points::<T>(&mut rng, n);
    let (t, _) = points::<T>(&mut rng, n);
    let mut group = c.benchmark_group("p2p");
    group.throughput(Throughput::Elements((n * n) as u64));
    for kind in [
        SourceKind::Charge,
        SourceKind::Dipole,
        SourceKind::ChargeDipole,
    ] {
        let per_source = kernel.values_per_source(kind);
        let (d, _) = points::<T>(&mut rng, n * per_source);
        let d = &d[..n * per_source];
        for mode in [
            EvalMode::Potential,
            EvalMode::PotentialGradient,
            EvalMode::PotentialGradientHessian,
        ] {
            if !kernel.supports(kind, mode) {
                continue;
            }
            let mut out = vec![T::ZERO; kernel.values_per_target(mode) * n];
            let id = BenchmarkId::new(
                format!(
                    "sources/{name}/{prec}{}/{}/dispatch",
                    kind.name(),
                    mode.name()
                ),
                format!("{n}x{n}"),
            );
            group.bench_function(id, |b| {
                b.iter(|| {
                    kernel.evaluate_sources(
                        kind,
                        mode,
                        black_box(&s),
                        black_box(d),
                        black_box(&t),
                        black_box(&mut out),
                    )
                })
            });
        }
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_laplace::<f64>(c, "f64");
    bench_laplace::<f32>(c, "f32");
    bench_assemble(c);
    bench_yukawa(c);
    let yukawa = ModifiedHelmholtz3d::new(1.0).unwrap();
    let helmholtz = Helmholtz3d::new(10.0).unwrap();
    let stokes = Stokes3d::default();
    bench_sources::<_, f64>(c, &Laplace3d, "laplace", "");
    bench_sources::<_, f64>(c, &yukawa, "yukawa", "");
    bench_sources::<_, f64>(c, &helmholtz, "helmholtz", "");
    bench_sources::<_, f64>(c, &stokes, "stokes", "");
    bench_sources::<_, f32>(c, &Laplace3d, "laplace", "f32/");
    bench_sources::<_, f32>(c, &yukawa, "yukawa", "f32/");
    bench_sources::<_, f32>(c, &helmholtz, "helmholtz", "f32/");
    bench_sources::<_, f32>(c, &stokes, "stokes", "f32/");
}

criterion_group!(p2p, benches);
criterion_main!(p2p);
