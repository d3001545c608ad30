//! Seeded charge vectors.
//!
//! Accuracy must be shown on both kinds of charge: with charges of one sign
//! the potential is as large as the sum of the terms the FMM approximates;
//! with zero-mean charges it is a small difference of large terms, and the
//! relative error is several times larger for the same absolute error.

use rand::RngExt;

use crate::rng::{SplitMix64, seeded};

/// The sign structure of a charge vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChargeSign {
    /// Uniform in `[0, 1)`: no cancellation.
    Positive,
    /// Uniform in `[-1, 1)`, then the mean subtracted: `sum q = 0` to
    /// rounding.
    ZeroMean,
}

/// `n` charges of the given sign structure from [`seeded`]`(seed)`.
pub fn with_sign(n: usize, sign: ChargeSign, seed: u64) -> Vec<f64> {
    match sign {
        ChargeSign::Positive => uniform_in(n, 0.0, 1.0, seed),
        ChargeSign::ZeroMean => {
            let mut q = uniform_in(n, -1.0, 1.0, seed);
            let mean = q.iter().sum::<f64>() / n.max(1) as f64;
            q.iter_mut().for_each(|v| *v -= mean);
            q
        }
    }
}

/// `n` charges uniform in `[lo, hi)` from [`seeded`]`(seed ^ 0x5eed)` (the
/// seed is mixed so that charges and points drawn with the same seed are
/// not the same numbers).
pub fn uniform_in(n: usize, lo: f64, hi: f64, seed: u64) -> Vec<f64> {
    let mut rng = seeded(seed ^ 0x5eed);
    (0..n).map(|_| rng.random_range(lo..hi)).collect()
}

/// `count` charges uniform in `[0, 1)` from an existing generator.
pub fn positive_from(rng: &mut SplitMix64, count: usize) -> Vec<f64> {
    (0..count).map(|_| rng.uniform()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signs_and_ranges() {
        let p = with_sign(1000, ChargeSign::Positive, 1);
        assert!(p.iter().all(|q| (0.0..1.0).contains(q)));
        let z = with_sign(1000, ChargeSign::ZeroMean, 1);
        assert!(z.iter().sum::<f64>().abs() < 1e-10);
        assert!(z.iter().any(|&q| q < 0.0) && z.iter().any(|&q| q > 0.0));
        assert!(with_sign(0, ChargeSign::ZeroMean, 1).is_empty());
        let u = uniform_in(100, -3.0, -2.0, 4);
        assert!(u.iter().all(|q| (-3.0..-2.0).contains(q)));
    }
}
