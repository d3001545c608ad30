//! What a run is given: its points and densities ([`Input`],
//! [`densities`]) and its parameters ([`Settings`]).

use std::path::PathBuf;

use ferrofmm_field::CacheSetting;
use ferrofmm_fmm::{Charges, Geometry};
use ferrofmm_kernels::{EvalMode, SourceKind};

use crate::commands::{KernelArg, PrecisionArg, SchemeArg};

/// Where the points and charges come from.
#[derive(Clone, Debug)]
pub enum Input {
    /// A built-in geometry and built-in charges; the targets are the sources.
    Generated {
        /// The distribution.
        geometry: Geometry,
        /// How the charges are drawn.
        charges: Charges,
        /// Number of points.
        n: usize,
        /// Random seed.
        seed: u64,
        /// The points, once made (by the automatic choices, which need
        /// them before the run): `None` until then.
        points: Option<Vec<f64>>,
    },
    /// Points and densities read from files (interleaved `f64`).
    Given {
        /// Sources.
        sources: Vec<f64>,
        /// Targets (`None`: the sources).
        targets: Option<Vec<f64>>,
        /// One charge per source (`None`: dipoles only).
        charges: Option<Vec<f64>>,
        /// One dipole vector per source, interleaved (`None`: charges only).
        dipoles: Option<Vec<f64>>,
        /// Stokes stresslets: strengths `m` and orientations `n`, three
        /// values each per source (`None`: none).
        stresslets: Option<(Vec<f64>, Vec<f64>)>,
    },
}

/// The source kind and interleaved densities of charges and / or dipoles
/// (`[q]`, `[nx, ny, nz]` or `[q, nx, ny, nz]` per source).
pub fn densities(
    charges: Option<Vec<f64>>,
    dipoles: Option<Vec<f64>>,
    components: usize,
) -> (SourceKind, Vec<f64>) {
    match (charges, dipoles) {
        (Some(q), None) => (SourceKind::Charge, q),
        (None, Some(n)) => (SourceKind::Dipole, n),
        (Some(q), Some(n)) => (
            SourceKind::ChargeDipole,
            q.chunks_exact(components)
                .zip(n.chunks_exact(3 * components))
                .flat_map(|(q, n)| q.iter().chain(n).copied())
                .collect(),
        ),
        (None, None) => (SourceKind::Charge, Vec::new()),
    }
}

/// Parameters of one run.
#[derive(Clone, Debug)]
pub struct Settings {
    /// `"demo"` or `"eval"`, for the report.
    pub command: &'static str,
    /// Expansion order (`None`: chosen).
    pub order: Option<usize>,
    /// Points per leaf at most (`None`: chosen).
    pub leaf_size: Option<usize>,
    /// M2L scheme.
    pub scheme: SchemeArg,
    /// Float type.
    pub precision: PrecisionArg,
    /// Potential and gradient (true) or potential only.
    pub gradients: bool,
    /// Hessians too (implies gradients).
    pub hessians: bool,
    /// The kernel.
    pub kernel: KernelArg,
    /// Evaluations to time (at least 1).
    pub repeats: usize,
    /// Targets to compare with direct summation (0: no check).
    pub check: usize,
    /// The operator cache (`--cache-dir`, `--no-cache`, else the default
    /// folder).
    pub cache: CacheSetting,
    /// Requested accuracy: parameters chosen by the library (`None` with
    /// no order either: [`ferrofmm_fmm::DEFAULT_TOLERANCE`]).
    pub tolerance: Option<f64>,
    /// Whether `tolerance` is the default one (set by [`run`](super::run); the report
    /// says so).
    pub default_tolerance: bool,
    /// Check the tolerance after evaluating.
    pub verify: bool,
    /// Precompute even beyond the memory limit (`--force`).
    pub force: bool,
    /// `eval --out-sources`: the first `n` targets are the sources, whose
    /// values go to this file (the rest to the output).
    pub out_sources: Option<(PathBuf, usize)>,
    /// Write a `.npy` output as complex numbers (the densities came as a
    /// complex `.npy` array); the values are then `re, im` pairs.
    pub complex_output: bool,
    /// Periodic boundaries (`--box`), `None` for free space.
    pub periodic: Option<ferrofmm_fmm::Periodic>,
    /// The Stokes pressure too (`eval --pressure`).
    pub pressure: bool,
}

impl Settings {
    /// The evaluation mode of `gradients` and `hessians`.
    pub fn mode(&self) -> EvalMode {
        if self.hessians {
            EvalMode::PotentialGradientHessian
        } else if self.gradients {
            EvalMode::PotentialGradient
        } else {
            EvalMode::Potential
        }
    }
}

/// The built-in points of `input`, or its given sources and targets.
pub(super) fn points_of(input: &Input) -> (std::borrow::Cow<'_, [f64]>, Option<&[f64]>) {
    match input {
        Input::Generated {
            points: Some(p), ..
        } => (p.as_slice().into(), None),
        Input::Generated {
            geometry, n, seed, ..
        } => (geometry.points::<f64>(*n, *seed).into(), None),
        Input::Given {
            sources, targets, ..
        } => (sources.as_slice().into(), targets.as_deref()),
    }
}
