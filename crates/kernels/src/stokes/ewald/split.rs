//! Hasimoto's split of the Stokeslet `S(d) = I / r + d d^T / r^3` into a
//! short-range part summed in real space and a smooth part summed in
//! Fourier space (see the [module docs](super)).

use std::f64::consts::FRAC_2_SQRT_PI;

/// Below this `alpha r` the long-range part's `d d^T` coefficient comes
/// from its Taylor series (the closed form cancels).
const SERIES_BELOW: f64 = 0.6;

/// The split at `alpha > 0`. Without the kernel's `1 / (8 pi mu)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HasimotoSplit {
    alpha: f64,
}

/// The radial coefficients of a `3 x 3` block `a I + b d d^T` and, for
/// gradients, `a' / r` and `b' / r` (`b` as a function of `r`), so that
/// `d_c (a delta_ij + b d_i d_j) = (a'/r) d_c delta_ij + (b'/r) d_c d_i
/// d_j + b (delta_ic d_j + delta_jc d_i)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Block {
    pub(crate) a: f64,
    pub(crate) b: f64,
    pub(crate) da: f64,
    pub(crate) db: f64,
}

impl Block {
    /// `u += (a f + b d (d . f))` into `out[0..3]`, and when `grad` the
    /// gradient `d_c u_i` into `out[3 + 3 c + i]`.
    #[inline]
    pub(crate) fn apply(&self, d: [f64; 3], f: [f64; 3], grad: bool, out: &mut [f64; 12]) {
        let df = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
        for i in 0..3 {
            out[i] += self.a * f[i] + self.b * d[i] * df;
        }
        if grad {
            for c in 0..3 {
                for i in 0..3 {
                    let mut v =
                        self.da * d[c] * f[i] + self.db * d[c] * d[i] * df + self.b * d[i] * f[c];
                    if i == c {
                        v += self.b * df;
                    }
                    out[3 + 3 * c + i] += v;
                }
            }
        }
    }
}

impl HasimotoSplit {
    /// The split with parameter `alpha > 0`.
    pub(crate) fn new(alpha: f64) -> Self {
        Self { alpha }
    }

    /// The short-range part `S_R = (erfc(alpha r) / r - E) I + (erfc(alpha
    /// r) / r^3 + E / r^2) d d^T`, `E = 2 alpha e^{-alpha^2 r^2} /
    /// sqrt(pi)`, at `r > 0`; derivatives only when `grad`.
    #[inline]
    pub(crate) fn short(&self, r: f64, grad: bool) -> Block {
        let rinv = 1.0 / r;
        let rinv2 = rinv * rinv;
        let ar = self.alpha * r;
        let c = libm::erfc(ar) * rinv;
        let e = FRAC_2_SQRT_PI * self.alpha * (-ar * ar).exp();
        let a = c - e;
        let b = (c + e) * rinv2;
        if !grad {
            return Block {
                a,
                b,
                ..Block::default()
            };
        }
        let two_a2_e = 2.0 * self.alpha * self.alpha * e;
        Block {
            a,
            b,
            da: -(e + c) * rinv2 + two_a2_e,
            db: -3.0 * (c + e) * rinv2 * rinv2 - two_a2_e * rinv2,
        }
    }

    /// The long-range part `S - S_R = (erf(alpha r) / r + E) I + ((erf(alpha
    /// r) / r - E) / r^2) d d^T`, smooth, at any `r >= 0` (no gradient).
    #[inline]
    pub(crate) fn long(&self, r: f64) -> Block {
        let al = self.alpha;
        let ar = al * r;
        let e = FRAC_2_SQRT_PI * al * (-ar * ar).exp();
        let erf_r = if ar < 1e-8 {
            FRAC_2_SQRT_PI * al * (1.0 - ar * ar / 3.0)
        } else {
            libm::erf(ar) / r
        };
        let b = if ar < SERIES_BELOW {
            // (erf(x)/x - e^{-x^2}) / x^2 = sum_{n>=1} (-1)^(n+1) 2n x^(2n-2) / ((2n+1) n!)
            let x2 = ar * ar;
            let mut term = 1.0; // x^(2n-2) / n! at n = 1
            let mut sum = 0.0;
            for n in 1..=16 {
                let nf = n as f64;
                let sign = if n % 2 == 1 { 1.0 } else { -1.0 };
                sum += sign * 2.0 * nf / (2.0 * nf + 1.0) * term;
                term *= x2 / (nf + 1.0);
            }
            FRAC_2_SQRT_PI * al * al * al * sum
        } else {
            (erf_r - e) / (r * r)
        };
        Block {
            a: erf_r + e,
            b,
            ..Block::default()
        }
    }

    /// The Fourier weight `8 pi (1 + k^2 / (4 alpha^2)) e^{-k^2 / (4
    /// alpha^2)} / k^2` of the projector `I - k k^T / k^2` at `k^2 > 0`.
    #[inline]
    pub(crate) fn fourier(&self, k2: f64) -> f64 {
        let q = k2 / (4.0 * self.alpha * self.alpha);
        8.0 * std::f64::consts::PI * (1.0 + q) * (-q).exp() / k2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `S_R + S_L` is the Stokeslet, and the series meets the closed form.
    #[test]
    fn the_two_parts_sum_to_the_stokeslet() {
        let s = HasimotoSplit::new(3.0);
        for &r in &[1e-3, 0.05, 0.19, 0.2, 0.21, 0.5, 1.3] {
            let (sr, sl) = (s.short(r, false), s.long(r));
            assert!((sr.a + sl.a - 1.0 / r).abs() < 1e-13 / r, "a at {r}");
            let b = 1.0 / (r * r * r);
            assert!((sr.b + sl.b - b).abs() < 1e-12 * b, "b at {r}");
        }
        // Continuity of the long part's series at its switch.
        let x = SERIES_BELOW / 3.0;
        let (lo, hi) = (s.long(x * (1.0 - 1e-9)), s.long(x * (1.0 + 1e-9)));
        assert!((lo.b - hi.b).abs() < 1e-8 * lo.b.abs());
    }

    /// The short part's derivatives against central differences.
    #[test]
    fn short_derivatives_match_differences() {
        let s = HasimotoSplit::new(2.0);
        for &r in &[0.1, 0.4, 0.9] {
            let h = 1e-6;
            let (p, m, c) = (
                s.short(r + h, false),
                s.short(r - h, false),
                s.short(r, true),
            );
            let da = (p.a - m.a) / (2.0 * h) / r;
            let db = (p.b - m.b) / (2.0 * h) / r;
            assert!(
                (da - c.da).abs() < 1e-6 * c.da.abs().max(1.0),
                "{da} {}",
                c.da
            );
            assert!(
                (db - c.db).abs() < 1e-6 * c.db.abs().max(1.0),
                "{db} {}",
                c.db
            );
        }
    }
}
