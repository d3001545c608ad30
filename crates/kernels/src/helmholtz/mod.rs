//! The oscillatory Helmholtz kernel `G(x, y) = e^{i k |x - y|} / (4 pi |x - y|)`,
//! a complex kernel in its real 2 x 2 form, for a real wavenumber `k >= 0`
//! or a complex one `k = a + i b` with `b >= 0` (damped waves, `e^{ikr} =
//! e^{-br} e^{iar}`).
//!
//! # Maths
//! With `r = |y - x|`, `d = y - x`, `z = ikr = -br + i ar` and the radial
//! functions
//!
//! ```text
//! f0 = e^{ikr} / (4 pi r) = e^z / (4 pi r)
//! f1 = f0' / r = f0 (z - 1) / r^2                  = e^{ikr} (ikr - 1) / (4 pi r^3)
//! f2 = f1' / r = f0 (z^2 - 3z + 3) / r^4           = e^{ikr} (3 - 3ikr - k^2 r^2) / (4 pi r^5)
//! f3 = f2' / r = f0 (z^3 - 6z^2 + 15z - 15) / r^6  = e^{ikr} (-15 + 15ikr + 6k^2 r^2 - ik^3 r^3) / (4 pi r^7)
//! ```
//!
//! (the modified Helmholtz functions with `k -> -ik`; the polynomials in
//! `z` hold for complex `k` as they are), a source with
//! complex charge `q` and complex dipole vector `n` adds at `y`
//!
//! ```text
//! u      = q f0 - f1 (n . d)
//! grad u = q f1 d - f2 (n . d) d - f1 n
//! ```
//!
//! (`n . grad_x G = -f1 n . d`: FMM3D's `dipvec` convention). The Hessian
//! `H_ab = d_{y_a} d_{y_b} u` follows from `d_{y_b} f_m = f_{m+1} d_b` and
//! `d_{y_b} d_a = delta_ab`:
//!
//! ```text
//! charge q:  H_ab = q (f2 d_a d_b + f1 delta_ab)
//! dipole n:  H_ab = -f3 (n . d) d_a d_b - f2 ((n . d) delta_ab + n_a d_b + n_b d_a)
//! ```
//!
//! which for a charge is `H_ab = delta_ab g'/r + d_a d_b (g'' - g'/r) / r^2`
//! with `g(r) = e^{ikr} / (4 pi r)`. Its trace is `-k^2 u` (away from the
//! sources, `(Delta + k^2) u = 0`, with the complex `k^2 = a^2 - b^2 + 2iab`
//! when damped). At `k = 0` these are the Laplace
//! functions `1/(4 pi r)`, `-1/(4 pi r^3)`, `3/(4 pi r^5)`, `-15/(4 pi r^7)`.
//!
//! # Real form
//! Complex numbers are stored as `[re, im]` pairs, so the kernel has two
//! [components](Kernel::components) and a complex product `G q` is the
//! 2 x 2 block `[[Re G, -Im G], [Im G, Re G]]` applied to `[Re q, Im q]`.
//! Densities per source are `[q, nx, ny, nz]` as complex pairs (8 values for
//! charge + dipole), outputs per target `[u, ux, uy, uz]` as complex pairs,
//! followed with Hessians by `[H_xx, H_yy, H_zz, H_xy, H_xz, H_yz]` as
//! complex pairs (20 values; the order of Laplace's and modified
//! Helmholtz's ten): the memory of NumPy `complex128` arrays.

mod pair;

use crate::{EvalMode, INV_4PI, Kernel, KernelError, Real, SourceKind};

/// The 3D Helmholtz Green's function `G = e^{ikr} / (4 pi r)`, the
/// outgoing solution of `(Delta + k^2) u = -delta`, as a complex kernel in
/// real 2 x 2 form (see the [module docs](self) for the layout and the
/// formulas).
///
/// * [`Kernel::components`] is 2 (real and imaginary parts);
/// * the wavenumber is real ([`Helmholtz3d::new`]) or complex with a
///   non-negative imaginary part ([`Helmholtz3d::new_complex`]: damped
///   waves `e^{-br} e^{iar}`, an absorbing medium); the damped kernel runs
///   its own vectorised loop (an `exp` per pair beside the `sin`/`cos`), so
///   a real `k` keeps the speed it had;
/// * not scale invariant for `k != 0`, so the FMM builds operators per
///   level, and [`Kernel::wavenumber`] is `Re k` (the oscillation; damping
///   only helps the expansions): the FMM refuses domains wider than the
///   low-frequency limit (`ferrofmm_fmm::MAX_WAVENUMBER_WIDTH / Re k`);
/// * charges and dipoles (alone or together), potentials, gradients and
///   Hessians.
///
/// ```
/// use ferrofmm_kernels::{EvalMode, Helmholtz3d, Kernel, SourceKind};
/// let helmholtz = Helmholtz3d::new(2.0).unwrap();
/// // A unit real charge at the origin, seen from (0.5, 0, 0): e^{i} / (2 pi).
/// let mut u = [0.0f64; 2];
/// helmholtz.evaluate(EvalMode::Potential, &[0.0; 3], &[1.0, 0.0], &[0.5, 0.0, 0.0], &mut u);
/// let a = 1.0 / (2.0 * std::f64::consts::PI);
/// assert!((u[0] - a * 1f64.cos()).abs() < 1e-15 && (u[1] - a * 1f64.sin()).abs() < 1e-15);
/// assert!(Helmholtz3d::new(f64::NAN).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helmholtz3d {
    /// The real part of the wavenumber, `Re k >= 0` (inverse length;
    /// wavelength `2 pi / Re k`).
    pub k: f64,
    /// The imaginary part of the wavenumber, `Im k >= 0` (inverse length):
    /// the waves decay as `e^{-r Im k}`; 0 for undamped waves.
    pub k_im: f64,
}

impl Helmholtz3d {
    /// The kernel with the real wavenumber `k`.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] when `k` is negative, NaN or
    /// infinite.
    pub fn new(k: f64) -> Result<Self, KernelError> {
        crate::error::check_wavenumber(k).map(|k| Helmholtz3d { k, k_im: 0.0 })
    }

    /// The kernel with the complex wavenumber `k = re + i im`: damped
    /// waves `e^{ikr} / (4 pi r) = e^{-im r} e^{i re r} / (4 pi r)`.
    ///
    /// ```
    /// use ferrofmm_kernels::{EvalMode, Helmholtz3d, Kernel};
    /// let h = Helmholtz3d::new_complex(2.0, 1.0).unwrap();
    /// let mut u = [0.0f64; 2];
    /// h.evaluate(EvalMode::Potential, &[0.0; 3], &[1.0, 0.0], &[0.5, 0.0, 0.0], &mut u);
    /// // e^{i (2 + i) 0.5} / (2 pi) = e^{-0.5} e^{i} / (2 pi)
    /// let a = (-0.5f64).exp() / (2.0 * std::f64::consts::PI);
    /// assert!((u[0] - a * 1f64.cos()).abs() < 1e-15 && (u[1] - a * 1f64.sin()).abs() < 1e-15);
    /// assert_eq!(h.parameters(), vec![2.0, 1.0]);
    /// assert!(Helmholtz3d::new_complex(2.0, -1.0).is_err());
    /// ```
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] when either part is negative,
    /// NaN or infinite (a negative imaginary part would grow
    /// exponentially).
    pub fn new_complex(re: f64, im: f64) -> Result<Self, KernelError> {
        let k = crate::error::check_wavenumber(re)?;
        let k_im = crate::error::check_parameter("Im k", im)?;
        Ok(Helmholtz3d { k, k_im })
    }

    /// Whether the wavenumber has an imaginary part (damped waves).
    pub fn is_damped(&self) -> bool {
        self.k_im != 0.0
    }
}

/// `e^{ikr}` times `1 / (4 pi r)` for `k = a + i b`: `(Re, Im)` of `f0`,
/// and `r^{-1}`.
#[inline(always)]
fn f0_parts<T: Real>(a: T, b: T, r2: T) -> (T, T, T) {
    let r = r2.sqrt();
    let rinv = T::ONE / r;
    let (s, c) = (a * r).sin_cos();
    let mut amp = T::from_f64(INV_4PI) * rinv;
    if b != T::ZERO {
        amp *= (-(b * r)).exp();
    }
    (c * amp, s * amp, rinv)
}

/// Complex product `(a + ib)(c + id)`.
#[inline(always)]
fn cmul<T: Real>(a: T, b: T, c: T, d: T) -> (T, T) {
    (a * c - b * d, a * d + b * c)
}

impl Kernel for Helmholtz3d {
    /// `"helmholtz3d"`.
    fn name(&self) -> String {
        "helmholtz3d".to_string()
    }

    /// `vec![k]` for a real wavenumber, `vec![Re k, Im k]` for a damped
    /// one (so operators cached for one are never read for the other).
    fn parameters(&self) -> Vec<f64> {
        if self.is_damped() {
            vec![self.k, self.k_im]
        } else {
            vec![self.k]
        }
    }

    /// `None` for `k != 0`; `Some(-1.0)` for `k = 0` (Laplace, complex).
    fn homogeneity(&self) -> Option<f64> {
        if self.k == 0.0 && self.k_im == 0.0 {
            Some(-1.0)
        } else {
            None
        }
    }

    /// 2: real and imaginary parts.
    fn components(&self) -> usize {
        2
    }

    /// `true`: the blocks are `[[Re G, -Im G], [Im G, Re G]]`.
    fn is_complex(&self) -> bool {
        true
    }

    /// `Re k`: the oscillation the expansions must resolve.
    fn wavenumber(&self) -> f64 {
        self.k
    }

    /// `Re G = e^{-br} cos(ar) / (4 pi r)` for `k = a + i b`.
    #[inline]
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        f0_parts(T::from_f64(self.k), T::from_f64(self.k_im), r2).0
    }

    /// `grad_y Re G = Re f1 d = Re(f0 (z - 1)) d / r^2` with `z = ikr`
    /// (`-(cos kr + kr sin kr) d / (4 pi r^3)` for a real `k`).
    #[inline]
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let (a, b) = (T::from_f64(self.k), T::from_f64(self.k_im));
        let (gr, gi, rinv) = f0_parts(a, b, r2);
        let r = r2 * rinv;
        let (zr, zi) = (-(b * r), a * r);
        let f1 = (gr * (zr - T::ONE) - gi * zi) * rinv * rinv;
        [f1 * d[0], f1 * d[1], f1 * d[2]]
    }

    crate::lanes::kernel_entry_points!();

    /// Every source kind (charges, dipoles or both) and output (potentials,
    /// gradients and Hessians).
    fn supports(&self, _kind: SourceKind, _mode: EvalMode) -> bool {
        true
    }

    /// `[[Re G, -Im G], [Im G, Re G]]` blocks (`2 n_targets x 2 n_sources`,
    /// row-major), zero for coincident pairs.
    fn assemble<T: Real>(&self, sources: &[T], targets: &[T], matrix: &mut [T]) {
        let ns = sources.len() / 3;
        let nt = targets.len() / 3;
        assert_eq!(matrix.len(), 4 * ns * nt, "helmholtz3d: matrix size");
        let (a, b) = (T::from_f64(self.k), T::from_f64(self.k_im));
        let cols = 2 * ns;
        for (j, y) in targets.chunks_exact(3).enumerate() {
            for (i, x) in sources.chunks_exact(3).enumerate() {
                let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let (gr, gi) = if r2 == T::ZERO {
                    (T::ZERO, T::ZERO)
                } else {
                    let (gr, gi, _) = f0_parts(a, b, r2);
                    (gr, gi)
                };
                let top = 2 * j * cols + 2 * i;
                matrix[top] = gr;
                matrix[top + 1] = -gi;
                matrix[top + cols] = gi;
                matrix[top + cols + 1] = gr;
            }
        }
    }
}

impl Helmholtz3d {
    /// The scalar pairwise loop (`sin_cos` and `exp` of the float type,
    /// the radial functions as polynomials in the complex `z = ikr` of the
    /// module docs), the reference the vectorised
    /// [`Kernel::evaluate_sources`] is tested against. Same layout and
    /// panics.
    pub fn evaluate_sources_pairwise<T: Real>(
        &self,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[T],
        densities: &[T],
        targets: &[T],
        out: &mut [T],
    ) {
        if let Err(e) =
            crate::direct::check_lengths(2, kind, mode, [sources, densities, targets, out])
        {
            panic!("helmholtz3d: {e}");
        }
        let (ka, kb) = (T::from_f64(self.k), T::from_f64(self.k_im));
        let vps = 2 * kind.values_per_source();
        let w = 2 * mode.values_per_target();
        let (grad, hess) = (mode.has_gradient(), mode.has_hessian());
        let (has_q, has_n) = (kind != SourceKind::Dipole, kind.has_dipoles());
        let n_off = if has_q { 2 } else { 0 };
        let c = |v: f64| T::from_f64(v);
        for (y, o) in targets.chunks_exact(3).zip(out.chunks_exact_mut(w)) {
            let mut acc = [T::ZERO; 20];
            for (x, q) in sources.chunks_exact(3).zip(densities.chunks_exact(vps)) {
                let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if r2 == T::ZERO {
                    continue;
                }
                let (gr, gi, rinv) = f0_parts(ka, kb, r2);
                let rinv2 = rinv * rinv;
                // z = ikr and the polynomials of the module docs.
                let r = r2 * rinv;
                let (zr, zi) = (-(kb * r), ka * r);
                let z2 = cmul(zr, zi, zr, zi);
                let z3 = cmul(z2.0, z2.1, zr, zi);
                // f1 = f0 (z - 1) / r^2
                let (f1r, f1i) = {
                    let (a, b) = cmul(gr, gi, zr - T::ONE, zi);
                    (a * rinv2, b * rinv2)
                };
                // f2 = f0 (z^2 - 3z + 3) / r^4
                let (f2r, f2i) = {
                    let (a, b) = cmul(gr, gi, z2.0 - c(3.0) * zr + c(3.0), z2.1 - c(3.0) * zi);
                    (a * rinv2 * rinv2, b * rinv2 * rinv2)
                };
                // Coefficient of d in the gradient, and the potential; with
                // Hessians the coefficients of d_a d_b (`h`) and delta_ab
                // (`c`, the gradient's).
                let (mut pr, mut pi) = (T::ZERO, T::ZERO);
                let (mut cr, mut ci) = (T::ZERO, T::ZERO);
                let (mut hr, mut hi) = (T::ZERO, T::ZERO);
                if has_q {
                    let (a, b) = cmul(gr, gi, q[0], q[1]);
                    pr += a;
                    pi += b;
                    if grad {
                        let (a, b) = cmul(f1r, f1i, q[0], q[1]);
                        cr += a;
                        ci += b;
                    }
                    if hess {
                        let (a, b) = cmul(f2r, f2i, q[0], q[1]);
                        hr += a;
                        hi += b;
                    }
                }
                let n = &q[n_off..];
                if has_n {
                    let ndr = n[0] * d[0] + n[2] * d[1] + n[4] * d[2];
                    let ndi = n[1] * d[0] + n[3] * d[1] + n[5] * d[2];
                    let (a, b) = cmul(f1r, f1i, ndr, ndi);
                    pr -= a;
                    pi -= b;
                    if grad {
                        let (a, b) = cmul(f2r, f2i, ndr, ndi);
                        cr -= a;
                        ci -= b;
                    }
                    if hess {
                        // f3 = f0 (z^3 - 6z^2 + 15z - 15) / r^6
                        let (a, b) = cmul(
                            gr,
                            gi,
                            z3.0 - c(6.0) * z2.0 + c(15.0) * zr - c(15.0),
                            z3.1 - c(6.0) * z2.1 + c(15.0) * zi,
                        );
                        let r6 = rinv2 * rinv2 * rinv2;
                        let (a, b) = cmul(a * r6, b * r6, ndr, ndi);
                        hr -= a;
                        hi -= b;
                    }
                }
                acc[0] += pr;
                acc[1] += pi;
                if grad {
                    for m in 0..3 {
                        acc[2 + 2 * m] += cr * d[m];
                        acc[3 + 2 * m] += ci * d[m];
                        if has_n {
                            let (a, b) = cmul(f1r, f1i, n[2 * m], n[2 * m + 1]);
                            acc[2 + 2 * m] -= a;
                            acc[3 + 2 * m] -= b;
                        }
                    }
                }
                if hess {
                    // H_ab = h d_a d_b + c delta_ab - f2 (n_a d_b + n_b d_a)
                    for (slot, (a, b)) in [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
                        .into_iter()
                        .enumerate()
                    {
                        let at = 8 + 2 * slot;
                        acc[at] += hr * d[a] * d[b];
                        acc[at + 1] += hi * d[a] * d[b];
                        if a == b {
                            acc[at] += cr;
                            acc[at + 1] += ci;
                        }
                        if has_n {
                            let (ar, ai) = cmul(f2r, f2i, n[2 * a], n[2 * a + 1]);
                            let (br, bi) = cmul(f2r, f2i, n[2 * b], n[2 * b + 1]);
                            acc[at] -= ar * d[b] + br * d[a];
                            acc[at + 1] -= ai * d[b] + bi * d[a];
                        }
                    }
                }
            }
            for (o, a) in o.iter_mut().zip(acc) {
                *o += a;
            }
        }
    }
}
