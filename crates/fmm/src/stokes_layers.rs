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
//! ([`SourceKind::ChargeDipole`] when both).
//!
//! Both FMMs take the caller's builder settings (points, targets, order or
//! tolerance, leaf size, cache, threads); each is verified on its own when
//! a tolerance is given. Periodic cells are refused (the Laplace pieces
//! would need their own lattice conventions).

use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, Real, SourceKind, Stokes3d};

use crate::{BuildScheme, Fmm, FmmBuilder, FmmError, Verification};

/// What a Stokes evaluation carries and computes beyond the velocity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StokesRequest {
    /// Point forces (Stokeslets), three values per source.
    pub forces: bool,
    /// Stresslets: a strength `m` and an orientation `n` per source.
    pub stresslets: bool,
    /// The pressure (and, with gradients, its gradient) at the targets.
    pub pressure: bool,
}

/// The Laplace companion's shape: which vectors, which kind, which mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LaplacePlan {
    kind: SourceKind,
    mode: EvalMode,
    /// Vector index of the stresslets' source flow.
    source_flow: Option<usize>,
    /// Vector index of the forces' pressure.
    force_pressure: Option<usize>,
    /// First of the three vectors of the force dipoles' pressure.
    dipole_pressure: Option<usize>,
    n_vectors: usize,
}

impl StokesRequest {
    /// What the Stokes FMM's sources carry.
    fn stokes_kind(&self) -> Result<SourceKind, FmmError> {
        match (self.forces, self.stresslets) {
            (true, false) => Ok(SourceKind::Charge),
            (false, true) => Ok(SourceKind::Dipole),
            (true, true) => Ok(SourceKind::ChargeDipole),
            (false, false) => Err(FmmError::InvalidParameter(
                "a Stokes evaluation needs forces, stresslets or both".into(),
            )),
        }
    }

    /// The Laplace FMM this request needs, if any (`gradient`: velocity
    /// and pressure gradients are asked for).
    fn laplace_plan(&self, gradient: bool) -> Option<LaplacePlan> {
        let mut n_vectors = 0;
        let mut next = |used: bool, width: usize| {
            used.then(|| {
                n_vectors += width;
                n_vectors - width
            })
        };
        let source_flow = next(self.stresslets, 1);
        let force_pressure = next(self.pressure && self.forces, 1);
        let dipole_pressure = next(self.pressure && self.stresslets, 3);
        if n_vectors == 0 {
            return None;
        }
        // Stresslets need derivatives of their Laplace fields; a force's
        // pressure is a potential unless its gradient is asked for.
        let mode = match (self.stresslets, gradient) {
            (true, true) => EvalMode::PotentialGradientHessian,
            (true, false) | (false, true) => EvalMode::PotentialGradient,
            (false, false) => EvalMode::Potential,
        };
        let kind = match (source_flow.is_some(), self.pressure) {
            (true, true) => SourceKind::ChargeDipole,
            (true, false) => SourceKind::Charge,
            (false, _) => SourceKind::Dipole,
        };
        Some(LaplacePlan {
            kind,
            mode,
            source_flow,
            force_pressure,
            dipole_pressure,
            n_vectors,
        })
    }
}

/// The results of one [`StokesLayers::evaluate`].
#[derive(Clone, Debug, PartialEq)]
pub struct StokesValues<T> {
    /// Per target the velocity `[u_x, u_y, u_z]`, then with gradients
    /// `d_c u_a` at `3 + 3 c + a` ([`Stokes3d`]'s layout): 3 or 12 values.
    pub velocity: Vec<T>,
    /// Per target `p`, then with gradients `[d_x p, d_y p, d_z p]`: 1 or 4
    /// values; `None` unless [`StokesRequest::pressure`].
    pub pressure: Option<Vec<T>>,
}

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
}

impl<T> StokesEvaluation<T> {
    /// The check to report: the one that missed, else the Stokes one
    /// (`None` when nothing was checked).
    pub fn verification(&self) -> Option<&Verification> {
        match (&self.stokes, &self.laplace) {
            (s, Some(l)) if !l.met && s.as_ref().is_none_or(|s| s.met) => Some(l),
            (s, _) => s.as_ref(),
        }
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
    request: StokesRequest,
    plan: Option<LaplacePlan>,
    gradient: bool,
}

impl<T: Real, S: BuildScheme<T>> StokesLayers<T, S> {
    /// Build from a [`Stokes3d`] builder (points, targets, mode
    /// [`EvalMode::Potential`] or [`EvalMode::PotentialGradient`], order or
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
        let kind = request.stokes_kind()?;
        if builder.periodic.is_some() && (request.stresslets || request.pressure) {
            return Err(FmmError::InvalidParameter(
                "stresslets and the pressure run in free space only (no periodic cell)".into(),
            ));
        }
        if builder.mode.has_hessian() {
            return Err(FmmError::InvalidParameter(
                "the Stokes kernel has no Hessians: use potentials or gradients".into(),
            ));
        }
        let gradient = builder.mode.has_gradient();
        let plan = request.laplace_plan(gradient);
        let laplace = match plan {
            None => None,
            Some(plan) => {
                let mut b = builder
                    .clone()
                    .kernel(Laplace3d)
                    .source_kind(plan.kind)
                    .mode(plan.mode);
                // A model made for the Stokeslet does not describe Laplace.
                b.tuning_model = None;
                Some(S::build(b)?)
            }
        };
        let stokes = S::build(builder.source_kind(kind))?;
        Ok(StokesLayers {
            stokes,
            laplace,
            request,
            plan,
            gradient,
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
        self.request
    }

    /// Whether velocity and pressure gradients are computed.
    pub fn has_gradient(&self) -> bool {
        self.gradient
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
        let (stokes_densities, laplace_densities) = self.densities(forces, stresslets)?;
        let (velocity, mut timings) = self.stokes.evaluate_timed(&stokes_densities)?;
        let laplace = match (&self.laplace, &self.plan) {
            (Some(fmm), Some(plan)) => {
                let per = fmm.n_sources() * plan.kind.values_per_source();
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
            values: self.combine(velocity, laplace.as_deref(), self.stokes.n_targets()),
            timings,
            stokes: None,
            laplace: None,
        })
    }

    /// As [`StokesLayers::evaluate`], the first evaluation of a tolerance
    /// verified (each FMM on its own, raising its order where it falls
    /// short).
    ///
    /// # Errors
    /// As [`StokesLayers::evaluate`].
    pub fn evaluate_verified(
        &mut self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<StokesEvaluation<T>, FmmError> {
        let (stokes_densities, laplace_densities) = self.densities(forces, stresslets)?;
        let stokes = self.stokes.evaluate_verified(&stokes_densities)?;
        let mut timings = stokes.timings;
        let (laplace, laplace_check) = match (&mut self.laplace, &self.plan) {
            (Some(fmm), Some(plan)) => {
                // The first vector is checked (it may raise the order);
                // the others are evaluated at the order it settles on.
                let per = fmm.n_sources() * plan.kind.values_per_source();
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
        Ok(StokesEvaluation {
            values: self.combine(stokes.values, laplace.as_deref(), self.stokes.n_targets()),
            timings,
            stokes: stokes.verification,
            laplace: laplace_check,
        })
    }

    /// The Stokes densities (forces, then `D = m n^T + n m^T`, per source)
    /// and the Laplace vectors of the plan, one after another.
    fn densities(
        &self,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<(Vec<T>, Vec<T>), FmmError> {
        let n = self.stokes.n_sources();
        let check = |what: &str, given: bool, wanted: bool| {
            if given == wanted {
                Ok(())
            } else if wanted {
                Err(FmmError::InvalidParameter(format!(
                    "this Stokes FMM's sources carry {what}: give them"
                )))
            } else {
                Err(FmmError::InvalidParameter(format!(
                    "this Stokes FMM's sources carry no {what}: build it with them"
                )))
            }
        };
        check("forces", forces.is_some(), self.request.forces)?;
        check("stresslets", stresslets.is_some(), self.request.stresslets)?;
        let length = |got: usize| {
            if got == 3 * n {
                Ok(())
            } else {
                Err(FmmError::DensityCount {
                    kind: "stokes",
                    per_source: 3,
                    expected: 3 * n,
                    got,
                })
            }
        };
        if let Some(f) = forces {
            length(f.len())?;
        }
        if let Some((m, v)) = stresslets {
            length(m.len())?;
            length(v.len())?;
        }
        let dipole = |i: usize| -> [T; 9] {
            let (m, v) = stresslets.expect("checked above");
            std::array::from_fn(|kc| {
                let (k, c) = (kc / 3, kc % 3);
                m[3 * i + k] * v[3 * i + c] + v[3 * i + k] * m[3 * i + c]
            })
        };
        let per = 3 * self.stokes.source_kind().values_per_source();
        let mut stokes = Vec::with_capacity(per * n);
        for i in 0..n {
            if let Some(f) = forces {
                stokes.extend_from_slice(&f[3 * i..3 * i + 3]);
            }
            if stresslets.is_some() {
                stokes.extend_from_slice(&dipole(i));
            }
        }
        let Some(plan) = self.plan else {
            return Ok((stokes, Vec::new()));
        };
        let width = plan.kind.values_per_source();
        let mut laplace = vec![T::ZERO; plan.n_vectors * n * width];
        let dipole_at = usize::from(plan.kind == SourceKind::ChargeDipole);
        let inverse_viscosity = T::from_f64(1.0 / self.stokes.kernel().viscosity);
        for i in 0..n {
            let at = |vector: usize| (vector * n + i) * width;
            if let (Some(v), Some((m, nu))) = (plan.source_flow, stresslets) {
                let dot = m[3 * i] * nu[3 * i]
                    + m[3 * i + 1] * nu[3 * i + 1]
                    + m[3 * i + 2] * nu[3 * i + 2];
                laplace[at(v)] = dot * inverse_viscosity;
            }
            if let (Some(v), Some(f)) = (plan.force_pressure, forces) {
                let o = at(v) + dipole_at;
                laplace[o..o + 3].copy_from_slice(&f[3 * i..3 * i + 3]);
            }
            if let Some(v0) = plan.dipole_pressure {
                // The force dipole just written among the Stokes densities.
                let d = &stokes[per * (i + 1) - 9..per * (i + 1)];
                for k in 0..3 {
                    let o = at(v0 + k) + dipole_at;
                    laplace[o..o + 3].copy_from_slice(&d[3 * k..3 * k + 3]);
                }
            }
        }
        Ok((stokes, laplace))
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
        let (stokes_densities, laplace_densities) = self.densities(forces, stresslets)?;
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
        let laplace = self.plan.map(|plan| {
            let lap = wide(&laplace_densities);
            let per = sources.len() / 3 * plan.kind.values_per_source();
            let w = plan.mode.values_per_target();
            let mut out = vec![0.0; plan.n_vectors * m * w];
            for (q, o) in lap.chunks_exact(per).zip(out.chunks_exact_mut(m * w)) {
                Laplace3d.evaluate_sources(plan.kind, plan.mode, &sources, q, &at, o);
            }
            out
        });
        let want = self.combine(velocity, laplace.as_deref(), m);
        let wv = if self.gradient { 12 } else { 3 };
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
        let velocity_gradient = self.gradient.then(|| {
            error(
                &part(&got_velocity, wv, 3, 12),
                &part(&want.velocity, wv, 3, 12),
            )
        });
        let (pressure, pressure_gradient) = match (&values.pressure, &want.pressure) {
            (Some(p), Some(pw)) => {
                let wp = if self.gradient { 4 } else { 1 };
                let got: Vec<f64> = sample
                    .iter()
                    .flat_map(|&j| p[wp * j..wp * j + wp].iter().map(|x| x.to_f64()))
                    .collect();
                (
                    Some(error(&part(&got, wp, 0, 1), &part(pw, wp, 0, 1))),
                    self.gradient
                        .then(|| error(&part(&got, wp, 1, 4), &part(pw, wp, 1, 4))),
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

impl<T: Real, S: BuildScheme<T>> StokesLayers<T, S> {
    /// Add the Laplace fields to the Stokes velocities and form the
    /// pressure (module docs' table).
    fn combine<U: Real>(
        &self,
        mut velocity: Vec<U>,
        laplace: Option<&[U]>,
        m: usize,
    ) -> StokesValues<U> {
        let (Some(plan), Some(lap)) = (self.plan, laplace) else {
            return StokesValues {
                velocity,
                pressure: None,
            };
        };
        let w = plan.mode.values_per_target();
        let field = |vector: usize, j: usize| &lap[(vector * m + j) * w..(vector * m + j + 1) * w];
        // Hessian entry (a, b) in the order xx, yy, zz, xy, xz, yz.
        let hess = |h: &[U], a: usize, b: usize| {
            h[match (a.min(b), a.max(b)) {
                (a, b) if a == b => 4 + a,
                (0, 1) => 7,
                (0, 2) => 8,
                _ => 9,
            }]
        };
        let wv = if self.gradient { 12 } else { 3 };
        if let Some(v) = plan.source_flow {
            for (j, u) in velocity.chunks_exact_mut(wv).enumerate() {
                let phi = field(v, j);
                for a in 0..3 {
                    u[a] -= phi[1 + a];
                }
                if self.gradient {
                    for c in 0..3 {
                        for a in 0..3 {
                            u[3 + 3 * c + a] -= hess(phi, a, c);
                        }
                    }
                }
            }
        }
        let pressure = self.request.pressure.then(|| {
            let wp = if self.gradient { 4 } else { 1 };
            let mut p = vec![U::ZERO; wp * m];
            for (j, pj) in p.chunks_exact_mut(wp).enumerate() {
                if let Some(v) = plan.force_pressure {
                    for (o, x) in pj.iter_mut().zip(field(v, j)) {
                        *o += *x;
                    }
                }
                if let Some(v0) = plan.dipole_pressure {
                    for k in 0..3 {
                        let phi = field(v0 + k, j);
                        pj[0] -= phi[1 + k];
                        if self.gradient {
                            for a in 0..3 {
                                pj[1 + a] -= hess(phi, a, k);
                            }
                        }
                    }
                }
            }
            p
        });
        StokesValues { velocity, pressure }
    }
}
