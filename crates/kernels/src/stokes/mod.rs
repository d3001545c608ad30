//! The Stokeslet: the velocity of a viscous fluid at `y` due to a point
//! force at `x`, a 3 x 3 kernel.
//!
//! # Maths
//! With `d = y - x`, `r = |d|` and viscosity `mu`,
//!
//! ```text
//! G_ab(d) = (delta_ab / r + d_a d_b / r^3) / (8 pi mu)
//! u_a(y)  = sum_i G_ab(y - x_i) f_{i,b}
//! ```
//!
//! and the velocity gradient (derivative `c` of component `a`) is
//!
//! ```text
//! d_c u_a = [ -f_a d_c + delta_ac (d . f) + d_a f_c - 3 d_a d_c (d . f) / r^2 ] / (8 pi mu r^3).
//! ```
//!
//! FMM3D's `stfmm3d` uses the same normalisation with `mu = 1`, and its
//! `grad[i, j] = d_i u_j` is the storage order below.
//!
//! # Force dipoles
//! A source may also carry a force dipole, a `3 x 3` tensor `D_kc`
//! (direction `k`, force component `c`): the limit of forces `D_k. / h` at
//! `x + h e_k` and `-D_k. / h` at `x`, the kernel's generic
//! [dipole](SourceKind::Dipole) `u_a = sum_kc D_kc d_{x_k} G_ac`. With
//! `A = D^T - D`, `tr = tr D` and `Q = d . D d`,
//!
//! ```text
//! u_a     = [ (A d)_a - tr d_a + 3 d_a Q / r^2 ] / (8 pi mu r^3)
//! d_m u_a = [ A_am - 3 (A d)_a d_m / r^2 - tr (delta_am - 3 d_a d_m / r^2)
//!             + 3 (delta_am Q + d_a ((D + D^T) d)_m - 5 d_a d_m Q / r^2) / r^2 ] / (8 pi mu r^3)
//! ```
//!
//! The symmetric part is a stresslet without its trace, the antisymmetric
//! part a rotlet; `D = I` gives no flow (the Stokeslet is divergence
//! free). FMM3D's stresslet `3 d (d . mu)(d . nu) / (4 pi r^5)` (its
//! `strslet` `mu` and `strsvec` `nu`) is the dipole `D = mu nu^T + nu mu^T`
//! at `mu = 1` plus the point-source flow `(mu . nu) d / (4 pi r^3)`, which
//! no Stokeslet carries (it has a net flux): a Laplace field
//! (`ferrofmm_fmm::stokes` composes the two).
//!
//! # Layout
//! Three [components](Kernel::components): forces `[f0x, f0y, f0z, f1x, ...]`
//! per source (force dipoles: `[D_xx, D_xy, D_xz, D_yx, ..., D_zz]`, nine
//! values, after the force with [`SourceKind::ChargeDipole`]); per target `[u_x, u_y, u_z]`, then for gradients
//! `[d_x u_x, d_x u_y, d_x u_z, d_y u_x, ..., d_z u_z]` (derivative-major,
//! as every kernel's outputs: the quantity, then its components).

pub mod ewald;
mod pair;

use crate::{EvalMode, Kernel, KernelError, Real, SourceKind};

/// The Stokeslet `G = (I / r + d d^T / r^3) / (8 pi mu)`: forces in,
/// velocities (and velocity gradients) out. See the [module docs](self).
///
/// * [`Kernel::components`] is 3;
/// * homogeneous of degree `-1`, so the FMM computes operators once and
///   rescales them per level;
/// * point forces, force dipoles or both (the module's "Force dipoles"),
///   with potentials or gradients; no Hessians.
///
/// ```
/// use ferrofmm_kernels::{EvalMode, Kernel, Stokes3d};
/// let stokes = Stokes3d::new(1.0).unwrap();
/// // A unit force along x at the origin, seen from (2, 0, 0): 2 / (8 pi 2).
/// let mut u = [0.0f64; 3];
/// stokes.evaluate(EvalMode::Potential, &[0.0; 3], &[1.0, 0.0, 0.0], &[2.0, 0.0, 0.0], &mut u);
/// let expected = 2.0 / (8.0 * std::f64::consts::PI * 2.0);
/// assert!((u[0] - expected).abs() < 1e-16 && u[1] == 0.0 && u[2] == 0.0);
/// assert!(Stokes3d::new(0.0).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stokes3d {
    /// The dynamic viscosity `mu > 0`.
    pub viscosity: f64,
}

impl Stokes3d {
    /// The Stokeslet for viscosity `mu`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] unless `mu` is finite and positive.
    pub fn new(viscosity: f64) -> Result<Self, KernelError> {
        if viscosity.is_finite() && viscosity > 0.0 {
            Ok(Stokes3d { viscosity })
        } else {
            Err(KernelError::InvalidParameter {
                name: "viscosity",
                value: viscosity,
                expected: "finite and > 0",
            })
        }
    }

    /// The scalar pairwise loop, the reference the vectorised
    /// [`Kernel::evaluate`] is tested against. Same layout and panics.
    ///
    /// # Panics
    /// When lengths are inconsistent or `mode` asks for Hessians.
    pub fn evaluate_pairwise<T: Real>(
        &self,
        mode: EvalMode,
        sources: &[T],
        charges: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        assert_evaluation(SourceKind::Charge, mode, sources, charges, targets, out);
        let scale = T::from_f64(self.scale());
        let three = T::from_f64(3.0);
        let w = 3 * mode.values_per_target();
        let grad = mode.has_gradient();
        for (y, o) in targets.chunks_exact(3).zip(out.chunks_exact_mut(w)) {
            let mut acc = [T::ZERO; 12];
            for (x, f) in sources.chunks_exact(3).zip(charges.chunks_exact(3)) {
                let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if r2 == T::ZERO {
                    continue;
                }
                let rinv = T::ONE / r2.sqrt();
                let rinv2 = rinv * rinv;
                let df = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
                let s = scale * rinv;
                let t = df * rinv2;
                for a in 0..3 {
                    acc[a] += s * (f[a] + d[a] * t);
                }
                if grad {
                    let s3 = s * rinv2;
                    for c in 0..3 {
                        for a in 0..3 {
                            let mut v = d[a] * f[c] - f[a] * d[c] - three * d[a] * d[c] * t;
                            if a == c {
                                v += df;
                            }
                            acc[3 + 3 * c + a] += s3 * v;
                        }
                    }
                }
            }
            for (o, a) in o.iter_mut().zip(acc) {
                *o += a;
            }
        }
    }

    /// The scalar pairwise loop for any [`SourceKind`] (forces, force
    /// dipoles or both; the module's formulas written out), the reference
    /// the vectorised [`Kernel::evaluate_sources`] is tested against. Same
    /// layout and panics.
    ///
    /// # Panics
    /// When lengths are inconsistent or `mode` asks for Hessians.
    pub fn evaluate_sources_pairwise<T: Real>(
        &self,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        assert_evaluation(kind, mode, sources, densities, targets, out);
        let per = 3 * kind.values_per_source();
        let with_forces = kind != SourceKind::Dipole;
        let n = sources.len() / 3;
        let mut forces = Vec::with_capacity(if with_forces { 3 * n } else { 0 });
        if with_forces {
            for q in densities.chunks_exact(per) {
                forces.extend_from_slice(&q[..3]);
            }
            self.evaluate_pairwise(mode, sources, &forces, targets, out);
        }
        if !kind.has_dipoles() {
            return;
        }
        let scale = self.scale();
        let w = 3 * mode.values_per_target();
        for (y, o) in targets.chunks_exact(3).zip(out.chunks_exact_mut(w)) {
            let mut acc = [0.0f64; 12];
            for (x, q) in sources.chunks_exact(3).zip(densities.chunks_exact(per)) {
                let d: [f64; 3] = std::array::from_fn(|a| (y[a] - x[a]).to_f64());
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if r2 == 0.0 {
                    continue;
                }
                let dm = |k: usize, c: usize| q[per - 9 + 3 * k + c].to_f64();
                let r = r2.sqrt();
                let s3 = scale / (r * r2);
                let tr = dm(0, 0) + dm(1, 1) + dm(2, 2);
                // (A d)_a with A = D^T - D, Q = d . D d, g = (D + D^T) d.
                let ad: [f64; 3] =
                    std::array::from_fn(|a| (0..3).map(|k| (dm(k, a) - dm(a, k)) * d[k]).sum());
                let q2: f64 = (0..3)
                    .flat_map(|k| (0..3).map(move |c| (k, c)))
                    .map(|(k, c)| d[k] * dm(k, c) * d[c])
                    .sum();
                let g: [f64; 3] =
                    std::array::from_fn(|m| (0..3).map(|c| (dm(m, c) + dm(c, m)) * d[c]).sum());
                for a in 0..3 {
                    acc[a] += s3 * (ad[a] - tr * d[a] + 3.0 * d[a] * q2 / r2);
                }
                if mode.has_gradient() {
                    for m in 0..3 {
                        for a in 0..3 {
                            let delta = if a == m { 1.0 } else { 0.0 };
                            let v = (dm(m, a) - dm(a, m))
                                - 3.0 * ad[a] * d[m] / r2
                                - tr * (delta - 3.0 * d[a] * d[m] / r2)
                                + 3.0 * (delta * q2 + d[a] * g[m] - 5.0 * d[a] * d[m] * q2 / r2)
                                    / r2;
                            acc[3 + 3 * m + a] += s3 * v;
                        }
                    }
                }
            }
            for (o, a) in o.iter_mut().zip(acc) {
                *o += T::from_f64(a);
            }
        }
    }

    /// `1 / (8 pi mu)`.
    fn scale(&self) -> f64 {
        1.0 / (8.0 * std::f64::consts::PI * self.viscosity)
    }
}

impl Default for Stokes3d {
    /// Unit viscosity.
    fn default() -> Self {
        Stokes3d { viscosity: 1.0 }
    }
}

impl Kernel for Stokes3d {
    /// `"stokes3d"`.
    fn name(&self) -> String {
        "stokes3d".to_string()
    }

    /// `vec![mu]`.
    fn parameters(&self) -> Vec<f64> {
        vec![self.viscosity]
    }

    /// `Some(-1.0)`.
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }

    /// `1e-5` up to order 5, `1e-6` at order 6, `1e-9` from order 7 on.
    ///
    /// The Stokeslet's single layer on a closed surface nearly annihilates
    /// normal densities, and the check matrices' smallest singular values
    /// fall much faster with the order than Laplace's (relative to the
    /// largest, upward check matrix: `2e-6` at order 4, `1e-8` at 5, `4e-11`
    /// at 6, `7e-13` at 7); a cutoff that keeps the smallest lets the
    /// equivalent densities grow along them, and the error rises. Measured (N = 1e4, leaf 64, FFT M2L; worst of velocity and gradient
    /// on 400 targets, cube with zero-mean forces): order 5 gives 4.8e-3 at
    /// `1e-9` (worse than order 4's 2.4e-3), 5.3e-4 at `1e-7` and 2.2e-4
    /// at `1e-5`; order 6 gives 1.1e-4 at `1e-9`, 4.2e-5 at `1e-6` and
    /// 8.7e-5 at `1e-5`; orders 7 and 8 are best at `1e-9` or `1e-8` and
    /// lose 2-4x at `1e-6`. The smaller default `1e-13` amplifies the null
    /// space's rounding at odd orders (N = 2000, positive forces: order 7
    /// gives 1.4e-4 at `1e-13`, 2.6e-7 at `1e-9`). With these cutoffs each
    /// order from 3 to 10 is more accurate than the one before, on the cube
    /// and on Plummer's positive forces (`docs/kernels.md`).
    fn pinv_rcond_floor(&self, order: usize) -> Option<f64> {
        Some(match order {
            ..=5 => 1e-5,
            6 => 1e-6,
            _ => 1e-9,
        })
    }

    /// 3: the force and velocity components.
    fn components(&self) -> usize {
        3
    }

    /// `G_xx = (1 / r + d_x^2 / r^3) / (8 pi mu)`.
    #[inline]
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let rinv = T::ONE / r2.sqrt();
        T::from_f64(self.scale()) * rinv * (T::ONE + d[0] * d[0] / r2)
    }

    /// `grad_y G_xx`: `d_c G_xx = (-d_c + 2 delta_xc d_x - 3 d_x^2 d_c / r^2) / (8 pi mu r^3)`.
    #[inline]
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let rinv = T::ONE / r2.sqrt();
        let s = T::from_f64(self.scale()) * rinv * rinv * rinv;
        let t = T::from_f64(3.0) * d[0] * d[0] / r2;
        let two = T::from_f64(2.0);
        [
            s * (-d[0] + two * d[0] - t * d[0]),
            s * (-d[1] - t * d[1]),
            s * (-d[2] - t * d[2]),
        ]
    }

    crate::lanes::kernel_entry_points!();

    /// Point forces, force dipoles or both, with potentials or gradients.
    fn supports(&self, _kind: SourceKind, mode: EvalMode) -> bool {
        !mode.has_hessian()
    }

    /// The `3 x 3` blocks `G_ab(y_j - x_i)` (`3 n_targets x 3 n_sources`,
    /// row-major), zero for coincident pairs.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        let ns = sources.len() / 3;
        let nt = targets.len() / 3;
        assert_eq!(matrix.len(), 9 * ns * nt, "stokes3d: matrix size");
        let scale = T::from_f64(self.scale());
        let cols = 3 * ns;
        for (j, y) in targets.chunks_exact(3).enumerate() {
            for (i, x) in sources.chunks_exact(3).enumerate() {
                let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                for a in 0..3 {
                    for b in 0..3 {
                        let v = if r2 == T::ZERO {
                            T::ZERO
                        } else {
                            let rinv = T::ONE / r2.sqrt();
                            let delta = if a == b { T::ONE } else { T::ZERO };
                            scale * rinv * (delta + d[a] * d[b] / r2)
                        };
                        matrix[(3 * j + a) * cols + 3 * i + b] = v;
                    }
                }
            }
        }
    }
}

/// The contract of every Stokes evaluation: consistent lengths (three
/// values per force and per output quantity, nine per force dipole) and no
/// Hessians.
///
/// # Panics
/// When it is broken.
fn assert_evaluation<T: Real>(
    kind: SourceKind,
    mode: EvalMode,
    sources: &[T],
    densities: &[T],
    targets: &[T],
    out: &[T],
) {
    if let Err(e) = crate::direct::check_lengths(3, kind, mode, [sources, densities, targets, out])
    {
        panic!("stokes3d: {e}");
    }
    assert!(
        !mode.has_hessian(),
        "stokes3d: no Hessians (Kernel::supports)"
    );
}
