//! A tolerance that is checked, not only predicted.
//!
//! [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) chooses the
//! parameters from an error model; [`Fmm::evaluate_verified`] then checks
//! what the evaluation achieved. It estimates the relative L2 errors of
//! every output asked for (the potential, and the gradient when evaluated)
//! on a random sample of targets against direct summation in `f64`
//! ([`estimate_errors`](crate::estimate_errors)), with the sample sized so that the direct sums
//! take about [`VERIFY_BUDGET`] of the evaluation time (at least
//! [`MIN_VERIFY_SAMPLE`], at most [`MAX_VERIFY_SAMPLE`] targets). For N
//! sources a sampled target costs `N` kernel evaluations against roughly
//! `N` times a per-point constant for the whole FMM, so the sample holds a
//! few hundred targets at any N.
//!
//! In a periodic cell ([`crate::periodic`]) the truth is the Ewald sum of
//! the charges ([`ferrofmm_kernels::EwaldSum`], to a tenth of the
//! tolerance, tuned for a few hundred targets); its set-up time counts as
//! the first check's.
//!
//! The estimate has sampling noise: a relative L2 error over `s` targets
//! varies by roughly `c / sqrt(s)` of itself ([`VERIFY_NOISE`]). So an
//! estimate `m` counts as meeting `eps` only when
//! `(1 + VERIFY_NOISE / sqrt(s)) m <= eps` ([`noise_margin`]: 1.28 for 200
//! targets, 1.13 for 1000); an estimate between `eps / margin` and `eps`
//! is repeated on [`RESAMPLE_FACTOR`] times the sample before a retry is
//! decided. A sample of every target measures the error itself: no margin,
//! no resampling. The relative errors' denominators come from the evaluated
//! values at every target, not from the sample's references (whose
//! gradients are heavy-tailed: a small sample overestimated the error up
//! to 14x). The chooser's safety factor
//! ([`SCENE_SAFETY_FACTOR`](crate::tuning::SCENE_SAFETY_FACTOR)) leaves
//! that room on the first attempt in the usual case.
//!
//! When the estimate misses, the order is raised (the tree and the lists
//! are kept; the operators and the M2L scheme are rebuilt) and the charges
//! evaluated again, at most [`MAX_VERIFY_RETRIES`] times. The new order is
//! the one the error model, **calibrated on the miss**, says is needed: the
//! model fitted to the points ([`ErrorModel::in_scene`]) with every order's
//! error multiplied by `c = margin m / predicted` (how far the attempt
//! fell short of its prediction), and its smallest admissible order above
//! the current one, so that one raise usually suffices where raising by
//! one at a time needed two (orders step by 6-14x). The SVD tolerance of
//! the new order comes from the same calibrated model.
//! Every attempt is reported ([`Verification::attempts`]); when the last
//! is still above the tolerance, [`Verification::met`] is `false` and the
//! values of that last (most accurate) attempt are returned: the caller is
//! told, never misled.

use std::time::{Duration, Instant};

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{Kernel, Real};

use crate::accuracy::{Comparison, ErrorReport, PeriodicTruth, Truth, estimate_errors_population};
use crate::tuning::{ChosenParameters, ErrorModel, Occupancy, Scene};
use crate::{EvalTimings, Fmm, FmmError};

/// The accuracy of a periodic run's Ewald truth, as a share of the
/// tolerance checked.
const PERIODIC_TRUTH_SHARE: f64 = 0.1;

/// The accuracy of the Ewald truth of [`Fmm::estimate_error`], which has
/// no tolerance to follow.
const PERIODIC_ESTIMATE_TOLERANCE: f64 = 1e-12;

/// Share of the evaluation time the direct sums of a verification may
/// take.
pub const VERIFY_BUDGET: f64 = 0.03;

/// Fewest targets a verification samples, whatever the budget. Errors of
/// the gradient of same-sign charges in a volume are heavy-tailed (a few
/// targets carry most of them): 60 targets underestimated them by up to
/// 1.2x beyond the noise margin (cube and Plummer, N = 1.2e4, eps 1e-3),
/// so a sample holds at least 200. Cheap at any N: 200 N kernel
/// evaluations against an FMM of roughly 1e3..1e4 N.
pub const MIN_VERIFY_SAMPLE: usize = 200;

/// Most targets a verification samples.
pub const MAX_VERIFY_SAMPLE: usize = 1000;

/// Re-evaluations at a higher order a verification may run.
pub const MAX_VERIFY_RETRIES: usize = 2;

/// Noise coefficient `c` of the estimate: a relative L2 error estimated on
/// `s` targets is within about `c / sqrt(s)` of itself. Measured (N = 1e4,
/// against every target): zero-mean charges within 1.1x on 32 to 124
/// targets; the gradient of all-positive charges in a uniform cube 1.47x
/// below the truth on 61 targets (its field nearly cancels inside the
/// cloud, so a few targets carry its error), which `c = 4` covers (1.51
/// at 61 targets).
pub const VERIFY_NOISE: f64 = 4.0;

/// An estimate within the noise band (at most the tolerance, above it
/// with [`noise_margin`]) is repeated on this many times the sample (and
/// budget), up to [`MAX_VERIFY_SAMPLE`] targets, before a retry is
/// decided: a larger sample costs a few percent of the evaluation, a retry
/// all of it.
pub const RESAMPLE_FACTOR: usize = 4;

/// The factor `1 + VERIFY_NOISE / sqrt(s)` an estimate over `s` targets is
/// multiplied by before it is compared with the tolerance.
///
/// ```
/// use ferrofmm_fmm::verify::noise_margin;
/// assert!((noise_margin(400) - 1.2).abs() < 1e-12);
/// assert!(noise_margin(32) > noise_margin(1000));
/// ```
pub fn noise_margin(n_sampled: usize) -> f64 {
    1.0 + VERIFY_NOISE / (n_sampled.max(1) as f64).sqrt()
}

/// One evaluation checked by a verification.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VerificationAttempt {
    /// Expansion order of the attempt.
    pub order: usize,
    /// SVD tolerance of the attempt (`None` for other schemes).
    pub svd_tolerance: Option<f64>,
    /// Error the model predicted for it (the larger of potential and
    /// gradient when gradients are evaluated).
    pub predicted_error: f64,
    /// Errors estimated on the sample.
    pub measured: ErrorReport,
    /// Seconds of the evaluation.
    pub evaluation_s: f64,
    /// Seconds of the direct sums on the sample.
    pub check_s: f64,
}

/// What [`Fmm::evaluate_verified`] found.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Verification {
    /// The relative L2 error asked for.
    pub tolerance: f64,
    /// Every evaluation, first to last; the values returned are the last's.
    pub attempts: Vec<VerificationAttempt>,
    /// Whether the last estimate is at most the tolerance (for the
    /// potential and, when evaluated, the gradient).
    pub met: bool,
    /// Seconds spent rebuilding operators at higher orders.
    pub rebuild_s: f64,
}

impl Verification {
    /// The last attempt (the one whose values were returned).
    pub fn last(&self) -> &VerificationAttempt {
        self.attempts
            .last()
            .expect("a verification holds at least one attempt")
    }

    /// Errors estimated for the returned values.
    pub fn measured(&self) -> ErrorReport {
        self.last().measured
    }

    /// Error predicted for the returned values.
    pub fn predicted_error(&self) -> f64 {
        self.last().predicted_error
    }

    /// Seconds of all direct sums on samples.
    pub fn check_s(&self) -> f64 {
        self.attempts.iter().map(|a| a.check_s).sum()
    }
}

/// The values of one [`Fmm::evaluate_verified`] call.
#[derive(Clone, Debug)]
pub struct Evaluation<T> {
    /// Potentials (and gradients), as [`Fmm::evaluate`] returns them.
    pub values: Vec<T>,
    /// Times of the evaluation that produced `values`.
    pub timings: EvalTimings,
    /// The check of the tolerance; `None` without a tolerance or with
    /// [`FmmBuilder::verify`](crate::FmmBuilder::verify)`(false)`.
    pub verification: Option<Verification>,
}

/// The order, SVD tolerance and predicted error of the next attempt after
/// `chosen` missed `eps` with the estimate `measured` (noise margin
/// included): `fitted` calibrated on the miss, `c = measured / predicted`
/// (at least 1) times every order's error, and its smallest admissible
/// order above `chosen.order` (the next order when none is).
pub(crate) fn raised_order(
    fitted: &ErrorModel,
    chosen: &ChosenParameters,
    measured: f64,
    eps: f64,
    ratio: f64,
) -> (usize, f64, f64) {
    let c = (measured / chosen.predicted_error.max(f64::MIN_POSITIVE)).max(1.0);
    let mut calibrated = fitted.clone();
    calibrated
        .order_errors
        .iter_mut()
        .for_each(|(_, e)| *e *= c);
    let next = calibrated
        .order_errors
        .iter()
        .map(|&(p, _)| p)
        .find(|&p| p > chosen.order && calibrated.admissible(p, eps, ratio))
        .unwrap_or(chosen.order + 1);
    let tau = calibrated.svd_tolerance(next, eps, ratio);
    let predicted = calibrated
        .predicted_error(next, tau, ratio)
        .unwrap_or(chosen.predicted_error);
    (next, tau, predicted)
}

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    /// Evaluate, then check the tolerance given to
    /// [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) (see the
    /// [module docs](self)): estimate the achieved errors on a sample of
    /// targets and, while they exceed the tolerance, raise the order and
    /// evaluate again (at most [`MAX_VERIFY_RETRIES`] times). A raised order
    /// stays for later evaluations. Without a tolerance, or with
    /// verification off, this is [`Fmm::evaluate_timed`].
    ///
    /// ```no_run
    /// use ferrofmm_fmm::{FmmBuilder, Geometry, charges};
    /// let points: Vec<f64> = Geometry::Sphere.points(100_000, 1);
    /// let q: Vec<f64> = charges(100_000, 2);
    /// let mut fmm = FmmBuilder::new(&points).tolerance(1e-6).build_svd()?;
    /// let out = fmm.evaluate_verified(&q)?;
    /// let v = out.verification.unwrap();
    /// assert!(v.met && v.measured().potential <= 1e-6);
    /// # Ok::<(), ferrofmm_fmm::FmmError>(())
    /// ```
    pub fn evaluate_verified(&mut self, charges: &[T]) -> Result<Evaluation<T>, FmmError> {
        let (mut values, mut timings) = self.evaluate_timed(charges)?;
        let (Some(chosen), true) = (self.chosen.clone(), self.verify) else {
            return Ok(Evaluation {
                values,
                timings,
                verification: None,
            });
        };
        let eps = chosen.tolerance;
        let model = self
            .error_model
            .clone()
            .unwrap_or_else(|| ErrorModel::laplace_for(T::PRECISION, self.mode));
        let ratio = chosen.estimated_work.rounding_ratio;
        let mut verification = Verification {
            tolerance: eps,
            attempts: Vec::new(),
            met: false,
            rebuild_s: 0.0,
        };
        let mut chosen = chosen;
        // The points in the caller's order, for the direct sums: made for
        // each check and dropped before an evaluation (24 bytes a point
        // not held through it), except in a periodic cell, whose Ewald
        // truth keeps them for every attempt.
        let periodic_points = self.periodic().is_some().then(|| self.original_points());
        let mut fresh: Option<OriginalPoints> = None;
        // The model fitted to the points, computed at the first miss.
        let mut fitted: Option<ErrorModel> = None;
        // A periodic run's truth (its Ewald sum's setup counts as the
        // first check's time).
        let t = Instant::now();
        let truth = match &periodic_points {
            Some(points) => self.periodic_truth(points, charges, eps)?,
            None => None,
        };
        let mut truth_s = t.elapsed().as_secs_f64();
        loop {
            if periodic_points.is_none() {
                fresh = Some(self.original_points());
            }
            let points = periodic_points
                .as_ref()
                .or(fresh.as_ref())
                .expect("points for the check");
            let mut attempt = self.check_attempt(
                points,
                charges,
                &values,
                &timings,
                &chosen,
                truth.as_deref(),
            );
            attempt.check_s += std::mem::take(&mut truth_s);
            // Every target sampled: the error is measured, not estimated.
            let margin = if attempt.measured.n_sampled >= self.n_targets {
                1.0
            } else {
                noise_margin(attempt.measured.n_sampled)
            };
            let measured = attempt.measured.worst() * margin;
            verification.attempts.push(attempt);
            if measured <= eps {
                verification.met = true;
                break;
            }
            let tries = verification.attempts.len() - 1;
            if tries >= MAX_VERIFY_RETRIES || model.order_error(chosen.order + 1).is_none() {
                break;
            }
            let fitted = fitted.get_or_insert_with(|| {
                let separate = points.targets.as_deref();
                Occupancy::new(
                    &points.sources,
                    separate,
                    None,
                    ferrofmm_tree::DEEPEST_LEVEL,
                )
                .map(|o| model.in_scene(&Scene::of(&o)))
                .unwrap_or_else(|_| model.clone())
            });
            let (next, tau, predicted) = raised_order(fitted, &chosen, measured, eps, ratio);
            fresh = None;
            let raised = ChosenParameters {
                order: next,
                svd_tolerance: tau,
                predicted_error: predicted,
                svd_rank: None,
                ..chosen.clone()
            };
            let t = Instant::now();
            self.rebuild_at_order(raised)?;
            verification.rebuild_s += t.elapsed().as_secs_f64();
            chosen = self.chosen.clone().expect("rebuilt with chosen parameters");
            drop(std::mem::take(&mut values)); // never hold two results at once
            (values, timings) = self.evaluate_timed(charges)?;
        }
        self.verification = Some(verification.clone());
        Ok(Evaluation {
            values,
            timings,
            verification: Some(verification),
        })
    }

    /// Estimate the errors of `values` for `charges` on a sample sized
    /// from `eval_time` (see the [module docs](self)).
    ///
    /// In a periodic cell the truth is an Ewald sum ([`ferrofmm_kernels::EwaldSum`]);
    /// should it fail (it does not for charges the FMM accepted), the
    /// report is of zero targets with NaN errors (never a passing one).
    pub fn estimate_error(&self, charges: &[T], values: &[T], eval_time: Duration) -> ErrorReport {
        let points = self.original_points();
        let truth = match self.periodic_truth(&points, charges, PERIODIC_ESTIMATE_TOLERANCE) {
            Ok(t) => t,
            Err(_) => {
                return ErrorReport {
                    n_sampled: 0,
                    potential: f64::NAN,
                    gradient: self.mode.has_gradient().then_some(f64::NAN),
                    hessian: self.mode.has_hessian().then_some(f64::NAN),
                };
            }
        };
        self.estimate_error_at(
            &points,
            charges,
            values,
            eval_time,
            MIN_VERIFY_SAMPLE,
            truth.as_deref(),
        )
    }

    /// The Ewald truth of a periodic run for `charges` at the points
    /// `(sources, targets)` (wrapped, the caller's order), accurate far
    /// below `eps`; `None` in free space.
    #[allow(clippy::type_complexity)]
    fn periodic_truth<'s>(
        &self,
        points: &'s OriginalPoints,
        charges: &[T],
        eps: f64,
    ) -> Result<Option<Box<Truth<'s>>>, FmmError> {
        let Some(far) = &self.periodic else {
            return Ok(None);
        };
        let tolerance = (eps * PERIODIC_TRUTH_SHARE).clamp(1e-15, 1e-4);
        let truth = PeriodicTruth::new(
            &self.kernel,
            &far.cell,
            far.lattice(),
            &points.sources,
            &charges[..self.n_sources * self.kernel.values_per_source(self.source_kind)],
            points.targets.as_deref(),
            self.mode,
            tolerance,
            2 * MIN_VERIFY_SAMPLE,
        )?;
        let w = self.kernel.values_per_target(self.mode);
        // The sample and the mode are the FMM's own, which the Ewald sum
        // accepts; should it not, the check fails (NaN), never passes.
        Ok(Some(Box::new(move |sample: &[usize]| {
            truth
                .at(sample)
                .unwrap_or_else(|_| vec![f64::NAN; w * sample.len()])
        })))
    }

    /// [`Fmm::estimate_error`] with the points in the caller's order given.
    fn estimate_error_at(
        &self,
        points: &OriginalPoints,
        charges: &[T],
        values: &[T],
        eval_time: Duration,
        min_sample: usize,
        truth: Option<&Truth<'_>>,
    ) -> ErrorReport {
        let problem = Comparison::new(
            &self.kernel,
            self.source_kind,
            self.mode,
            &points.sources,
            charges,
            points.targets(),
            values,
        )
        .with_truth(truth);
        estimate_errors_population(
            &problem,
            eval_time.mul_f64(VERIFY_BUDGET),
            min_sample,
            MAX_VERIFY_SAMPLE,
        )
    }

    /// The last verification (see [`Fmm::evaluate_verified`]).
    pub fn verification(&self) -> Option<&Verification> {
        self.verification.as_ref()
    }

    fn check_attempt(
        &self,
        points: &OriginalPoints,
        charges: &[T],
        values: &[T],
        timings: &EvalTimings,
        chosen: &ChosenParameters,
        truth: Option<&Truth<'_>>,
    ) -> VerificationAttempt {
        let t = Instant::now();
        let eps = chosen.tolerance;
        let mut budget = timings.total;
        let mut min_sample = MIN_VERIFY_SAMPLE;
        let mut measured =
            self.estimate_error_at(points, charges, values, budget, min_sample, truth);
        // Within the noise band (at most eps, but not with the margin):
        // a larger sample decides, which is far cheaper than a retry. A
        // sample that cannot grow (every target sampled already) stops it:
        // the budget would grow until the duration overflows.
        while measured.worst() <= eps
            && measured.n_sampled < self.n_targets
            && measured.worst() * noise_margin(measured.n_sampled) > eps
            && measured.n_sampled < MAX_VERIFY_SAMPLE
        {
            let before = measured.n_sampled;
            budget = budget.saturating_mul(RESAMPLE_FACTOR as u32);
            min_sample = (RESAMPLE_FACTOR * measured.n_sampled).min(MAX_VERIFY_SAMPLE);
            measured = self.estimate_error_at(points, charges, values, budget, min_sample, truth);
            if measured.n_sampled <= before {
                break;
            }
        }
        VerificationAttempt {
            order: self.order,
            svd_tolerance: self
                .config_from_chosen
                .as_ref()
                .map(|_| chosen.svd_tolerance),
            predicted_error: chosen.predicted_error,
            measured,
            evaluation_s: timings.total.as_secs_f64(),
            check_s: t.elapsed().as_secs_f64(),
        }
    }

    /// The sources and (when they are a separate set) the targets, in the
    /// caller's order and coordinates (`f64`), rebuilt from the copy the
    /// FMM keeps (in tree order, relative to the tree's coordinate origin;
    /// periodic points wrapped into the cell). Exact in `f64` (the
    /// differences to the origin are exact, see the `coordinates` module);
    /// in `f32` the relative coordinates were rounded to `f32`. So a caller
    /// of an `f64` run that needs its points only now and then need not
    /// hold them (`24` bytes a point).
    pub fn points_f64(&self) -> (Vec<f64>, Option<Vec<f64>>) {
        let p = self.original_points();
        (p.sources, p.targets)
    }

    /// Sources and targets in the caller's original order (absolute
    /// coordinates, `f64`): the stored points are in tree order and
    /// relative to the domain's centre.
    fn original_points(&self) -> OriginalPoints {
        let mut sources = vec![0.0f64; 3 * self.n_sources];
        let mut targets = vec![
            0.0f64;
            if self.separate_targets {
                3 * self.n_targets
            } else {
                0
            }
        ];
        for part in &self.parts {
            part.write_original_points(&mut sources, &mut targets);
        }
        OriginalPoints {
            sources,
            targets: self.separate_targets.then_some(targets),
        }
    }
}

/// The points of an [`Fmm`] in the caller's order, absolute, `f64`.
struct OriginalPoints {
    sources: Vec<f64>,
    /// `None`: the targets are the sources (not held twice).
    targets: Option<Vec<f64>>,
}

impl OriginalPoints {
    fn targets(&self) -> &[f64] {
        self.targets.as_deref().unwrap_or(&self.sources)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
    use ferrofmm_kernels::{EvalMode, Laplace3d};

    /// A choice that is too optimistic (order 3 for 1e-6) is caught by the
    /// estimate and repaired by raising the order to the one the calibrated
    /// model needs, and the report says what happened.
    #[test]
    fn too_low_an_order_is_raised() {
        let n = 6000;
        let points: Vec<f64> = Geometry::Cube.points(n, 5);
        let q: Vec<f64> = charges(n, 6);
        // A leaf size given: a tree (6000 points would be a direct sum).
        let mut fmm = FmmBuilder::new(&points)
            .tolerance(1e-6)
            .leaf_size(64)
            .mode(EvalMode::PotentialGradient)
            .build_svd()
            .unwrap();
        let chosen = fmm.chosen_parameters().unwrap().clone();
        assert!(chosen.order > 4);
        // Sabotage: pretend the chooser had taken order 3.
        fmm.rebuild_at_order(ChosenParameters {
            order: 3,
            ..chosen.clone()
        })
        .unwrap();
        assert_eq!(fmm.order(), 3);
        let out = fmm.evaluate_verified(&q).unwrap();
        let v = out.verification.unwrap();
        let orders: Vec<usize> = v.attempts.iter().map(|a| a.order).collect();
        assert!(v.attempts[0].measured.worst() > 1e-6);
        // The miss (about 1e-3 against a prediction of about 1e-6) is
        // measured, and the order jumps to what the calibrated model says
        // is needed: more than one step at once, met on the first raise.
        assert_eq!(orders.len(), 2, "{v:?}");
        assert!(orders[1] >= 6, "{orders:?}");
        assert!(v.met, "{v:?}");
        assert!(v.attempts[1].measured.potential < v.attempts[0].measured.potential);
        assert_eq!(fmm.order(), orders[1]);
        assert!(v.rebuild_s > 0.0);
        // The values returned are those of the last attempt.
        assert_eq!(out.values, fmm.evaluate(&q).unwrap());
        let e = relative_errors(
            &Laplace3d,
            EvalMode::PotentialGradient,
            &points,
            &q,
            &points,
            &out.values,
            &sample_indices(n, 997),
        );
        assert!(e.potential < 1e-6, "{e:?}");
        // The estimate tracks the real error within sampling noise.
        let est = v.measured();
        assert!(est.potential / e.potential > 0.3 && est.potential / e.potential < 3.0);
        // A second call starts from the raised order and needs no raise.
        let again = fmm.evaluate_verified(&q).unwrap().verification.unwrap();
        assert_eq!(again.attempts[0].order, orders[1]);
        assert_eq!(again.attempts.len(), 1);
        assert!(again.met, "{again:?}");
    }

    #[test]
    fn estimate_is_cheap_next_to_the_evaluation() {
        let n = 40_000;
        let points: Vec<f64> = Geometry::Sphere.points(n, 5);
        let q: Vec<f64> = charges(n, 6);
        let mut fmm = FmmBuilder::new(&points)
            .tolerance(1e-5)
            .build_svd()
            .unwrap();
        let out = fmm.evaluate_verified(&q).unwrap();
        let v = out.verification.unwrap();
        let a = v.last();
        assert!(a.measured.n_sampled >= MIN_VERIFY_SAMPLE);
        assert!(a.measured.n_sampled <= MAX_VERIFY_SAMPLE);
        assert!(v.met);
    }
}
