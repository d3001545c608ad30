//! The M2L schemes on a whole level: dense against a per-pair reference,
//! SVD against dense, chunking independence.

use crate::common;

use common::*;
use ferrofmm_field::{
    DenseConfig, DenseM2l, M2lInteractions, M2lScheme, OperatorParams, Operators, SvdConfig,
    SvdM2l, default_svd_tolerance,
};
use ferrofmm_kernels::{Kernel, Laplace3d, ModifiedHelmholtz3d, Real};

const LEVEL: u32 = 3;
const SIDE: i32 = 8;

/// Multipoles (P2M of 20 random sources) of every box of a uniform level-3
/// grid.
fn grid_multipoles<T: Real, K: Kernel>(kernel: &K, ops: &Operators<T>) -> Vec<T> {
    let mut rng = SplitMix64(11);
    let h = ops.half_width(LEVEL);
    let mut all = Vec::new();
    for x in 0..SIDE {
        for y in 0..SIDE {
            for z in 0..SIDE {
                let c = box_center(LEVEL, [x, y, z]);
                let src = in_box(&mut rng, 20, c, h);
                let q = positive_from(&mut rng, 20);
                all.extend(p2m(kernel, ops, LEVEL, c, &src, &q));
            }
        }
    }
    all
}

/// Reference: one kernel evaluation per pair, in f64.
fn reference<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    pairs: &[(usize, usize, [i32; 3])],
    m: &[T],
) -> Vec<f64> {
    let n = ops.n_surface();
    let side = SIDE as usize;
    let center = |i: usize| {
        box_center(
            LEVEL,
            [
                (i / (side * side)) as i32,
                ((i / side) % side) as i32,
                (i % side) as i32,
            ],
        )
    };
    let mut out = vec![0.0; n * side * side * side];
    let h = ops.half_width(LEVEL);
    for &(t, s, v) in pairs {
        let (ct, cs) = (center(t), center(s));
        for d in 0..3 {
            assert!((cs[d] - ct[d] - 2.0 * h * v[d] as f64).abs() < 1e-12);
        }
        let ue: Vec<f64> =
            ferrofmm_field::surface_points(ops.order(), cs, h, ops.radii().upward_equivalent);
        let dc: Vec<f64> =
            ferrofmm_field::surface_points(ops.order(), ct, h, ops.radii().downward_check);
        let phi = to_f64(&m[s * n..(s + 1) * n]);
        ferrofmm_kernels::reference::evaluate_pairwise(
            kernel,
            ferrofmm_kernels::EvalMode::Potential,
            &ue,
            &phi,
            &dc,
            &mut out[t * n..(t + 1) * n],
        );
    }
    out
}

fn dense_matches_reference<T: Real, K: Kernel>(kernel: &K, p: usize, tol: f64) {
    let params = OperatorParams::new(p);
    let ops = Operators::<T>::new(kernel, &params, 1.0, LEVEL).unwrap();
    let n = ops.n_surface();
    let m = grid_multipoles(kernel, &ops);
    let pairs = uniform_v_lists(SIDE);
    let dense = DenseM2l::<T>::precompute(kernel, &params, &DenseConfig, 1.0, LEVEL).unwrap();
    assert_eq!(dense.name(), "dense");
    let sets = if kernel.homogeneity().is_some() {
        1
    } else {
        LEVEL as usize - 1
    };
    assert_eq!(
        dense.memory_bytes(),
        sets * 316 * n * n * std::mem::size_of::<T>()
    );
    let want = reference(kernel, &ops, &pairs, &m);
    let nb = (SIDE * SIDE * SIDE) as usize;
    for chunk in [1, 7, 64, 1000] {
        let inter = M2lInteractions::with_chunk_size(nb, nb, &pairs, chunk).unwrap();
        let mut got = vec![T::ONE; n * nb]; // accumulates onto existing values
        dense.apply(LEVEL, &inter, &m, &mut got);
        let got: Vec<f64> = got.iter().map(|x| x.to_f64() - 1.0).collect();
        let e = relative_l2(&got, &want);
        assert!(
            e < tol,
            "{} {} chunk {chunk}: {e:.2e}",
            kernel.name(),
            T::PRECISION.name()
        );
    }
}

#[test]
fn dense_matches_per_pair_reference() {
    dense_matches_reference::<f64, _>(&Laplace3d, 4, 1e-13);
    dense_matches_reference::<f32, _>(&Laplace3d, 4, 1e-5);
    dense_matches_reference::<f64, _>(&ModifiedHelmholtz3d::new(3.0).unwrap(), 4, 1e-13);
}

fn svd_vs_dense<T: Real, K: Kernel>(kernel: &K, p: usize, config: SvdConfig) -> (f64, usize, f64) {
    let params = OperatorParams::new(p);
    let ops = Operators::<T>::new(kernel, &params, 1.0, LEVEL).unwrap();
    let n = ops.n_surface();
    let m = grid_multipoles(kernel, &ops);
    let pairs = uniform_v_lists(SIDE);
    let nb = (SIDE * SIDE * SIDE) as usize;
    let inter = M2lInteractions::new(nb, nb, &pairs);
    let dense = DenseM2l::<T>::precompute(kernel, &params, &DenseConfig, 1.0, LEVEL).unwrap();
    let svd = SvdM2l::<T>::precompute(kernel, &params, &config, 1.0, LEVEL).unwrap();
    assert_eq!(svd.name(), "svd");
    let mut want = vec![T::ZERO; n * nb];
    dense.apply(LEVEL, &inter, &m, &mut want);
    let mut got = vec![T::ZERO; n * nb];
    svd.apply(LEVEL, &inter, &m, &mut got);
    let e = relative_l2(&to_f64(&got), &to_f64(&want));
    println!(
        "{} {} p={p} {config:?}: rank {}/{n}, tolerance {:.1e}, estimate {:.1e}, |svd - dense| / |dense| = {e:.2e}, \
         flops svd/dense = {:.2}",
        kernel.name(),
        T::PRECISION.name(),
        svd.rank(),
        svd.tolerance(),
        svd.truncation_estimate(),
        svd.flops(&inter) / dense.flops(&inter)
    );
    (e, svd.rank(), svd.tolerance())
}

#[test]
fn svd_matches_dense_to_its_tolerance() {
    for p in [4, 6] {
        for tol in [1e-3, 1e-5, 0.0] {
            let (e, k, t) = svd_vs_dense::<f64, _>(
                &Laplace3d,
                p,
                SvdConfig {
                    rank: None,
                    tolerance: tol,
                },
            );
            assert!(
                e <= t,
                "p={p}: error {e:.2e} above tolerance {t:.1e} (rank {k})"
            );
            if tol == 0.0 {
                assert_eq!(
                    t,
                    default_svd_tolerance(ferrofmm_kernels::Precision::F64, p)
                );
            }
        }
    }
    // Full rank reproduces dense to rounding.
    let (e, k, _) = svd_vs_dense::<f64, _>(
        &Laplace3d,
        4,
        SvdConfig {
            rank: Some(1000),
            tolerance: 0.0,
        },
    );
    assert_eq!(k, 56);
    assert!(e < 1e-13, "{e:.2e}");
    // A fixed small rank is honoured and is worse.
    let (e, k, _) = svd_vs_dense::<f64, _>(
        &Laplace3d,
        4,
        SvdConfig {
            rank: Some(10),
            tolerance: 0.0,
        },
    );
    assert_eq!(k, 10);
    assert!(e > 1e-4);
    // f32 and a non-homogeneous kernel (per-level bases).
    let (e, _, t) = svd_vs_dense::<f32, _>(&Laplace3d, 5, SvdConfig::default());
    assert!(e <= t.max(1e-5), "{e:.2e}");
    let (e, _, t) = svd_vs_dense::<f64, _>(
        &ModifiedHelmholtz3d::new(3.0).unwrap(),
        5,
        SvdConfig::default(),
    );
    assert!(e <= t, "{e:.2e}");
}

#[test]
fn empty_and_bad_configs() {
    let params = OperatorParams::new(3);
    let dense = DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, 1.0, 3).unwrap();
    let inter = M2lInteractions::new(2, 2, &[]);
    let n = 26;
    let mut check = vec![1.0; 2 * n];
    dense.apply(3, &inter, &vec![5.0; 2 * n], &mut check);
    assert!(check.iter().all(|&x| x == 1.0));
    assert!(
        SvdM2l::<f64>::precompute(
            &Laplace3d,
            &params,
            &SvdConfig {
                rank: Some(0),
                tolerance: 0.0
            },
            1.0,
            3
        )
        .is_err()
    );
    assert!(
        SvdM2l::<f64>::precompute(
            &Laplace3d,
            &params,
            &SvdConfig {
                rank: None,
                tolerance: f64::NAN
            },
            1.0,
            3
        )
        .is_err()
    );
    assert!(
        DenseM2l::<f64>::precompute(&Laplace3d, &OperatorParams::new(1), &DenseConfig, 1.0, 3)
            .is_err()
    );
    assert!(DenseM2l::<f64>::precompute(&Laplace3d, &params, &DenseConfig, -1.0, 3).is_err());
}

#[test]
#[should_panic(expected = "has no operators")]
fn non_homogeneous_level_out_of_range_panics() {
    let params = OperatorParams::new(3);
    let k = ModifiedHelmholtz3d::new(1.0).unwrap();
    let dense = DenseM2l::<f64>::precompute(&k, &params, &DenseConfig, 1.0, 3).unwrap();
    let inter = M2lInteractions::new(1, 1, &[(0, 0, [2, 0, 0])]);
    let mut check = vec![0.0; 26];
    dense.apply(4, &inter, &[0.0; 26], &mut check);
}

#[test]
fn svd_factors_each_transfer_vector_at_its_own_rank() {
    let params = OperatorParams::new(6);
    let tol =
        SvdM2l::<f64>::precompute(&Laplace3d, &params, &SvdConfig::default(), 1.0, LEVEL).unwrap();
    // Per-vector ranks are well below k (measured mean 18 of 94), so the
    // factored C_v = A_v B_v^T (4 k r_v flops per pair) beats k^2.
    let (k, r) = (tol.rank(), tol.mean_vector_rank());
    assert!(r < k as f64 / 3.0, "mean vector rank {r:.1} of k = {k}");
    // A fixed rank keeps every C_v whole.
    let fixed = SvdM2l::<f64>::precompute(
        &Laplace3d,
        &params,
        &SvdConfig {
            rank: Some(k),
            tolerance: 0.0,
        },
        1.0,
        LEVEL,
    )
    .unwrap();
    assert_eq!(fixed.mean_vector_rank(), k as f64);
    let pairs = uniform_v_lists(SIDE);
    let nb = (SIDE * SIDE * SIDE) as usize;
    let inter = M2lInteractions::new(nb, nb, &pairs);
    assert!(tol.flops(&inter) < 0.6 * fixed.flops(&inter));
    assert!(tol.memory_bytes() < fixed.memory_bytes());
}

/// The FFT scheme applies a level in runs whose source spectra fit its
/// budget: any budget gives the same check potentials, bit for bit, and
/// they agree with the dense scheme (the same operator).
#[test]
fn fft_results_do_not_depend_on_the_spectra_budget() {
    use ferrofmm_field::{FftConfig, FftM2l, SPECTRA_BUDGET_BYTES};
    use ferrofmm_kernels::Helmholtz3d;
    fn run<K: Kernel>(kernel: &K, p: usize) {
        let params = OperatorParams::new(p);
        let len = kernel.components() * ferrofmm_field::n_surface_points(p);
        let nb = (SIDE * SIDE * SIDE) as usize;
        let m: Vec<f64> = {
            let mut rng = SplitMix64(5);
            (0..len * nb).map(|_| rng.uniform() - 0.5).collect()
        };
        // Columns in Morton order, so that siblings share a group.
        let morton = |i: usize| {
            let side = SIDE as usize;
            let p = [i / (side * side), (i / side) % side, i % side];
            (0..3)
                .flat_map(|bit| (0..3).map(move |d| (bit, d)))
                .fold(0, |k, (bit, d)| k | ((p[d] >> bit) & 1) << (3 * bit + d))
        };
        let pairs: Vec<_> = uniform_v_lists(SIDE)
            .into_iter()
            .map(|(t, s, v)| (morton(t), morton(s), v))
            .collect();
        let mut mm = vec![0.0; m.len()];
        for i in 0..nb {
            mm[morton(i) * len..(morton(i) + 1) * len].copy_from_slice(&m[i * len..(i + 1) * len]);
        }
        let inter = M2lInteractions::new(nb, nb, &pairs);
        let mut fft = FftM2l::<f64>::precompute(kernel, &params, &FftConfig, 1.0, LEVEL).unwrap();
        let mut whole = vec![0.0; len * nb];
        fft.apply(LEVEL, &inter, &mm, &mut whole);
        let level_bytes = fft.apply_scratch_bytes(&inter);
        assert!(level_bytes > 0 && level_bytes < SPECTRA_BUDGET_BYTES);
        for budget in [1, 100_000, 2_000_000] {
            fft.set_spectra_budget(budget);
            assert!(fft.apply_scratch_bytes(&inter) <= budget.max(level_bytes));
            let mut runs = vec![0.0; len * nb];
            fft.apply(LEVEL, &inter, &mm, &mut runs);
            assert_eq!(runs, whole, "{} budget {budget}", kernel.name());
        }
        let dense = DenseM2l::<f64>::precompute(kernel, &params, &DenseConfig, 1.0, LEVEL).unwrap();
        let mut want = vec![0.0; len * nb];
        dense.apply(LEVEL, &inter, &mm, &mut want);
        let e = relative_l2(&whole, &want);
        assert!(e < 1e-12, "{}: fft vs dense {e:.2e}", kernel.name());
    }
    run(&Laplace3d, 4);
    run(&Helmholtz3d::new(2.0).unwrap(), 3);
}
