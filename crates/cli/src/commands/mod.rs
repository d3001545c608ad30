//! The subcommands and the argument types they share.

pub mod calibrate;
pub mod demo;
pub mod eval;
pub mod run;
pub mod sweep;

use clap::{Args, ValueEnum};
use ferrofmm_fmm::{Charges, Geometry};
use serde::{Deserialize, Serialize};

use crate::error::CliError;

/// Float type of a run (in reports: `"f32"`, `"f64"`).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, ValueEnum, Serialize, Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum PrecisionArg {
    /// Single precision (about 7 digits: errors level off near 1e-7 to 1e-6).
    F32,
    /// Double precision.
    F64,
    /// With `--tolerance EPS`: f32 where it still reaches EPS on these
    /// points, else f64. Without a tolerance: f64.
    Auto,
}

impl PrecisionArg {
    /// The float type it names (`auto` before it is resolved: f64, the
    /// type whose default tolerance and limits apply).
    pub fn float_type(self) -> ferrofmm_kernels::Precision {
        match self {
            PrecisionArg::F32 => ferrofmm_kernels::Precision::F32,
            _ => ferrofmm_kernels::Precision::F64,
        }
    }

    /// `"f32"` or `"f64"`.
    pub fn name(self) -> &'static str {
        match self {
            PrecisionArg::F32 => "f32",
            PrecisionArg::F64 => "f64",
            PrecisionArg::Auto => "auto",
        }
    }
}

/// `Display` as the argument's name (width and alignment flags apply).
macro_rules! display_by_name {
    ($($arg:ty),*) => {$(
        impl std::fmt::Display for $arg {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.pad(self.name())
            }
        }
    )*};
}

display_by_name!(PrecisionArg);

/// M2L translation scheme (in reports: `"svd"`, `"dense"`, `"fft"`): the
/// library's [`SchemeChoice`](ferrofmm_fmm::SchemeChoice), whose `auto`
/// rule every front end shares.
pub use ferrofmm_fmm::SchemeChoice as SchemeArg;

/// The parser of `--scheme` and `--schemes`: the names clap lists in help
/// and checks, mapped to [`SchemeArg`].
pub fn scheme_parser() -> impl clap::builder::TypedValueParser<Value = SchemeArg> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(SchemeArg::ALL.map(SchemeArg::name)).map(|name| {
        SchemeArg::parse(&name).unwrap_or_else(|e| unreachable!("clap checked the name: {e}"))
    })
}

/// The kernel of `--kernel`: the kernels crate's [`KernelChoice`](ferrofmm_kernels::KernelChoice), whose
/// parse errors are bad input here (exit status 1).
pub use ferrofmm_kernels::KernelChoice as KernelArg;

/// Parse `--kernel` (a name of the kernel registry: `laplace`, `yukawa:K`,
/// `helmholtz:K`, `stokes`).
pub fn parse_kernel(value: &str) -> Result<KernelArg, CliError> {
    KernelArg::parse(value).map_err(|e| CliError::InvalidArgument(format!("--kernel {e}")))
}

/// Help text of `--kernel`, from the kernel registry.
pub fn kernel_help() -> String {
    format!("Kernel: {}", KernelArg::help())
}

/// Built-in point distributions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum GeometryArg {
    /// Uniform in the unit cube.
    Cube,
    /// Uniform on the unit sphere's surface.
    Sphere,
    /// A Plummer sphere: strongly clustered, a deep adaptive tree.
    #[value(alias = "clustered")]
    Plummer,
    /// Two equal-count clusters whose sizes differ 1000x.
    TwoClusters,
    /// Uniform on the unit square in the plane z = 0 (a flat sheet).
    Plane,
    /// Uniform along a trefoil knot (a closed space curve).
    Curve,
    /// Uniform on a torus surface (a thin closed surface with a hole).
    Torus,
}

impl GeometryArg {
    /// The library's geometry.
    pub fn geometry(self) -> Geometry {
        match self {
            GeometryArg::Cube => Geometry::Cube,
            GeometryArg::Sphere => Geometry::Sphere,
            GeometryArg::Plummer => Geometry::Plummer,
            GeometryArg::TwoClusters => Geometry::TwoClusters,
            GeometryArg::Plane => Geometry::Plane,
            GeometryArg::Curve => Geometry::Curve,
            GeometryArg::Torus => Geometry::Torus,
        }
    }

    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        self.geometry().name()
    }
}

/// Built-in charges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ChargesArg {
    /// Zero-mean, uniform in [-0.5, 0.5) (the peers' workload; the default).
    Signed,
    /// All positive, uniform in [0, 1): the potential's relative error
    /// looks ~8x smaller (a smooth mean dominates), the gradient's larger.
    Positive,
}

/// Help text of `--charges`.
pub const CHARGES_HELP: &str = "Built-in charges: `signed` (zero-mean, uniform in [-0.5, 0.5): \
the peers' workload, the default) or `positive` (uniform in [0, 1): the potential's relative \
error looks ~8x smaller, the gradient's larger)";

impl ChargesArg {
    /// Parse `--charges` (an unknown value is bad input: exit status 1).
    pub fn parse(value: &str) -> Result<Self, CliError> {
        match Charges::from_name(value) {
            Some(Charges::Signed) => Ok(ChargesArg::Signed),
            Some(Charges::Positive) => Ok(ChargesArg::Positive),
            None => Err(CliError::InvalidArgument(format!(
                "--charges must be `signed` or `positive`, got `{value}`"
            ))),
        }
    }

    /// The library's kind.
    pub fn charges(self) -> Charges {
        match self {
            ChargesArg::Signed => Charges::Signed,
            ChargesArg::Positive => Charges::Positive,
        }
    }

    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        self.charges().name()
    }
}

/// FMM parameters common to `demo` and `eval`.
#[derive(Args, Clone, Debug)]
pub struct FmmArgs {
    /// Expansion order p (2..=20): the potential error falls roughly 7-10x
    /// per order (p = 6: about 1e-6). Alone (without --tolerance), the
    /// leaf size and the scheme (with --scheme auto) are chosen for it by
    /// the cost model, or a direct sum where that is faster. Without
    /// --order and --tolerance, the run is chosen for the default
    /// tolerance 1e-6 (and verified).
    #[arg(long, short = 'p')]
    pub order: Option<usize>,
    /// Largest number of points in a leaf box (default: chosen by the cost
    /// model for the order or tolerance; a given leaf size always builds a
    /// tree, never a direct sum).
    #[arg(long)]
    pub leaf_size: Option<usize>,
    /// M2L translation scheme.
    #[arg(long, default_value_t = SchemeArg::Auto, value_parser = scheme_parser(), help = SchemeArg::help())]
    pub scheme: SchemeArg,
    /// Float type of the whole computation.
    #[arg(long, value_enum, default_value_t = PrecisionArg::F64)]
    pub precision: PrecisionArg,
    /// Directory of the on-disk operator cache. Default: FERROFMM_CACHE
    /// (a folder, or `off`), else $XDG_CACHE_HOME/ferrofmm, else
    /// ~/.cache/ferrofmm; at most FERROFMM_CACHE_SIZE (default 2G) kept,
    /// least recently used files deleted first.
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<std::path::PathBuf>,
    /// Keep the operators in memory only: no cache folder is read or
    /// written.
    #[arg(long, conflicts_with = "cache_dir")]
    pub no_cache: bool,
    #[arg(long, default_value = "laplace", value_name = "NAME[:K]", help = kernel_help())]
    pub kernel: String,
    /// Requested relative L2 error, e.g. 1e-6, of the potential and (with
    /// gradients) of the gradient (default 1e-6 unless --order is given):
    /// the order, leaf size, scheme and SVD rank (or a direct sum) are then
    /// chosen for these points (an --order or --leaf-size given is kept),
    /// reported, and checked after evaluation (see --verify).
    #[arg(long, value_name = "EPS")]
    pub tolerance: Option<f64>,
    /// With --tolerance: `on` (default) checks the achieved error after
    /// evaluating (on a sample of targets against direct summation, a few
    /// percent of the run) and raises the order, at most twice, while it is
    /// above EPS; `off` trusts the prediction (and the report says so).
    #[arg(long, default_value = "on", value_name = "on|off")]
    pub verify: String,
    /// Precompute the operators even when their predicted memory exceeds
    /// the memory available (or FERROFMM_MEMORY_LIMIT): without it such a
    /// run stops before any work with the estimate.
    #[arg(long)]
    pub force: bool,
    /// Periodic boundaries: the side of the cell that repeats, `L` (or
    /// `LX,LY,LZ`; only cubes run in this release). Every target sees
    /// every image of every source (Ewald's convention, tin-foil
    /// surroundings unless --surface vacuum); points outside the cell are
    /// wrapped into it. Laplace (the cell must be neutral; demo charges
    /// are made so), Yukawa (screened: any charges, no surface term) or
    /// Stokes (Hasimoto: zero mean velocity, any forces, a net force
    /// balanced by a uniform pressure gradient) kernels, and damped
    /// Helmholtz waves (`helmholtz:RE+IMi`, summed over super-cells of
    /// images; refused where the damping is too weak), charges (point
    /// forces) only.
    #[arg(long = "box", value_name = "L|LX,LY,LZ")]
    pub periodic_box: Option<String>,
    /// The periodic cell's lower corner (default 0,0,0).
    #[arg(long, value_name = "X,Y,Z", requires = "periodic_box")]
    pub box_origin: Option<String>,
    /// Which axes repeat: xyz (the default with --box), xy (a slab: z is
    /// free space) or x (a rod: y and z are). Slabs and rods run Laplace
    /// (neutral, no surface term) and Yukawa; their points must lie within
    /// the cell along the open axes.
    #[arg(long, value_name = "xyz|xy|x", requires = "periodic_box")]
    pub periodic: Option<String>,
    /// How the periodic Laplace sum is closed: tin-foil (conducting
    /// surroundings, the default, as particle-mesh Ewald) or vacuum (adds
    /// the dipole term). Yukawa's sum converges absolutely and Stokes'
    /// is Hasimoto's: tin-foil only.
    #[arg(long, value_name = "tin-foil|vacuum", requires = "periodic_box")]
    pub surface: Option<String>,
}

/// Up to three comma-separated numbers of an option.
fn numbers(option: &str, text: &str) -> Result<Vec<f64>, CliError> {
    text.split(',')
        .map(|t| {
            t.trim().parse::<f64>().map_err(|_| {
                CliError::InvalidArgument(format!("{option} takes numbers, got `{text}`"))
            })
        })
        .collect()
}

impl FmmArgs {
    /// The periodic cell asked for with `--box` (and `--box-origin`,
    /// `--periodic`, `--surface`), `None` without `--box`. Checked when the
    /// FMM is built.
    pub fn periodic(&self) -> Result<Option<ferrofmm_fmm::Periodic>, CliError> {
        use ferrofmm_fmm::{Periodic, PeriodicAxes, SurfaceTerm};
        let Some(text) = &self.periodic_box else {
            return Ok(None);
        };
        let lengths = match numbers("--box", text)?[..] {
            [l] => [l; 3],
            [a, b, c] => [a, b, c],
            _ => {
                return Err(CliError::InvalidArgument(format!(
                    "--box takes one side or three (LX,LY,LZ), got `{text}`"
                )));
            }
        };
        let mut cell = Periodic::with_lengths(lengths);
        if let Some(o) = &self.box_origin {
            match numbers("--box-origin", o)?[..] {
                [x, y, z] => cell = cell.with_origin([x, y, z]),
                _ => {
                    return Err(CliError::InvalidArgument(format!(
                        "--box-origin takes three numbers (X,Y,Z), got `{o}`"
                    )));
                }
            }
        }
        if let Some(a) = &self.periodic {
            let axes: PeriodicAxes = a
                .parse()
                .map_err(|e: ferrofmm_fmm::FmmError| CliError::InvalidArgument(e.to_string()))?;
            cell = cell.with_axes(axes);
        }
        if let Some(s) = &self.surface {
            let surface: SurfaceTerm = s
                .parse()
                .map_err(|e: ferrofmm_fmm::FmmError| CliError::InvalidArgument(e.to_string()))?;
            cell = cell.with_surface(surface);
        }
        cell.validate()
            .map_err(|e| CliError::InvalidArgument(format!("--box: {e}")))?;
        Ok(Some(cell))
    }

    /// The operator cache asked for: `--cache-dir`, `--no-cache`, else the
    /// default location.
    pub fn cache(&self) -> ferrofmm_field::CacheSetting {
        use ferrofmm_field::CacheSetting;
        match (&self.cache_dir, self.no_cache) {
            (Some(dir), _) => CacheSetting::Dir(dir.clone()),
            (None, true) => CacheSetting::Off,
            (None, false) => CacheSetting::Default,
        }
    }

    /// `--verify` as a switch (a value other than `on` / `off` is bad
    /// input: exit status 1).
    pub fn verify(&self) -> Result<bool, CliError> {
        match self.verify.as_str() {
            "on" => Ok(true),
            "off" => Ok(false),
            other => Err(CliError::InvalidArgument(format!(
                "--verify must be `on` or `off`, got `{other}`"
            ))),
        }
    }
}
