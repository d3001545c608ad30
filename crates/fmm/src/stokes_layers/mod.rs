//! Stokes double layers (stresslets) and the pressure, composed from the
//! Stokeslet FMM and one Laplace FMM on the same points.
//!
//! # Maths
//! With `d = y - x` (target minus source), `r = |d|` and viscosity `mu`,
//! FMM3D's `stfmm3d` sums, at `mu = 1`,
//!
//! ```text
//! velocity of a force f:                 u = (f / r + d (d . f) / r^3) / (8 pi mu)
//! pressure of a force f:                 p = f . d / (4 pi r^3)
//! velocity of a stresslet (m, n):        u = 3 d (d . m)(d . n) / (4 pi mu r^5)
//! pressure of a stresslet (m, n):        p = (6 (d . m)(d . n) / r^5 - 2 (m . n) / r^3) / (4 pi)
//! ```
//!
//! (`m` is FMM3D's `strslet`, `n` its `strsvec`, usually a surface normal).
//! The stresslet is the [force dipole](ferrofmm_kernels::Stokes3d)
//! `D = m n^T + n m^T` of the Stokeslet plus a point-source flow
//!
//! ```text
//! u = Stokeslet dipole D (velocity, /mu)  +  (m . n) d / (4 pi mu r^3)
//! ```
//!
//! The source flow carries a net flux no Stokeslet density can, so the
//! KIFMM's Stokeslet expansions cannot hold it: it is `-grad` of the
//! Laplace potential of charges `(m . n) / mu`. Every pressure is a
//! Laplace field too: a force's is the Laplace dipole potential
//! `n . d / (4 pi r^3)` with `n = f` (our Laplace dipole convention), and a
//! force dipole's is `p = -sum_k d_k phi_k` with `phi_k` the Laplace dipole
//! potential of the vectors `D_k.`. So one Laplace FMM with up to five
//! density vectors completes the Stokes FMM:
//!
//! | vector | densities | gives |
//! |---|---|---|
//! | source | charges `(m . n) / mu` | `u -= grad phi`, `grad u -= hess phi` |
//! | force pressure | dipoles `f` | `p += phi`, `grad p += grad phi` |
//! | dipole pressure `k` | dipoles `D_k.` | `p -= d_k phi`, `d_j p -= hess_jk phi` |
//!
//! Velocity gradients of stresslets, and pressure gradients of stresslets,
//! need the Laplace Hessian; pressure gradients of forces its gradient.
//! The Stokes FMM sees forces and the force dipoles `D`
//! ([`SourceKind::ChargeDipole`](ferrofmm_kernels::SourceKind::ChargeDipole) when both).
//!
//! [`StokesLayerPlan`] (module `plan`) holds the two local steps, the
//! densities of each source and the combination at each target, so that
//! any pair of FMMs on the same points can serve it (the distributed FMM
//! of `ferrofmm-mpi` does).
//!
//! Both FMMs take the caller's builder settings (points, targets, order or
//! tolerance, leaf size, cache, threads); each is verified on its own when
//! a tolerance is given. Periodic cells are refused (the Laplace pieces
//! would need their own lattice conventions).

mod plan;

use ferrofmm_kernels::{Kernel, Laplace3d, Real, Stokes3d};

use crate::{BuildScheme, Fmm, FmmBuilder, FmmError, Verification};
pub use plan::{LaplacePart, StokesLayerPlan, StokesRequest, StokesValues};

/// [`StokesValues`] with their times and the verification of each FMM
/// (the first evaluation of a tolerance; see [`Fmm::evaluate_verified`]).
#[derive(Clone, Debug)]
pub struct StokesEvaluation<T> {
    /// The values.
    pub values: StokesValues<T>,
    /// Time per operator, both FMMs added up (the verification's direct
    /// sums not included).
    pub timings: crate::EvalTimings,
    /// The Stokes FMM's verification.
    pub stokes: Option<Verification>,
    /// The Laplace FMM's verification (when there is one).
    pub laplace: Option<Verification>,
    /// The check of what is delivered, when both FMMs were verified:
    /// velocity and pressure against direct sums of the same pieces at
    /// sampled targets, one attempt per Laplace order (each attempt's
    /// `potential` the worst of velocity and pressure, its `gradient` the
    /// worst of their gradients).
    pub delivered: Option<Verification>,
}

impl<T> StokesEvaluation<T> {
    /// The check to report: the first that missed (Stokes, Laplace, then
    /// what is delivered), else the Stokes one (`None` when nothing was
    /// checked).
    pub fn verification(&self) -> Option<&Verification> {
        [&self.stokes, &self.laplace, &self.delivered]
            .into_iter()
            .flatten()
            .find(|v| !v.met)
            .or(self.stokes.as_ref())
    }
}

/// A Stokes FMM for forces and stresslets with the pressure: a
/// [`Stokes3d`] FMM and, where the request needs one, a [`Laplace3d`] FMM
/// (see the [module docs](self) for the maths).
///
/// ```
/// use ferrofmm_field::FftM2l;
/// use ferrofmm_fmm::{FmmBuilder, StokesLayers, StokesRequest};
/// use ferrofmm_kernels::Stokes3d;
/// let points: Vec<f64> = (0..1500).map(|i| (i as f64 * 0.618).fract()).collect();
/// let m: Vec<f64> = (0..1500).map(|i| (i as f64 * 0.37).sin()).collect();
/// let n: Vec<f64> = (0..1500).map(|i| (i as f64 * 0.91).cos()).collect();
/// let builder = FmmBuilder::new(&points).kernel(Stokes3d::default()).tolerance(1e-6);
/// let request = StokesRequest { forces: false, stresslets: true, pressure: true };
/// let layers = StokesLayers::<f64, FftM2l<f64>>::build(builder, request).unwrap();
/// let out = layers.evaluate(None, Some((&m, &n))).unwrap();
/// assert_eq!(out.velocity.len(), 3 * 500);
/// assert_eq!(out.pressure.unwrap().len(), 500);
/// ```
pub struct StokesLayers<T: Real, S: BuildScheme<T>> {
    stokes: Fmm<T, Stokes3d, S>,
    laplace: Option<Fmm<T, Laplace3d, S>>,
    plan: StokesLayerPlan,
}

impl<T: Real, S: BuildScheme<T>> StokesLayers<T, S> {
    /// Build from a [`Stokes3d`] builder (points, targets, mode
    /// [`EvalMode::Potential`](ferrofmm_kernels::EvalMode::Potential) or
    /// [`EvalMode::PotentialGradient`](ferrofmm_kernels::EvalMode::PotentialGradient), order or
    /// tolerance, cache, ...): its source kind is set from `request`; the
    /// Laplace FMM, when needed, takes the same settings with its own
    /// source kind and mode.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when the request carries nothing or
    /// the builder is periodic or asks for Hessians; otherwise as the
    /// builds.
    pub fn build(
        builder: FmmBuilder<'_, T, Stokes3d>,
        request: StokesRequest,
    ) -> Result<Self, FmmError> {
        let plan = StokesLayerPlan::new(request, builder.mode, builder.kernel.viscosity)?;
        if builder.periodic.is_some() && (request.stresslets || request.pressure) {
            return Err(FmmError::InvalidParameter(
                "stresslets and the pressure run in free space only (no periodic cell)".into(),
            ));
        }
        let laplace = match plan.laplace_part() {
            None => None,
            Some(part) => {
                let mut b = builder
                    .clone()
                    .kernel(Laplace3d)
                    .source_kind(part.sources)
                    .mode(part.mode);
                // A model made for the Stokeslet does not describe Laplace.
                b.tuning_model = None;
                Some(S::build(b)?)
            }
        };
        let stokes = S::build(builder.source_kind(plan.stokes_sources()))?;
        Ok(StokesLayers {
            stokes,
            laplace,
            plan,
        })
    }

    /// The Stokes FMM.
    pub fn stokes(&self) -> &Fmm<T, Stokes3d, S> {
        &self.stokes
    }

    /// The Laplace FMM, when the request needs one.
    pub fn laplace(&self) -> Option<&Fmm<T, Laplace3d, S>> {
        self.laplace.as_ref()
    }

    /// What this evaluates.
    pub fn request(&self) -> StokesRequest {
        self.plan.request()
    }

    /// The plan: what the two FMMs carry and how their values combine.
    pub fn plan(&self) -> &StokesLayerPlan {
        &self.plan
    }

    /// Whether velocity and pressure gradients are computed.
    pub fn has_gradient(&self) -> bool {
        self.plan.has_gradient()
    }

    /// Report the passes' progress of both FMMs to `f`
    /// ([`Fmm::set_progress`]).
    pub fn set_progress(&mut self, f: Option<std::sync::Arc<crate::ProgressFn>>) {
        if let Some(laplace) = &mut self.laplace {
            laplace.set_progress(f.clone());
        }
        self.stokes.set_progress(f);
    }

    /// Velocities (and pressures) of `forces` (three values per source)
    /// and stresslets `(m, n)` (three values each per source), as the
    /// request says.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when a density the request needs is
    /// missing or one it does not carry is given; [`FmmError::DensityCount`]
    /// for a wrong length; otherwise as [`Fmm::evaluate`].
    pub fn evaluate(
        &self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<StokesValues<T>, FmmError> {
        self.evaluate_timed(forces, stresslets).map(|e| e.values)
    }

    /// As [`StokesLayers::evaluate`], with the time of each operator (both
    /// FMMs' added up) in [`StokesEvaluation::timings`].
    ///
    /// # Errors
    /// As [`StokesLayers::evaluate`].
    pub fn evaluate_timed(
        &self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<StokesEvaluation<T>, FmmError> {
        let (stokes_densities, laplace_densities) =
            self.plan
                .densities(self.stokes.n_sources(), forces, stresslets)?;
        let (velocity, mut timings) = self.stokes.evaluate_timed(&stokes_densities)?;
        let laplace = match (&self.laplace, self.plan.laplace_part()) {
            (Some(fmm), Some(part)) => {
                let per = fmm.n_sources() * part.sources.values_per_source();
                let mut values = Vec::new();
                for one in laplace_densities.chunks_exact(per) {
                    let (v, t) = fmm.evaluate_timed(one)?;
                    values.extend(v);
                    timings.accumulate(&t);
                }
                Some(values)
            }
            _ => None,
        };
        Ok(StokesEvaluation {
            values: self
                .plan
                .combine(velocity, laplace.as_deref(), self.stokes.n_targets()),
            timings,
            stokes: None,
            laplace: None,
            delivered: None,
        })
    }

    /// As [`StokesLayers::evaluate`], the first evaluation of a tolerance
    /// verified: each FMM on its own, raising its order where it falls
    /// short; then what is delivered (velocity and pressure against direct
    /// sums of the same pieces at sampled targets,
    /// [`StokesEvaluation::delivered`]), raising the Laplace FMM while it
    /// misses (the pressure of a stresslet sums the derivatives of three
    /// Laplace dipole fields, whose errors need not cancel as the fields
    /// do).
    ///
    /// # Errors
    /// As [`StokesLayers::evaluate`].
    pub fn evaluate_verified(
        &mut self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<StokesEvaluation<T>, FmmError> {
        let (stokes_densities, laplace_densities) =
            self.plan
                .densities(self.stokes.n_sources(), forces, stresslets)?;
        let stokes = self.stokes.evaluate_verified(&stokes_densities)?;
        let mut timings = stokes.timings;
        let (laplace, laplace_check) = match (&mut self.laplace, self.plan.laplace_part()) {
            (Some(fmm), Some(part)) => {
                // The first vector is checked (it may raise the order);
                // the others are evaluated at the order it settles on.
                let per = fmm.n_sources() * part.sources.values_per_source();
                let first = fmm.evaluate_verified(&laplace_densities[..per])?;
                timings.accumulate(&first.timings);
                let mut values = first.values;
                for one in laplace_densities[per..].chunks_exact(per) {
                    let (v, t) = fmm.evaluate_timed(one)?;
                    values.extend(v);
                    timings.accumulate(&t);
                }
                (Some(values), first.verification)
            }
            _ => (None, None),
        };
        let m = self.stokes.n_targets();
        let mut values = self
            .plan
            .combine(stokes.values.clone(), laplace.as_deref(), m);
        let delivered = match (&stokes.verification, &laplace_check) {
            (Some(check), Some(_)) => {
                let mut laplace = laplace.unwrap_or_default();
                let d = self.check_delivered(
                    forces,
                    stresslets,
                    check.tolerance,
                    &stokes.values,
                    &laplace_densities,
                    &mut laplace,
                    &mut values,
                    &mut timings,
                )?;
                Some(d)
            }
            _ => None,
        };
        Ok(StokesEvaluation {
            values,
            timings,
            stokes: stokes.verification,
            laplace: laplace_check,
            delivered,
        })
    }

    /// Checks `values` (combined from the Stokes FMM's `velocity` and the
    /// Laplace FMM's `laplace` values) against direct sums at sampled
    /// targets and, while the worst error exceeds `eps`, rebuilds the
    /// Laplace FMM one order up and evaluates its vectors again, at most
    /// [`MAX_VERIFY_RETRIES`](crate::verify::MAX_VERIFY_RETRIES) times.
    #[allow(clippy::too_many_arguments)]
    fn check_delivered(
        &mut self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
        eps: f64,
        velocity: &[T],
        laplace_densities: &[T],
        laplace: &mut Vec<T>,
        values: &mut StokesValues<T>,
        timings: &mut crate::EvalTimings,
    ) -> Result<Verification, FmmError> {
        let m = self.stokes.n_targets();
        let sample = crate::sample_indices(m, crate::verify::MIN_VERIFY_SAMPLE);
        let mut verification = Verification {
            tolerance: eps,
            attempts: Vec::new(),
            met: false,
            rebuild_s: 0.0,
        };
        let mut evaluation_s = timings.total.as_secs_f64();
        loop {
            let t = std::time::Instant::now();
            let e = self.relative_errors(forces, stresslets, values, &sample)?;
            let fmm = self.laplace.as_mut().expect("a Laplace FMM");
            let chosen = fmm.chosen.clone();
            let worst_of = |a: Option<f64>, b: Option<f64>| match (a, b) {
                (None, None) => None,
                (a, b) => Some(a.unwrap_or(0.0).max(b.unwrap_or(0.0))),
            };
            verification
                .attempts
                .push(crate::verify::VerificationAttempt {
                    order: fmm.order(),
                    svd_tolerance: chosen.as_ref().map(|c| c.svd_tolerance),
                    predicted_error: chosen.as_ref().map_or(0.0, |c| c.predicted_error),
                    measured: crate::ErrorReport {
                        n_sampled: e.n_sampled,
                        potential: e.velocity.max(e.pressure.unwrap_or(0.0)),
                        gradient: worst_of(e.velocity_gradient, e.pressure_gradient),
                        hessian: None,
                    },
                    evaluation_s,
                    check_s: t.elapsed().as_secs_f64(),
                });
            if e.worst() <= eps {
                verification.met = true;
                break;
            }
            let Some(mut raised) = chosen else { break };
            if verification.attempts.len() > crate::verify::MAX_VERIFY_RETRIES
                || raised.order >= ferrofmm_field::MAX_ORDER
            {
                break;
            }
            let model = fmm.error_model.clone().unwrap_or_else(|| {
                crate::tuning::ErrorModel::laplace_for(T::PRECISION, fmm.mode())
            });
            raised.order += 1;
            raised.svd_tolerance =
                model.svd_tolerance(raised.order, eps, raised.estimated_work.rounding_ratio);
            raised.svd_rank = None;
            let t = std::time::Instant::now();
            fmm.rebuild_at_order(raised)?;
            verification.rebuild_s += t.elapsed().as_secs_f64();
            laplace.clear();
            let per = fmm.n_sources() * fmm.source_kind().values_per_source();
            let t = std::time::Instant::now();
            for one in laplace_densities.chunks_exact(per) {
                let (v, tv) = fmm.evaluate_timed(one)?;
                laplace.extend(v);
                timings.accumulate(&tv);
            }
            evaluation_s = t.elapsed().as_secs_f64();
            *values = self.plan.combine(velocity.to_vec(), Some(laplace), m);
        }
        Ok(verification)
    }

    /// Relative L2 errors of [`StokesLayers::evaluate`]'s `values` at the
    /// targets `sample` (indices), against direct sums of the same pieces
    /// (the Stokeslet with forces and force dipoles, the Laplace vectors)
    /// in `f64`, combined as the FMM's are.
    ///
    /// # Errors
    /// As [`StokesLayers::evaluate`] for the densities.
    pub fn relative_errors(
        &self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
        values: &StokesValues<T>,
        sample: &[usize],
    ) -> Result<StokesErrors, FmmError> {
        let (stokes_densities, laplace_densities) =
            self.plan
                .densities(self.stokes.n_sources(), forces, stresslets)?;
        let wide = |v: &[T]| v.iter().map(|x| x.to_f64()).collect::<Vec<f64>>();
        let (sources, targets) = self.stokes.points_f64();
        let targets = targets.as_deref().unwrap_or(&sources);
        let at: Vec<f64> = sample
            .iter()
            .flat_map(|&j| targets[3 * j..3 * j + 3].iter().copied())
            .collect();
        let m = sample.len();
        let mode = self.stokes.mode();
        let stokes_kernel = *self.stokes.kernel();
        let mut velocity = vec![0.0; m * stokes_kernel.values_per_target(mode)];
        stokes_kernel.evaluate_sources(
            self.stokes.source_kind(),
            mode,
            &sources,
            &wide(&stokes_densities),
            &at,
            &mut velocity,
        );
        let laplace = self.plan.laplace_part().map(|part| {
            let lap = wide(&laplace_densities);
            let per = sources.len() / 3 * part.sources.values_per_source();
            let w = part.mode.values_per_target();
            let mut out = vec![0.0; part.vectors * m * w];
            for (q, o) in lap.chunks_exact(per).zip(out.chunks_exact_mut(m * w)) {
                Laplace3d.evaluate_sources(part.sources, part.mode, &sources, q, &at, o);
            }
            out
        });
        let want = self.plan.combine(velocity, laplace.as_deref(), m);
        let (wv, wp) = self.plan.values_per_target();
        let gradient = self.plan.has_gradient();
        let got_velocity: Vec<f64> = sample
            .iter()
            .flat_map(|&j| {
                values.velocity[wv * j..wv * j + wv]
                    .iter()
                    .map(|x| x.to_f64())
            })
            .collect();
        let part = |v: &[f64], w: usize, lo: usize, hi: usize| -> Vec<f64> {
            v.chunks_exact(w).flat_map(|c| c[lo..hi].to_vec()).collect()
        };
        let error = |got: &[f64], want: &[f64]| {
            let num: f64 = got.iter().zip(want).map(|(a, b)| (a - b) * (a - b)).sum();
            let den: f64 = want.iter().map(|b| b * b).sum();
            if den > 0.0 {
                (num / den).sqrt()
            } else {
                num.sqrt()
            }
        };
        let velocity_error = error(
            &part(&got_velocity, wv, 0, 3),
            &part(&want.velocity, wv, 0, 3),
        );
        let velocity_gradient = gradient.then(|| {
            error(
                &part(&got_velocity, wv, 3, 12),
                &part(&want.velocity, wv, 3, 12),
            )
        });
        let (pressure, pressure_gradient) = match (&values.pressure, &want.pressure) {
            (Some(p), Some(pw)) => {
                let got: Vec<f64> = sample
                    .iter()
                    .flat_map(|&j| p[wp * j..wp * j + wp].iter().map(|x| x.to_f64()))
                    .collect();
                (
                    Some(error(&part(&got, wp, 0, 1), &part(pw, wp, 0, 1))),
                    gradient.then(|| error(&part(&got, wp, 1, 4), &part(pw, wp, 1, 4))),
                )
            }
            _ => (None, None),
        };
        Ok(StokesErrors {
            n_sampled: m,
            velocity: velocity_error,
            velocity_gradient,
            pressure,
            pressure_gradient,
        })
    }
}

/// Relative L2 errors of a [`StokesLayers`] evaluation on sampled targets
/// ([`StokesLayers::relative_errors`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StokesErrors {
    /// Targets compared.
    pub n_sampled: usize,
    /// The velocity's error.
    pub velocity: f64,
    /// The velocity gradient's (with gradients).
    pub velocity_gradient: Option<f64>,
    /// The pressure's (with the pressure).
    pub pressure: Option<f64>,
    /// The pressure gradient's (with the pressure and gradients).
    pub pressure_gradient: Option<f64>,
}

impl StokesErrors {
    /// The largest of the errors.
    pub fn worst(&self) -> f64 {
        [
            self.velocity_gradient,
            self.pressure,
            self.pressure_gradient,
        ]
        .into_iter()
        .flatten()
        .fold(self.velocity, f64::max)
    }
}
