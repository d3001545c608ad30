//! The models behind a choice, keyed on kernel and M2L scheme
//! ([`TuningModel`]).

use std::sync::Arc;

use ferrofmm_field::M2lCostShape;
use ferrofmm_kernels::{EvalMode, Kernel, KernelChoice, Precision, TuningFamily};

use super::cost::CostModel;
use super::error_model::{ErrorModel, MAX_OSCILLATORY_ORDER, MAX_TUNED_ORDER, hessian_factor};

/// What the chooser needs to know about one kernel (and, through `scheme`,
/// one M2L scheme): how the error falls with the order, and what the work
/// costs. [`Tuner`](super::Tuner) asks it for an [`ErrorModel`] and a [`CostModel`] for
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
    /// A short name for reports ([`ChosenParameters::model`](super::ChosenParameters::model)).
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

/// The Helmholtz kernel `e^{ikr} / (4 pi r)` (complex, two components):
/// the Laplace tables times the measured growth of the error with the
/// number of wavelengths across the domain ([`helmholtz_error_factor`]),
/// measured for `k W` up to [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH)
/// (`examples/components_sweep.rs`, `docs/kernels.md`); costs are the
/// Laplace model's with [`HELMHOLTZ_P2P_FACTOR`] per pair and two
/// components, convolved as one complex spectrum by the FFT scheme
/// ([`CostModel::with_complex_components`](crate::tuning::CostModel::with_complex_components)).
#[derive(Clone, Copy, Debug)]
pub struct HelmholtzModel {
    /// `k` times the domain width.
    pub k_width: f64,
}

/// P2P cost of the complex Helmholtz kernel relative to Laplace's (a
/// `sin`/`cos` pair and complex products per pair): 159 and 129 million
/// pairs per second (potential, gradient) against 844 and 757 on one AVX2
/// core, `benches/p2p.rs` (`docs/kernels.md`).
pub const HELMHOLTZ_P2P_FACTOR: f64 = 5.8;

/// P2P cost of the Stokeslet relative to Laplace's (a 3 x 3 block per
/// pair): the FMM's P2P pass with the lane engine (issue 34), 1e5 uniform
/// cube, order 7, leaf 256 (the same tree for both), 2 threads, release,
/// best of two: 191 ms against Laplace's 90 ms (`ferrofmm eval --sources
/// x.npy --charges q.npy|f.npy --kernel laplace|stokes --order 7
/// --leaf-size 256 --scheme fft`). It was 6.4 (131 against 844 million
/// pairs per second) before the lane engine.
pub const STOKES_P2P_FACTOR: f64 = 2.1;

/// As [`STOKES_P2P_FACTOR`] with velocity gradients (`--gradients`): 456
/// against 147 ms, best of two (526 against 149 ms in the other run). It
/// was 17 (45 against 757 million pairs per second, before the lane
/// engine), which steered the chooser to leaves of 48 points whose M2L
/// cost 3.6x the whole run at leaf 256 (1e5 points, order 7: 3.54 s
/// against 0.97 s).
pub const STOKES_GRADIENT_P2P_FACTOR: f64 = 3.3;

/// Factor on the Laplace error table of order `order` for the Helmholtz
/// kernel at `k W = k_width`: the measured ratio of the Helmholtz error
/// (worst of potential and gradient) at `k W` to the one at `k W = 10`,
/// at the same order (N = 2e4, cube, charges and dipoles, leaf 64, FFT;
/// `examples/components_sweep.rs`, `docs/kernels.md`), with a safety of
/// about 1.5 on the columns past 40 and the rows above 8. Rows: orders 4,
/// 6, 8, 10, 12, 14, 16; columns: `k W` = 10, 20, 30, 40, 50, 70, 100
/// (orders 4 and 6 beyond 40 were not measured: they are set so high that
/// they are never chosen there). The factor is 1 up to `k W = 10` and
/// interpolated in `log` between rows and columns; orders below 4 take
/// the order-4 row, above 16 the order-16 row; beyond 100 the last
/// column's growth continues (the FMM refuses `k W` above
/// [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH)).
///
/// ```
/// use ferrofmm_fmm::tuning::helmholtz_error_factor;
/// assert_eq!(helmholtz_error_factor(6, 5.0), 1.0);
/// assert!(helmholtz_error_factor(4, 40.0) > helmholtz_error_factor(8, 40.0));
/// assert!(helmholtz_error_factor(6, 30.0) > helmholtz_error_factor(6, 20.0));
/// // At k W = 100 only high orders resolve the boxes of level 2.
/// assert!(helmholtz_error_factor(16, 100.0) < 1e-1 * helmholtz_error_factor(12, 100.0));
/// ```
pub fn helmholtz_error_factor(order: usize, k_width: f64) -> f64 {
    const ORDERS: [f64; 7] = [4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0];
    const K_WIDTHS: [f64; 7] = [10.0, 20.0, 30.0, 40.0, 50.0, 70.0, 100.0];
    const ROWS: [[f64; 7]; 7] = [
        [1.0, 5.0, 60.0, 3200.0, 1e5, 1e7, 1e9],
        [1.0, 3.0, 25.0, 400.0, 1e4, 1e6, 1e8],
        [1.0, 3.0, 8.0, 130.0, 2500.0, 1.8e5, 3.5e7],
        [1.0, 3.5, 5.0, 16.0, 250.0, 5e4, 1.4e7],
        [1.0, 1.5, 2.0, 6.0, 30.0, 1.1e4, 1e7],
        [1.0, 1.5, 1.5, 2.5, 5.0, 700.0, 2.6e6],
        [1.0, 1.5, 1.5, 2.0, 2.0, 25.0, 2.2e5],
    ];
    if k_width <= K_WIDTHS[0] {
        return 1.0;
    }
    // Position of `x` in `grid`: the segment `i` and the fraction within.
    let locate = |grid: &[f64], x: f64| -> (usize, f64) {
        let last = grid.len() - 2;
        let i = grid.windows(2).position(|w| x < w[1]).unwrap_or(last);
        (i, (x - grid[i]) / (grid[i + 1] - grid[i]))
    };
    let (r, fr) = locate(&ORDERS, order as f64);
    let fr = fr.clamp(0.0, 1.0);
    let (c, fc) = locate(&K_WIDTHS, k_width);
    let at = |row: usize| {
        let (a, b) = (ROWS[row][c].ln(), ROWS[row][c + 1].ln());
        a * (1.0 - fc) + b * fc
    };
    (at(r) * (1.0 - fr) + at(r + 1) * fr).exp()
}

/// Errors of the Helmholtz kernel at orders 13 to
/// [`MAX_OSCILLATORY_ORDER`] and `k W = 10`, where the Laplace tables stop
/// ([`MAX_TUNED_ORDER`]) but the Helmholtz error still falls: measured 2.1e-11
/// at order 14 and 2.3e-12 at 16 (3.4e-10 at 12; N = 2e4 unit cube,
/// zero-mean charges and dipoles, leaf 64, FFT, worst of potential and
/// gradient on 400 targets, `examples/components_sweep.rs`), orders 13 and
/// 15 interpolated in `log`. They serve every output (times
/// [`HESSIAN_ERROR_FACTOR`](super::HESSIAN_ERROR_FACTOR) with Hessians): where these orders are needed,
/// at high `k W`, the potential's error is the gradient's (`k D = 100`,
/// order 14: potential 3.3e-5 at 1e5 points against 3.6e-5 for the worst
/// output at 2e4). [`helmholtz_error_factor`] scales them with `k W` as it
/// does the Laplace tables.
pub const HELMHOLTZ_HIGH_ORDER_ERRORS: [f64; MAX_OSCILLATORY_ORDER - MAX_TUNED_ORDER] =
    [8.5e-11, 2.1e-11, 7.0e-12, 2.3e-12];

impl TuningModel for HelmholtzModel {
    fn name(&self) -> String {
        format!(
            "helmholtz (laplace tables x wavelength factor, kW = {:.3})",
            self.k_width
        )
    }

    fn measured(&self) -> bool {
        // The limit as the build checks it (room for the root's padding).
        self.k_width
            <= crate::MAX_WAVENUMBER_WIDTH * (1.0 + crate::validate::WAVENUMBER_WIDTH_SLACK)
    }

    fn error_model(&self, precision: Precision, mode: EvalMode, _: M2lCostShape) -> ErrorModel {
        // Orders to 16: at k W near 100 only they resolve the coarse boxes.
        let hessian = hessian_factor(mode);
        let high: Vec<(usize, f64)> = HELMHOLTZ_HIGH_ORDER_ERRORS
            .iter()
            .enumerate()
            .map(|(i, e)| (MAX_TUNED_ORDER + 1 + i, e * hessian))
            .collect();
        let mut m = ErrorModel::laplace_for(precision, mode).with_orders(&high);
        for (p, e) in m.order_errors.iter_mut() {
            *e *= helmholtz_error_factor(*p, self.k_width);
        }
        // The wavelength factor was measured on the cube only: keep the
        // worst case (and its safety factor) rather than fit to a scene.
        m.scalable = None;
        m
    }

    fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
        CostModel::default()
            .for_mode(mode)
            .scaled_kernel(HELMHOLTZ_P2P_FACTOR)
            .with_complex_components()
    }
}

/// Factor on the Laplace error tables for the Stokeslet: its worst
/// measured ratio to the Laplace gradient table over orders 4, 6 and 8 of
/// `examples/components_sweep.rs` (N = 2e4; cube with zero-mean forces,
/// Plummer with positive ones, whose velocity gradient is the worst output:
/// 2.2x, 7.6x and 10.7x the table), with a safety of 2.
pub const STOKES_ERROR_FACTOR: f64 = 20.0;

/// The Stokeslet (three components): the Laplace tables times
/// [`STOKES_ERROR_FACTOR`], Laplace costs with [`STOKES_P2P_FACTOR`] (or
/// [`STOKES_GRADIENT_P2P_FACTOR`]) and three components.
///
/// Every order from 3 to 10 is more accurate than the one before with
/// every M2L scheme, now that the pseudo-inverse cutoff follows the order
/// ([`Stokes3d::pinv_rcond_floor`](ferrofmm_kernels::Stokes3d)); before,
/// order 5 was no better than order 4 with the exact operators and this
/// model gave it order 4's error.
///
/// ```
/// use ferrofmm_fmm::tuning::{M2lCostShape, StokesModel, TuningModel};
/// use ferrofmm_kernels::{EvalMode, Precision};
/// let at = |shape, p| {
///     let m = StokesModel.error_model(Precision::F64, EvalMode::Potential, shape);
///     m.order_errors.iter().find(|(q, _)| *q == p).unwrap().1
/// };
/// for shape in [M2lCostShape::Compressed, M2lCostShape::Fft] {
///     assert!(at(shape, 5) < at(shape, 4));
/// }
/// ```
#[derive(Clone, Copy, Debug, Default)]
pub struct StokesModel;

impl TuningModel for StokesModel {
    fn name(&self) -> String {
        "stokes (laplace tables x factor)".into()
    }

    fn error_model(
        &self,
        precision: Precision,
        mode: EvalMode,
        _scheme: M2lCostShape,
    ) -> ErrorModel {
        let mut m = ErrorModel::laplace_for(precision, mode);
        for (_, e) in m.order_errors.iter_mut() {
            *e *= STOKES_ERROR_FACTOR;
        }
        // The factor is a worst ratio over two scenes: no scene fit.
        m.scalable = None;
        m
    }

    fn cost_model(&self, mode: EvalMode, _: M2lCostShape) -> CostModel {
        let factor = if mode.has_gradient() {
            STOKES_GRADIENT_P2P_FACTOR
        } else {
            STOKES_P2P_FACTOR
        };
        CostModel::default()
            .for_mode(mode)
            .scaled_kernel(factor)
            .with_components(3)
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
        // Nobody measured this kernel: the worst case, not a scene's
        // typical error, backs the first choice.
        let mut m = self.from.error_model(precision, mode, scheme);
        m.scalable = None;
        m
    }

    fn cost_model(&self, mode: EvalMode, scheme: M2lCostShape) -> CostModel {
        self.from.cost_model(mode, scheme)
    }
}

/// The model [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) uses
/// for `kernel` unless given one: [`LaplaceModel`] for
/// [`Laplace3d`](ferrofmm_kernels::Laplace3d), [`YukawaModel`] for
/// [`ModifiedHelmholtz3d`](ferrofmm_kernels::ModifiedHelmholtz3d) (with `k`
/// times `domain_width`), [`HelmholtzModel`] for
/// [`Helmholtz3d`](ferrofmm_kernels::Helmholtz3d), [`StokesModel`] for
/// [`Stokes3d`](ferrofmm_kernels::Stokes3d), and the Laplace model
/// [borrowed](BorrowedModel) for any other kernel: the kernel registry's
/// [`TuningFamily`] names the model of each built-in kernel.
///
/// ```
/// use ferrofmm_fmm::tuning::{TuningModel, default_model};
/// use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d};
/// assert!(default_model(&Laplace3d, 1.0).measured());
/// assert!(default_model(&ModifiedHelmholtz3d::new(2.0).unwrap(), 1.0).measured());
/// ```
pub fn default_model<K: Kernel>(kernel: &K, domain_width: f64) -> Arc<dyn TuningModel> {
    // The registry's description names the model; the parameter is the
    // wavenumber of the screened and oscillatory kernels.
    let Some(choice) = KernelChoice::of(kernel) else {
        return Arc::new(BorrowedModel {
            kernel: kernel.name(),
            from: Arc::new(LaplaceModel),
        });
    };
    let k_width = choice.parameter().unwrap_or(0.0) * domain_width;
    match choice.description().tuning {
        TuningFamily::Laplace => Arc::new(LaplaceModel),
        TuningFamily::ModifiedHelmholtz => Arc::new(YukawaModel { k_width }),
        TuningFamily::Helmholtz => Arc::new(HelmholtzModel { k_width }),
        TuningFamily::Stokes => Arc::new(StokesModel),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(k_width: f64, precision: Precision, mode: EvalMode) -> ErrorModel {
        HelmholtzModel { k_width }.error_model(precision, mode, M2lCostShape::Fft)
    }

    /// At `k W = 100` the orders above 12 are what reaches 1e-3 .. 1e-6
    /// (the potential): 2.2e-3 at order 12, 3.6e-5 at 14 and 3.3e-7 at 16
    /// measured; each tolerance takes a higher order than the last.
    #[test]
    fn high_wavenumbers_use_orders_to_16() {
        let m = model(100.0, Precision::F64, EvalMode::Potential);
        let top = m.order_errors.last().unwrap().0;
        assert_eq!(top, MAX_OSCILLATORY_ORDER);
        let orders: Vec<Option<usize>> = [1e-3, 1e-4, 1e-5, 1e-6]
            .iter()
            .map(|&eps| m.smallest_order(eps, 0.0))
            .collect();
        assert!(
            orders
                .iter()
                .all(|p| p.is_some_and(|p| p > MAX_TUNED_ORDER)),
            "{orders:?}"
        );
        assert!(orders.windows(2).all(|w| w[0] < w[1]), "{orders:?}");
        // The predictions stay above what was measured at orders 14 and 16
        // (worst of potential and gradient, N = 2e4 cube; the potential
        // alone at 1e5, order 14: 3.3e-5).
        assert!(m.order_error(14).unwrap() >= 3.6e-5);
        assert!(m.order_error(16).unwrap() >= 3.3e-7);
        // With gradients too: the high orders' errors are the worst output's.
        let g = model(100.0, Precision::F64, EvalMode::PotentialGradient);
        assert_eq!(g.smallest_order(1e-6, 0.0), orders[3]);
    }

    /// At low wavenumbers the orders above 12 fall towards f64's rounding
    /// (with gradients, whose order-12 entry is the higher); `f32` keeps
    /// its orders.
    #[test]
    fn high_orders_fall_towards_rounding() {
        let m = model(5.0, Precision::F64, EvalMode::PotentialGradient);
        for p in MAX_TUNED_ORDER + 1..=MAX_OSCILLATORY_ORDER {
            let e = m.order_error(p).unwrap();
            assert!(
                e >= 1e-12 && e < m.order_error(p - 1).unwrap(),
                "p={p}: {e:e}"
            );
        }
        let f32 = model(100.0, Precision::F32, EvalMode::Potential);
        assert_eq!(
            f32.order_errors.last().unwrap().0,
            crate::tuning::MAX_F32_ORDER
        );
        // The Laplace model itself is unchanged.
        let laplace = ErrorModel::laplace(Precision::F64);
        assert_eq!(laplace.order_errors.last().unwrap().0, MAX_TUNED_ORDER);
    }
}
