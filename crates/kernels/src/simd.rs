//! Runtime choice of the instruction set used by the vectorised kernels.
//!
//! The crate is compiled for the portable baseline (`x86_64` = SSE2, no
//! `-C target-cpu` needed). Kernels that have hand-vectorised variants
//! compile them with `#[target_feature]` and pick one at run time:
//!
//! | [`SimdLevel`] | requires | used for |
//! |---|---|---|
//! | [`SimdLevel::Avx512`] | `avx512f` | 8 `f64` / 16 `f32` target lanes per register |
//! | [`SimdLevel::Avx2`] | `avx2` and `fma` | 4 `f64` / 8 `f32` target lanes per register |
//! | [`SimdLevel::Scalar`] | nothing | portable lane-chunked Rust (auto-vectorised for the baseline) |
//!
//! [`SimdLevel::detected`] is the best level the CPU supports (detected once
//! and cached). [`SimdLevel::active`] is the level the dispatching entry points
//! (e.g. [`Laplace3d`](crate::Laplace3d)'s `evaluate`) use: the detected one,
//! unless lowered with [`set_simd_level`] or the environment variable
//! `FERROFMM_SIMD` (`scalar`, `avx2` or `avx512`, read once). Functions such as
//! [`laplace_p2p_with`](crate::laplace_p2p_with) take the level explicitly,
//! which is what tests and benchmarks should use.
//!
//! A requested level is always clamped to what the CPU supports, so no choice
//! made through this API can execute an unsupported instruction.

use std::fmt;
use std::str::FromStr;
use std::sync::atomic::{AtomicU8, Ordering};

/// An instruction-set level for the hand-vectorised kernels, ordered from
/// least to most capable (`Scalar < Avx2 < Avx512`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdLevel {
    /// Portable Rust with lane-chunked loops (exact `sqrt` and division);
    /// runs everywhere, the compiler vectorises it for the baseline target.
    Scalar,
    /// x86-64 AVX2 + FMA (256-bit registers).
    Avx2,
    /// x86-64 AVX-512F (512-bit registers, mask registers, `vrsqrt14`).
    Avx512,
}

const UNSET: u8 = u8::MAX;
static DETECTED: AtomicU8 = AtomicU8::new(UNSET);
/// `UNSET`: not yet initialised from the environment; `NO_OVERRIDE`: none.
static OVERRIDE: AtomicU8 = AtomicU8::new(UNSET);
const NO_OVERRIDE: u8 = u8::MAX - 1;

impl SimdLevel {
    /// Every level, from least to most capable.
    pub const ALL: [SimdLevel; 3] = [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512];

    /// Short lower-case name: `"scalar"`, `"avx2"` or `"avx512"`.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
        }
    }

    fn to_u8(self) -> u8 {
        self as u8
    }

    fn from_u8(v: u8) -> SimdLevel {
        match v {
            0 => SimdLevel::Scalar,
            1 => SimdLevel::Avx2,
            _ => SimdLevel::Avx512,
        }
    }

    /// The most capable level this CPU supports (detected on first call, then
    /// cached).
    pub fn detected() -> SimdLevel {
        let v = DETECTED.load(Ordering::Relaxed);
        if v != UNSET {
            return SimdLevel::from_u8(v);
        }
        let level = detect();
        DETECTED.store(level.to_u8(), Ordering::Relaxed);
        level
    }

    /// Whether this CPU can run this level (`self <= SimdLevel::detected()`).
    pub fn is_supported(self) -> bool {
        self <= SimdLevel::detected()
    }

    /// The supported levels, least capable first (always starts with
    /// [`SimdLevel::Scalar`]).
    pub fn supported() -> Vec<SimdLevel> {
        SimdLevel::ALL
            .into_iter()
            .filter(|l| l.is_supported())
            .collect()
    }

    /// `self` lowered to the most capable supported level.
    pub fn clamp_supported(self) -> SimdLevel {
        self.min(SimdLevel::detected())
    }

    /// The level used by dispatching entry points: the override from
    /// [`set_simd_level`] or `FERROFMM_SIMD` if any, else
    /// [`SimdLevel::detected`]; always supported by this CPU.
    pub fn active() -> SimdLevel {
        let mut v = OVERRIDE.load(Ordering::Relaxed);
        if v == UNSET {
            v = match std::env::var("FERROFMM_SIMD")
                .ok()
                .and_then(|s| s.parse::<SimdLevel>().ok())
            {
                Some(l) => l.to_u8(),
                None => NO_OVERRIDE,
            };
            // A concurrent `set_simd_level` wins over the environment.
            v = match OVERRIDE.compare_exchange(UNSET, v, Ordering::Relaxed, Ordering::Relaxed) {
                Ok(_) => v,
                Err(current) => current,
            };
        }
        if v == NO_OVERRIDE {
            SimdLevel::detected()
        } else {
            SimdLevel::from_u8(v).clamp_supported()
        }
    }
}

/// Force the level used by dispatching entry points for the whole process
/// (`None` restores automatic detection). The request is clamped to what the
/// CPU supports; the level that will actually be used is returned.
///
/// This is a global switch meant for benchmarks and experiments (e.g. timing a
/// whole FMM with the portable P2P). Code that runs concurrently should prefer
/// the explicit `*_with(level, ..)` functions.
///
/// ```
/// use ferrofmm_kernels::{set_simd_level, SimdLevel};
/// assert_eq!(set_simd_level(Some(SimdLevel::Scalar)), SimdLevel::Scalar);
/// assert_eq!(SimdLevel::active(), SimdLevel::Scalar);
/// set_simd_level(None);
/// assert_eq!(SimdLevel::active(), SimdLevel::detected());
/// ```
pub fn set_simd_level(level: Option<SimdLevel>) -> SimdLevel {
    OVERRIDE.store(
        level.map_or(NO_OVERRIDE, SimdLevel::to_u8),
        Ordering::Relaxed,
    );
    SimdLevel::active()
}

#[cfg(target_arch = "x86_64")]
fn detect() -> SimdLevel {
    if std::arch::is_x86_feature_detected!("avx512f") {
        SimdLevel::Avx512
    } else if std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
    {
        SimdLevel::Avx2
    } else {
        SimdLevel::Scalar
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> SimdLevel {
    SimdLevel::Scalar
}

impl fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error parsing a [`SimdLevel`] name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown SIMD level {0:?} (expected scalar, avx2 or avx512)")]
pub struct ParseSimdLevelError(pub String);

impl FromStr for SimdLevel {
    type Err = ParseSimdLevelError;

    /// Parses `"scalar"`, `"avx2"` or `"avx512"` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "scalar" => Ok(SimdLevel::Scalar),
            "avx2" => Ok(SimdLevel::Avx2),
            "avx512" => Ok(SimdLevel::Avx512),
            _ => Err(ParseSimdLevelError(s.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordering_names_and_parsing() {
        assert!(SimdLevel::Scalar < SimdLevel::Avx2 && SimdLevel::Avx2 < SimdLevel::Avx512);
        for l in SimdLevel::ALL {
            assert_eq!(l.name().parse::<SimdLevel>().unwrap(), l);
            assert_eq!(SimdLevel::from_u8(l.to_u8()), l);
        }
        assert!("sse9".parse::<SimdLevel>().is_err());
        assert!(SimdLevel::Scalar.is_supported());
        assert_eq!(SimdLevel::supported()[0], SimdLevel::Scalar);
        assert_eq!(SimdLevel::Avx512.clamp_supported(), SimdLevel::detected());
    }
}
