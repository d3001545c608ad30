//! The models behind a choice, keyed on kernel and M2L scheme
//! ([`TuningModel`]).

// The parent's imports and the sibling modules' items (one namespace,
// split by job).
#[allow(unused_imports)]
use super::*;

/// What the chooser needs to know about one kernel (and, through `scheme`,
/// one M2L scheme): how the error falls with the order, and what the work
/// costs. [`Tuner`] asks it for an [`ErrorModel`] and a [`CostModel`] for
/// the float type, the evaluation mode and the scheme being built;
/// [`FmmBuilder::tuning_model`](crate::FmmBuilder::tuning_model) replaces
/// the default ([`default_model`]) with one of your own.
///
/// A model for a new kernel is a table of the worst relative L2 error per
/// order, measured over the inputs it will see (the example
/// `error_model` and `docs/tolerance.md` show how the Laplace table was
/// measured), wrapped in an [`ErrorModel`]; the cost model can stay the
/// Laplace one scaled by the kernel's relative P2P cost
/// ([`CostModel::scaled_kernel`]).
///
/// ```
/// use std::sync::Arc;
/// use ferrofmm_fmm::tuning::{CostModel, ErrorModel, M2lCostShape, TuningModel, Tuner};
/// use ferrofmm_kernels::{EvalMode, Precision};
///
/// /// A kernel whose error at each order is a tenth of Laplace's.
/// #[derive(Debug)]
/// struct Smooth;
/// impl TuningModel for Smooth {
///     fn name(&self) -> String {
///         "smooth kernel".into()
///     }
///     fn error_model(&self, precision: Precision, mode: EvalMode, _: M2lCostShape) -> ErrorModel {
///         let mut m = ErrorModel::laplace_for(precision, mode);
///         m.order_errors.iter_mut().for_each(|(_, e)| *e *= 0.1);
///         m
///     }
///     fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
///         CostModel::default().for_mode(mode)
///     }
/// }
/// let laplace = Tuner::new(Precision::F64);
/// let smooth = Tuner::new(Precision::F64).with_model(Arc::new(Smooth));
/// let p = |t: &Tuner| t.error.smallest_order(1e-6, 0.0).unwrap();
/// assert!(p(&smooth) < p(&laplace));
/// ```
pub trait TuningModel: Send + Sync + std::fmt::Debug {
    /// A short name for reports ([`ChosenParameters::model`]).
    fn name(&self) -> String;

    /// Whether the error table was measured for the kernel it is used for.
    /// A borrowed table ([`BorrowedModel`]) says `false`, and only the
    /// after-the-fact check ([`crate::verify`]) backs the tolerance.
    fn measured(&self) -> bool {
        true
    }

    /// The error model for float type `precision`, for everything `mode`
    /// evaluates, with an M2L scheme that scales as `scheme`.
    fn error_model(&self, precision: Precision, mode: EvalMode, scheme: M2lCostShape)
    -> ErrorModel;

    /// Seconds per unit of work for `mode` and `scheme`.
    fn cost_model(&self, mode: EvalMode, scheme: M2lCostShape) -> CostModel;
}

/// The measured model of the Laplace kernel `1 / (4 pi r)`: the error
/// tables of [`ErrorModel::laplace_for`] and the cost model fitted on this
/// code ([`CostModel::default`]). The tables were measured with the SVD
/// scheme at its default tolerance; the dense and FFT schemes apply the
/// same operators without the SVD truncation, so the tables bound them too
/// (they have no SVD tolerance to loosen).
#[derive(Clone, Copy, Debug, Default)]
pub struct LaplaceModel;

impl TuningModel for LaplaceModel {
    fn name(&self) -> String {
        "laplace".into()
    }

    fn error_model(&self, precision: Precision, mode: EvalMode, _: M2lCostShape) -> ErrorModel {
        ErrorModel::laplace_for(precision, mode)
    }

    fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
        CostModel::default().for_mode(mode)
    }
}

/// The modified Helmholtz (Yukawa) kernel `e^{-k r} / (4 pi r)` with the
/// Laplace tables: its expansions converge at least as fast as Laplace's
/// (the screening only damps the far field), measured at `k` from 0.5 to
/// [`YUKAWA_MEASURED_K`] times the domain width (`docs/tolerance.md`). Its
/// kernel costs [`YUKAWA_P2P_FACTOR`] (potentials) or
/// [`YUKAWA_GRADIENT_P2P_FACTOR`] (with gradients) times Laplace's per pair.
#[derive(Clone, Copy, Debug)]
pub struct YukawaModel {
    /// `k` times the domain width.
    pub k_width: f64,
}

/// Largest `k` times domain width at which the Laplace tables were checked
/// against the modified Helmholtz errors.
pub const YUKAWA_MEASURED_K: f64 = 10.0;

/// P2P cost of the modified Helmholtz potential relative to Laplace's (an
/// exponential per pair): 4.88e9 against 1.01e9 interactions per second on
/// one AVX-512 core (`cargo bench --bench p2p`, `docs/performance.md`).
pub const YUKAWA_P2P_FACTOR: f64 = 4.8;

/// As [`YUKAWA_P2P_FACTOR`] with gradients: 3.05e9 against 0.78e9.
pub const YUKAWA_GRADIENT_P2P_FACTOR: f64 = 3.9;

impl TuningModel for YukawaModel {
    fn name(&self) -> String {
        "modified-helmholtz (laplace tables)".into()
    }

    fn measured(&self) -> bool {
        self.k_width <= YUKAWA_MEASURED_K
    }

    fn error_model(&self, precision: Precision, mode: EvalMode, _: M2lCostShape) -> ErrorModel {
        ErrorModel::laplace_for(precision, mode)
    }

    fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
        let factor = match mode {
            EvalMode::Potential => YUKAWA_P2P_FACTOR,
            EvalMode::PotentialGradient | EvalMode::PotentialGradientHessian => {
                YUKAWA_GRADIENT_P2P_FACTOR
            }
        };
        CostModel::default().for_mode(mode).scaled_kernel(factor)
    }
}

/// Another kernel's model used for a kernel nobody measured (a user
/// kernel without a model of its own): the same numbers, reported as
/// borrowed ([`TuningModel::measured`] is `false`).
#[derive(Clone, Debug)]
pub struct BorrowedModel {
    /// The kernel it is used for ([`Kernel::name`](ferrofmm_kernels::Kernel::name)).
    pub kernel: String,
    /// The model it borrows.
    pub from: Arc<dyn TuningModel>,
}

impl TuningModel for BorrowedModel {
    fn name(&self) -> String {
        format!("{} tables for {}", self.from.name(), self.kernel)
    }

    fn measured(&self) -> bool {
        false
    }

    fn error_model(
        &self,
        precision: Precision,
        mode: EvalMode,
        scheme: M2lCostShape,
    ) -> ErrorModel {
        self.from.error_model(precision, mode, scheme)
    }

    fn cost_model(&self, mode: EvalMode, scheme: M2lCostShape) -> CostModel {
        self.from.cost_model(mode, scheme)
    }
}

/// The model [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) uses
/// for `kernel` unless given one: [`LaplaceModel`] for
/// [`Laplace3d`](ferrofmm_kernels::Laplace3d), [`YukawaModel`] for
/// [`ModifiedHelmholtz3d`](ferrofmm_kernels::ModifiedHelmholtz3d) (with `k`
/// times `domain_width`), and the Laplace model [borrowed](BorrowedModel)
/// for any other kernel.
///
/// ```
/// use ferrofmm_fmm::tuning::{TuningModel, default_model};
/// use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d};
/// assert!(default_model(&Laplace3d, 1.0).measured());
/// assert!(default_model(&ModifiedHelmholtz3d::new(2.0).unwrap(), 1.0).measured());
/// ```
pub fn default_model<K: Kernel>(kernel: &K, domain_width: f64) -> Arc<dyn TuningModel> {
    match kernel.name().as_str() {
        "laplace3d" => Arc::new(LaplaceModel),
        "modified_helmholtz3d" => Arc::new(YukawaModel {
            k_width: kernel.parameters().first().copied().unwrap_or(0.0) * domain_width,
        }),
        other => Arc::new(BorrowedModel {
            kernel: other.to_string(),
            from: Arc::new(LaplaceModel),
        }),
    }
}
