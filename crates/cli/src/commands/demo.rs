//! `ferrofmm demo`: an FMM on built-in random points, checked against
//! direct summation.

use clap::Args;

use super::run::{Input, Settings, run};
use super::{CHARGES_HELP, ChargesArg, FmmArgs, GeometryArg, parse_kernel};
use crate::error::{CliError, Result};

/// Default number of points.
pub const DEFAULT_N: usize = 1_000_000;

/// Arguments of `ferrofmm demo`.
#[derive(Args, Clone, Debug)]
pub struct DemoArgs {
    /// Number of points (sources = targets).
    #[arg(long, short = 'n', default_value_t = DEFAULT_N)]
    pub n: usize,
    /// Point distribution.
    #[arg(long, value_enum, default_value_t = GeometryArg::Cube)]
    pub geometry: GeometryArg,
    #[arg(long, default_value = "signed", value_name = "signed|positive", help = CHARGES_HELP)]
    pub charges: String,
    #[command(flatten)]
    pub fmm: FmmArgs,
    /// Evaluate potentials and gradients (the default).
    #[arg(long, overrides_with = "no_gradients")]
    pub gradients: bool,
    /// Evaluate potentials only.
    #[arg(long = "no-gradients", overrides_with = "gradients")]
    pub no_gradients: bool,
    /// Also evaluate the Hessians (six second derivatives per target;
    /// implies gradients).
    #[arg(long)]
    pub hessians: bool,
    /// Evaluate this many times and report the fastest (and the median).
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Targets to compare with direct summation (0: skip the check).
    #[arg(long, default_value_t = 1000, value_name = "TARGETS")]
    pub check: usize,
    /// Random seed of the points and charges.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object (the last line of stdout) instead of the table.
    /// Printed also with --quiet, which then silences only the rest.
    #[arg(long)]
    pub json: bool,
}

/// Run `ferrofmm demo`.
pub fn demo(args: &DemoArgs) -> Result<()> {
    if args.n == 0 {
        return Err(CliError::InvalidArgument("--n must be at least 1".into()));
    }
    if args.repeats == 0 {
        return Err(CliError::InvalidArgument(
            "--repeats must be at least 1".into(),
        ));
    }
    let input = Input::Generated {
        geometry: args.geometry.geometry(),
        charges: ChargesArg::parse(&args.charges)?.charges(),
        n: args.n,
        seed: args.seed,
        points: None,
    };
    let settings = Settings {
        command: "demo",
        order: args.fmm.order,
        leaf_size: args.fmm.leaf_size,
        scheme: args.fmm.scheme,
        precision: args.fmm.precision,
        gradients: !args.no_gradients || args.hessians,
        hessians: args.hessians,
        kernel: parse_kernel(&args.fmm.kernel)?,
        repeats: args.repeats,
        check: args.check,
        cache: args.fmm.cache(),
        tolerance: args.fmm.tolerance,
        default_tolerance: false,
        verify: args.fmm.verify()?,
        periodic: args.fmm.periodic()?,
        pressure: false,
        force: args.fmm.force,
        out_sources: None,
        complex_output: false,
    };
    let report = run(input, &settings, None)?;
    if args.json {
        crate::stdout::println(&report.json())
    } else {
        crate::stdout::report(&report.table())
    }
}
