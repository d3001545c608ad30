//! `ferrofmm calibrate`: measure this machine's cost model and save it
//! where the chooser finds it.
//!
//! The chooser weighs P2P, far field, M2L and tree work with coefficients
//! fitted on one machine ([`CostModel::default`](ferrofmm_fmm::tuning::CostModel));
//! this command times a few small Laplace FMMs here and saves, for each
//! group of coefficients, the ratio of the measured to the predicted
//! seconds ([`MachineCalibration`]) in the operator cache folder. Later
//! runs with that cache folder, the same processor and the same number of
//! threads (`ferrofmm demo`, `ferrofmm eval`, the Python module) choose
//! their leaf size and scheme with it.

use std::path::PathBuf;

use clap::Args;
use ferrofmm_field::{CacheSetting, M2lCostShape};
use ferrofmm_fmm::tuning::{CALIBRATION_POINTS, CalibrationRun, MachineCalibration};
use serde_json::json;

use crate::error::Result;
use crate::stdout;

/// Arguments of `ferrofmm calibrate`.
#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// Points of each calibration run (a uniform cube; at least 1000).
    #[arg(short = 'n', long, default_value_t = CALIBRATION_POINTS)]
    pub points: usize,
    /// Folder to save the calibration in (and to keep the runs' operators
    /// in); default: the operator cache folder (FERROFMM_CACHE, else
    /// $XDG_CACHE_HOME/ferrofmm, else ~/.cache/ferrofmm).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run `ferrofmm calibrate`.
pub fn calibrate(args: &CalibrateArgs) -> Result<()> {
    let setting = match &args.cache_dir {
        Some(dir) => CacheSetting::Dir(dir.clone()),
        None => CacheSetting::Default,
    };
    let (calibration, runs, path) = MachineCalibration::measure_and_save(&setting, args.points)?;
    if args.json {
        let runs: Vec<_> = runs
            .iter()
            .map(|r| {
                json!({
                    "scheme": scheme_name(r),
                    "order": r.order,
                    "leaf_size": r.leaf_size,
                    "measured_s": r.measured,
                    "predicted_s": r.predicted,
                })
            })
            .collect();
        let v = json!({
            "processor": calibration.processor,
            "threads": calibration.threads,
            "points": args.points,
            "scales": calibration.scales,
            "runs": runs,
            "file": path.display().to_string(),
        });
        return stdout::print(&format!("{v}\n"));
    }
    stdout::report(&report(&calibration, &runs, args.points, &path))
}

fn scheme_name(r: &CalibrationRun) -> &'static str {
    match r.shape {
        M2lCostShape::Fft => "fft",
        _ => "svd",
    }
}

/// The human-readable report: each run's measured and predicted seconds
/// per group, then the scales and where they were saved.
fn report(
    c: &MachineCalibration,
    runs: &[CalibrationRun],
    points: usize,
    path: &std::path::Path,
) -> String {
    let mut s = format!(
        "calibration of the cost model on {} ({} threads), {points} uniform points, \
         Laplace potentials, f64\n\n\
         scheme order  leaf |  p2p s (model) |  far s (model) |  m2l s (model) | tree s (model)\n",
        c.processor, c.threads
    );
    for r in runs {
        let (m, p) = (&r.measured, &r.predicted);
        s += &format!(
            "{:>6} {:>5} {:>5} | {:6.3} ({:6.3}) | {:6.3} ({:6.3}) | {:6.3} ({:6.3}) | {:6.3} ({:6.3})\n",
            scheme_name(r),
            r.order,
            r.leaf_size,
            m.p2p,
            p.p2p,
            m.far,
            p.far,
            m.m2l,
            p.m2l,
            m.tree,
            p.tree
        );
    }
    let sc = &c.scales;
    s += &format!(
        "\nmeasured / model: p2p {:.2}x, far field {:.2}x, SVD M2L {:.2}x, FFT M2L {:.2}x, tree {:.2}x\n\
         saved to {} (used by runs with this cache folder on this processor with {} threads)\n",
        sc.p2p,
        sc.far,
        sc.m2l_compressed,
        sc.m2l_fft,
        sc.tree,
        path.display(),
        c.threads
    );
    s
}
