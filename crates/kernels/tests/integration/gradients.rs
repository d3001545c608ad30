//! Gradients against central finite differences of the potential, for every
//! kernel and SIMD level.

use crate::common;

use common::{levels, random_points};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, ModifiedHelmholtz3d, laplace_p2p_with};

/// Central differences of `phi` with step `h` in each coordinate of each
/// target; `phi` evaluates potentials at the given targets.
fn finite_difference_gradient(
    targets: &[f64],
    h: f64,
    phi: impl Fn(&[f64]) -> Vec<f64>,
) -> Vec<[f64; 3]> {
    let nt = targets.len() / 3;
    let mut g = vec![[0.0; 3]; nt];
    for c in 0..3 {
        let mut plus = targets.to_vec();
        let mut minus = targets.to_vec();
        for j in 0..nt {
            plus[3 * j + c] += h;
            minus[3 * j + c] -= h;
        }
        let (pp, pm) = (phi(&plus), phi(&minus));
        for j in 0..nt {
            g[j][c] = (pp[j] - pm[j]) / (2.0 * h);
        }
    }
    g
}

/// Targets well separated from the sources (distance >= 1), so that the
/// central difference with h = 1e-4 has truncation error ~h^2 |K'''| ~ 1e-8
/// and cancellation error ~eps |phi| / h ~ 1e-12, relative to |grad|.
fn separated_problem() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (s, q) = random_points::<f64>(21, 23);
    let (mut t, _) = random_points::<f64>(22, 19);
    for x in t.iter_mut() {
        *x = if *x >= 0.0 { *x + 2.0 } else { *x - 2.0 };
    }
    let q = q.iter().map(|x| x.abs() + 0.1).collect();
    (s, q, t)
}

fn check_kernel_gradient<K: Kernel>(kernel: &K, eval: impl Fn(EvalMode, &[f64], &mut [f64])) {
    let (_, _, t) = separated_problem();
    let nt = t.len() / 3;
    let mut out = vec![0.0; 4 * nt];
    eval(EvalMode::PotentialGradient, &t, &mut out);
    let fd = finite_difference_gradient(&t, 1e-4, |tt| {
        let mut p = vec![0.0; nt];
        eval(EvalMode::Potential, tt, &mut p);
        p
    });
    for j in 0..nt {
        let g = &out[4 * j + 1..4 * j + 4];
        let norm = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        assert!(norm > 0.0);
        for c in 0..3 {
            let err = (g[c] - fd[j][c]).abs() / norm;
            assert!(
                err < 1e-7,
                "{} target {j} component {c}: {err:e}",
                kernel.name()
            );
        }
    }
}

#[test]
fn laplace_gradient_matches_finite_differences() {
    let (s, q, _) = separated_problem();
    for level in levels() {
        check_kernel_gradient(&Laplace3d, |mode, t, out| {
            laplace_p2p_with(level, mode, &s, &q, t, out)
        });
    }
    check_kernel_gradient(&Laplace3d, |mode, t, out| {
        ferrofmm_kernels::reference::evaluate_pairwise(&Laplace3d, mode, &s, &q, t, out)
    });
}

#[test]
fn yukawa_gradient_matches_finite_differences() {
    let (s, q, _) = separated_problem();
    for k in [0.0, 0.5, 3.0] {
        let kernel = ModifiedHelmholtz3d::new(k).unwrap();
        check_kernel_gradient(&kernel, |mode, t, out| {
            kernel.evaluate(mode, &s, &q, t, out)
        });
    }
}

type ValueFn = Box<dyn Fn([f64; 3]) -> f64>;

/// `kernel_gradient` itself, per pair.
#[test]
fn pointwise_kernel_gradients_match_finite_differences() {
    let h = 1e-5;
    for d in [[0.3, -0.7, 1.1], [2.0, 0.0, 0.0], [-0.5, 0.25, -0.125]] {
        let y = ModifiedHelmholtz3d::new(1.7).unwrap();
        let kernels: [(&str, ValueFn, [f64; 3]); 2] = [
            (
                "laplace",
                Box::new(|d| Laplace3d.kernel_value(d)),
                Laplace3d.kernel_gradient(d),
            ),
            (
                "yukawa",
                Box::new(move |d| y.kernel_value(d)),
                y.kernel_gradient(d),
            ),
        ];
        for (name, value, grad) in kernels {
            for c in 0..3 {
                let (mut p, mut m) = (d, d);
                p[c] += h;
                m[c] -= h;
                let fd = (value(p) - value(m)) / (2.0 * h);
                assert!(
                    (fd - grad[c]).abs() < 1e-8,
                    "{name} {d:?} {c}: {fd} vs {}",
                    grad[c]
                );
            }
        }
    }
}
