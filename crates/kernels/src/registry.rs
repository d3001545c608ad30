//! The built-in kernels by name, described once for every front end.
//!
//! A command line, a configuration file or Python names a kernel as text
//! (`laplace`, `yukawa:2.5`, `helmholtz:10`, `stokes`). Everything a front
//! end needs to know about it — its names, its parameter, its components,
//! which sources it takes, which M2L scheme `auto` means for it and which
//! tuning model the accuracy chooser uses — is one [`KernelDescription`],
//! supplied by the kernel type through [`BuiltinKernel`]. The list of
//! registered types (the `registry!` invocation at the bottom of this file)
//! is the only other place a built-in kernel is named: the CLI, the MPI
//! command, the Python module and the chooser read the descriptions, and
//! generic code reaches the kernel value through [`KernelVisitor`].
//!
//! | name | kernel `K(x, y)`, `r = abs(x - y)` | components `c` |
//! |---|---|---|
//! | `laplace` | `1 / (4 pi r)` ([`Laplace3d`]) | 1 |
//! | `yukawa:K` (or `modified-helmholtz:K`) | `exp(-K r) / (4 pi r)`, `K >= 0` ([`ModifiedHelmholtz3d`]) | 1 |
//! | `helmholtz:K` | `exp(i K r) / (4 pi r)`, `K >= 0` or complex `A+Bi` with `B >= 0` (damped; [`Helmholtz3d`]; charges and values as `[re, im]`) | 2 |
//! | `stokes` | the Stokeslet `(I / r + r r^T / r^3) / (8 pi)`, viscosity 1 ([`Stokes3d`]; forces in, velocities out) | 3 |
//!
//! ```
//! use ferrofmm_kernels::{Kernel, KernelChoice, KernelVisitor};
//! let k: KernelChoice = "helmholtz:10".parse().unwrap();
//! assert_eq!(k.components(), 2);
//! assert_eq!(k.name(), "helmholtz:10");
//! assert_eq!(k.parameter(), Some(10.0));
//! // A complex wavenumber (damped waves), written `A+Bi` (or `A+Bj`):
//! let damped: KernelChoice = "helmholtz:10+0.5i".parse().unwrap();
//! assert_eq!((damped.parameter(), damped.imaginary_part()), (Some(10.0), 0.5));
//! assert_eq!(damped.name(), "helmholtz:10+0.5i");
//! assert!("yukawa:1+1i".parse::<KernelChoice>().is_err()); // a real parameter
//! struct Name;
//! impl KernelVisitor for Name {
//!     type Output = String;
//!     fn visit<K: Kernel>(self, kernel: K) -> String {
//!         kernel.name()
//!     }
//! }
//! assert_eq!(KernelChoice::parse("stokes").unwrap().visit(Name), "stokes3d");
//! assert!("yukawa".parse::<KernelChoice>().is_err()); // no wavenumber
//! // Every built-in kernel, for help texts and bindings:
//! let names: Vec<&str> = KernelChoice::registered().iter().map(|d| d.name).collect();
//! assert!(names.starts_with(&["laplace", "yukawa", "helmholtz", "stokes"]));
//! ```
//!
//! # Registering a kernel
//! Give the kernel type (in its own folder) an `impl BuiltinKernel` with
//! its description, and add the type to the `registry!` list below. Its
//! name then parses on every surface; see docs/architecture.md, "Add a
//! kernel".

use std::any::Any;
use std::str::FromStr;

use crate::{
    Helmholtz3d, Kernel, KernelError, Laplace3d, ModifiedHelmholtz3d, SourceKind, Stokes3d,
};

/// What every front end needs to know about a built-in kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelDescription {
    /// The name on every surface (`laplace`, `yukawa`, ...): the part of
    /// `name:PARAMETER` before the colon.
    pub name: &'static str,
    /// Other names accepted for it (`modified-helmholtz` for `yukawa`).
    pub aliases: &'static [&'static str],
    /// One line for help texts: the formula and what goes in and out.
    pub summary: &'static str,
    /// The kernel as a report's header names it, `{}` standing for the
    /// parameter's value (`modified Helmholtz exp(-{} r)/(4 pi r)`); see
    /// [`KernelChoice::title`].
    pub title: &'static str,
    /// The kernel's one parameter, when it has one (`name:VALUE`).
    pub parameter: Option<ParameterDescription>,
    /// Suffixes of one quantity's columns: none for a scalar kernel, `re,
    /// im` for a complex one, `x, y, z` for a vector one. Their count is
    /// the kernel's [components](Kernel::components) (at least 1).
    pub component_names: &'static [&'static str],
    /// Whether the components are the real and imaginary parts of complex
    /// values (front ends may then take and give complex arrays).
    pub complex: bool,
    /// The source kinds it takes.
    pub source_kinds: &'static [SourceKind],
    /// What front ends call one source's density (`charges`, or `forces`
    /// for Stokes).
    pub density_name: &'static str,
    /// What the scheme `auto` means for it.
    pub auto_scheme: AutoScheme,
    /// Which tuning model the accuracy chooser uses for it.
    pub tuning: TuningFamily,
}

impl KernelDescription {
    /// How the name is written with a placeholder for its parameter:
    /// `laplace`, `yukawa:K`.
    pub fn spelling(&self) -> String {
        match self.parameter {
            Some(p) => format!("{}:{}", self.name, p.name.to_uppercase()),
            None => self.name.to_string(),
        }
    }

    /// The kernel with its example parameter (`yukawa:2.5`), for examples
    /// and for tests that run every registered kernel.
    pub fn example(&self) -> KernelChoice {
        let name = match self.parameter {
            Some(p) => format!("{}:{}", self.name, p.example),
            None => self.name.to_string(),
        };
        KernelChoice::parse(&name)
            .unwrap_or_else(|e| unreachable!("a registered example parses: {e}"))
    }
}

/// A kernel's one parameter (`yukawa:K`), real or complex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParameterDescription {
    /// Its short name (`k`, the keyword in Python).
    pub name: &'static str,
    /// What it is (`wavenumber`).
    pub meaning: &'static str,
    /// A value for examples in messages (`2.5`).
    pub example: &'static str,
    /// Whether it may be complex (`helmholtz:10+0.5i`; a Python `complex`):
    /// the kernel type's [`BuiltinKernel::with_complex_parameter`] takes
    /// the imaginary part.
    pub complex: bool,
}

/// What the M2L scheme `auto` means for a kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AutoScheme {
    /// With a tolerance, whichever scheme the cost model predicts faster;
    /// without, SVD.
    CostModel,
    /// Always FFT: kernels with several components, whose SVD
    /// precomputation factorises `c` times larger matrices (FFT builds
    /// 7-40x faster to the same accuracy, docs/kernels.md), and kernels
    /// without [homogeneity](Kernel::homogeneity), whose operators are
    /// built per level (an SVD compression at every level: tens of seconds
    /// where FFT's precomputation takes well under one).
    Fft,
}

/// Which measured error and cost model of the FMM's tuning serves a
/// kernel (the models live in `ferrofmm_fmm::tuning`; this names them so
/// the description can say which).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TuningFamily {
    /// The Laplace model (also borrowed by unregistered kernels).
    Laplace,
    /// The screened model, scaled by `k` times the domain width.
    ModifiedHelmholtz,
    /// The oscillatory model, scaled by `k` times the domain width.
    Helmholtz,
    /// The Stokes model.
    Stokes,
}

/// A kernel type with a name on every surface: its description and how to
/// make it from its parameter.
pub trait BuiltinKernel: Kernel {
    /// The description every front end reads.
    const DESCRIPTION: KernelDescription;

    /// The kernel with `parameter` (`None` exactly when the description
    /// has no parameter).
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a value out of range.
    fn with_parameter(parameter: Option<f64>) -> Result<Self, KernelError>;

    /// The parameter of this value (`None` when it has none); its real
    /// part when it is complex.
    fn parameter(&self) -> Option<f64>;

    /// The kernel with the complex parameter `re + i im`, for a kernel
    /// whose description says its parameter may be complex
    /// ([`ParameterDescription::complex`]). The default takes a real one
    /// only.
    ///
    /// # Errors
    /// [`KernelError::InvalidParameter`] for a value out of range, or an
    /// imaginary part the kernel does not take.
    fn with_complex_parameter(re: f64, im: f64) -> Result<Self, KernelError> {
        if im == 0.0 {
            Self::with_parameter(Some(re))
        } else {
            Err(KernelError::InvalidParameter {
                name: "imaginary part",
                value: im,
                expected: "0 (the parameter is real)",
            })
        }
    }

    /// The imaginary part of this value's parameter (0 unless complex).
    fn imaginary_part(&self) -> f64 {
        0.0
    }
}

/// One of the built-in kernels with its parameter (see the [module
/// docs](self) for the names and formulas): made by [`KernelChoice::parse`],
/// [`KernelChoice::from_parts`] or [`KernelChoice::of`], so its parameter
/// is always valid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelChoice {
    /// Index into the registry.
    index: usize,
    parameter: Option<f64>,
    /// The parameter's imaginary part (0 unless it is complex).
    imaginary: f64,
}

/// A kernel name that is not a registered one, or a parameter out of
/// range; displays as `name: why`.
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
    /// Parses `NAME` or `NAME:PARAMETER` (`laplace`, `yukawa:K`, alias
    /// `modified-helmholtz:K`, `helmholtz:K`, `stokes`); a complex
    /// parameter is written `A+Bi`, `A-Bi`, `Bi` (or with `j`), without
    /// spaces or with them (`helmholtz:10+0.5i`).
    ///
    /// # Errors
    /// [`ParseKernelError`] naming what is wrong.
    pub fn parse(spec: &str) -> Result<Self, ParseKernelError> {
        let bad = |why: String| ParseKernelError {
            spec: spec.to_string(),
            why,
        };
        let (name, parameter) = match spec.split_once(':') {
            Some((name, value)) => {
                let value = parse_complex(value).ok_or_else(|| {
                    let meaning = lookup(name)
                        .and_then(|(_, d)| d.parameter)
                        .map_or("parameter", |p| p.meaning);
                    bad(format!("the {meaning} `{value}` is not a number"))
                })?;
                (name, Some(value))
            }
            None => (spec, None),
        };
        let (re, im) = parameter.map_or((None, 0.0), |(re, im)| (Some(re), im));
        Self::made(name, re, im).map_err(|e| bad(e.why))
    }

    /// The kernel called `name` with the complex parameter `re + i im`
    /// (`kernel="helmholtz", k=10+0.5j` in Python).
    ///
    /// # Errors
    /// [`ParseKernelError`] for an unknown name, a kernel whose parameter
    /// is real (and `im != 0`), or a value out of range.
    pub fn from_complex_parts(name: &str, re: f64, im: f64) -> Result<Self, ParseKernelError> {
        Self::made(name, Some(re), im)
    }

    /// The kernel called `name` (or an alias) with `parameter`, as a
    /// binding passes them (`kernel="yukawa", k=2.5`).
    ///
    /// # Errors
    /// [`ParseKernelError`] for an unknown name, a missing or unexpected
    /// parameter, or a value out of range.
    pub fn from_parts(name: &str, parameter: Option<f64>) -> Result<Self, ParseKernelError> {
        Self::made(name, parameter, 0.0)
    }

    /// [`KernelChoice::from_complex_parts`] and [`KernelChoice::from_parts`]:
    /// the parameter `parameter + i imaginary` (`imaginary` 0 for a real
    /// one), checked by name, presence, kind and range.
    fn made(name: &str, parameter: Option<f64>, imaginary: f64) -> Result<Self, ParseKernelError> {
        let bad = |why: String| ParseKernelError {
            spec: match parameter {
                Some(p) => format!("{name}:{}", complex_text(p, imaginary)),
                None => name.to_string(),
            },
            why,
        };
        let Some((index, d)) = lookup(name) else {
            return Err(bad(format!("use {}", Self::usage())));
        };
        match (d.parameter, parameter) {
            (Some(p), None) => {
                return Err(bad(format!(
                    "give the {}, e.g. {}:{}",
                    p.meaning, d.name, p.example
                )));
            }
            (None, Some(_)) => {
                return Err(bad(format!("{} takes no parameter", d.name)));
            }
            (Some(p), Some(_)) if imaginary != 0.0 && !p.complex => {
                return Err(bad(format!(
                    "the {} of {} is real, e.g. {}:{}",
                    p.meaning, d.name, d.name, p.example
                )));
            }
            _ => {}
        }
        let choice = KernelChoice {
            index,
            parameter,
            // -0 is 0: one choice, one name.
            imaginary: if imaginary == 0.0 { 0.0 } else { imaginary },
        };
        choice.check().map_err(|e| bad(e.to_string()))?;
        Ok(choice)
    }

    /// Range check: the kernel type's own constructor.
    fn check(self) -> Result<(), KernelError> {
        struct Check;
        impl KernelVisitor for Check {
            type Output = ();
            fn visit<K: Kernel>(self, _: K) {}
        }
        self.try_visit(Check)
    }

    /// The choice naming `kernel`, when its type is registered.
    pub fn of<K: Kernel>(kernel: &K) -> Option<Self> {
        find(kernel as &dyn Any)
    }

    /// The descriptions of every registered kernel, in registry order.
    pub fn registered() -> &'static [KernelDescription] {
        DESCRIPTIONS
    }

    /// The registered names as a phrase for messages: `laplace, yukawa:K,
    /// helmholtz:K or stokes`.
    pub fn usage() -> String {
        let names: Vec<String> = DESCRIPTIONS
            .iter()
            .map(KernelDescription::spelling)
            .collect();
        match names.split_last() {
            Some((last, [])) => last.clone(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        }
    }

    /// Help text listing every registered kernel: `name` (summary), ...
    pub fn help() -> String {
        let entries: Vec<String> = DESCRIPTIONS
            .iter()
            .map(|d| format!("`{}` ({})", d.spelling(), d.summary))
            .collect();
        entries.join(", ")
    }

    /// The kernel as a report names it: the description's
    /// [title](KernelDescription::title) with the parameter's value
    /// (`modified Helmholtz exp(-2.5 r)/(4 pi r)`; a complex one in
    /// brackets, `exp(i (10+0.5i) r)`).
    pub fn title(self) -> String {
        let title = self.description().title;
        match self.parameter {
            Some(p) if self.imaginary != 0.0 => {
                title.replace("{}", &format!("({})", complex_text(p, self.imaginary)))
            }
            Some(p) => title.replace("{}", &p.to_string()),
            None => title.to_string(),
        }
    }

    /// Its description.
    pub fn description(self) -> &'static KernelDescription {
        &DESCRIPTIONS[self.index]
    }

    /// Its parameter (`None` for a kernel without one); the real part of
    /// a complex one.
    pub fn parameter(self) -> Option<f64> {
        self.parameter
    }

    /// The imaginary part of its parameter (0 for a real one).
    pub fn imaginary_part(self) -> f64 {
        self.imaginary
    }

    /// The name [`KernelChoice::parse`] reads back: `laplace`, `yukawa:K`,
    /// `helmholtz:K`, `helmholtz:A+Bi` or `stokes`.
    pub fn name(self) -> String {
        let d = self.description();
        match self.parameter {
            Some(p) => format!("{}:{}", d.name, complex_text(p, self.imaginary)),
            None => d.name.to_string(),
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
        self.description().component_names
    }

    /// Whether the kernel takes dipole sources.
    pub fn takes_dipoles(self) -> bool {
        self.description()
            .source_kinds
            .contains(&SourceKind::Dipole)
    }

    /// `Ok` when the kernel takes dipole sources, else why not, as the
    /// one-line message every command prints (`--kernel stokes does not
    /// support dipole sources ...`).
    pub fn check_dipoles(self) -> Result<(), String> {
        if self.takes_dipoles() {
            Ok(())
        } else {
            Err(format!(
                "--kernel {} does not support dipole sources (its sources are point {}: --charges)",
                self.name(),
                self.description().density_name
            ))
        }
    }

    /// Calls `visitor` with the kernel.
    pub fn visit<V: KernelVisitor>(self, visitor: V) -> V::Output {
        // The parameter was checked when the choice was made, so making
        // the kernel cannot fail.
        self.try_visit(visitor)
            .unwrap_or_else(|e| unreachable!("a checked kernel choice: {e}"))
    }

    fn try_visit<V: KernelVisitor>(self, visitor: V) -> Result<V::Output, KernelError> {
        visit_index(self.index, self.parameter, self.imaginary, visitor)
    }
}

impl FromStr for KernelChoice {
    type Err = ParseKernelError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        KernelChoice::parse(s)
    }
}

impl std::fmt::Display for KernelChoice {
    /// [`KernelChoice::name`].
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(&self.name())
    }
}

/// The registered description called `name` (or an alias) and its index.
fn lookup(name: &str) -> Option<(usize, &'static KernelDescription)> {
    DESCRIPTIONS
        .iter()
        .enumerate()
        .find(|(_, d)| d.name == name || d.aliases.contains(&name))
}

/// `re` alone when `im` is 0, else `re+imi` (`10+0.5i`, `10-0.5i`).
fn complex_text(re: f64, im: f64) -> String {
    if im == 0.0 {
        re.to_string()
    } else if im < 0.0 {
        format!("{re}-{}i", -im)
    } else {
        format!("{re}+{im}i")
    }
}

/// A real number, or a complex one written `A+Bi`, `A-Bi`, `Bi` (`j` for
/// `i` too), as `(re, im)`; spaces around the sign are allowed.
fn parse_complex(text: &str) -> Option<(f64, f64)> {
    let t: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(body) = t.strip_suffix(['i', 'j']) else {
        return t.parse::<f64>().ok().map(|re| (re, 0.0));
    };
    // The sign that starts the imaginary part: the last `+` or `-` that is
    // not the first character nor an exponent's.
    let bytes = body.as_bytes();
    let split = (1..bytes.len())
        .rev()
        .find(|&i| matches!(bytes[i], b'+' | b'-') && !matches!(bytes[i - 1], b'e' | b'E'));
    let number = |s: &str| -> Option<f64> {
        match s {
            "" | "+" => Some(1.0),
            "-" => Some(-1.0),
            _ => s.parse::<f64>().ok(),
        }
    };
    match split {
        Some(i) => Some((body[..i].parse::<f64>().ok()?, number(&body[i..])?)),
        None => Some((0.0, number(body)?)),
    }
}

const WAVENUMBER: ParameterDescription = ParameterDescription {
    name: "k",
    meaning: "wavenumber",
    example: "2.5",
    complex: false,
};

/// [`WAVENUMBER`], complex allowed.
const COMPLEX_WAVENUMBER: ParameterDescription = ParameterDescription {
    complex: true,
    ..WAVENUMBER
};

const ALL_SOURCES: &[SourceKind] = &[
    SourceKind::Charge,
    SourceKind::Dipole,
    SourceKind::ChargeDipole,
];

impl BuiltinKernel for Laplace3d {
    const DESCRIPTION: KernelDescription = KernelDescription {
        name: "laplace",
        aliases: &[],
        summary: "1/(4 pi r), the default",
        title: "Laplace 1/(4 pi r)",
        parameter: None,
        component_names: &[],
        complex: false,
        source_kinds: ALL_SOURCES,
        density_name: "charges",
        auto_scheme: AutoScheme::CostModel,
        tuning: TuningFamily::Laplace,
    };

    fn with_parameter(_: Option<f64>) -> Result<Self, KernelError> {
        Ok(Laplace3d)
    }

    fn parameter(&self) -> Option<f64> {
        None
    }
}

impl BuiltinKernel for ModifiedHelmholtz3d {
    const DESCRIPTION: KernelDescription = KernelDescription {
        name: "yukawa",
        aliases: &["modified-helmholtz"],
        summary: "modified Helmholtz exp(-K r)/(4 pi r), K >= 0 in inverse units of the coordinates",
        title: "modified Helmholtz exp(-{} r)/(4 pi r)",
        parameter: Some(WAVENUMBER),
        component_names: &[],
        complex: false,
        source_kinds: ALL_SOURCES,
        density_name: "charges",
        auto_scheme: AutoScheme::Fft,
        tuning: TuningFamily::ModifiedHelmholtz,
    };

    fn with_parameter(parameter: Option<f64>) -> Result<Self, KernelError> {
        ModifiedHelmholtz3d::new(parameter.unwrap_or(f64::NAN))
    }

    fn parameter(&self) -> Option<f64> {
        self.parameters().first().copied()
    }
}

impl BuiltinKernel for Helmholtz3d {
    const DESCRIPTION: KernelDescription = KernelDescription {
        name: "helmholtz",
        aliases: &[],
        summary: "exp(iKr)/(4 pi r), K >= 0 or complex A+Bi with B >= 0 (damped waves): complex \
                  charges and outputs as re, im columns",
        title: "Helmholtz exp(i {} r)/(4 pi r), complex",
        parameter: Some(COMPLEX_WAVENUMBER),
        component_names: &["re", "im"],
        complex: true,
        source_kinds: ALL_SOURCES,
        density_name: "charges",
        auto_scheme: AutoScheme::Fft,
        tuning: TuningFamily::Helmholtz,
    };

    fn with_parameter(parameter: Option<f64>) -> Result<Self, KernelError> {
        Helmholtz3d::new(parameter.unwrap_or(f64::NAN))
    }

    fn parameter(&self) -> Option<f64> {
        Some(self.k)
    }

    fn with_complex_parameter(re: f64, im: f64) -> Result<Self, KernelError> {
        Helmholtz3d::new_complex(re, im)
    }

    fn imaginary_part(&self) -> f64 {
        self.k_im
    }
}

impl BuiltinKernel for Stokes3d {
    const DESCRIPTION: KernelDescription = KernelDescription {
        name: "stokes",
        aliases: &[],
        summary: "the Stokeslet, viscosity 1: forces fx, fy, fz (and force dipoles D_kc, nine \
                  per source) in, velocities out",
        title: "Stokeslet (viscosity 1), 3 components",
        parameter: None,
        component_names: &["x", "y", "z"],
        complex: false,
        source_kinds: ALL_SOURCES,
        density_name: "forces",
        auto_scheme: AutoScheme::Fft,
        tuning: TuningFamily::Stokes,
    };

    fn with_parameter(_: Option<f64>) -> Result<Self, KernelError> {
        Ok(Stokes3d::default())
    }

    fn parameter(&self) -> Option<f64> {
        None
    }
}

/// The registry: the one list of built-in kernel types. Generates the
/// description table, the visit by index and the lookup of a kernel value.
macro_rules! registry {
    ($($kernel:ty),+ $(,)?) => {
        const DESCRIPTIONS: &[KernelDescription] = &[$(<$kernel as BuiltinKernel>::DESCRIPTION),+];

        fn visit_index<V: KernelVisitor>(
            index: usize,
            parameter: Option<f64>,
            imaginary: f64,
            visitor: V,
        ) -> Result<V::Output, KernelError> {
            let mut at = 0;
            $(
                if index == at {
                    let kernel = match (parameter, imaginary) {
                        (Some(re), im) if im != 0.0 => {
                            <$kernel as BuiltinKernel>::with_complex_parameter(re, im)?
                        }
                        _ => <$kernel as BuiltinKernel>::with_parameter(parameter)?,
                    };
                    return Ok(visitor.visit(kernel));
                }
                at += 1;
            )+
            let _ = at;
            unreachable!("kernel index {index} is not registered")
        }

        fn find(kernel: &dyn Any) -> Option<KernelChoice> {
            let mut index = 0;
            $(
                if let Some(k) = kernel.downcast_ref::<$kernel>() {
                    return Some(KernelChoice {
                        index,
                        parameter: BuiltinKernel::parameter(k),
                        imaginary: BuiltinKernel::imaginary_part(k),
                    });
                }
                index += 1;
            )+
            let _ = index;
            None
        }
    };
}

registry!(Laplace3d, ModifiedHelmholtz3d, Helmholtz3d, Stokes3d);

#[cfg(test)]
mod tests {
    use super::*;

    fn choice(name: &str) -> KernelChoice {
        KernelChoice::parse(name).unwrap()
    }

    #[test]
    fn names_round_trip_and_bad_names_are_errors() {
        for name in ["laplace", "yukawa:2.5", "helmholtz:10", "stokes"] {
            let k = choice(name);
            assert_eq!(k.name(), name);
            assert_eq!(KernelChoice::parse(&k.name()), Ok(k));
        }
        assert_eq!(choice("modified-helmholtz:1"), choice("yukawa:1"));
        for bad in [
            "",
            "coulomb",
            "yukawa",
            "helmholtz:x",
            "yukawa:-1",
            "helmholtz:inf",
            "laplace:1",
            "stokes:2",
        ] {
            let e = KernelChoice::parse(bad).unwrap_err();
            assert_eq!(e.spec, bad);
            assert!(!e.why.is_empty());
        }
        let e = KernelChoice::parse("yukawa").unwrap_err();
        assert!(e.why.contains("yukawa:2.5"), "{e}");
        let e = KernelChoice::parse("coulomb").unwrap_err();
        for d in KernelChoice::registered() {
            assert!(e.why.contains(d.name), "{e} does not name {}", d.name);
        }
    }

    #[test]
    fn complex_wavenumbers_parse_and_round_trip() {
        for (spec, re, im) in [
            ("helmholtz:10+0.5i", 10.0, 0.5),
            ("helmholtz:10+0.5j", 10.0, 0.5),
            ("helmholtz: 3 + 2i", 3.0, 2.0),
            ("helmholtz:2.5i", 0.0, 2.5),
            ("helmholtz:i", 0.0, 1.0),
            ("helmholtz:1e1+5e-1i", 10.0, 0.5),
            ("helmholtz:4+0i", 4.0, 0.0),
        ] {
            let k = choice(spec);
            assert_eq!(
                (k.parameter(), k.imaginary_part()),
                (Some(re), im),
                "{spec}"
            );
            assert_eq!(KernelChoice::parse(&k.name()), Ok(k), "{spec}");
            struct Wavenumber;
            impl KernelVisitor for Wavenumber {
                type Output = Vec<f64>;
                fn visit<K: Kernel>(self, kernel: K) -> Vec<f64> {
                    kernel.parameters()
                }
            }
            let want = if im == 0.0 { vec![re] } else { vec![re, im] };
            assert_eq!(k.visit(Wavenumber), want, "{spec}");
            assert_eq!(
                KernelChoice::from_complex_parts("helmholtz", re, im),
                Ok(k),
                "{spec}"
            );
        }
        assert_eq!(choice("helmholtz:4+0i"), choice("helmholtz:4"));
        assert_eq!(choice("helmholtz:10+0.5i").name(), "helmholtz:10+0.5i");
        assert_eq!(
            choice("helmholtz:10+0.5i").title(),
            "Helmholtz exp(i (10+0.5i) r)/(4 pi r), complex"
        );
        let damped = Helmholtz3d::new_complex(3.0, 0.25).unwrap();
        assert_eq!(KernelChoice::of(&damped), Some(choice("helmholtz:3+0.25i")));
        for bad in [
            "helmholtz:10-0.5i",
            "helmholtz:-1+1i",
            "helmholtz:1+infi",
            "helmholtz:1+xi",
            "helmholtz:1+2+3i",
            "yukawa:1+1i",
            "laplace:1i",
        ] {
            let e = KernelChoice::parse(bad).unwrap_err();
            assert_eq!(e.spec, bad);
            assert!(!e.why.is_empty(), "{bad}");
        }
        let e = KernelChoice::parse("yukawa:1+1i").unwrap_err();
        assert!(e.why.contains("real"), "{e}");
        assert!(KernelChoice::from_complex_parts("stokes", 1.0, 1.0).is_err());
    }

    #[test]
    fn from_parts_matches_parse() {
        assert_eq!(
            KernelChoice::from_parts("helmholtz", Some(3.0)),
            Ok(choice("helmholtz:3"))
        );
        assert!(KernelChoice::from_parts("helmholtz", None).is_err());
        assert!(KernelChoice::from_parts("laplace", Some(1.0)).is_err());
    }

    #[test]
    fn visit_hands_over_the_named_kernel_and_of_finds_it_again() {
        struct Describe;
        impl KernelVisitor for Describe {
            type Output = (usize, Option<KernelChoice>);
            fn visit<K: Kernel>(self, kernel: K) -> Self::Output {
                (kernel.components(), KernelChoice::of(&kernel))
            }
        }
        for (name, c) in [
            ("laplace", 1),
            ("yukawa:1", 1),
            ("helmholtz:3", 2),
            ("stokes", 3),
        ] {
            let k = choice(name);
            let (components, found) = k.visit(Describe);
            assert_eq!(components, c);
            assert_eq!(k.components(), c);
            assert_eq!(found, Some(k));
        }
    }

    #[test]
    fn descriptions_agree_with_their_kernels() {
        struct Components;
        impl KernelVisitor for Components {
            type Output = usize;
            fn visit<K: Kernel>(self, kernel: K) -> usize {
                kernel.components()
            }
        }
        for d in KernelChoice::registered() {
            let k = d.example();
            let name = k.name();
            assert_eq!(
                k.visit(Components),
                d.component_names.len().max(1),
                "{name}"
            );
            assert_eq!(d.complex, d.component_names == ["re", "im"], "{name}");
            assert!(d.source_kinds.contains(&SourceKind::Charge), "{name}");
        }
        // Stokes takes force dipoles (nine values per source) since issue 35.
        assert!(choice("stokes").check_dipoles().is_ok());
        assert!(choice("laplace").check_dipoles().is_ok());
        assert_eq!(
            choice("yukawa:2.5").title(),
            "modified Helmholtz exp(-2.5 r)/(4 pi r)"
        );
        for d in KernelChoice::registered() {
            assert_eq!(d.parameter.is_some(), d.title.contains("{}"), "{}", d.name);
        }
    }
}
