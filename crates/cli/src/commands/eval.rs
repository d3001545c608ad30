//! `ferrofmm eval`: the FMM on points and charges from files.

use std::path::PathBuf;

use clap::Args;
use ferrofmm_field::MemoryLimit;
use ferrofmm_fmm::StokesRequest;

use super::run::{Input, Settings, run};
use super::{FmmArgs, parse_kernel};
use crate::error::{CliError, Result};
use crate::stdout;
use ferrofmm_io::{self as io, Contents};

/// Arguments of `ferrofmm eval`.
#[derive(Args, Clone, Debug)]
pub struct EvalArgs {
    /// Source points: .csv (x,y,z per line), .npy (N x 3, float64/float32)
    /// or raw .f64 (little-endian float64, x, y, z per point).
    #[arg(long, value_name = "FILE")]
    pub sources: PathBuf,
    /// Target points, same formats (default: the sources).
    #[arg(long, value_name = "FILE")]
    pub targets: Option<PathBuf>,
    /// Charges, one per source: .csv (one per line), .npy (N) or raw .f64.
    /// For a complex kernel (helmholtz:K): complex .npy (N, complex128 or
    /// complex64; the output is then complex too), re, im pairs (.csv
    /// `re,im` per line, .npy N x 2), or real charges alone (zero
    /// imaginary parts). At least one of --charges and --dipoles.
    #[arg(long, value_name = "FILE", required_unless_present_any = ["dipoles", "strslet"])]
    pub charges: Option<PathBuf>,
    /// Dipole vectors n, one per source: .csv (nx,ny,nz per line) or .npy
    /// (N x 3). Each source then adds n . grad_x K(x, y) (a double-layer
    /// potential), with its charge when --charges is given too.
    /// For `--kernel stokes`: force dipoles, nine values per source (`D_kc`,
    /// the derivative along `k` of the Stokeslet of force component `c`;
    /// .npy N x 9).
    #[arg(long, value_name = "FILE")]
    pub dipoles: Option<PathBuf>,
    /// `--kernel stokes` only: stresslet strengths `m` (FMM3D's `strslet`),
    /// one 3-vector per source (.csv or .npy N x 3), with `--strsvec`. Each
    /// adds `3 d (d . m)(d . n) / (4 pi r^5)` to the velocity (`d`: target
    /// minus source); with `--charges` too, forces and stresslets.
    #[arg(long, value_name = "FILE", requires = "strsvec")]
    pub strslet: Option<PathBuf>,
    /// `--kernel stokes` only: stresslet orientations `n` (FMM3D's
    /// `strsvec`, e.g. surface normals), same format, with `--strslet`.
    #[arg(long, value_name = "FILE", requires = "strslet")]
    pub strsvec: Option<PathBuf>,
    /// `--kernel stokes` only: also the pressure (FMM3D's `pre`), and with
    /// --gradients its gradient: columns `pressure` (and `pressure_grad_x,
    /// pressure_grad_y, pressure_grad_z`) after the velocity's. Free space
    /// only.
    #[arg(long)]
    pub pressure: bool,
    /// Output file, .csv or .npy, in the run's precision, one row per
    /// target: `potential`; with --gradients also `grad_x, grad_y, grad_z`
    /// (N x 4); with --hessians also `hess_xx, hess_yy, hess_zz, hess_xy,
    /// hess_xz, hess_yz` (N x 10). For a complex kernel each value is
    /// re, im columns (`potential_re, potential_im, ...`); after a complex
    /// .npy input of charges or dipoles, a .npy output holds complex
    /// numbers instead (complex128, or complex64 with --precision f32),
    /// one per quantity. Must not be one of the input files; replaced
    /// only once fully written.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// With --targets: also write the values at the sources (each source
    /// excluding itself) to this file, in the same run (FMM3D's `pg` and
    /// `pgt` together). The sources are evaluated as extra targets.
    #[arg(long, value_name = "FILE", requires = "targets")]
    pub out_sources: Option<PathBuf>,
    #[command(flatten)]
    pub fmm: FmmArgs,
    /// Also evaluate the gradient with respect to the target.
    #[arg(long)]
    pub gradients: bool,
    /// Also evaluate the gradient and the Hessian (the six second
    /// derivatives with respect to the target).
    #[arg(long)]
    pub hessians: bool,
    /// Compare this many sampled targets with direct summation (0: no check).
    #[arg(long, default_value_t = 0, value_name = "TARGETS")]
    pub check: usize,
    /// Print one JSON object (parameters, timings, tree) as the last line of
    /// stdout instead of the table.
    /// Printed also with --quiet, which then silences only the rest.
    #[arg(long)]
    pub json: bool,
}

/// Run `ferrofmm eval`.
pub fn eval(args: &EvalArgs) -> Result<()> {
    let kernel = parse_kernel(&args.fmm.kernel)?;
    if args.dipoles.is_some() {
        kernel.check_dipoles().map_err(CliError::InvalidArgument)?;
    }
    let layered = args.strslet.is_some() || args.pressure;
    StokesRequest::check_flags(&kernel, layered, args.dipoles.is_some())
        .map_err(CliError::InvalidArgument)?;
    if layered && args.hessians {
        return Err(CliError::InvalidArgument(
            "--kernel stokes has no Hessians".to_string(),
        ));
    }
    let mut inputs = vec![("--sources", args.sources.as_path())];
    for (flag, path) in [
        ("--charges", &args.charges),
        ("--dipoles", &args.dipoles),
        ("--strslet", &args.strslet),
        ("--strsvec", &args.strsvec),
        ("--targets", &args.targets),
    ] {
        if let Some(p) = path {
            inputs.push((flag, p.as_path()));
        }
    }
    // Fail on an unusable output path before any work: a directory, an
    // unknown type, one of the inputs, or a directory that takes no new
    // file.
    io::output::check(&args.out, &inputs)?;
    if let Some(path) = &args.out_sources {
        io::output::check(path, &inputs)?;
        let absolute = |p: &std::path::Path| {
            let p = io::output::resolve(p);
            std::path::absolute(&p).unwrap_or(p)
        };
        if absolute(path) == absolute(&args.out) {
            return Err(CliError::InvalidArgument(
                "--out-sources and --out name the same file".to_string(),
            ));
        }
    }

    // Inputs within the memory limit of the run (the memory available, or
    // FERROFMM_MEMORY_LIMIT; --force lifts it): an endless stream such as
    // /dev/zero is an error, not an out-of-memory kill.
    let limit = if args.fmm.force {
        MemoryLimit::Unlimited
    } else {
        MemoryLimit::Auto
    }
    .resolve()
    .map_err(|e| CliError::InvalidArgument(e.to_string()))?;
    let reader = io::Reader::new().memory_limit(limit);
    let sources = reader.read(&args.sources, Contents::Points)?;
    let targets = args
        .targets
        .as_deref()
        .map(|p| reader.read(p, Contents::Points))
        .transpose()?;
    let n_sources = sources.len() / 3;
    let c = kernel.components();
    let complex = kernel.description().complex;
    // A complex .npy input of densities makes the .npy output complex.
    let mut complex_output = false;
    let mut read_densities = |path: &std::path::Path, contents: Contents| {
        let table = reader.read_table(path, contents, |n| 0..n)?;
        complex_output |= table.complex;
        Ok::<_, CliError>(table.values)
    };
    let charges = match &args.charges {
        Some(path) => {
            let q = read_densities(path, Contents::charges(c, complex))?;
            if q.len() != c * n_sources {
                return Err(CliError::CountMismatch {
                    what: "charges",
                    charges_path: path.clone(),
                    charges: q.len() / c,
                    sources_path: args.sources.clone(),
                    sources: n_sources,
                });
            }
            Some(q)
        }
        None => None,
    };
    let dipoles = match &args.dipoles {
        Some(path) => {
            let n = read_densities(path, Contents::dipoles(c, complex))?;
            if n.len() != 3 * c * n_sources {
                return Err(CliError::CountMismatch {
                    what: "dipoles",
                    charges_path: path.clone(),
                    charges: n.len() / (3 * c),
                    sources_path: args.sources.clone(),
                    sources: n_sources,
                });
            }
            Some(n)
        }
        None => None,
    };

    let stresslets = match (&args.strslet, &args.strsvec) {
        (Some(m), Some(n)) => {
            let read = |path: &std::path::Path, what: &'static str| {
                let v = reader.read(path, Contents::Points)?;
                if v.len() != 3 * n_sources {
                    return Err(CliError::CountMismatch {
                        what,
                        charges_path: path.to_path_buf(),
                        charges: v.len() / 3,
                        sources_path: args.sources.clone(),
                        sources: n_sources,
                    });
                }
                Ok(v)
            };
            Some((
                read(m, "stresslet strengths")?,
                read(n, "stresslet orientations")?,
            ))
        }
        _ => None,
    };

    // Values at the sources too: the sources lead the targets (a target on
    // a source skips that source: K(x, x) := 0, so each source's value
    // excludes itself, as without --targets).
    let split = args
        .out_sources
        .as_ref()
        .map(|path| (path.clone(), n_sources));
    let targets = match (targets, &split) {
        (Some(t), Some(_)) => Some(sources.iter().chain(&t).copied().collect()),
        (t, _) => t,
    };
    let input = Input::Given {
        sources,
        targets,
        charges,
        dipoles,
        stresslets,
    };
    let settings = Settings {
        command: "eval",
        order: args.fmm.order,
        leaf_size: args.fmm.leaf_size,
        scheme: args.fmm.scheme,
        precision: args.fmm.precision,
        gradients: args.gradients || args.hessians,
        hessians: args.hessians,
        kernel,
        repeats: 1,
        check: args.check,
        cache: args.fmm.cache(),
        tolerance: args.fmm.tolerance,
        default_tolerance: false,
        verify: args.fmm.verify()?,
        periodic: args.fmm.periodic()?,
        pressure: args.pressure,
        force: args.fmm.force,
        out_sources: split,
        complex_output,
    };
    let report = run(input, &settings, Some(&args.out))?;
    if args.json {
        stdout::println(&report.json())
    } else {
        let also = match &args.out_sources {
            Some(p) => format!(" and {}", p.display()),
            None => String::new(),
        };
        stdout::report(&format!(
            "{}wrote {}{also}\n",
            report.table(),
            args.out.display()
        ))
    }
}
