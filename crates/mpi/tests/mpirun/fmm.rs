//! The distributed FMM against the single-machine FMM.

use crate::common::*;

/// The distributed FMM equals the single-machine FMM on the same tree and
/// operators (relative L2 difference <= 1e-12 of potentials and
/// gradients), for four geometries, inputs spread evenly or with the first
/// rank empty; Laplace and modified Helmholtz with the SVD, dense and FFT
/// M2L schemes spread over the rank counts (the SVD precomputation is the
/// slow part of a debug build); two charge vectors on one build (input
/// order) and one in tree order; bad charges on one rank are the same
/// error everywhere. Both FMMs load their operators from the tests'
/// cache (computed by rank 0 of the first case; the empty-rank test below
/// computes them on every rank).
#[test]
fn distributed_fmm_equals_the_single_machine_fmm_on_1_to_4_ranks() {
    let methods = [
        "laplace-svd,laplace-fft",
        "laplace-dense,helmholtz-svd",
        "laplace-svd,helmholtz-fft",
        "laplace-fft,laplace-dense,helmholtz-svd",
    ];
    let cache = test_cache().to_string_lossy().into_owned();
    for (ranks, method) in (1..=4).zip(methods) {
        let args = [
            "fmm-check",
            "--n",
            "1500",
            "--order",
            "3",
            "--method",
            method,
            "--cache-dir",
            &cache,
        ];
        let (ok, out) = mpirun(ranks, &args);
        assert!(
            ok && out.contains("FMM CHECK PASSED"),
            "R = {ranks}:\n{out}"
        );
    }
}

/// Ranks that hold no point of the tree (fewer points than ranks), and a
/// tree that is one leaf.
#[test]
fn distributed_fmm_with_empty_ranks_and_a_single_leaf() {
    for ranks in [2, 4] {
        for n in ["3", "30"] {
            let (ok, out) = mpirun(
                ranks,
                &[
                    "fmm-check",
                    "--n",
                    n,
                    "--geometry",
                    "uniform,two-clusters",
                    "--method",
                    "laplace-svd,helmholtz-fft",
                ],
            );
            assert!(
                ok && out.contains("FMM CHECK PASSED"),
                "R = {ranks}, n = {n}:\n{out}"
            );
        }
    }
}

/// Kernels with several components (complex Helmholtz, Stokes) and dipole
/// sources: the distributed FMM equals the single-machine FMM (1e-12) on
/// 2 to 4 ranks, with the SVD and FFT schemes (operators from the tests'
/// cache).
#[test]
fn distributed_fmm_with_vector_kernels_and_dipoles() {
    let methods = [
        (2, "oscillatory-svd,stokes-fft,dipoles-svd"),
        (3, "oscillatory-fft,stokes-svd"),
        (4, "stokes-fft,dipoles-svd,oscillatory-fft"),
    ];
    let cache = test_cache().to_string_lossy().into_owned();
    for (ranks, method) in methods {
        let args = [
            "fmm-check",
            "--n",
            "1200",
            "--order",
            "3",
            "--geometry",
            "plummer,two-clusters",
            "--method",
            method,
            "--cache-dir",
            &cache,
        ];
        let (ok, out) = mpirun(ranks, &args);
        assert!(
            ok && out.contains("FMM CHECK PASSED"),
            "R = {ranks}:\n{out}"
        );
    }
}
