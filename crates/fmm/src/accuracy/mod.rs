//! Checking an FMM result against direct summation.
//!
//! The metric every peer reports is the relative L2 error over a sample of
//! targets,
//!
//! ```text
//! e = sqrt( sum_j |phi_j - phi_j^direct|^2 / sum_j |phi_j^direct|^2 ),
//! ```
//!
//! computed separately for the potential and (when evaluated) the gradient
//! and the Hessian (each over all its components), with the direct sums in
//! `f64` whatever the FMM's float type. Sources of any
//! [`SourceKind`] (charges, dipoles) are compared the same way.
//!
//! # Scaling
//!
//! `e` does not change when every charge is multiplied by the same `s`, but
//! its sums of squares do: charges of `1e200` overflow them, charges of
//! `1e-300` underflow them. Both the reference and the compared values are
//! therefore divided by `s = max |q_i|` first (exact up to one rounding),
//! so that `e` is right for any representable charges.
//!
//! # Cost
//!
//! The reference of one target costs one pass over all N sources. The sums
//! run in parallel over blocks of sources (each block adds its share to all
//! sampled targets), so a sample of a few dozen targets still uses every
//! core. [`estimate_errors`] picks the sample size from a time budget (the
//! after-the-fact verification of [`crate::Fmm::evaluate_verified`]).

use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

use crate::progress::{ProgressFn, Work};

/// Relative L2 errors of an FMM result on sampled targets.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorReport {
    /// Targets compared.
    pub n_sampled: usize,
    /// Relative L2 error of the potential.
    pub potential: f64,
    /// Relative L2 error of the gradient (`None` for potential-only results).
    pub gradient: Option<f64>,
    /// Relative L2 error of the Hessian, its six entries together (`None`
    /// unless evaluated).
    #[serde(default)]
    pub hessian: Option<f64>,
}

impl ErrorReport {
    /// The largest of the potential, gradient and Hessian errors (of those
    /// evaluated): the error of everything the caller asked for.
    pub fn worst(&self) -> f64 {
        [self.gradient, self.hessian]
            .into_iter()
            .flatten()
            .fold(self.potential, f64::max)
    }
}

/// Evenly spaced sample of at most `count` target indices out of `n`.
pub fn sample_indices(n: usize, count: usize) -> Vec<usize> {
    let count = count.min(n).max(1);
    (0..count).map(|k| k * n / count).collect()
}

/// `count` distinct target indices out of `n` (all of them when
/// `count >= n`), drawn at random with a fixed seed: the same for the same
/// `(n, count)`, and free of the patterns an evenly spaced sample can pick
/// up (every other point, one row of a grid). A prefix of the result is
/// itself such a sample, which [`estimate_errors`] relies on.
pub fn random_sample(n: usize, count: usize) -> Vec<usize> {
    if count >= n {
        return (0..n).collect();
    }
    let mut rng = StdRng::seed_from_u64(0x5a17_e5ed ^ n as u64);
    let mut seen = std::collections::HashSet::with_capacity(2 * count);
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let j = rng.random_range(0..n);
        if seen.insert(j) {
            out.push(j);
        }
    }
    out
}

/// Compare `values` (the FMM output for all targets in original order, `mode`
/// layout) with direct summation at the targets `sample`.
///
/// ```
/// use ferrofmm_fmm::{relative_errors, sample_indices};
/// use ferrofmm_kernels::{direct_sum, EvalMode, Laplace3d};
/// let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0];
/// let charges = [1e200, -2e200, 3e200]; // sums of squares would overflow
/// let mut exact = [0.0; 3];
/// direct_sum(&Laplace3d, EvalMode::Potential, &points, &charges, &points, &mut exact);
/// let e = relative_errors(&Laplace3d, EvalMode::Potential, &points, &charges, &points, &exact, &[0, 1, 2]);
/// assert!(e.potential < 1e-15);
/// ```
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
    relative_errors_sources(
        kernel,
        SourceKind::Charge,
        mode,
        sources,
        charges,
        targets,
        values,
        sample,
    )
}

/// [`relative_errors`] for sources of any [`SourceKind`] (`densities`
/// holds [`SourceKind::values_per_source`] values per source), with the
/// points in a float type `P` of their own: give the caller's `f64`
/// coordinates to check an `f32` run against the truth of those points.
#[allow(clippy::too_many_arguments)]
pub fn relative_errors_sources<P: Real, T: Real, K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[P],
    densities: &[T],
    targets: &[P],
    values: &[T],
    sample: &[usize],
) -> ErrorReport {
    Comparison::new(kernel, kind, mode, sources, densities, targets, values).errors_at(sample)
}

/// [`relative_errors_sources`] reporting its progress to `progress`: the
/// direct sums (a source at a sampled target is one unit of
/// [`EvalProgress`](crate::EvalProgress)) are counted per block of
/// sources, so that a front end can show the time left of a long check
/// (1000 targets against 1e8 sources is 1e11 pairs, a minute or more).
/// The result is that of [`relative_errors_sources`], bit for bit.
///
/// ```
/// use std::sync::{Arc, Mutex};
/// use ferrofmm_fmm::{EvalProgress, ProgressFn, relative_errors_sources_with_progress};
/// use ferrofmm_kernels::{EvalMode, Laplace3d, SourceKind};
/// let points: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.618_034).fract()).collect();
/// let charges = vec![1.0; 1000];
/// let values = vec![0.0; 1000];
/// let seen = Arc::new(Mutex::new(Vec::new()));
/// let log = seen.clone();
/// let progress: Arc<ProgressFn> = Arc::new(move |p: EvalProgress| log.lock().unwrap().push(p));
/// let e = relative_errors_sources_with_progress(
///     &Laplace3d, SourceKind::Charge, EvalMode::Potential,
///     &points, &charges, &points, &values, &[0, 1, 2], &progress,
/// );
/// assert!(e.potential > 0.99); // all-zero values: the whole reference is the error
/// let seen = seen.lock().unwrap();
/// assert_eq!(seen.last().unwrap().done, seen.last().unwrap().total);
/// ```
#[allow(clippy::too_many_arguments)]
pub fn relative_errors_sources_with_progress<P: Real, T: Real, K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[P],
    densities: &[T],
    targets: &[P],
    values: &[T],
    sample: &[usize],
    progress: &Arc<ProgressFn>,
) -> ErrorReport {
    Comparison::new(kernel, kind, mode, sources, densities, targets, values)
        .with_progress(Some(progress))
        .errors_at(sample)
}

/// The Ewald truth of a periodic Laplace, Yukawa or Stokes problem
/// ([`crate::periodic::LatticeSum`]): the densities at the sources (`f64`,
/// wrapped or not) in `cell`, at the `targets` (`None`: the sources
/// themselves, each leaving out only itself), to `tolerance`, tuned for
/// about `expected` targets. The one truth of a periodic run's
/// verification and of [`relative_errors_periodic`].
pub(crate) struct PeriodicTruth<'a> {
    sum: LatticeTruth,
    targets: Option<&'a [f64]>,
    mode: EvalMode,
}

/// The Ewald sum behind a [`PeriodicTruth`].
enum LatticeTruth {
    /// Laplace or Yukawa.
    Scalar(ferrofmm_kernels::EwaldSum),
    /// Hasimoto's Stokes sum.
    Stokes(ferrofmm_kernels::StokesEwaldSum),
    /// Laplace or Yukawa in a slab, pair by pair.
    Slab(ferrofmm_kernels::SlabGreen, Vec<f64>, Vec<f64>),
    /// Laplace or Yukawa in a rod, pair by pair.
    Rod(ferrofmm_kernels::RodGreen, Vec<f64>, Vec<f64>),
    /// Any other kernel: the image sum, shell by shell.
    Images(Box<dyn ImageTruth>),
}

/// An image sum of any kernel, behind one type
/// ([`crate::periodic::images::ImageSum`]).
trait ImageTruth: Send + Sync {
    fn at_points(&self, at: &[f64], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError>;
    fn at_sources(&self, sample: &[usize], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError>;
}

impl<K: Kernel> ImageTruth for crate::periodic::images::ImageSum<K> {
    fn at_points(&self, at: &[f64], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError> {
        crate::periodic::images::ImageSum::at_points(self, at, mode)
    }

    fn at_sources(&self, sample: &[usize], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError> {
        crate::periodic::images::ImageSum::at_sources(self, sample, mode)
    }
}

impl LatticeTruth {
    fn at_points(&self, at: &[f64], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError> {
        Ok(match self {
            LatticeTruth::Scalar(s) => s.at_points(at, mode)?,
            LatticeTruth::Stokes(s) => s.at_points(at, mode)?,
            LatticeTruth::Slab(g, x, q) => g.sum_at_points(x, q, at, mode)?,
            LatticeTruth::Rod(g, x, q) => g.sum_at_points(x, q, at, mode)?,
            LatticeTruth::Images(s) => s.at_points(at, mode)?,
        })
    }

    fn at_sources(&self, sample: &[usize], mode: EvalMode) -> Result<Vec<f64>, crate::FmmError> {
        Ok(match self {
            LatticeTruth::Scalar(s) => s.at_sources(sample, mode)?,
            LatticeTruth::Stokes(s) => s.at_sources(sample, mode)?,
            LatticeTruth::Slab(g, x, q) => g.sum_at_sources(x, q, sample, mode)?,
            LatticeTruth::Rod(g, x, q) => g.sum_at_sources(x, q, sample, mode)?,
            LatticeTruth::Images(s) => s.at_sources(sample, mode)?,
        })
    }
}

impl<'a> PeriodicTruth<'a> {
    /// # Errors
    /// What [`ferrofmm_kernels::EwaldSum::with_options`] refuses.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new<T: Real, K: Kernel>(
        kernel: &K,
        cell: &crate::Periodic,
        lattice: crate::periodic::LatticeSum,
        sources: &[f64],
        charges: &[T],
        targets: Option<&'a [f64]>,
        mode: EvalMode,
        tolerance: f64,
        expected: usize,
    ) -> Result<Self, crate::FmmError> {
        use crate::periodic::LatticeSum;
        let q: Vec<f64> = charges.iter().map(|q| q.to_f64()).collect();
        if let LatticeSum::Images { .. } = lattice {
            let sum = crate::periodic::images::ImageSum::new(kernel, cell, sources, &q, tolerance);
            return Ok(PeriodicTruth {
                sum: LatticeTruth::Images(Box::new(sum)),
                targets,
                mode,
            });
        }
        let axes = cell.axes();
        let cell = ferrofmm_kernels::PeriodicCell::new(cell.origin(), cell.lengths())?;
        if axes != crate::PeriodicAxes::Xyz {
            let kappa = match lattice {
                LatticeSum::Laplace => 0.0,
                LatticeSum::Yukawa { kappa } => kappa,
                LatticeSum::Stokes { .. } | LatticeSum::Images { .. } => {
                    return Err(crate::FmmError::InvalidParameter(format!(
                        "no Stokes lattice sum for a {}",
                        axes.kind()
                    )));
                }
            };
            let x = sources.to_vec();
            let sum = match axes {
                crate::PeriodicAxes::Xy => LatticeTruth::Slab(
                    ferrofmm_kernels::SlabGreen::screened(cell, kappa, tolerance)?,
                    x,
                    q,
                ),
                _ => LatticeTruth::Rod(
                    ferrofmm_kernels::RodGreen::screened(cell, kappa, tolerance)?,
                    x,
                    q,
                ),
            };
            return Ok(PeriodicTruth { sum, targets, mode });
        }
        let options = ferrofmm_kernels::EwaldOptions::new(tolerance).expected_targets(expected);
        let sum = match lattice {
            LatticeSum::Stokes { viscosity } => {
                LatticeTruth::Stokes(ferrofmm_kernels::StokesEwaldSum::with_options(
                    cell, sources, &q, viscosity, options,
                )?)
            }
            LatticeSum::Yukawa { kappa } => {
                LatticeTruth::Scalar(ferrofmm_kernels::EwaldSum::with_options(
                    cell,
                    sources,
                    &q,
                    options.screening(kappa),
                )?)
            }
            LatticeSum::Laplace => LatticeTruth::Scalar(ferrofmm_kernels::EwaldSum::with_options(
                cell, sources, &q, options,
            )?),
            LatticeSum::Images { .. } => unreachable!("summed by images above"),
        };
        Ok(PeriodicTruth { sum, targets, mode })
    }

    /// The values at the targets `sample`.
    ///
    /// # Errors
    /// An index out of range, or a mode the Ewald sum does not give.
    pub(crate) fn at(&self, sample: &[usize]) -> Result<Vec<f64>, crate::FmmError> {
        Ok(match self.targets {
            Some(t) => {
                let at: Vec<f64> = sample
                    .iter()
                    .flat_map(|&j| [t[3 * j], t[3 * j + 1], t[3 * j + 2]])
                    .collect();
                self.sum.at_points(&at, self.mode)?
            }
            None => self.sum.at_sources(sample, self.mode)?,
        })
    }
}

/// Kernel evaluations [`relative_errors_periodic`] plans for an image sum.
const IMAGE_CHECK_PAIRS: f64 = 1e10;

/// [`relative_errors`] of a periodic run ([`crate::Periodic`]) of
/// `kernel` ([`crate::periodic::lattice_sum`]): the truth at the sampled
/// targets is the Ewald sum ([`ferrofmm_kernels::EwaldSum`] to `1e-13`,
/// screened for Yukawa; [`ferrofmm_kernels::StokesEwaldSum`] for Stokes)
/// of the charges (or forces) at the sources in the cell, at the
/// `targets` (`None`: the targets are the sources, each leaving out only
/// itself). For any other kernel
/// ([`LatticeSum::Images`](crate::periodic::LatticeSum::Images)) it is the
/// image sum, shell by shell, to `1e-10`, at no more of the sampled
/// targets (every k-th) than keep it near `IMAGE_CHECK_PAIRS` (`1e10`)
/// kernel evaluations for 729 images: the report's `n_sampled` says how
/// many.
///
/// # Errors
/// [`FmmError::InvalidParameter`](crate::FmmError::InvalidParameter) for a
/// kernel with no lattice sum here; what
/// [`ferrofmm_kernels::EwaldSum::new`] refuses (a bad cell, points or
/// charges that do not match, Hessians).
#[allow(clippy::too_many_arguments)]
pub fn relative_errors_periodic<T: Real, K: Kernel>(
    kernel: &K,
    cell: &crate::Periodic,
    mode: EvalMode,
    sources: &[f64],
    charges: &[T],
    targets: Option<&[f64]>,
    values: &[T],
    sample: &[usize],
) -> Result<ErrorReport, crate::FmmError> {
    let lattice = crate::periodic::required_lattice(kernel)?;
    let (tolerance, kept);
    let sample = match lattice {
        crate::periodic::LatticeSum::Images { .. } => {
            let per_target = (sources.len() / 3).max(1) as f64 * 729.0;
            let most = ((IMAGE_CHECK_PAIRS / per_target) as usize).max(1);
            let step = sample.len().div_ceil(most).max(1);
            kept = sample.iter().copied().step_by(step).collect::<Vec<_>>();
            tolerance = 1e-10;
            &kept[..]
        }
        _ => {
            tolerance = 1e-13;
            sample
        }
    };
    let exact = PeriodicTruth::new(
        kernel,
        cell,
        lattice,
        sources,
        charges,
        targets,
        mode,
        tolerance,
        sample.len(),
    )?
    .at(sample)?;
    let truth = |_: &[usize]| -> Vec<f64> { exact.clone() };
    let problem = Comparison::new(
        kernel,
        SourceKind::Charge,
        mode,
        sources,
        charges,
        targets.unwrap_or(sources),
        values,
    )
    .with_truth(Some(&truth));
    Ok(problem.errors_at(sample))
}

/// Estimate the relative L2 errors of `values` on a random sample of
/// targets whose direct sums take about `budget` (at least `min_sample`
/// and at most `max_sample` targets, fewer only when there are fewer
/// targets).
///
/// The first 16 targets are summed and timed; the rest of the sample is
/// sized from that rate to fill what is left of the budget. The sample is
/// a prefix of [`random_sample`]`(n_targets, max_sample)`, so the same
/// targets are used for the same problem whatever the budget. `charges`
/// holds `kind.values_per_source()` values per source.
#[allow(clippy::too_many_arguments)]
pub fn estimate_errors<P: Real, T: Real, K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[P],
    charges: &[T],
    targets: &[P],
    values: &[T],
    budget: Duration,
    min_sample: usize,
    max_sample: usize,
) -> ErrorReport {
    let problem = Comparison::new(kernel, kind, mode, sources, charges, targets, values);
    sample_sums(&problem, budget, min_sample, max_sample).report(mode)
}

/// The error sums of [`estimate_errors`]'s sample of `problem`.
fn sample_sums<P: Real, T: Real, K: Kernel>(
    problem: &Comparison<'_, P, T, K>,
    budget: Duration,
    min_sample: usize,
    max_sample: usize,
) -> ErrorSums {
    const PROBE: usize = 16;
    let n_targets = problem.targets.len() / 3;
    let max_sample = max_sample.max(min_sample).max(1);
    let sample = random_sample(n_targets, max_sample);
    let mut sums = ErrorSums::default();
    let first = PROBE.min(sample.len());
    let t = Instant::now();
    problem.add(&mut sums, &sample[..first]);
    let spent = t.elapsed().as_secs_f64();
    let per_target = spent / first.max(1) as f64;
    let left = budget.as_secs_f64() - spent;
    let affordable = if per_target > 0.0 {
        (left / per_target).max(0.0).min(sample.len() as f64) as usize
    } else {
        sample.len()
    };
    let end = (first + affordable).max(min_sample).min(sample.len());
    problem.add(&mut sums, &sample[first..end.max(first)]);
    sums
}

/// [`estimate_errors`] with the denominators of the relative errors taken
/// from `values` at **every** target instead of the reference at the
/// sampled ones:
///
/// ```text
/// e^2 = (N / s) sum_{j in sample} |v_j - r_j|^2 / sum_{all j} |v_j|^2
/// ```
///
/// The references of the gradient are heavy-tailed (a target with a close
/// neighbour has a gradient orders of magnitude above the median), so a
/// small sample usually misses the targets that dominate the sum of
/// `|r_j|^2` and overestimates the relative error, by up to 14x on 64 of
/// 1e4 points on a sphere (measured against all targets); the squared
/// errors of the FMM, made in the far field, are spread far more evenly.
/// `values` approximate the references to the error being estimated, so
/// their sum is the population's to that relative accuracy.
pub(crate) fn estimate_errors_population<P: Real, T: Real, K: Kernel>(
    problem: &Comparison<'_, P, T, K>,
    budget: Duration,
    min_sample: usize,
    max_sample: usize,
) -> ErrorReport {
    let mut sums = sample_sums(problem, budget, min_sample, max_sample);
    let Comparison {
        kernel,
        mode,
        targets,
        values,
        scale,
        ..
    } = *problem;
    let n_targets = targets.len() / 3;
    let comps = kernel.components();
    let w = kernel.values_per_target(mode);
    let (pot, grad, hess) = values
        .par_chunks(w.max(1))
        .map(|v| {
            let mut q = [0.0f64; 3];
            for (c, x) in v.iter().enumerate() {
                let x = x.to_f64() / scale;
                let quantity = c / comps;
                q[if quantity == 0 {
                    0
                } else if quantity < 4 {
                    1
                } else {
                    2
                }] += x * x;
            }
            (q[0], q[1], q[2])
        })
        .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    let share = sums.n as f64 / n_targets.max(1) as f64;
    sums.ref_pot = share * pot;
    sums.ref_grad = share * grad;
    sums.ref_hess = share * hess;
    sums.report(mode)
}

/// `max |q_i|` (1 when all charges are zero): the scale that keeps the
/// sums of squares of [`relative_errors`] representable.
fn charge_scale<T: Real>(charges: &[T]) -> f64 {
    let m = charges
        .par_iter()
        .map(|q| q.to_f64().abs())
        .reduce(|| 0.0, f64::max);
    if m > 0.0 && m.is_finite() { m } else { 1.0 }
}

/// Sums of squared differences and of squared references, potential and
/// gradient apart.
#[derive(Default)]
struct ErrorSums {
    n: usize,
    diff_pot: f64,
    ref_pot: f64,
    diff_grad: f64,
    ref_grad: f64,
    diff_hess: f64,
    ref_hess: f64,
}

/// What is compared: an FMM result and the problem it solved, with the
/// charge scale of the error sums.
pub(crate) struct Comparison<'a, P, T, K> {
    kernel: &'a K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &'a [P],
    charges: &'a [T],
    targets: &'a [P],
    values: &'a [T],
    /// [`charge_scale`] of the charges.
    scale: f64,
    /// The exact values at given targets, when they are not the direct
    /// sum (a periodic cell's Ewald sums).
    truth: Option<&'a Truth<'a>>,
    /// Where the direct sums report their progress.
    progress: Option<&'a Arc<ProgressFn>>,
}

/// The exact values (`values_per_target` each, unscaled) at the targets of
/// the given indices, for problems whose truth is not a direct sum.
pub(crate) type Truth<'a> = dyn Fn(&[usize]) -> Vec<f64> + Sync + 'a;

impl<'a, P: Real, T: Real, K: Kernel> Comparison<'a, P, T, K> {
    /// `values` of the problem of `kernel` (in `mode`) on `sources` with
    /// `charges` (`kind`) at `targets`, against direct sums.
    pub(crate) fn new(
        kernel: &'a K,
        kind: SourceKind,
        mode: EvalMode,
        sources: &'a [P],
        charges: &'a [T],
        targets: &'a [P],
        values: &'a [T],
    ) -> Self {
        Comparison {
            kernel,
            kind,
            mode,
            sources,
            charges,
            targets,
            values,
            scale: charge_scale(charges),
            truth: None,
            progress: None,
        }
    }

    /// The direct sums report to `progress` (see
    /// [`relative_errors_sources_with_progress`]).
    pub(crate) fn with_progress(self, progress: Option<&'a Arc<ProgressFn>>) -> Self {
        Comparison { progress, ..self }
    }

    /// The same comparison against `truth` (when given) instead of the
    /// direct sums.
    pub(crate) fn with_truth(self, truth: Option<&'a Truth<'a>>) -> Self {
        Comparison { truth, ..self }
    }

    /// The errors at the targets of `sample`.
    fn errors_at(&self, sample: &[usize]) -> ErrorReport {
        let mut sums = ErrorSums::default();
        self.add(&mut sums, sample);
        sums.report(self.mode)
    }

    /// Add the targets `sample` to `sums`.
    fn add(&self, sums: &mut ErrorSums, sample: &[usize]) {
        if sample.is_empty() {
            return;
        }
        let comps = self.kernel.components();
        let w = self.kernel.values_per_target(self.mode);
        let t = self.targets;
        let at: Vec<f64> = sample
            .iter()
            .flat_map(|&j| [t[3 * j], t[3 * j + 1], t[3 * j + 2]])
            .map(|x| x.to_f64())
            .collect();
        let reference = match self.truth {
            Some(truth) => truth(sample).iter().map(|v| v / self.scale).collect(),
            None => {
                let pairs = (self.sources.len() / 3) as u64 * sample.len() as u64;
                let work = Work::new(self.progress, || pairs);
                let r = scaled_reference(
                    self.kernel,
                    self.kind,
                    self.mode,
                    self.sources,
                    self.charges,
                    self.scale,
                    &at,
                    &work,
                );
                work.finish();
                r
            }
        };
        for (k, &j) in sample.iter().enumerate() {
            for c in 0..w {
                let r = reference[w * k + c];
                let e = self.values[w * j + c].to_f64() / self.scale - r;
                // Quantity-major: `comps` values of the potential, then of
                // each derivative.
                let quantity = c / comps;
                if quantity == 0 {
                    sums.diff_pot += e * e;
                    sums.ref_pot += r * r;
                } else if quantity < 4 {
                    sums.diff_grad += e * e;
                    sums.ref_grad += r * r;
                } else {
                    sums.diff_hess += e * e;
                    sums.ref_hess += r * r;
                }
            }
        }
        sums.n += sample.len();
    }
}

impl ErrorSums {
    fn report(&self, mode: EvalMode) -> ErrorReport {
        let ratio = |d: f64, n: f64| if n > 0.0 { (d / n).sqrt() } else { d.sqrt() };
        ErrorReport {
            n_sampled: self.n,
            potential: ratio(self.diff_pot, self.ref_pot),
            gradient: mode
                .has_gradient()
                .then(|| ratio(self.diff_grad, self.ref_grad)),
            hessian: mode
                .has_hessian()
                .then(|| ratio(self.diff_hess, self.ref_hess)),
        }
    }
}

/// Sources per block of the parallel reference sum.
const REFERENCE_BLOCK: usize = 4096;

/// Direct sums in `f64` at the points `at` (interleaved) for the densities
/// divided by `scale`: every block of sources adds its share to all
/// targets, blocks in parallel, each counted done in `work` (its sources
/// times the targets).
#[allow(clippy::too_many_arguments)]
fn scaled_reference<P: Real, T: Real, K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[P],
    charges: &[T],
    scale: f64,
    at: &[f64],
    work: &Work<'_>,
) -> Vec<f64> {
    let len = kernel.values_per_target(mode) * (at.len() / 3);
    let nq = kernel.values_per_source(kind);
    sources
        .par_chunks(3 * REFERENCE_BLOCK)
        .zip(charges.par_chunks(nq * REFERENCE_BLOCK))
        .fold(
            || vec![0.0f64; len],
            |mut acc, (s, q)| {
                let s: Vec<f64> = s.iter().map(|x| x.to_f64()).collect();
                let q: Vec<f64> = q.iter().map(|x| x.to_f64() / scale).collect();
                let mut part = vec![0.0f64; len];
                kernel.evaluate_sources(kind, mode, &s, &q, at, &mut part);
                acc.iter_mut().zip(&part).for_each(|(a, p)| *a += p);
                work.add((s.len() / 3) as u64 * (at.len() / 3) as u64);
                acc
            },
        )
        .reduce(
            || vec![0.0f64; len],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        )
}

#[cfg(test)]
mod tests;
