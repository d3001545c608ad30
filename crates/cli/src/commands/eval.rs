//! `ferrofmm eval`: the FMM on points and charges from files.

use std::path::PathBuf;

use clap::Args;

use super::FmmArgs;
use super::run::{Input, Settings, run};
use crate::error::{CliError, Result};
use crate::io::{self, Format};

/// Arguments of `ferrofmm eval`.
#[derive(Args, Clone, Debug)]
pub struct EvalArgs {
    /// Source points: .csv (x,y,z per line) or .npy (N x 3, float64/float32).
    #[arg(long, value_name = "FILE")]
    pub sources: PathBuf,
    /// Target points, same formats (default: the sources).
    #[arg(long, value_name = "FILE")]
    pub targets: Option<PathBuf>,
    /// Charges, one per source: .csv (one per line) or .npy (N).
    #[arg(long, value_name = "FILE")]
    pub charges: PathBuf,
    /// Output file, .csv or .npy: one potential per target, or potential and
    /// gradient (N x 4) with --gradients, in the run's precision. Must not
    /// be one of the input files; replaced only once fully written.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    #[command(flatten)]
    pub fmm: FmmArgs,
    /// Also evaluate the gradient with respect to the target.
    #[arg(long)]
    pub gradients: bool,
    /// Compare this many sampled targets with direct summation (0: no check).
    #[arg(long, default_value_t = 0, value_name = "TARGETS")]
    pub check: usize,
    /// Print one JSON object (parameters, timings, tree) as the last line of
    /// stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Run `ferrofmm eval`.
pub fn eval(args: &EvalArgs) -> Result<()> {
    // Fail on an unusable output path before any work: unknown type, one
    // of the inputs, a directory, or a directory that takes no new file.
    Format::of(&args.out)?;
    let mut inputs = vec![
        ("--sources", args.sources.as_path()),
        ("--charges", args.charges.as_path()),
    ];
    if let Some(t) = &args.targets {
        inputs.push(("--targets", t.as_path()));
    }
    io::output::check(&args.out, &inputs)?;

    let sources = io::read_points(&args.sources)?;
    let targets = args.targets.as_deref().map(io::read_points).transpose()?;
    let charges = io::read_charges(&args.charges)?;
    if charges.len() != sources.len() / 3 {
        return Err(CliError::CountMismatch {
            charges_path: args.charges.clone(),
            charges: charges.len(),
            sources_path: args.sources.clone(),
            sources: sources.len() / 3,
        });
    }

    let input = Input::Given {
        sources,
        targets,
        charges,
    };
    let settings = Settings {
        command: "eval",
        order: args.fmm.order,
        leaf_size: args.fmm.leaf_size,
        scheme: args.fmm.scheme,
        precision: args.fmm.precision,
        gradients: args.gradients,
        repeats: 1,
        check: args.check,
        cache_dir: args.fmm.cache_dir.clone(),
        tolerance: args.fmm.tolerance,
        verify: args.fmm.verify()?,
        force: args.fmm.force,
    };
    let report = run(input, &settings, Some(&args.out))?;
    if args.json {
        io::stdout::println(&report.json())
    } else {
        io::stdout::print(&format!("{}wrote {}\n", report.table(), args.out.display()))
    }
}
