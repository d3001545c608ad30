//! The [`Kernel`] seam: what the FMM needs to know about a Green's function.

use crate::Real;

/// What a kernel evaluation produces per target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EvalMode {
    /// The potential `phi(y) = sum_i K(x_i, y) q_i`: one value per target.
    Potential,
    /// The potential and its gradient with respect to the target,
    /// `[phi, d phi/d y1, d phi/d y2, d phi/d y3]`: four values per target.
    PotentialGradient,
}

impl EvalMode {
    /// Values written per target: 1 or 4.
    #[inline]
    pub fn values_per_target(self) -> usize {
        match self {
            EvalMode::Potential => 1,
            EvalMode::PotentialGradient => 4,
        }
    }
}

/// A scalar, translation-invariant kernel `K(x, y) = k(x - y)` in 3D.
///
/// # Layout
/// Points are **interleaved** `[x0, y0, z0, x1, y1, z1, ...]` (length `3 n`).
/// Charges hold one value per source. Outputs hold
/// [`EvalMode::values_per_target`] values per target, interleaved
/// (`[phi0, gx0, gy0, gz0, phi1, ...]` for gradients).
///
/// # Conventions
/// * `K(x, x) := 0`: a source that coincides with a target contributes
///   nothing (no NaN or Inf), in every code path.
/// * `evaluate` **accumulates** into `out` (`out += K q`), so callers can sum
///   contributions from many source sets.
/// * The methods are generic over the float type, so one implementation
///   serves `f32` and `f64` (operators are precomputed in `f64` and rounded).
///
/// # Implementing your own kernel
/// Implement [`Kernel::kernel_value`] (and [`Kernel::kernel_gradient`] for
/// gradients); the default `evaluate` and `assemble` loop over pairs with
/// them. Override `evaluate` with a vectorised loop when speed matters. State
/// [`Kernel::homogeneity`] honestly: a scale-invariant kernel lets the FMM
/// compute operators once and rescale them per level.
pub trait Kernel: Clone + Send + Sync + 'static {
    /// A stable, unique name (part of operator-cache keys), e.g. `"laplace3d"`.
    fn name(&self) -> String;

    /// Parameters that change the kernel's values (part of cache keys), e.g.
    /// the wavenumber of modified Helmholtz. Empty for Laplace.
    fn parameters(&self) -> Vec<f64> {
        Vec::new()
    }

    /// `Some(d)` when `K(s x, s y) = s^d K(x, y)` for all `s > 0` (Laplace:
    /// `d = -1`); `None` when the kernel has no such scaling (it then needs
    /// operators computed per tree level).
    fn homogeneity(&self) -> Option<f64>;

    /// `K` at separation `d = target - source` (`|d| > 0`).
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T;

    /// `grad_y K(x, y)` at separation `d = y - x` (`|d| > 0`).
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3];

    /// Accumulate `out[j] += sum_i K(x_i, y_j) q_i` (and the gradient for
    /// [`EvalMode::PotentialGradient`]) over all sources `x_i` and targets
    /// `y_j`. Coincident pairs are skipped.
    ///
    /// Panics (debug) when lengths disagree; the public drivers validate
    /// user input before it gets here.
    fn evaluate<T: Real>(
        &self,
        mode: EvalMode,
        sources: &[T],
        charges: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        crate::reference::evaluate_pairwise(self, mode, sources, charges, targets, out);
    }

    /// Write the dense kernel matrix `A[j, i] = K(x_i, y_j)` (row-major,
    /// `n_targets x n_sources`, potential only) into `matrix`.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        crate::reference::assemble_pairwise(self, sources, targets, matrix);
    }
}
