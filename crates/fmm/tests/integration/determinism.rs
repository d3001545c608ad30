//! Stability suite, determinism: with a fixed number of threads the same
//! input gives bitwise the same output, build after build and evaluation
//! after evaluation; across 1, 2 and 3 threads the results agree to 1e-12
//! (max-norm, relative to the largest |value|).
//!
//! Why this holds: the tree sort breaks ties between equal keys by the
//! caller's index; every parallel pass writes disjoint outputs (per leaf,
//! per column block) or sums block products in a fixed order, so an
//! evaluation is bitwise independent of the thread count. Two things in the
//! *build* depend on it, both only in rounding (measured: 1e-15 relative in
//! f64): faer's SVDs of the operator precomputation run with faer's global
//! parallelism (blocking by thread count), and `M2lInteractions` sizes its
//! target chunks by `rayon::current_num_threads()`, which changes the shapes
//! of the M2L matrix products. With `faer::set_global_parallelism(Par::Seq)`
//! and a fixed chunk size (`M2lInteractions::with_chunk_size`) the results
//! are bitwise identical across thread counts too.

use crate::stability_common;

use ferrofmm_fmm::{FmmBuilder, Geometry};
use ferrofmm_kernels::{EvalMode, Real};
use stability_common::{Scheme, charges_in, max_rel_diff, uniform};

/// Build and evaluate twice inside a pool of `threads` threads; the two
/// builds (and two evaluations of the first) must agree bitwise.
fn run_in_pool<T: Real>(threads: usize, points: &[T], q: &[T], scheme: Scheme) -> Vec<T> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let build = || {
            let b = FmmBuilder::new(points)
                .order(4)
                .leaf_size(8)
                .mode(EvalMode::PotentialGradient);
            match scheme {
                Scheme::Dense => b.build_dense().unwrap().evaluate(q).unwrap(),
                Scheme::Svd => {
                    let fmm = b.build_svd().unwrap();
                    let first = fmm.evaluate(q).unwrap();
                    assert!(
                        first == fmm.evaluate(q).unwrap(),
                        "{threads} threads: two evaluations differ"
                    );
                    first
                }
            }
        };
        let a = build();
        let b = build();
        assert!(a == b, "{threads} threads: two builds differ");
        a
    })
}

fn check<T: Real>(name: &str, points: &[T], q: &[T], scheme: Scheme) {
    let results: Vec<Vec<T>> = [1, 2, 3]
        .iter()
        .map(|&t| run_in_pool(t, points, q, scheme))
        .collect();
    for (k, r) in results.iter().enumerate().skip(1) {
        let d = max_rel_diff(r, &results[0]);
        eprintln!(
            "{name} {scheme:?} {}: {} threads vs 1: max relative difference {d:.1e}{}",
            T::PRECISION.name(),
            k + 1,
            if r == &results[0] {
                " (bitwise equal)"
            } else {
                ""
            }
        );
        let bound = match T::PRECISION {
            ferrofmm_kernels::Precision::F64 => 1e-12,
            // The same sums, rounded in f32: a few units of f32 rounding.
            ferrofmm_kernels::Precision::F32 => 1e-5,
        };
        assert!(d <= bound, "{name}: {} threads vs 1: {d:.2e}", k + 1);
    }
}

#[test]
fn same_input_same_output_across_runs_and_thread_counts() {
    // Clustered points with duplicates (ties in the Morton sort), mixed
    // charges, potentials and gradients.
    let n = 1500;
    let mut pts: Vec<f64> = Geometry::Plummer.points(n - 300, 1);
    let dup: Vec<f64> = pts[..900].to_vec();
    pts.extend(dup);
    let q: Vec<f64> = charges_in(n, -1.0, 1.0, 2);
    check("plummer + duplicates", &pts, &q, Scheme::Svd);
    check("plummer + duplicates", &pts, &q, Scheme::Dense);
    let pts32: Vec<f32> = pts.iter().map(|&x| x as f32).collect();
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    check("plummer + duplicates", &pts32, &q32, Scheme::Dense);
    let cube: Vec<f64> = uniform(n, 0.0, 1.0, 3);
    check("cube", &cube, &q, Scheme::Svd);
}
