//! [`StokesLayerPlan`]: how forces and stresslets become the densities of
//! one Stokeslet FMM and one Laplace FMM, and how their fields combine into
//! the velocity and the pressure (the [module docs](super)' table).
//!
//! Both steps are local: the densities of a source depend on that source
//! alone, the combined values of a target on the two FMMs' values at that
//! target alone. So any pair of FMMs on the same sources and targets can
//! serve a plan: [`StokesLayers`](super::StokesLayers) on one machine, two
//! distributed FMMs (`ferrofmm-mpi`) on many, each rank passing its own
//! rows.

use ferrofmm_kernels::{EvalMode, KernelChoice, Real, SourceKind};

use crate::FmmError;

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

/// The Laplace FMM a [`StokesLayerPlan`] needs: what its sources carry,
/// what it evaluates, and how many density vectors it sums (each a
/// separate evaluation on the same FMM, in order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LaplacePart {
    /// Charges (the stresslets' source flow), dipoles (the pressures) or
    /// both.
    pub sources: SourceKind,
    /// Potentials, gradients or Hessians (the stresslets' derivatives).
    pub mode: EvalMode,
    /// Density vectors: 1 to 5.
    pub vectors: usize,
}

impl StokesRequest {
    /// The command lines' check of their stresslet and pressure flags
    /// (`--strslet`, `--strsvec`, `--pressure`; `layered`: any of them is
    /// given) against the kernel and force dipoles (`--dipoles`), with the
    /// message both `ferrofmm eval` and `ferrofmm-mpi eval` print.
    ///
    /// ```
    /// use ferrofmm_fmm::StokesRequest;
    /// use ferrofmm_kernels::KernelChoice;
    /// let stokes = KernelChoice::parse("stokes").unwrap();
    /// let laplace = KernelChoice::parse("laplace").unwrap();
    /// assert!(StokesRequest::check_flags(&stokes, true, false).is_ok());
    /// assert!(StokesRequest::check_flags(&laplace, false, true).is_ok());
    /// assert!(StokesRequest::check_flags(&laplace, true, false).unwrap_err().contains("stokes"));
    /// assert!(StokesRequest::check_flags(&stokes, true, true).is_err());
    /// ```
    ///
    /// # Errors
    /// The message, for flags given to another kernel or with force
    /// dipoles.
    pub fn check_flags(
        kernel: &KernelChoice,
        layered: bool,
        force_dipoles: bool,
    ) -> Result<(), String> {
        if layered && kernel.name() != "stokes" {
            return Err(format!(
                "--strslet, --strsvec and --pressure belong to --kernel stokes, not {}",
                kernel.name()
            ));
        }
        if layered && force_dipoles {
            return Err(
                "--dipoles (force dipoles) do not combine with stresslets or --pressure: give \
                 stresslets as --strslet and --strsvec"
                    .to_string(),
            );
        }
        Ok(())
    }

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

/// The results of one Stokes evaluation with layers and the pressure.
#[derive(Clone, Debug, PartialEq)]
pub struct StokesValues<T> {
    /// Per target the velocity `[u_x, u_y, u_z]`, then with gradients
    /// `d_c u_a` at `3 + 3 c + a` ([`Stokes3d`](ferrofmm_kernels::Stokes3d)'s
    /// layout): 3 or 12 values.
    pub velocity: Vec<T>,
    /// Per target `p`, then with gradients `[d_x p, d_y p, d_z p]`: 1 or 4
    /// values; `None` unless [`StokesRequest::pressure`].
    pub pressure: Option<Vec<T>>,
}

/// How a [`StokesRequest`] is computed by a Stokeslet FMM and a Laplace
/// FMM on the same sources and targets (see the [module docs](super) for
/// the maths): [`StokesLayerPlan::densities`] makes both FMMs' density
/// vectors from the forces and stresslets, [`StokesLayerPlan::combine`]
/// their values into velocity and pressure.
///
/// ```
/// use ferrofmm_fmm::{StokesLayerPlan, StokesRequest};
/// use ferrofmm_kernels::{EvalMode, SourceKind};
/// let request = StokesRequest { forces: true, stresslets: true, pressure: true };
/// let plan = StokesLayerPlan::new(request, EvalMode::PotentialGradient, 1.0).unwrap();
/// // The Stokeslet FMM sees forces and force dipoles; the Laplace FMM the
/// // source flow (charges) and five pressure vectors' worth of dipoles.
/// assert_eq!(plan.stokes_sources(), SourceKind::ChargeDipole);
/// let laplace = plan.laplace_part().unwrap();
/// assert_eq!((laplace.sources, laplace.mode, laplace.vectors),
///            (SourceKind::ChargeDipole, EvalMode::PotentialGradientHessian, 5));
/// // One source: a force along x, a stresslet m = n = e_z.
/// let (stokes, lap) = plan
///     .densities::<f64>(1, Some(&[1.0, 0.0, 0.0]), Some((&[0.0, 0.0, 1.0], &[0.0, 0.0, 1.0])))
///     .unwrap();
/// assert_eq!(stokes.len(), 3 + 9);
/// assert_eq!(stokes[3 + 8], 2.0); // D_zz = 2 m_z n_z
/// assert_eq!(lap.len(), 5 * 4);
/// assert_eq!(lap[0], 1.0); // the source flow's charge, m . n / mu
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StokesLayerPlan {
    request: StokesRequest,
    stokes_kind: SourceKind,
    laplace: Option<LaplacePlan>,
    gradient: bool,
    viscosity: f64,
}

impl StokesLayerPlan {
    /// The plan of `request` for `mode` ([`EvalMode::Potential`]: velocity
    /// and pressure; [`EvalMode::PotentialGradient`]: their gradients too)
    /// and a fluid of `viscosity`.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when the request carries neither
    /// forces nor stresslets, for Hessians (the Stokes kernel has none), or
    /// for a viscosity that is not finite and positive.
    pub fn new(request: StokesRequest, mode: EvalMode, viscosity: f64) -> Result<Self, FmmError> {
        let stokes_kind = request.stokes_kind()?;
        if mode.has_hessian() {
            return Err(FmmError::InvalidParameter(
                "the Stokes kernel has no Hessians: use potentials or gradients".into(),
            ));
        }
        if !(viscosity.is_finite() && viscosity > 0.0) {
            return Err(FmmError::InvalidParameter(format!(
                "the viscosity must be finite and positive, got {viscosity}"
            )));
        }
        let gradient = mode.has_gradient();
        Ok(StokesLayerPlan {
            request,
            stokes_kind,
            laplace: request.laplace_plan(gradient),
            gradient,
            viscosity,
        })
    }

    /// What is computed.
    pub fn request(&self) -> StokesRequest {
        self.request
    }

    /// Whether velocity and pressure gradients are computed.
    pub fn has_gradient(&self) -> bool {
        self.gradient
    }

    /// What the Stokeslet FMM's sources carry: forces
    /// ([`SourceKind::Charge`]), the stresslets' force dipoles
    /// ([`SourceKind::Dipole`], nine values) or both.
    pub fn stokes_sources(&self) -> SourceKind {
        self.stokes_kind
    }

    /// The Laplace FMM this plan needs (`None`: forces alone, without the
    /// pressure).
    pub fn laplace_part(&self) -> Option<LaplacePart> {
        self.laplace.map(|p| LaplacePart {
            sources: p.kind,
            mode: p.mode,
            vectors: p.n_vectors,
        })
    }

    /// Values per target of the velocity (3, or 12 with gradients) and of
    /// the pressure (0 without it, 1, or 4 with gradients).
    pub fn values_per_target(&self) -> (usize, usize) {
        let velocity = if self.gradient { 12 } else { 3 };
        let pressure = match (self.request.pressure, self.gradient) {
            (false, _) => 0,
            (true, false) => 1,
            (true, true) => 4,
        };
        (velocity, pressure)
    }

    /// The names of the pressure's columns in an output file, after the
    /// velocity's: none, `pressure`, or with gradients also
    /// `pressure_grad_x`, `pressure_grad_y`, `pressure_grad_z`.
    pub fn pressure_column_names(&self) -> Vec<String> {
        let (_, wp) = self.values_per_target();
        [
            "pressure",
            "pressure_grad_x",
            "pressure_grad_y",
            "pressure_grad_z",
        ][..wp]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    /// One row per target of `values`: its velocity values, then its
    /// pressure values (the layout of the commands' output files).
    pub fn rows<T: Copy>(&self, values: &StokesValues<T>) -> Vec<T> {
        let (wv, wp) = self.values_per_target();
        match &values.pressure {
            Some(p) if wp > 0 => values
                .velocity
                .chunks_exact(wv)
                .zip(p.chunks_exact(wp))
                .flat_map(|(u, p)| u.iter().chain(p).copied())
                .collect(),
            _ => values.velocity.clone(),
        }
    }

    /// The densities of `n` sources: the Stokeslet FMM's (per source the
    /// force, then the force dipole `D = m n^T + n m^T`, as
    /// [`StokesLayerPlan::stokes_sources`] says) and the Laplace FMM's
    /// vectors one after another (each `n` sources times
    /// [`LaplacePart::sources`]' values; empty without a Laplace part).
    /// `forces` are three values per source, stresslets `(m, n)` three
    /// each.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when a density the request needs is
    /// missing or one it does not carry is given; [`FmmError::DensityCount`]
    /// for a wrong length.
    #[allow(clippy::type_complexity)]
    pub fn densities<T: Real>(
        &self,
        n: usize,
        forces: Option<&[T]>,
        stresslets: Option<(&[T], &[T])>,
    ) -> Result<(Vec<T>, Vec<T>), FmmError> {
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
        let per = 3 * self.stokes_kind.values_per_source();
        let mut stokes = Vec::with_capacity(per * n);
        for i in 0..n {
            if let Some(f) = forces {
                stokes.extend_from_slice(&f[3 * i..3 * i + 3]);
            }
            if stresslets.is_some() {
                stokes.extend_from_slice(&dipole(i));
            }
        }
        let Some(plan) = self.laplace else {
            return Ok((stokes, Vec::new()));
        };
        let width = plan.kind.values_per_source();
        let mut laplace = vec![T::ZERO; plan.n_vectors * n * width];
        let dipole_at = usize::from(plan.kind == SourceKind::ChargeDipole);
        let inverse_viscosity = T::from_f64(1.0 / self.viscosity);
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

    /// Velocity and pressure at `m` targets from the Stokeslet FMM's
    /// `velocity` (its values there, as [`StokesValues::velocity`] lays
    /// them out) and the Laplace FMM's values for each of its vectors, one
    /// vector after another (`laplace`; `None` without a Laplace part).
    ///
    /// # Panics
    /// When `laplace` is shorter than the Laplace part's vectors times `m`
    /// targets (a caller's bug, not an input error).
    pub fn combine<U: Real>(
        &self,
        mut velocity: Vec<U>,
        laplace: Option<&[U]>,
        m: usize,
    ) -> StokesValues<U> {
        let (Some(plan), Some(lap)) = (self.laplace, laplace) else {
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
        let (wv, wp) = self.values_per_target();
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
