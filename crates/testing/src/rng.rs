//! Deterministic random numbers for tests.
//!
//! [`SplitMix64`] (Steele, Lea & Flood 2014) is the generator of the
//! operator tests: a 64-bit counter stepped by the golden-ratio increment
//! `0x9E3779B97F4A7C15` and finalised by two xor-shift-multiply rounds. It
//! needs no crate and its streams never change between `rand` versions.
//! [`seeded`] is a `StdRng` from a `u64` seed, for tests that want `rand`'s
//! distributions.

use rand::SeedableRng;
use rand::rngs::StdRng;

/// SplitMix64: `z = s += 0x9E3779B97F4A7C15`, then
/// `z = (z ^ z >> 30) * 0xBF58476D1CE4E5B9`,
/// `z = (z ^ z >> 27) * 0x94D049BB133111EB`, output `z ^ z >> 31`.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`: the top 53 bits over `2^53`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
}

/// A `StdRng` seeded from `seed` (`SeedableRng::seed_from_u64`).
pub fn seeded(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_is_in_range_and_deterministic() {
        let mut a = SplitMix64(42);
        let mut b = SplitMix64(42);
        for _ in 0..1000 {
            let x = a.range(-2.0, 3.0);
            assert!((-2.0..3.0).contains(&x));
            assert_eq!(x, b.range(-2.0, 3.0));
        }
        assert_ne!(SplitMix64(1).next_u64(), SplitMix64(2).next_u64());
    }
}
