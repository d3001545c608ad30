//! Stability suite, concurrency: one `Fmm` evaluated from several threads at
//! once gives bitwise the results of serial evaluation, and concurrent
//! builds sharing an operator cache directory all get correct operators.

use crate::stability_common;

use ferrofmm_field::{M2lScheme, SvdM2l};
use ferrofmm_fmm::{Fmm, FmmBuilder, Geometry};
use ferrofmm_kernels::{EvalMode, Laplace3d};
use ferrofmm_testing::TempDir;
use stability_common::{charges_in, potential_error, tol};

const THREADS: usize = 4;

#[test]
fn fmm_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<Fmm<f64, Laplace3d, SvdM2l<f64>>>();
    check::<Fmm<f32, Laplace3d, ferrofmm_field::DenseM2l<f32>>>();
}

#[test]
fn concurrent_evaluations_match_serial_bitwise() {
    // A clustered problem (deep tree, all four lists busy), potentials and
    // gradients; each thread evaluates its own charge vector three times
    // while the others run.
    let n = 3000;
    let pts: Vec<f64> = Geometry::Plummer.points(n, 1);
    let fmm = FmmBuilder::new(&pts)
        .order(5)
        .leaf_size(32)
        .mode(EvalMode::PotentialGradient)
        .build_dense()
        .unwrap();
    let charges: Vec<Vec<f64>> = (0..THREADS as u64)
        .map(|t| charges_in(n, -1.0, 1.0, 10 + t))
        .collect();
    let serial: Vec<Vec<f64>> = charges.iter().map(|q| fmm.evaluate(q).unwrap()).collect();
    let parallel: Vec<Vec<Vec<f64>>> = std::thread::scope(|s| {
        let handles: Vec<_> = charges
            .iter()
            .map(|q| {
                let fmm = &fmm;
                s.spawn(move || (0..3).map(|_| fmm.evaluate(q).unwrap()).collect())
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (t, runs) in parallel.iter().enumerate() {
        for r in runs {
            assert!(
                r == &serial[t],
                "thread {t}: concurrent result differs from serial"
            );
        }
    }
    // And the serial results are right (potential part).
    let phi: Vec<f64> = serial[0].chunks_exact(4).map(|c| c[0]).collect();
    let e = potential_error(&pts, &pts, &charges[0], &phi);
    assert!(e <= 30.0 * tol::<f64>(5), "{e:.2e}"); // mixed signs, see stability_geometry
    // The threads really did differ: different charges, different results.
    assert_ne!(serial[0], serial[1]);
}

#[test]
fn concurrent_builds_share_a_cache_directory() {
    // Four threads build the same problem with the same, initially empty,
    // cache directory: they race to compute and write the same files
    // (written under temporary names and renamed into place). Every build
    // must end with correct operators, whoever won.
    let n = 1000;
    let pts: Vec<f64> = Geometry::Cube.points(n, 2);
    let q: Vec<f64> = charges_in(n, 0.0, 1.0, 3);
    let reference = FmmBuilder::new(&pts)
        .order(4)
        .leaf_size(16)
        .build_svd()
        .unwrap()
        .evaluate(&q)
        .unwrap();
    let dir = TempDir::new("concurrent");
    for round in 0..2 {
        let results: Vec<(Vec<f64>, bool)> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..THREADS)
                .map(|_| {
                    s.spawn(|| {
                        let fmm = FmmBuilder::new(&pts)
                            .order(4)
                            .leaf_size(16)
                            .cache_dir(dir.path())
                            .build_svd()
                            .unwrap();
                        let hit = fmm.operators().cache_status().is_hit()
                            && fmm.m2l_scheme().cache_status().is_hit();
                        (fmm.evaluate(&q).unwrap(), hit)
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for (values, hit) in &results {
            assert!(values == &reference, "round {round}: results differ");
            if round == 1 {
                assert!(hit, "round 1 should load the files of round 0");
            }
        }
    }
    // No temporary files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
