//! Issue 31, item 3, "no more than the scene needs": with
//! `FmmBuilder::tolerance(eps)` and the verification on, the delivered
//! error (the larger of the potential's and the gradient's relative L2
//! error, measured here against direct summation at every target,
//! independently of the verification's own sample) is
//!
//! * at most `eps` on every geometry of the tolerance suite
//!   (`Geometry::ALL`), for zero-mean and all-positive charges: the
//!   verification raises the order where the first choice misses;
//! * at least `eps / 10` on the median geometry for zero-mean charges, at
//!   each `eps` (measured 0.12 eps at 1e-3 and 1e-5, 0.13 at 1e-7), and at
//!   least `eps / 30` for all-positive charges (measured 0.05-0.07 eps: the
//!   chooser does not know the charges, see the test's comment): the
//!   chooser does not deliver 10x more accuracy than asked on the typical
//!   input. (Not on every input: orders step by 6-14x
//!   and a curve's errors are 100-1000x below a volume's at the same order,
//!   so single inputs land anywhere between `eps / 14` and `eps`, or below
//!   at the lowest order.)
//!
//! N = 1e4 points, gradients on, the SVD scheme, two tolerances (1e-7
//! passed too, but its order-9 operators take a minute to compute cold).

use ferrofmm_fmm::{Charges, FmmBuilder, Geometry, relative_errors};
use ferrofmm_kernels::{EvalMode, Laplace3d};

const N: usize = 10_000;

fn cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("right-sized-operators")
}

/// Delivered error of one (geometry, charges, eps), the order of the first
/// attempt and the number of attempts.
fn delivered(g: Geometry, kind: Charges, eps: f64) -> (f64, usize, usize) {
    let mode = EvalMode::PotentialGradient;
    let points: Vec<f64> = g.points(N, 7);
    let q: Vec<f64> = kind.generate(N, 11);
    let mut fmm = FmmBuilder::new(&points)
        .tolerance(eps)
        .mode(mode)
        .cache_dir(cache())
        .build_svd()
        .unwrap();
    let out = fmm.evaluate_verified(&q).unwrap();
    let v = out.verification.expect("verification is on by default");
    // Every target: the relative L2 error of the gradient on a sample
    // depends on whether the sample holds the few targets with a close
    // neighbour that dominate the gradient's norm (on 997 of these 1e4
    // points up to 9x above the error over all of them).
    let all: Vec<usize> = (0..N).collect();
    let e = relative_errors(&Laplace3d, mode, &points, &q, &points, &out.values, &all);
    let worst = e.potential.max(e.gradient.unwrap());
    let orders: Vec<usize> = v.attempts.iter().map(|a| a.order).collect();
    eprintln!(
        "{:13} {:8} eps {eps:.0e}: delivered {worst:.2e} ({:.2} eps), orders {orders:?}, estimates {:?}",
        g.name(),
        kind.name(),
        worst / eps,
        v.attempts
            .iter()
            .map(|a| format!("{:.2e}/{}", a.measured.worst(), a.measured.n_sampled))
            .collect::<Vec<_>>()
    );
    assert!(
        v.met,
        "{g:?} {kind:?} {eps:e}: not met after retries: {v:?}"
    );
    assert!(
        worst <= eps,
        "{g:?} {kind:?}: {eps:e} not met: {e:?} (verification {v:?})"
    );
    (worst, orders[0], v.attempts.len())
}

#[test]
fn delivered_error_is_between_a_tenth_of_eps_and_eps_on_the_median_geometry() {
    // (charges, eps, median delivered / eps)
    let mut medians = Vec::new();
    for eps in [1e-3, 1e-5] {
        for kind in Charges::ALL {
            let mut errors: Vec<f64> = Geometry::ALL
                .iter()
                .map(|&g| delivered(g, kind, eps).0)
                .collect();
            errors.sort_by(f64::total_cmp);
            let median = errors[errors.len() / 2];
            eprintln!(
                "{kind:?} eps {eps:.0e}: median {median:.2e} ({:.2} eps)",
                median / eps
            );
            medians.push((kind, eps, median / eps));
        }
    }
    // Zero-mean charges (the model's tables): at every eps.
    for &(kind, eps, m) in &medians {
        if kind == Charges::Signed {
            assert!(
                m >= 0.1,
                "{kind:?} {eps:e}: median at {m:.3} eps ({medians:?})"
            );
        }
    }
    // All-positive charges: the median geometry is a surface, whose
    // potential error with all-positive charges is 2-4x below zero-mean
    // charges' at the same order, and the chooser does not know the
    // charges: measured 0.05 eps (1e-3) and 0.07 eps (1e-5), 0.06 at 1e-7.
    // Asserted: within 30x (the 10x is not reached for them).
    for &(kind, eps, m) in &medians {
        if kind == Charges::Positive {
            assert!(
                m >= 1.0 / 30.0,
                "{kind:?} {eps:e}: median at {m:.3} eps ({medians:?})"
            );
        }
    }
}
