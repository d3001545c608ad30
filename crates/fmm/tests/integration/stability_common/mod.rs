//! Helpers shared by the stability suite (`stability_*.rs`, `concurrency.rs`,
//! `determinism.rs`, `proptest_fmm.rs`).
//!
//! # Tolerances
//!
//! The worst single interaction chain (P2M -> M2M -> M2L -> L2L -> L2P from
//! one box to another, docs/stability.md, operator section) has a relative
//! error of about `5 * 10^-p` in f64 for `p = 6..12` (p = 6: 5.1e-6, p = 8:
//! 4.6e-8, p = 10: 6.7e-10), and f32 bottoms out at about 1e-6 whatever the
//! order. The whole FMM sums many such chains with errors of both signs, so
//! its relative L2 error is at most that (uniform points: 2e-7 at p = 6).
//! [`tol`] allows 10x the single-chain error: a tree or list bug that drops,
//! duplicates or misplaces the contribution of one box pair gives errors of
//! 1e-4 and more, far above it.
//!
//! Where charges of both signs cancel, the relative error is measured
//! against the potential's norm, which can be far smaller than the size of
//! the terms the FMM approximates; [`cancellation`] measures that ratio.
#![allow(dead_code)]

use ferrofmm_fmm::{FmmBuilder, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d, Precision, Real, direct_sum};
use ferrofmm_testing::errors::max_relative_diff;
pub use ferrofmm_testing::errors::norm2;
use ferrofmm_testing::{charges, points};

/// Bound on the relative L2 potential error of an order-`p` FMM in `T`
/// (see the module docs): `50 * 10^-p`, and at least `1e-5` in f32.
pub fn tol<T: Real>(p: usize) -> f64 {
    let f64_bound = 50.0 * 10f64.powi(-(p as i32));
    match T::PRECISION {
        Precision::F64 => f64_bound,
        Precision::F32 => f64_bound.max(1e-5),
    }
}

/// Which M2L scheme to build with. The geometry and input cases use the
/// dense (reference) scheme: it is the cheapest to precompute at p <= 8
/// (0.1-0.5 s against 2-8 s for the SVD scheme's compression), and the
/// scheme is not what they test; the SVD scheme gets its own cases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    Dense,
    Svd,
}

/// Build and evaluate once; `None` targets means targets = sources.
pub fn evaluate<T: Real>(
    sources: &[T],
    targets: Option<&[T]>,
    charges: &[T],
    order: usize,
    leaf_size: usize,
    scheme: Scheme,
) -> Vec<T> {
    let mut b = FmmBuilder::new(sources).order(order).leaf_size(leaf_size);
    if let Some(t) = targets {
        b = b.targets(t);
    }
    match scheme {
        Scheme::Dense => b.build_dense().unwrap().evaluate(charges).unwrap(),
        Scheme::Svd => b.build_svd().unwrap().evaluate(charges).unwrap(),
    }
}

/// Relative L2 potential error of `values` against direct summation at (a
/// sample of at most 1000 of) the targets.
pub fn potential_error<T: Real>(sources: &[T], targets: &[T], charges: &[T], values: &[T]) -> f64 {
    let m = targets.len() / 3;
    relative_errors(
        &Laplace3d,
        EvalMode::Potential,
        sources,
        charges,
        targets,
        values,
        &sample_indices(m, 1000),
    )
    .potential
}

/// Build, evaluate and measure in one go; prints the case for the log.
#[allow(clippy::too_many_arguments)]
pub fn measure<T: Real>(
    case: &str,
    sources: &[T],
    targets: Option<&[T]>,
    charges: &[T],
    order: usize,
    leaf_size: usize,
    scheme: Scheme,
) -> f64 {
    let values = evaluate(sources, targets, charges, order, leaf_size, scheme);
    assert!(
        values.iter().all(|v| v.is_finite()),
        "{case}: non-finite output"
    );
    let e = potential_error(sources, targets.unwrap_or(sources), charges, &values);
    eprintln!(
        "{case}: {} p={order} leaf={leaf_size} {scheme:?}: relative L2 error {e:.2e}",
        T::PRECISION.name()
    );
    e
}

/// Assert that the relative error `e` of an order-`order` FMM in `T` is
/// within [`tol`].
pub fn assert_meets_tol<T: Real>(e: f64, order: usize) {
    let bound = tol::<T>(order);
    assert!(e <= bound, "error {e:.2e} > {bound:.1e}");
}

/// Direct-sum potentials in f64 at all targets.
pub fn direct<T: Real>(sources: &[T], charges: &[T], targets: &[T]) -> Vec<f64> {
    let mut out = vec![0.0; targets.len() / 3];
    direct_sum(
        &Laplace3d,
        EvalMode::Potential,
        &up(sources),
        &up(charges),
        &up(targets),
        &mut out,
    );
    out
}

/// Cancellation ratio `||sum_i |q_i| K(x_i, y_j)||_2 / ||phi||_2` over all
/// targets: 1 for charges of one sign, large when the potential is a small
/// difference of large terms. The FMM's absolute error scales with the
/// numerator, so its relative error can reach `tol * cancellation`.
pub fn cancellation<T: Real>(sources: &[T], charges: &[T], targets: &[T]) -> f64 {
    let abs_q: Vec<T> = charges.iter().map(|q| q.abs()).collect();
    let magnitude = direct(sources, &abs_q, targets);
    let phi = direct(sources, charges, targets);
    norm2(&magnitude) / norm2(&phi)
}

/// Max-norm relative difference of two outputs (see
/// [`ferrofmm_testing::errors::max_relative_diff`]).
pub fn max_rel_diff<T: Real>(a: &[T], b: &[T]) -> f64 {
    max_relative_diff(&up(a), &up(b))
}

/// `n` points uniform in `[lo, lo + width)^3`.
pub fn uniform<T: Real>(n: usize, lo: f64, width: f64, seed: u64) -> Vec<T> {
    down(&points::uniform_cube(n, lo, width, seed))
}

/// `n` charges uniform in `[lo, hi)`.
pub fn charges_in<T: Real>(n: usize, lo: f64, hi: f64, seed: u64) -> Vec<T> {
    down(&charges::uniform_in(n, lo, hi, seed))
}

/// `x` in f64.
pub fn up<T: Real>(x: &[T]) -> Vec<f64> {
    x.iter().map(|v| v.to_f64()).collect()
}

/// `x` rounded to `T`.
pub fn down<T: Real>(x: &[f64]) -> Vec<T> {
    x.iter().map(|&v| T::from_f64(v)).collect()
}
