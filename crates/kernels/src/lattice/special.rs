//! Special functions of the lattice sums that repeat along one axis (rods):
//! the entire exponential integral `Ein` and the incomplete Bessel
//! integrals of the reciprocal sum, by Gauss-Legendre quadrature.
//!
//! # Maths
//! ```text
//! Ein(x) = int_0^x (1 - e^{-t}) / t dt = sum_{n >= 1} (-1)^{n+1} x^n / (n n!)
//!        = E1(x) + ln x + gamma
//! ```
//!
//! (series below `x = 1`, else `E1` by its continued fraction). For `a, b
//! >= 0` and `c > 0`,
//!
//! ```text
//! I(a, b) = int_0^c e^{-a c / u - b u / c} du / u = int_{-inf}^0 e^{-a e^{-v} - b e^v} dv
//! J(a, b) = int_{-inf}^0 e^{v} e^{-a e^{-v} - b e^v} dv
//! ```
//!
//! (`u = c e^v`), taken by composite Gauss-Legendre quadrature in `v` on
//! panels of width 1/2 from `v = ln(a / 46)` (where the integrand is below
//! `e^{-46}`) to 0, 12 nodes a panel: the integrand `e^{-g}` varies on the
//! scale `1 / g` and the rule's error is below `1e-20` wherever it is not
//! itself that small.

use std::sync::OnceLock;

/// Euler's constant.
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// Below this exponent the integrand of `I` and `J` is negligible.
const NEGLIGIBLE_EXPONENT: f64 = 46.0;

/// Panel width in `v`.
const PANEL: f64 = 0.5;

/// Gauss-Legendre nodes per panel.
const NODES: usize = 12;

/// `Ein(x)` for `x >= 0`.
pub(crate) fn ein(x: f64) -> f64 {
    if x == 0.0 {
        return 0.0;
    }
    if x < 1.0 {
        // Alternating series, terms falling at least 2x from n = 2.
        let mut term = x;
        let mut sum = x;
        let mut n = 1.0;
        loop {
            term *= -x / (n + 1.0);
            n += 1.0;
            let t = term / n;
            sum += t;
            if t.abs() <= 1e-17 * sum.abs() {
                return sum;
            }
        }
    }
    e1(x) + x.ln() + EULER_GAMMA
}

/// `E1(x)` for `x >= 1` by its continued fraction (modified Lentz).
fn e1(x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -((i * i) as f64);
        b += 2.0;
        d = 1.0 / (an * d + b);
        c = b + an / c;
        let del = c * d;
        h *= del;
        if (del - 1.0).abs() < 1e-16 {
            break;
        }
    }
    h * (-x).exp()
}

/// Nodes and weights of the `NODES`-point Gauss-Legendre rule on `[-1, 1]`
/// (Newton on the Legendre recurrence).
fn gauss_legendre() -> &'static [(f64, f64); NODES] {
    static RULE: OnceLock<[(f64, f64); NODES]> = OnceLock::new();
    RULE.get_or_init(|| {
        let n = NODES;
        let mut rule = [(0.0, 0.0); NODES];
        for (i, slot) in rule.iter_mut().enumerate() {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            *slot = (x, 2.0 / ((1.0 - x * x) * dp * dp));
        }
        rule
    })
}

/// `(I(a, b), J(a, b))` of the module docs, for `a > 0`, `b >= 0`.
pub(crate) fn incomplete_bessel(a: f64, b: f64) -> (f64, f64) {
    if a >= NEGLIGIBLE_EXPONENT {
        return (0.0, 0.0);
    }
    let rule = gauss_legendre();
    let start = (a / NEGLIGIBLE_EXPONENT).ln();
    let panels = (-start / PANEL).ceil().max(1.0) as usize;
    let width = -start / panels as f64;
    let (mut i_sum, mut j_sum) = (0.0, 0.0);
    for p in 0..panels {
        let mid = start + (p as f64 + 0.5) * width;
        for &(x, w) in rule {
            let v = mid + 0.5 * width * x;
            let ev = v.exp();
            let f = (-a / ev - b * ev).exp() * w;
            i_sum += f;
            j_sum += f * ev;
        }
    }
    (0.5 * width * i_sum, 0.5 * width * j_sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ein_matches_series_and_continued_fraction() {
        // Known values: Ein(1) = 0.796599599297053..., E1(2) = 0.04890051070806112.
        assert!(
            (ein(1.0) - 0.796_599_599_297_053_1).abs() < 1e-15,
            "{}",
            ein(1.0)
        );
        assert!(
            (e1(2.0) - 0.048_900_510_708_061_12).abs() < 1e-16,
            "{}",
            e1(2.0)
        );
        // Continuity at the switch.
        assert!((ein(1.0 - 1e-12) - ein(1.0)).abs() < 1e-11);
        assert_eq!(ein(0.0), 0.0);
    }

    #[test]
    fn incomplete_bessel_integrals() {
        // b = 0: I = E1(a) (u = c e^v: int_a^inf e^{-t}/t dt), J = a K_1-like; check I.
        let (i, _) = incomplete_bessel(2.0, 0.0);
        assert!((i - e1(2.0)).abs() < 1e-15, "{i}");
        // J at b = 0: int e^v e^{-a e^{-v}} dv = a Gamma(-1, a) = e^{-a} - a E1(a).
        let (_, j) = incomplete_bessel(2.0, 0.0);
        assert!((j - ((-2.0f64).exp() - 2.0 * e1(2.0))).abs() < 1e-15, "{j}");
        // Symmetric in a <-> b for I over the whole line; here check against
        // a finer rule by halving panels through the sum of two calls'
        // agreement with a direct trapezoid on a fine grid.
        let (a, b) = (0.3, 5.0);
        let (i, j) = incomplete_bessel(a, b);
        let (mut ti, mut tj) = (0.0, 0.0);
        let h = 1e-4;
        let mut v = 0.0;
        while v > (a / NEGLIGIBLE_EXPONENT).ln() - 1.0 {
            let f = (-a * (-v).exp() - b * v.exp()).exp();
            let wgt = if v == 0.0 { 0.5 } else { 1.0 };
            ti += wgt * h * f;
            tj += wgt * h * f * v.exp();
            v -= h;
        }
        assert!((i - ti).abs() < 1e-9 * i, "{i} {ti}");
        assert!((j - tj).abs() < 1e-9 * j, "{j} {tj}");
    }
}
