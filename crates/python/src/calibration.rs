//! `calibrate`: the cost model measured on this machine
//! ([`MachineCalibration`]), saved in the operator cache folder where
//! later runs with that folder, on this processor and with as many
//! threads, find it. The public wrapper is `ferrofmm.calibrate`.

use std::path::PathBuf;

use ferrofmm_field::CacheSetting;
use ferrofmm_fmm::tuning::MachineCalibration;
use pyo3::prelude::*;
use serde_json::json;

use crate::errors::fmm_error;
use crate::run::{Threads, interruptible};

/// Measure and save the calibration with `threads` threads (`None`: as
/// the runs' default) on `points` uniform points, in `cache_dir` (`None`:
/// the default cache folder). Returns a JSON report: the processor, the
/// threads, the scales, the file.
#[pyfunction]
#[pyo3(signature = (points, cache_dir, threads))]
pub(crate) fn calibrate(
    py: Python<'_>,
    points: usize,
    cache_dir: Option<PathBuf>,
    threads: Option<usize>,
) -> PyResult<String> {
    let setting = match cache_dir {
        Some(dir) => CacheSetting::Dir(dir),
        None => CacheSetting::Default,
    };
    let threads = Threads::new(py, threads)?;
    let (calibration, path) = interruptible(py, &threads, None, move || {
        MachineCalibration::measure_and_save(&setting, points).map(|(c, _, path)| (c, path))
    })?
    .map_err(fmm_error)?;
    Ok(json!({
        "processor": calibration.processor,
        "threads": calibration.threads,
        "scales": calibration.scales,
        "file": path.display().to_string(),
    })
    .to_string())
}
