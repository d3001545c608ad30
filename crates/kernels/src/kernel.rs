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

/// A translation-invariant kernel `K(x, y) = k(x - y)` in 3D: scalar, or
/// with [`Kernel::components`] `c > 1` a `c x c` block (complex kernels in
/// their real 2 x 2 form, vector kernels such as Stokes).
///
/// # Layout
/// Points are **interleaved** `[x0, y0, z0, x1, y1, z1, ...]` (length `3 n`).
/// Charges hold one value per source. Outputs hold
/// [`EvalMode::values_per_target`] values per target, interleaved
/// (`[phi0, gx0, gy0, gz0, phi1, ...]` for gradients).
///
/// With `c` components every density and every output is a `c`-vector,
/// stored **quantity-major**: per source, `c` values of the charge, then `c`
/// of each dipole direction; per target, `c` values of the potential, then
/// `c` of each derivative. So [`Kernel::values_per_source`] is
/// `c * kind.values_per_source()` and [`Kernel::values_per_target`] is
/// `c * mode.values_per_target()`. For a complex kernel (`c = 2`, the
/// components being the real and imaginary parts) this is exactly the
/// memory of an array of complex numbers (`[re, im]` pairs), so complex
/// charges and outputs are read and written in place.
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

    /// Components `c` of each density and each potential: 1 for a scalar
    /// kernel (the default), 2 for a complex kernel in real form, 3 for
    /// Stokes. A kernel with `c > 1` overrides [`Kernel::evaluate`] (or
    /// [`Kernel::evaluate_sources`]) and [`Kernel::assemble`]: the pairwise
    /// defaults know only the scalar `kernel_value`.
    fn components(&self) -> usize {
        1
    }

    /// `true` for a complex scalar kernel in its real form: `c = 2` and
    /// every block is `[[Re K, -Im K], [Im K, Re K]]` (the `(1, 0)` entry
    /// of [`Kernel::assemble`]'s block is `Im K`), so that a complex
    /// density `q_0 + i q_1` gives the complex potential `K q`. M2L
    /// schemes may then work in complex arithmetic (the FFT scheme
    /// convolves one complex spectrum instead of four real ones). `false`
    /// (the default) uses the general `c x c` path, which is right for any
    /// kernel, so only a kernel whose blocks have that structure exactly
    /// may say `true`.
    fn is_complex(&self) -> bool {
        false
    }

    /// Values per source of `kind`: `components() * kind.values_per_source()`.
    fn values_per_source(&self, kind: SourceKind) -> usize {
        self.components() * kind.values_per_source()
    }

    /// Values per target of `mode`: `components() * mode.values_per_target()`.
    fn values_per_target(&self, mode: EvalMode) -> usize {
        self.components() * mode.values_per_target()
    }

    /// The wavenumber `k` (inverse length) of an oscillatory kernel such as
    /// Helmholtz `e^{ikr} / (4 pi r)`; `0` (the default) for kernels that do
    /// not oscillate. The FMM's operators resolve a limited number of
    /// wavelengths per box, so it refuses domains wider than
    /// `ferrofmm_fmm::MAX_WAVENUMBER_WIDTH / k`.
    fn wavenumber(&self) -> f64 {
        0.0
    }

    /// The smallest relative cutoff the FMM's check-to-equivalent
    /// pseudo-inverses should use at expansion order `order` when the user
    /// sets none (the library's default is `1e-13` in `f64`, `1e-7` in
    /// `f32`; the larger of the two is used). `None` (the default) for
    /// kernels whose equivalent-density problem is merely ill-conditioned.
    /// A kernel whose single layer on a closed surface has a near-null
    /// space (Stokes: a density along the normal makes no flow outside)
    /// needs a cutoff above it, or the pseudo-inverse amplifies what the
    /// check points cannot see; how far above can depend on the order
    /// ([`Stokes3d`](crate::Stokes3d)'s does).
    fn pinv_rcond_floor(&self, _order: usize) -> Option<f64> {
        None
    }

    /// `K` at separation `d = target - source` (`|d| > 0`); for a kernel
    /// with `c > 1` components, the `(0, 0)` entry of its block (the real
    /// part of a complex kernel).
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T;

    /// `grad_y K(x, y)` at separation `d = y - x` (`|d| > 0`); the `(0, 0)`
    /// entry's gradient for a kernel with `c > 1` components.
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
    /// `n_targets x n_sources`, potential only) into `matrix`. With `c`
    /// [components](Kernel::components) the matrix is `c n_targets x c
    /// n_sources` and entry `[c j + a, c i + b]` is the block entry
    /// `K_ab(x_i, y_j)`: potential component `a` at `y_j` per unit of
    /// density component `b` at `x_i`. Coincident pairs give zero blocks.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        crate::reference::assemble_pairwise(self, sources, targets, matrix);
    }
}
