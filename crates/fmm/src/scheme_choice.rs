//! The M2L scheme a front end names (`auto`, `svd`, `dense`, `fft`) and
//! the one rule that resolves `auto`, shared by the CLI, the MPI command
//! and the Python module.
//!
//! `auto` resolves, in this order:
//! 1. to the kernel's own rule when its
//!    [description](ferrofmm_kernels::KernelDescription::auto_scheme) says
//!    [`AutoScheme::Fft`] (kernels with several components or operators per
//!    level, whose SVD precomputation costs tens of seconds where FFT's takes
//!    well under one);
//! 2. with a tolerance or an order, and the points, to whichever of SVD
//!    and FFT the cost model predicts faster (for that order, when one is
//!    fixed), the SVD precomputation counted unless the operators are
//!    cached ([`choose_scheme_for`]);
//! 3. otherwise to SVD.
//!
//! ```
//! use ferrofmm_fmm::SchemeChoice;
//! use ferrofmm_kernels::{EvalMode, KernelChoice, Precision};
//! let auto: SchemeChoice = "auto".parse().unwrap();
//! let stokes = KernelChoice::parse("stokes").unwrap();
//! let resolved = auto
//!     .resolve(stokes, None, None, None, EvalMode::Potential, Precision::F64, false, None)
//!     .unwrap();
//! assert_eq!(resolved, SchemeChoice::Fft);
//! assert_eq!(SchemeChoice::Svd.name(), "svd");
//! assert!("fast".parse::<SchemeChoice>().is_err());
//! ```

use std::str::FromStr;

use ferrofmm_field::M2lCostShape;
use ferrofmm_kernels::{AutoScheme, EvalMode, Kernel, KernelChoice, Precision};
use serde::{Deserialize, Serialize};

use crate::FmmError;
use crate::tuning::{MachineCalibration, choose_scheme_for};

/// An M2L translation scheme by name, or `auto`.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize, Default,
)]
#[serde(rename_all = "lowercase")]
pub enum SchemeChoice {
    /// Truncated SVD of the stacked M2L operators (Fong-Darve): fast
    /// evaluation, a precomputation that is cached.
    Svd,
    /// One full matrix per transfer vector: the reference.
    Dense,
    /// Convolution on the surface lattice with FFTs: the dense operator (no
    /// compression), precomputed in milliseconds.
    Fft,
    /// Resolved by [`SchemeChoice::resolve`] (see the module docs of `scheme_choice`).
    #[default]
    Auto,
}

impl SchemeChoice {
    /// Every choice, in the order help texts list them.
    pub const ALL: [SchemeChoice; 4] = [
        SchemeChoice::Auto,
        SchemeChoice::Svd,
        SchemeChoice::Dense,
        SchemeChoice::Fft,
    ];

    /// `"svd"`, `"dense"`, `"fft"` or `"auto"`.
    pub fn name(self) -> &'static str {
        match self {
            SchemeChoice::Svd => "svd",
            SchemeChoice::Dense => "dense",
            SchemeChoice::Fft => "fft",
            SchemeChoice::Auto => "auto",
        }
    }

    /// Help text of a front end's `--scheme` (the CLI and the MPI
    /// command); the kernels whose `auto` is FFT come from the kernel
    /// registry.
    pub fn help() -> String {
        let fft: Vec<String> = KernelChoice::registered()
            .iter()
            .filter(|d| d.auto_scheme == AutoScheme::Fft)
            .map(|d| d.spelling())
            .collect();
        format!(
            "M2L translation scheme: svd (truncated SVD of the stacked operators, Fong-Darve), \
             dense (one full matrix per transfer vector: the reference), fft (convolution on the \
             surface lattice, precomputed in milliseconds) or auto (fft for {}; otherwise svd or \
             fft, whichever the cost model predicts faster for these points and the tolerance or \
             order, the SVD precomputation counted unless --cache-dir is given)",
            fft.join(", ")
        )
    }

    /// Parses a name of [`SchemeChoice::name`].
    ///
    /// # Errors
    /// A one-line message naming the choices.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| {
                format!("unknown M2L scheme {name:?}: use \"auto\", \"svd\", \"dense\" or \"fft\"")
            })
    }

    /// The scheme to run: itself unless `auto`, which resolves by the rule
    /// of the module docs of `scheme_choice` for `kernel`, the tolerance `eps` (the
    /// front end's [`effective_tolerance`](crate::effective_tolerance)),
    /// a fixed `order` and the points (`(sources, targets)`; the targets
    /// `None` when they are the sources) in float type `precision`;
    /// `cached` when the operators come from a cache (the SVD
    /// precomputation is then free); `calibration`, this machine's
    /// calibration of the cost model, if any
    /// ([`MachineCalibration::from_cache`](crate::tuning::MachineCalibration::from_cache)).
    ///
    /// # Errors
    /// What [`choose_scheme_for`] reports for unreachable tolerances or bad
    /// points.
    #[allow(clippy::too_many_arguments)]
    pub fn resolve(
        self,
        kernel: KernelChoice,
        eps: Option<f64>,
        order: Option<usize>,
        points: Option<(&[f64], Option<&[f64]>)>,
        mode: EvalMode,
        precision: Precision,
        cached: bool,
        calibration: Option<&MachineCalibration>,
    ) -> Result<SchemeChoice, FmmError> {
        if self != SchemeChoice::Auto {
            return Ok(self);
        }
        if kernel.description().auto_scheme == AutoScheme::Fft {
            return Ok(SchemeChoice::Fft);
        }
        match (eps, order, points) {
            (None, None, _) | (_, _, None) => Ok(SchemeChoice::Svd),
            (eps, order, Some((sources, targets))) => {
                let (shape, _) = choose_scheme_for(
                    eps,
                    order,
                    mode,
                    precision,
                    sources,
                    targets,
                    cached,
                    calibration,
                )?;
                Ok(SchemeChoice::of_shape(shape))
            }
        }
    }

    /// Whether `auto` is FFT for `kernel` whatever the points (rule 1 of the
    /// module docs of `scheme_choice`): what its registry description says, and for a
    /// kernel outside the registry, whether it has several components or no
    /// homogeneity (operators per level), the two reasons the built-in
    /// kernels have.
    pub fn auto_is_fft<K: Kernel>(kernel: &K) -> bool {
        match KernelChoice::of(kernel) {
            Some(choice) => choice.description().auto_scheme == AutoScheme::Fft,
            None => kernel.components() > 1 || kernel.homogeneity().is_none(),
        }
    }

    /// Whether `auto` needs the points to resolve for `kernel` (so a front
    /// end makes them only then).
    pub fn needs_points(
        self,
        kernel: KernelChoice,
        eps: Option<f64>,
        order: Option<usize>,
    ) -> bool {
        self == SchemeChoice::Auto
            && (eps.is_some() || order.is_some())
            && kernel.description().auto_scheme == AutoScheme::CostModel
    }

    /// The scheme of a cost shape.
    pub fn of_shape(shape: M2lCostShape) -> SchemeChoice {
        match shape {
            M2lCostShape::Fft => SchemeChoice::Fft,
            M2lCostShape::Dense => SchemeChoice::Dense,
            _ => SchemeChoice::Svd,
        }
    }

    /// The cost shape of a scheme (`None` for `auto`).
    pub fn shape(self) -> Option<M2lCostShape> {
        match self {
            SchemeChoice::Svd => Some(M2lCostShape::Compressed),
            SchemeChoice::Dense => Some(M2lCostShape::Dense),
            SchemeChoice::Fft => Some(M2lCostShape::Fft),
            SchemeChoice::Auto => None,
        }
    }
}

impl FromStr for SchemeChoice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SchemeChoice::parse(s)
    }
}

impl std::fmt::Display for SchemeChoice {
    /// The name (width and alignment flags apply).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resolve(kernel: &str, eps: Option<f64>, points: Option<&[f64]>) -> SchemeChoice {
        SchemeChoice::Auto
            .resolve(
                KernelChoice::parse(kernel).unwrap(),
                eps,
                None,
                points.map(|p| (p, None)),
                EvalMode::PotentialGradient,
                Precision::F64,
                false,
                None,
            )
            .unwrap()
    }

    #[test]
    fn names_round_trip() {
        for s in SchemeChoice::ALL {
            assert_eq!(SchemeChoice::parse(s.name()), Ok(s));
            assert_eq!(s.to_string(), s.name());
        }
        assert!(SchemeChoice::parse("SVD").unwrap_err().contains("auto"));
    }

    #[test]
    fn auto_follows_the_kernel_then_the_cost_model() {
        for k in ["helmholtz:2", "stokes", "yukawa:3"] {
            assert_eq!(resolve(k, None, None), SchemeChoice::Fft, "{k}");
            assert_eq!(resolve(k, Some(1e-6), None), SchemeChoice::Fft, "{k}");
        }
        assert_eq!(resolve("laplace", None, None), SchemeChoice::Svd);
        let points = crate::Geometry::Cube.points::<f64>(20_000, 1);
        let chosen = resolve("laplace", Some(1e-6), Some(&points));
        assert_ne!(chosen, SchemeChoice::Auto);
        assert_ne!(chosen, SchemeChoice::Dense);
        // Explicit choices win.
        let stokes = KernelChoice::parse("stokes").unwrap();
        let svd = SchemeChoice::Svd
            .resolve(
                stokes,
                None,
                None,
                None,
                EvalMode::Potential,
                Precision::F64,
                false,
                None,
            )
            .unwrap();
        assert_eq!(svd, SchemeChoice::Svd);
        let laplace = KernelChoice::parse("laplace").unwrap();
        assert!(SchemeChoice::Auto.needs_points(laplace, Some(1e-3), None));
        assert!(SchemeChoice::Auto.needs_points(laplace, None, Some(8)));
        assert!(!SchemeChoice::Auto.needs_points(laplace, None, None));
        assert!(!SchemeChoice::Auto.needs_points(stokes, Some(1e-3), None));
        // An order alone: the scheme the cost model prefers at that order
        // (FFT at a high order on many points).
        let high = SchemeChoice::Auto
            .resolve(
                laplace,
                None,
                Some(10),
                Some((&points, None)),
                EvalMode::Potential,
                Precision::F64,
                false,
                None,
            )
            .unwrap();
        assert_eq!(high, SchemeChoice::Fft);
    }
}
