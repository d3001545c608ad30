//! The Ewald split of the screened (Yukawa) kernel `e^{-kappa r} / r`,
//! which is Laplace's `1 / r` at `kappa = 0`: the short-range part summed
//! in real space, the long-range part's Fourier coefficients and its value
//! near and at zero distance. One place for this maths; the real-space
//! sum, the reciprocal lattice and [`PeriodicGreen`](super::PeriodicGreen)
//! all call it.
//!
//! # Maths
//! With `b = kappa / (2 alpha)` and `h(t) = e^{kappa t} erfc(b + alpha t)`,
//! the kernel splits as `e^{-kappa r} / r = psi(r) + l(r)`:
//!
//! ```text
//! psi(r) = [ e^{-kappa r} erfc(alpha r - b) + e^{kappa r} erfc(alpha r + b) ] / (2 r)
//! l(r)   = -[ h(r) - h(-r) ] / (2 r)                       (smooth, even)
//! l(0)   = 2 alpha e^{-b^2} / sqrt(pi) - kappa erfc(b)
//! ```
//!
//! `psi` decays like `e^{-alpha^2 r^2 - b^2} / (alpha r^2)`, faster than
//! Laplace's `erfc(alpha r) / r`, so the same real-space cut-off serves;
//! `l` is the inverse transform of
//!
//! ```text
//! l^(k) = 4 pi e^{-(k^2 + kappa^2) / (4 alpha^2)} / (k^2 + kappa^2)
//! ```
//!
//! so a periodic sum of `l` over a cell of volume `V` is
//! `(1/V) sum_k l^(k) e^{i k . r}`, with the `k = 0` term
//! `4 pi e^{-b^2} / (V kappa^2)` when `kappa > 0`. At `kappa = 0` that term
//! is dropped (tin-foil) and the uniform background gives the constant
//! `-pi / (alpha^2 V)` instead (see the [module docs](super)). The
//! short-range part's derivative, for gradients, is
//!
//! ```text
//! psi'(r) = [ kappa (B - A) - 4 alpha e^{-alpha^2 r^2 - b^2} / sqrt(pi) ] / (2 r) - psi / r
//! ```
//!
//! with `A = e^{-kappa r} erfc(alpha r - b)` and `B = e^{kappa r} erfc(alpha
//! r + b)`. Near `r = 0`, `l` is a difference of nearly equal terms, so
//! below `r (alpha (1 + b) + kappa) < 0.02` it is taken from its Taylor
//! series `l(r) = -(h'(0) + h'''(0) r^2 / 6 + h^(5)(0) r^4 / 120)`, the
//! derivatives from Hermite polynomials: `d^j/dt^j erfc(b + alpha t) =
//! -(2 alpha / sqrt(pi)) (-alpha)^(j-1) H_{j-1}(b + alpha t) e^{-(b + alpha
//! t)^2}`.
//!
//! The same cut-offs serve every `b`: at `r_c = s / alpha` (`s^2 =
//! ln(1/tol)`) the larger term is `e^{-kappa r_c} erfc(s - b) ~ e^{-s^2 -
//! b^2}`, so `alpha` is chosen as for Laplace whatever `kappa` is. (Raising
//! it with `kappa` would grow the reciprocal lattice as `kappa^3`: at `kappa
//! L = 2000`, some `1e9` wave vectors.) Strong screening makes `b` large:
//! `psi` is then the whole kernel, `l` vanishes, and `e^{kappa r}
//! erfc(alpha r + b)`, a huge factor times one that underflows, is taken
//! through logarithms where `e^{kappa r}` would overflow.

use super::TWO_OVER_SQRT_PI;

/// Below this `r (alpha (1 + b) + kappa)`, `l(r)` comes from its series.
const SERIES_BELOW: f64 = 0.02;

/// The split of `e^{-kappa r} / r` at `alpha` (module docs). All values
/// are without the kernel's `1 / (4 pi)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Split {
    alpha: f64,
    kappa: f64,
    /// `kappa / (2 alpha)`.
    b: f64,
    /// `e^{-b^2}`.
    gauss_b: f64,
    /// `-h'(0)`, `-h'''(0) / 6`, `-h^(5)(0) / 120`: `l(r)`'s series.
    series: [f64; 3],
    /// `alpha (1 + b) + kappa`: the scale of `l`'s derivatives.
    scale: f64,
}

impl Split {
    /// The split at `alpha > 0` of the kernel with screening `kappa >= 0`.
    pub(crate) fn new(alpha: f64, kappa: f64) -> Self {
        let b = kappa / (2.0 * alpha);
        let gauss_b = (-b * b).exp();
        // u_j = d^j/dt^j erfc(b + alpha t) at t = 0, j = 0..=5.
        let mut hermite = [0.0f64; 5];
        hermite[0] = 1.0;
        hermite[1] = 2.0 * b;
        for n in 1..4 {
            hermite[n + 1] = 2.0 * b * hermite[n] - 2.0 * n as f64 * hermite[n - 1];
        }
        let mut u = [0.0f64; 6];
        u[0] = libm::erfc(b);
        for j in 1..6 {
            u[j] =
                -TWO_OVER_SQRT_PI * alpha * (-alpha).powi(j as i32 - 1) * hermite[j - 1] * gauss_b;
        }
        // h^(m)(0) = sum_j C(m, j) kappa^(m - j) u_j.
        let h = |m: usize| -> f64 {
            let mut binom = 1.0;
            let mut sum = 0.0;
            for (j, uj) in u.iter().enumerate().take(m + 1) {
                sum += binom * kappa.powi((m - j) as i32) * uj;
                binom = binom * (m - j) as f64 / (j + 1) as f64;
            }
            sum
        };
        Split {
            alpha,
            kappa,
            b,
            gauss_b,
            series: [-h(1), -h(3) / 6.0, -h(5) / 120.0],
            scale: alpha * (1.0 + b) + kappa,
        }
    }

    /// `kappa`.
    pub(crate) fn kappa(&self) -> f64 {
        self.kappa
    }

    /// `psi(r)` and, when `grad`, `-psi'(r) / r` (so that the gradient of
    /// `psi(|d|)` with respect to the target is `-that * d`), for `r > 0`.
    #[inline]
    pub(crate) fn short(&self, r: f64, grad: bool) -> (f64, f64) {
        let rinv = 1.0 / r;
        let ar = self.alpha * r;
        if self.kappa == 0.0 {
            let e = libm::erfc(ar);
            let psi = e * rinv;
            let g = if grad {
                (psi + TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp()) * rinv * rinv
            } else {
                0.0
            };
            return (psi, g);
        }
        let kr = self.kappa * r;
        let a = (-kr).exp() * libm::erfc(ar - self.b);
        let b = grow(kr, libm::erfc(ar + self.b));
        let psi = 0.5 * (a + b) * rinv;
        let g = if grad {
            let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp() * self.gauss_b;
            (psi - 0.5 * self.kappa * (b - a) + gauss) * rinv * rinv
        } else {
            0.0
        };
        (psi, g)
    }

    /// `l(r) = e^{-kappa r} / r - psi(r)` for `r >= 0`, accurate to
    /// rounding near zero (series) and at zero (`l(0)`).
    #[inline]
    pub(crate) fn long(&self, r: f64) -> f64 {
        if self.kappa == 0.0 {
            return if r < 1e-300 {
                TWO_OVER_SQRT_PI * self.alpha
            } else {
                libm::erf(self.alpha * r) / r
            };
        }
        if r * self.scale < SERIES_BELOW {
            let r2 = r * r;
            return self.series[0] + r2 * (self.series[1] + r2 * self.series[2]);
        }
        let kr = self.kappa * r;
        let ar = self.alpha * r;
        let forward = grow(kr, libm::erfc(self.b + ar));
        let backward = (-kr).exp() * libm::erfc(self.b - ar);
        (backward - forward) / (2.0 * r)
    }

    /// `-l'(r) / r` for `r >= 0` (so that the gradient of `l(|d|)` with
    /// respect to the target is `-that * d`), from series near zero where
    /// the closed form cancels.
    #[inline]
    pub(crate) fn long_gradient(&self, r: f64) -> f64 {
        if self.kappa == 0.0 {
            let ar = self.alpha * r;
            if ar < 0.05 {
                // erf(x)/x = (2/sqrt(pi)) (1 - x^2/3 + x^4/10 - x^6/42 + ...).
                let x2 = ar * ar;
                let a3 = self.alpha * self.alpha * self.alpha;
                return -TWO_OVER_SQRT_PI * a3 * (-2.0 / 3.0 + x2 * (0.4 - x2 / 7.0));
            }
            // l = erf(ar)/r: l' = 2 alpha e^{-a^2 r^2} / (sqrt(pi) r) - l / r.
            let l = libm::erf(ar) / r;
            let dl = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp() / r - l / r;
            return -dl / r;
        }
        if r * self.scale < SERIES_BELOW {
            return -(2.0 * self.series[1] + 4.0 * self.series[2] * r * r);
        }
        // l = K - psi with K = e^{-kappa r} / r.
        let k = (-self.kappa * r).exp() / r;
        let dk = -k * (self.kappa + 1.0 / r);
        let (_, g) = self.short(r, true);
        -dk / r - g
    }

    /// The Fourier coefficient's factor `e^{-(k^2 + kappa^2) / (4 alpha^2)}
    /// / (k^2 + kappa^2)` (times `4 pi / V` in a sum) at `k^2 > 0`.
    #[inline]
    pub(crate) fn fourier(&self, k2: f64) -> f64 {
        let q2 = k2 + self.kappa * self.kappa;
        (-q2 / (4.0 * self.alpha * self.alpha)).exp() / q2
    }

    /// The constant a unit source adds through the `k = 0` term of a
    /// periodic sum over a cell of volume `V`, times `1 / (4 pi)`: `e^{-b^2}
    /// / (V kappa^2)` when screened, and for Laplace the uniform
    /// background's `-1 / (4 alpha^2 V)` (tin-foil).
    pub(crate) fn k_zero(&self, volume: f64) -> f64 {
        if self.kappa == 0.0 {
            -1.0 / (4.0 * self.alpha * self.alpha * volume)
        } else {
            self.gauss_b / (volume * self.kappa * self.kappa)
        }
    }
}

/// `e^{x} e`, finite where the product is: for `x` beyond `exp`'s range
/// the product is taken through logarithms (it is then tiny, `e` being an
/// `erfc` far in its tail).
#[inline]
pub(crate) fn grow(x: f64, e: f64) -> f64 {
    if x < 700.0 {
        x.exp() * e
    } else if e > 0.0 {
        (x + e.ln()).exp()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `psi + l` is the kernel, and `l`'s series joins its closed form.
    #[test]
    fn split_adds_up_and_series_joins() {
        for &(alpha, kappa) in &[
            (3.0, 0.0),
            (3.0, 1.0),
            (2.0, 7.5),
            (7.0, 40.0),
            (7.0, 2000.0),
        ] {
            let s = Split::new(alpha, kappa);
            for &r in &[1e-3, 0.05, 0.3, 0.9, 1.7] {
                let (psi, _) = s.short(r, false);
                let exact = (-kappa * r).exp() / r;
                assert!(
                    ((psi + s.long(r)) - exact).abs() <= 1e-14 * exact,
                    "alpha {alpha} kappa {kappa} r {r}"
                );
            }
            // Either side of the series threshold.
            let r0 = SERIES_BELOW / s.scale;
            let (lo, hi) = (s.long(r0 * (1.0 - 1e-13)), s.long(r0 * (1.0 + 1e-13)));
            assert!((lo - hi).abs() <= 1e-12 * lo.abs().max(1.0), "{lo} {hi}");
            // l(0) = 2 alpha e^{-b^2} / sqrt(pi) - kappa erfc(b).
            let b = kappa / (2.0 * alpha);
            let l0 = TWO_OVER_SQRT_PI * alpha * (-b * b).exp() - kappa * libm::erfc(b);
            assert!((s.long(0.0) - l0).abs() <= 1e-14 * l0.abs());
        }
    }

    /// The gradient factor is `-psi' / r` (central differences).
    #[test]
    fn short_derivative() {
        for &(alpha, kappa) in &[(3.0, 0.0), (2.0, 7.5)] {
            let s = Split::new(alpha, kappa);
            for &r in &[0.1, 0.4, 1.1] {
                let h = 1e-5;
                let d = (s.short(r + h, false).0 - s.short(r - h, false).0) / (2.0 * h);
                let g = s.short(r, true).1;
                assert!((-d / r - g).abs() <= 1e-6 * g.abs(), "{d} {g}");
            }
        }
    }
}
