//! Stokes double layers (stresslets) and the pressure across ranks: a
//! distributed Stokeslet FMM and, where the request needs one, a
//! distributed Laplace FMM on the same points, each a [`DistSolver`].
//!
//! The maths is the single-machine one ([`ferrofmm_fmm::stokes_layers`]):
//! the stresslet `(m, n)` is the Stokeslet's force dipole
//! `D = m n^T + n m^T` plus a source flow `-grad` of the Laplace potential
//! of charges `(m . n) / mu`, and every pressure is a Laplace field.
//! [`StokesLayerPlan`] turns each rank's forces and stresslets into the
//! two FMMs' densities (a source's densities depend on that source alone)
//! and their values into velocity and pressure (a target's on that target
//! alone), so each rank passes its own rows and gets its own rows back, in
//! its input order.
//!
//! Each FMM is planned for the same request (order, or tolerance and
//! verification, scheme, cache) and verified on its own at its first
//! evaluation, as on one machine: the Stokeslet FMM on the forces and
//! force dipoles, the Laplace FMM on its first vector. Then what is
//! delivered is checked: velocity and pressure at the sampled targets
//! against direct sums of the same pieces
//! ([`DistStokesLayers::sampled_errors`]), and while the worst error
//! exceeds the tolerance the Laplace FMM is raised one order (its
//! dipole fields' derivatives make the pressure; the Stokeslet FMM
//! already meets the tolerance on its own densities).

use ferrofmm_fmm::{StokesErrors, StokesLayerPlan, StokesRequest, StokesValues};
use ferrofmm_kernels::{EvalMode, Kernel, KernelChoice, Laplace3d, Stokes3d};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::agree_message;
use crate::{DistError, DistRequest, DistSolution, DistSolver, EvalStats};
use ferrofmm_fmm::verify::MAX_VERIFY_RETRIES;

/// One evaluation of [`DistStokesLayers`] on this rank.
#[derive(Clone, Debug)]
pub struct DistStokesSolution {
    /// Velocity (and pressure) at this rank's targets, in its input order
    /// ([`StokesValues`]' layout).
    pub values: StokesValues<f64>,
    /// Both FMMs' times and bytes on this rank, added up (the last
    /// evaluation of each, after a raised order).
    pub stats: EvalStats,
    /// The Stokeslet FMM's errors `[velocity, velocity gradient]` and
    /// whether they met the tolerance, when this evaluation verified it.
    pub stokes_check: Option<([f64; 2], bool)>,
    /// The Laplace FMM's errors `[potential, derivatives]` on its first
    /// vector and whether they met the tolerance, when verified.
    pub laplace_check: Option<([f64; 2], bool)>,
    /// When this evaluation was verified: the errors of what is delivered,
    /// velocity and pressure, against direct sums at the sampled targets
    /// (after any order the check raised).
    pub check: Option<StokesErrors>,
    /// Whether the delivered values met the tolerance (`None`: not
    /// verified this time).
    pub verified: Option<bool>,
}

/// Forces and stresslets with the pressure, across ranks (see the
/// [module docs](self)).
pub struct DistStokesLayers<C: Communicator + 'static> {
    plan: StokesLayerPlan,
    stokes: DistSolver<C>,
    laplace: Option<DistSolver<C>>,
}

impl<C: Communicator + 'static> DistStokesLayers<C> {
    /// Plans and builds both FMMs for this rank's `points` (interleaved
    /// `xyz`, any number including none) and, when given, its own
    /// `targets` (otherwise the points are the targets). `request` names
    /// the Stokes kernel and says the mode (potentials: velocity and
    /// pressure; gradients: theirs too), the order or tolerance, the
    /// scheme and the cache; its `sources` are set from `layers`. A
    /// collective.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: a kernel other than Stokes, a
    /// request with neither forces nor stresslets, Hessians; otherwise as
    /// [`DistSolver::build`].
    pub fn build(
        comm: &C,
        points: Vec<f64>,
        targets: Option<Vec<f64>>,
        request: DistRequest,
        layers: StokesRequest,
    ) -> Result<Self, DistError> {
        let plan = agree_message(comm, plan_of(&request, layers))?;
        let solver = |kernel: KernelChoice, part: Option<ferrofmm_fmm::LaplacePart>| {
            let mut r = request.clone();
            r.kernel = kernel;
            match part {
                Some(p) => {
                    r.sources = p.sources;
                    r.mode = p.mode;
                }
                None => r.sources = plan.stokes_sources(),
            }
            match &targets {
                None => DistSolver::build(comm, points.clone(), r),
                Some(t) => DistSolver::build_with_targets(comm, points.clone(), t.clone(), r),
            }
        };
        let laplace = match plan.laplace_part() {
            Some(part) => {
                let laplace = KernelChoice::of(&Laplace3d).expect("Laplace is registered");
                Some(solver(laplace, Some(part))?)
            }
            None => None,
        };
        let stokes = solver(request.kernel, None)?;
        Ok(DistStokesLayers {
            plan,
            stokes,
            laplace,
        })
    }

    /// Velocity (and pressure) at this rank's targets for its `forces`
    /// (three values per point, input order) and stresslets `(m, n)`
    /// (three values each), as the request says. The first evaluation of
    /// a tolerance is verified, each FMM on its own (raising its order
    /// while it misses, as [`DistSolver::evaluate`]). A collective.
    ///
    /// # Errors
    /// The same [`DistError`] on every rank: densities missing, not asked
    /// for or of the wrong length on some rank; otherwise as
    /// [`DistSolver::evaluate`].
    pub fn evaluate(
        &mut self,
        comm: &C,
        forces: Option<&[f64]>,
        stresslets: Option<(&[f64], &[f64])>,
    ) -> Result<DistStokesSolution, DistError> {
        let n = self.stokes.points().len() / 3;
        let densities = self
            .plan
            .densities(n, forces, stresslets)
            .map_err(|e| e.to_string());
        let (stokes_q, laplace_q) = agree_message(comm, densities)?;
        let stokes = self.stokes.evaluate(comm, &stokes_q)?;
        let check = |s: &DistSolution| s.errors.zip(s.verified);
        let stokes_check = check(&stokes);
        let mut stats = stokes.stats.clone();
        let (mut laplace_values, laplace_check) = match &mut self.laplace {
            Some(solver) => {
                let (values, s, first) = laplace_vectors(comm, solver, &self.plan, n, &laplace_q)?;
                stats.merge(&s);
                (Some(values), first)
            }
            None => (None, None),
        };
        let m = self.n_targets();
        let mut values = self
            .plan
            .combine(stokes.values.clone(), laplace_values.as_deref(), m);
        // Each FMM checked itself on its own densities; what is delivered
        // combines them (the pressure of a stresslet is a sum of the
        // Laplace dipole fields' derivatives, whose errors add up and may
        // cancel less than the fields do), so it is checked too, and the
        // Laplace FMM raised while it misses.
        let verifying = stokes_check.is_some() || laplace_check.is_some();
        let (mut combined, mut met) = (None, None);
        if let (true, Some(eps)) = (verifying, self.stokes.plan().tolerance) {
            let k = self.stokes.samples();
            let mut raised = 0;
            loop {
                let e = self.sampled_errors(comm, forces, stresslets, &values, k)?;
                combined = Some(e);
                met = Some(e.worst() <= eps);
                let Some(solver) = self.laplace.as_mut() else {
                    break;
                };
                if e.worst() <= eps
                    || raised >= MAX_VERIFY_RETRIES
                    || solver.plan().order >= ferrofmm_field::MAX_ORDER
                {
                    break;
                }
                solver.raise_order(comm)?;
                raised += 1;
                let (again, s, _) = laplace_vectors(comm, solver, &self.plan, n, &laplace_q)?;
                stats.merge(&s);
                laplace_values = Some(again);
                values = self
                    .plan
                    .combine(stokes.values.clone(), laplace_values.as_deref(), m);
            }
        }
        Ok(DistStokesSolution {
            values,
            stats,
            stokes_check,
            laplace_check,
            check: combined,
            verified: met,
        })
    }

    /// This rank's number of targets (its points without separate
    /// targets).
    pub fn n_targets(&self) -> usize {
        self.stokes.targets().unwrap_or(self.stokes.points()).len() / 3
    }

    /// The plan: what the two FMMs carry and how they combine.
    pub fn plan(&self) -> &StokesLayerPlan {
        &self.plan
    }

    /// The Stokeslet FMM.
    pub fn stokes(&self) -> &DistSolver<C> {
        &self.stokes
    }

    /// The Laplace FMM, when the request needs one.
    pub fn laplace(&self) -> Option<&DistSolver<C>> {
        self.laplace.as_ref()
    }
}

/// The Laplace FMM's values for every vector of `laplace_q` (`n` sources
/// each), one vector after another, their figures added up, and the
/// first vector's check when it was verified. Every rank evaluates every
/// vector (a rank without points passes empty ones): each is a
/// collective.
#[allow(clippy::type_complexity)]
fn laplace_vectors<C: Communicator + 'static>(
    comm: &C,
    solver: &mut DistSolver<C>,
    plan: &StokesLayerPlan,
    n: usize,
    laplace_q: &[f64],
) -> Result<(Vec<f64>, EvalStats, Option<([f64; 2], bool)>), DistError> {
    let part = plan.laplace_part().expect("a plan with a Laplace part");
    let per = n * part.sources.values_per_source();
    let mut values = Vec::new();
    let mut stats = EvalStats::default();
    let mut first = None;
    for v in 0..part.vectors {
        let s = solver.evaluate(comm, &laplace_q[v * per..(v + 1) * per])?;
        if v == 0 {
            first = s.errors.zip(s.verified);
        }
        stats.merge(&s.stats);
        values.extend(s.values);
    }
    Ok((values, stats, first))
}

/// The plan of a request for the Stokes kernel (viscosity 1, as the
/// registry's `stokes`).
fn plan_of(request: &DistRequest, layers: StokesRequest) -> Result<StokesLayerPlan, String> {
    if KernelChoice::of(&Stokes3d::default()) != Some(request.kernel) {
        return Err(format!(
            "stresslets and the pressure belong to the Stokes kernel, not {}",
            request.kernel.name()
        ));
    }
    StokesLayerPlan::new(layers, request.mode, Stokes3d::default().viscosity)
        .map_err(|e| e.to_string())
}

impl<C: Communicator + 'static> DistStokesLayers<C> {
    /// Relative L2 errors of `values` (this rank's [`DistStokesSolution`]
    /// values for `forces` and `stresslets`) at `samples` targets spread
    /// over the global input order, against direct sums over every rank's
    /// sources of the same pieces (the Stokeslet with forces and force
    /// dipoles, the Laplace vectors) in `f64`, combined as the FMMs' are.
    /// A collective.
    ///
    /// # Errors
    /// As [`DistStokesLayers::evaluate`] for the densities.
    pub fn sampled_errors(
        &self,
        comm: &C,
        forces: Option<&[f64]>,
        stresslets: Option<(&[f64], &[f64])>,
        values: &StokesValues<f64>,
        samples: usize,
    ) -> Result<StokesErrors, DistError> {
        let sources = self.stokes.points();
        let targets = self.stokes.targets().unwrap_or(sources);
        let densities = self
            .plan
            .densities(sources.len() / 3, forces, stresslets)
            .map_err(|e| e.to_string());
        let (stokes_q, laplace_q) = agree_message(comm, densities)?;
        let (wv, wp) = self.plan.values_per_target();
        let w = wv + wp;
        let rows = self.plan.rows(values);
        let Some(shared) = crate::accuracy::gather_sample(comm, targets, &rows, w, samples) else {
            return Ok(StokesErrors {
                n_sampled: 0,
                velocity: 0.0,
                velocity_gradient: None,
                pressure: None,
                pressure_gradient: None,
            });
        };
        let k = shared.len() / (3 + w);
        let (at, got) = shared.split_at(3 * k);
        // This rank's sources at the samples, then the sum over ranks.
        let mode = if self.plan.has_gradient() {
            EvalMode::PotentialGradient
        } else {
            EvalMode::Potential
        };
        let stokes_kernel = Stokes3d::default();
        let mut velocity = vec![0.0; k * stokes_kernel.values_per_target(mode)];
        stokes_kernel.evaluate_sources(
            self.plan.stokes_sources(),
            mode,
            sources,
            &stokes_q,
            at,
            &mut velocity,
        );
        let sum = |v: Vec<f64>| {
            let mut s = vec![0.0; v.len()];
            comm.all_reduce_into(&v[..], &mut s[..], SystemOperation::sum());
            s
        };
        let velocity = sum(velocity);
        let laplace = self.plan.laplace_part().map(|part| {
            let per = sources.len() / 3 * part.sources.values_per_source();
            let wl = part.mode.values_per_target();
            let mut out = vec![0.0; part.vectors * k * wl];
            for (v, o) in out.chunks_exact_mut(k * wl).enumerate() {
                let q = &laplace_q[v * per..(v + 1) * per];
                Laplace3d.evaluate_sources(part.sources, part.mode, sources, q, at, o);
            }
            sum(out)
        });
        let want = self
            .plan
            .rows(&self.plan.combine(velocity, laplace.as_deref(), k));
        let error = |lo: usize, hi: usize| {
            let (mut num, mut den) = (0.0, 0.0);
            for (g, d) in got.chunks_exact(w).zip(want.chunks_exact(w)) {
                for c in lo..hi {
                    num += (g[c] - d[c]) * (g[c] - d[c]);
                    den += d[c] * d[c];
                }
            }
            if den > 0.0 {
                (num / den).sqrt()
            } else {
                num.sqrt()
            }
        };
        let gradient = self.plan.has_gradient();
        Ok(StokesErrors {
            n_sampled: k,
            velocity: error(0, 3),
            velocity_gradient: gradient.then(|| error(3, 12)),
            pressure: (wp > 0).then(|| error(wv, wv + 1)),
            pressure_gradient: (wp > 1).then(|| error(wv + 1, wv + 4)),
        })
    }
}
