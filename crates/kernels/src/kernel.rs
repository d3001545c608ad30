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
    /// The potential, its gradient and its Hessian (the second derivatives
    /// with respect to the target, symmetric, so six of them):
    /// `[phi, g1, g2, g3, H11, H22, H33, H12, H13, H23]`, ten values per
    /// target (the order of FMM3D's `hess`). Kernels that support it say so
    /// through [`Kernel::supports`].
    PotentialGradientHessian,
}

impl EvalMode {
    /// Values written per target: 1, 4 or 10.
    #[inline]
    pub fn values_per_target(self) -> usize {
        match self {
            EvalMode::Potential => 1,
            EvalMode::PotentialGradient => 4,
            EvalMode::PotentialGradientHessian => 10,
        }
    }

    /// Whether the gradient is among the outputs.
    #[inline]
    pub fn has_gradient(self) -> bool {
        self != EvalMode::Potential
    }

    /// Whether the Hessian is among the outputs.
    #[inline]
    pub fn has_hessian(self) -> bool {
        self == EvalMode::PotentialGradientHessian
    }

    /// A short name: `"potential"`, `"gradient"` or `"hessian"`.
    pub fn name(self) -> &'static str {
        match self {
            EvalMode::Potential => "potential",
            EvalMode::PotentialGradient => "gradient",
            EvalMode::PotentialGradientHessian => "hessian",
        }
    }
}

/// What each source carries: the densities a kernel evaluation reads per
/// source, interleaved like the points.
///
/// With `K(x, y)` the kernel, a source at `x` with charge `q` and dipole
/// vector `n` contributes at `y`
///
/// ```text
/// u(y) = q K(x, y) + n . grad_x K(x, y)
/// ```
///
/// (the single- and double-layer terms of a boundary integral; FMM3D's
/// `charges` and `dipvec`, with the same sign). The derivative is taken with
/// respect to the **source**; for a radial kernel `K(|x - y|)` this is
/// `K'(r) n . (x - y) / r`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum SourceKind {
    /// A charge `q` per source: `[q0, q1, ...]`.
    #[default]
    Charge,
    /// A dipole vector `n` per source: `[n0x, n0y, n0z, n1x, ...]`.
    Dipole,
    /// Both, `[q0, n0x, n0y, n0z, q1, ...]`: four values per source.
    ChargeDipole,
}

impl SourceKind {
    /// Values read per source: 1, 3 or 4.
    #[inline]
    pub fn values_per_source(self) -> usize {
        match self {
            SourceKind::Charge => 1,
            SourceKind::Dipole => 3,
            SourceKind::ChargeDipole => 4,
        }
    }

    /// Whether the sources carry dipoles.
    #[inline]
    pub fn has_dipoles(self) -> bool {
        self != SourceKind::Charge
    }

    /// A short name: `"charge"`, `"dipole"` or `"charge+dipole"`.
    pub fn name(self) -> &'static str {
        match self {
            SourceKind::Charge => "charge",
            SourceKind::Dipole => "dipole",
            SourceKind::ChargeDipole => "charge+dipole",
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
    /// user input before it gets here. The default (pairwise) handles
    /// potentials and gradients only; a kernel that
    /// [supports](Kernel::supports) Hessians of charges handles
    /// [`EvalMode::PotentialGradientHessian`] here too.
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

    /// Whether [`Kernel::evaluate_sources`] handles sources of `kind` with
    /// outputs `mode`. The default is what every kernel can do from
    /// [`Kernel::kernel_value`] and [`Kernel::kernel_gradient`]: charges,
    /// potentials and gradients. The FMM asks before it builds, and reports
    /// an unsupported pair as an error.
    fn supports(&self, kind: SourceKind, mode: EvalMode) -> bool {
        kind == SourceKind::Charge && !mode.has_hessian()
    }

    /// Accumulate the field of sources of any [`SourceKind`]: `densities`
    /// holds [`SourceKind::values_per_source`] values per source
    /// (interleaved), `out` [`EvalMode::values_per_target`] per target:
    ///
    /// ```text
    /// out_j += sum_i D_y^m [ q_i K(x_i, y_j) + n_i . grad_x K(x_i, y_j) ]
    /// ```
    ///
    /// for the target derivatives `D_y^m` of `mode`. The FMM calls this
    /// method (never [`Kernel::evaluate`] directly), so a kernel that
    /// supports more than charges overrides it together with
    /// [`Kernel::supports`]. The default handles charges by calling
    /// [`Kernel::evaluate`].
    ///
    /// # Panics
    /// When `(kind, mode)` is not [`Kernel::supports`]ed, or (debug) when
    /// lengths disagree.
    fn evaluate_sources<T: Real>(
        &self,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        assert!(
            self.supports(kind, mode) && kind == SourceKind::Charge,
            "{}: {} sources with {} outputs are not supported (Kernel::supports)",
            self.name(),
            kind.name(),
            mode.name()
        );
        self.evaluate(mode, sources, densities, targets, out);
    }

    /// Write the dense kernel matrix `A[j, i] = K(x_i, y_j)` (row-major,
    /// `n_targets x n_sources`, potential only) into `matrix`.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        crate::reference::assemble_pairwise(self, sources, targets, matrix);
    }
}
