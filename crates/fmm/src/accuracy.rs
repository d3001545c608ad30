//! Checking an FMM result against direct summation.
//!
//! The metric every peer reports is the relative L2 error over a sample of
//! targets,
//!
//! ```text
//! e = sqrt( sum_j |phi_j - phi_j^direct|^2 / sum_j |phi_j^direct|^2 ),
//! ```
//!
//! computed separately for the potential and (when evaluated) the gradient,
//! with the direct sums in `f64` whatever the FMM's float type.

use ferrofmm_kernels::{EvalMode, Kernel, Real, direct_sum};

/// Relative L2 errors of an FMM result on sampled targets.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ErrorReport {
    /// Targets compared.
    pub n_sampled: usize,
    /// Relative L2 error of the potential.
    pub potential: f64,
    /// Relative L2 error of the gradient (`None` for potential-only results).
    pub gradient: Option<f64>,
}

/// Evenly spaced sample of at most `count` target indices out of `n`.
pub fn sample_indices(n: usize, count: usize) -> Vec<usize> {
    let count = count.min(n).max(1);
    (0..count).map(|k| k * n / count).collect()
}

/// Compare `values` (the FMM output for all targets in original order, `mode`
/// layout) with direct summation at the targets `sample`.
#[allow(clippy::too_many_arguments)]
pub fn relative_errors<T: Real, K: Kernel>(
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    values: &[T],
    sample: &[usize],
) -> ErrorReport {
    let w = mode.values_per_target();
    let up = |v: &[T]| v.iter().map(|x| x.to_f64()).collect::<Vec<f64>>();
    let sampled: Vec<f64> = sample
        .iter()
        .flat_map(|&j| [targets[3 * j], targets[3 * j + 1], targets[3 * j + 2]])
        .map(|x| x.to_f64())
        .collect();
    let mut reference = vec![0.0f64; w * sample.len()];
    direct_sum(
        kernel,
        mode,
        &up(sources),
        &up(charges),
        &sampled,
        &mut reference,
    );
    let (mut dp, mut np, mut dg, mut ng) = (0.0, 0.0, 0.0, 0.0);
    for (k, &j) in sample.iter().enumerate() {
        for c in 0..w {
            let e = values[w * j + c].to_f64() - reference[w * k + c];
            let r = reference[w * k + c];
            if c == 0 {
                dp += e * e;
                np += r * r;
            } else {
                dg += e * e;
                ng += r * r;
            }
        }
    }
    let ratio = |d: f64, n: f64| if n > 0.0 { (d / n).sqrt() } else { d.sqrt() };
    ErrorReport {
        n_sampled: sample.len(),
        potential: ratio(dp, np),
        gradient: (w == 4).then(|| ratio(dg, ng)),
    }
}
