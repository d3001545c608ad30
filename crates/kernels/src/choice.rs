//! The built-in kernels by name: what a command line or a configuration file
//! names (`laplace`, `yukawa:2.5`, `helmholtz:10`, `stokes`), parsed once
//! for every front end, and handed to generic code through
//! [`KernelVisitor`].
//!
//! | name | kernel `K(x, y)`, `r = abs(x - y)` | components `c` |
//! |---|---|---|
//! | `laplace` | `1 / (4 pi r)` ([`Laplace3d`]) | 1 |
//! | `yukawa:K` (or `modified-helmholtz:K`) | `exp(-K r) / (4 pi r)`, `K >= 0` ([`ModifiedHelmholtz3d`]) | 1 |
//! | `helmholtz:K` | `exp(i K r) / (4 pi r)`, `K >= 0` ([`Helmholtz3d`]; charges and values as `[re, im]`) | 2 |
//! | `stokes` | the Stokeslet `(I / r + r r^T / r^3) / (8 pi)`, viscosity 1 ([`Stokes3d`]; forces in, velocities out) | 3 |
//!
//! ```
//! use ferrofmm_kernels::{Kernel, KernelChoice, KernelVisitor};
//! let k: KernelChoice = "helmholtz:10".parse().unwrap();
//! assert_eq!(k.components(), 2);
//! assert_eq!(k.name(), "helmholtz:10");
//! struct Name;
//! impl KernelVisitor for Name {
//!     type Output = String;
//!     fn visit<K: Kernel>(self, kernel: K) -> String {
//!         kernel.name()
//!     }
//! }
//! assert_eq!(KernelChoice::Stokes.visit(Name), "stokes3d");
//! assert!("yukawa".parse::<KernelChoice>().is_err()); // no wavenumber
//! ```

use std::str::FromStr;

use crate::{Helmholtz3d, Kernel, Laplace3d, ModifiedHelmholtz3d, Stokes3d};

/// One of the built-in kernels with its parameter (see the [module
/// docs](self) for the names and formulas).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KernelChoice {
    /// Laplace `1 / (4 pi r)`.
    Laplace,
    /// Modified Helmholtz (Yukawa) `exp(-k r) / (4 pi r)` with `k >= 0`.
    Yukawa(f64),
    /// Helmholtz `exp(i k r) / (4 pi r)` with `k >= 0`: complex charges and
    /// values (two components, real and imaginary parts).
    Helmholtz(f64),
    /// The Stokeslet (unit viscosity): forces in, velocities out (three
    /// components).
    Stokes,
}

/// A kernel name that is not one of [`KernelChoice`]'s, or a parameter
/// out of range; displays as `name: why`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{spec}: {why}")]
pub struct ParseKernelError {
    /// The text that was parsed.
    pub spec: String,
    /// What is wrong with it.
    pub why: String,
}

/// Generic code over the kernel a [`KernelChoice`] names:
/// [`KernelChoice::visit`] calls [`KernelVisitor::visit`] with the kernel
/// value, so one generic function serves every built-in kernel.
pub trait KernelVisitor {
    /// What the visit returns.
    type Output;
    /// Called with the chosen kernel.
    fn visit<K: Kernel>(self, kernel: K) -> Self::Output;
}

impl KernelChoice {
    /// Parses `laplace`, `yukawa:K` (alias `modified-helmholtz:K`),
    /// `helmholtz:K` or `stokes`; the wavenumber must be finite and `>= 0`.
    ///
    /// # Errors
    /// [`ParseKernelError`] naming what is wrong.
    pub fn parse(spec: &str) -> Result<Self, ParseKernelError> {
        let bad = |why: String| ParseKernelError {
            spec: spec.to_string(),
            why,
        };
        let wavenumber = |k: &str| {
            k.parse::<f64>()
                .map_err(|_| bad(format!("the wavenumber `{k}` is not a number")))
        };
        match spec.split_once(':') {
            None if spec == "laplace" => Ok(KernelChoice::Laplace),
            None if spec == "stokes" => Ok(KernelChoice::Stokes),
            Some(("yukawa" | "modified-helmholtz", k)) => {
                let k = wavenumber(k)?;
                ModifiedHelmholtz3d::new(k)
                    .map(|_| KernelChoice::Yukawa(k))
                    .map_err(|e| bad(e.to_string()))
            }
            Some(("helmholtz", k)) => {
                let k = wavenumber(k)?;
                Helmholtz3d::new(k)
                    .map(|_| KernelChoice::Helmholtz(k))
                    .map_err(|e| bad(e.to_string()))
            }
            None if spec == "yukawa" || spec == "modified-helmholtz" || spec == "helmholtz" => {
                Err(bad(format!("give the wavenumber, e.g. {spec}:2.5")))
            }
            _ => Err(bad("use laplace, yukawa:K, helmholtz:K or stokes".into())),
        }
    }

    /// The name [`KernelChoice::parse`] reads back: `laplace`, `yukawa:K`,
    /// `helmholtz:K` or `stokes`.
    pub fn name(self) -> String {
        match self {
            KernelChoice::Laplace => "laplace".to_string(),
            KernelChoice::Yukawa(k) => format!("yukawa:{k}"),
            KernelChoice::Helmholtz(k) => format!("helmholtz:{k}"),
            KernelChoice::Stokes => "stokes".to_string(),
        }
    }

    /// The kernel's [components](Kernel::components): values per charge
    /// and per output quantity (1, 2 for Helmholtz, 3 for Stokes).
    pub fn components(self) -> usize {
        self.component_names().len().max(1)
    }

    /// Suffixes of one quantity's columns: none for the scalar kernels,
    /// `re, im` for Helmholtz, `x, y, z` for Stokes.
    pub fn component_names(self) -> &'static [&'static str] {
        match self {
            KernelChoice::Laplace | KernelChoice::Yukawa(_) => &[],
            KernelChoice::Helmholtz(_) => &["re", "im"],
            KernelChoice::Stokes => &["x", "y", "z"],
        }
    }

    /// Whether the kernel takes dipole sources: all but Stokes, whose
    /// sources are point forces.
    pub fn takes_dipoles(self) -> bool {
        self != KernelChoice::Stokes
    }

    /// `Ok` when the kernel takes dipole sources, else why not, as the
    /// one-line message every command prints (`--kernel stokes does not
    /// support dipole sources ...`).
    pub fn check_dipoles(self) -> Result<(), String> {
        if self.takes_dipoles() {
            Ok(())
        } else {
            Err(format!(
                "--kernel {} does not support dipole sources (its sources are point forces: --charges)",
                self.name()
            ))
        }
    }

    /// Calls `visitor` with the kernel (the wavenumbers were checked by
    /// [`KernelChoice::parse`]; a variant built by hand with an invalid
    /// one is clamped to 0 rather than panicking).
    pub fn visit<V: KernelVisitor>(self, visitor: V) -> V::Output {
        let valid = |k: f64| if k.is_finite() && k >= 0.0 { k } else { 0.0 };
        match self {
            KernelChoice::Laplace => visitor.visit(Laplace3d),
            KernelChoice::Yukawa(k) => visitor.visit(
                ModifiedHelmholtz3d::new(valid(k)).expect("a finite wavenumber >= 0 is valid"),
            ),
            KernelChoice::Helmholtz(k) => visitor
                .visit(Helmholtz3d::new(valid(k)).expect("a finite wavenumber >= 0 is valid")),
            KernelChoice::Stokes => visitor.visit(Stokes3d::default()),
        }
    }
}

impl FromStr for KernelChoice {
    type Err = ParseKernelError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        KernelChoice::parse(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_bad_names_are_errors() {
        for k in [
            KernelChoice::Laplace,
            KernelChoice::Yukawa(2.5),
            KernelChoice::Helmholtz(10.0),
            KernelChoice::Stokes,
        ] {
            assert_eq!(KernelChoice::parse(&k.name()), Ok(k));
        }
        assert_eq!(
            KernelChoice::parse("modified-helmholtz:1"),
            Ok(KernelChoice::Yukawa(1.0))
        );
        for bad in [
            "",
            "coulomb",
            "yukawa",
            "helmholtz:x",
            "yukawa:-1",
            "helmholtz:inf",
        ] {
            let e = KernelChoice::parse(bad).unwrap_err();
            assert_eq!(e.spec, bad);
            assert!(!e.why.is_empty());
        }
    }

    #[test]
    fn visit_hands_over_the_named_kernel() {
        struct Describe;
        impl KernelVisitor for Describe {
            type Output = (String, usize);
            fn visit<K: Kernel>(self, kernel: K) -> (String, usize) {
                (kernel.name(), kernel.components())
            }
        }
        for (k, c) in [
            (KernelChoice::Laplace, 1),
            (KernelChoice::Yukawa(1.0), 1),
            (KernelChoice::Helmholtz(3.0), 2),
            (KernelChoice::Stokes, 3),
        ] {
            let (_, got) = k.visit(Describe);
            assert_eq!(got, c);
            assert_eq!(k.components(), c);
        }
    }
}
