//! `ewald` and `stokes_ewald`: the Ewald reference sums of charges
//! ([`EwaldSum`]) and of point forces ([`StokesEwaldSum`]) in a periodic
//! cell, the truths the periodic FMM is checked against.

use std::time::Instant;

use ferrofmm_kernels::{
    EvalMode, EwaldOptions, EwaldSum, KernelError, PeriodicCell, RodGreen, SlabGreen,
    StokesEwaldSum,
};
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::json;

use crate::engine::Floats;
use crate::run::{Threads, interruptible};

/// `1/2 sum q phi` of values at the sources (`mode`'s values per source).
fn energy(charges: &[f64], values: &[f64], mode: EvalMode) -> f64 {
    let w = mode.values_per_target();
    0.5 * charges
        .iter()
        .zip(values.chunks_exact(w))
        .map(|(q, v)| q * v[0])
        .sum::<f64>()
}

fn kernel_error(e: KernelError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The Ewald sum (Laplace with tin-foil surroundings, or the Yukawa kernel
/// `e^{-k r} / (4 pi r)` with screening `k > 0`) of `charges` at `sources`
/// in the orthorhombic cell `origin + [0, lengths)`, evaluated at the
/// sources (each without its own direct term, its images kept) or at
/// `targets` (flat, interleaved `x, y, z`), to relative tolerance `eps`.
/// Returns the flat values (`phi` or `phi, gx, gy, gz` per target,
/// float64), the energy `1/2 sum q phi` (at the sources only) and a JSON
/// report. `periodic` `"xy"` (a slab) or `"x"` (a rod) sums the images
/// along those axes only ([`SlabGreen`], [`RodGreen`], pair by pair).
#[pyfunction]
#[pyo3(signature = (sources, charges, lengths, origin, targets, gradient, eps, threads=None, k=0.0, periodic="xyz"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn ewald_sum<'py>(
    py: Python<'py>,
    sources: &Bound<'py, PyAny>,
    charges: &Bound<'py, PyAny>,
    lengths: Vec<f64>,
    origin: Vec<f64>,
    targets: Option<&Bound<'py, PyAny>>,
    gradient: bool,
    eps: f64,
    threads: Option<usize>,
    k: f64,
    periodic: &str,
) -> PyResult<(Bound<'py, PyAny>, Option<f64>, String)> {
    let threads = Threads::new(py, threads)?;
    let axes: ferrofmm_fmm::PeriodicAxes = periodic
        .parse()
        .map_err(|e: ferrofmm_fmm::FmmError| PyValueError::new_err(e.to_string()))?;
    let Inputs {
        cell,
        sources,
        densities: charges,
        targets,
        mode,
    } = Inputs::read(
        &lengths,
        origin,
        sources,
        ("charges", charges),
        targets,
        gradient,
    )?;
    let result = interruptible(py, &threads, None, move || {
        let start = Instant::now();
        let n = sources.len() / 3;
        let mut options = EwaldOptions::new(eps).screening(k);
        if let Some(t) = &targets {
            options = options.expected_targets(t.len() / 3);
        }
        if axes != ferrofmm_fmm::PeriodicAxes::Xyz {
            let all: Vec<usize> = (0..n).collect();
            let values =
                match (axes, &targets) {
                    (ferrofmm_fmm::PeriodicAxes::Xy, Some(t)) => SlabGreen::screened(cell, k, eps)?
                        .sum_at_points(&sources, &charges, t, mode)?,
                    (ferrofmm_fmm::PeriodicAxes::Xy, None) => SlabGreen::screened(cell, k, eps)?
                        .sum_at_sources(&sources, &charges, &all, mode)?,
                    (_, Some(t)) => RodGreen::screened(cell, k, eps)?
                        .sum_at_points(&sources, &charges, t, mode)?,
                    (_, None) => RodGreen::screened(cell, k, eps)?
                        .sum_at_sources(&sources, &charges, &all, mode)?,
                };
            let energy = targets.is_none().then(|| energy(&charges, &values, mode));
            let info = json!({
                "kernel": if k > 0.0 { "yukawa" } else { "laplace" },
                "k": k,
                "method": if axes == ferrofmm_fmm::PeriodicAxes::Xy { "ewald (slab, Parry)" } else { "ewald (rod)" },
                "dtype": "float64",
                "eps": eps,
                "n_sources": n,
                "n_targets": targets.as_ref().map_or(n, |t| t.len() / 3),
                "total_charge": charges.iter().sum::<f64>(),
                "threads": rayon::current_num_threads(),
                "periodic": {
                    "box": cell.lengths(),
                    "origin": cell.origin(),
                    "axes": axes.name(),
                    "surface": "none",
                },
                "timings": {"total": start.elapsed().as_secs_f64()},
            });
            return Ok((values, energy, info.to_string()));
        }
        let sum = EwaldSum::with_options(cell, &sources, &charges, options)?;
        let values = match &targets {
            Some(t) => sum.at_points(t, mode)?,
            None => sum.all(mode)?,
        };
        let energy = targets.is_none().then(|| energy(&charges, &values, mode));
        let p = sum.parameters();
        let info = json!({
            "kernel": if k > 0.0 { "yukawa" } else { "laplace" },
            "k": k,
            "method": "ewald",
            "dtype": "float64",
            "eps": eps,
            "n_sources": n,
            "n_targets": targets.as_ref().map_or(n, |t| t.len() / 3),
            "total_charge": sum.total_charge(),
            "alpha": p.alpha,
            "r_cut": p.r_cut,
            "k_cut": p.k_cut,
            "wave_vectors": sum.n_wave_vectors(),
            "threads": rayon::current_num_threads(),
            "periodic": {
                "box": cell.lengths(),
                "origin": cell.origin(),
                "axes": "xyz",
                "surface": if k > 0.0 { "none (screened)" } else { "tin-foil" },
            },
            "timings": {"total": start.elapsed().as_secs_f64()},
        });
        Ok::<_, KernelError>((values, energy, info.to_string()))
    })?;
    let (values, energy, info) = result.map_err(kernel_error)?;
    Ok((PyArray1::from_vec(py, values).into_any(), energy, info))
}

/// Hasimoto's Ewald sum of the point `forces` (three per source, flat) at
/// `sources` in the orthorhombic cell `origin + [0, lengths)`, viscosity 1
/// (zero mean velocity, a net force balanced by a uniform pressure
/// gradient: [`StokesEwaldSum`]), evaluated at the sources (each without
/// its own direct term, its images kept) or at `targets`, to relative
/// tolerance `eps`. Returns the flat values (`u` (3), then with `gradient`
/// `d_c u_a` at `3 + 3 c + a`, per target, float64) and a JSON report.
#[pyfunction]
#[pyo3(signature = (sources, forces, lengths, origin, targets, gradient, eps, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn stokes_ewald_sum<'py>(
    py: Python<'py>,
    sources: &Bound<'py, PyAny>,
    forces: &Bound<'py, PyAny>,
    lengths: Vec<f64>,
    origin: Vec<f64>,
    targets: Option<&Bound<'py, PyAny>>,
    gradient: bool,
    eps: f64,
    threads: Option<usize>,
) -> PyResult<(Bound<'py, PyAny>, String)> {
    let threads = Threads::new(py, threads)?;
    let Inputs {
        cell,
        sources,
        densities: forces,
        targets,
        mode,
    } = Inputs::read(
        &lengths,
        origin,
        sources,
        ("forces", forces),
        targets,
        gradient,
    )?;
    let result = interruptible(py, &threads, None, move || {
        let start = Instant::now();
        let n = sources.len() / 3;
        let mut options = EwaldOptions::new(eps);
        if let Some(t) = &targets {
            options = options.expected_targets(t.len() / 3);
        }
        let sum = StokesEwaldSum::with_options(cell, &sources, &forces, 1.0, options)?;
        let values = match &targets {
            Some(t) => sum.at_points(t, mode)?,
            None => sum.all(mode)?,
        };
        let p = sum.parameters();
        let total: Vec<f64> = (0..3)
            .map(|c| forces.iter().skip(c).step_by(3).sum())
            .collect();
        let info = json!({
            "kernel": "stokes",
            "method": "ewald",
            "dtype": "float64",
            "eps": eps,
            "n_sources": n,
            "n_targets": targets.as_ref().map_or(n, |t| t.len() / 3),
            "total_force": total,
            "alpha": p.alpha,
            "r_cut": p.r_cut,
            "k_cut": p.k_cut,
            "threads": rayon::current_num_threads(),
            "periodic": {
                "box": cell.lengths(),
                "origin": cell.origin(),
                "axes": "xyz",
                "surface": "none (Hasimoto: zero mean velocity)",
            },
            "timings": {"total": start.elapsed().as_secs_f64()},
        });
        Ok::<_, KernelError>((values, info.to_string()))
    })?;
    let (values, info) = result.map_err(kernel_error)?;
    Ok((PyArray1::from_vec(py, values).into_any(), info))
}

/// The arguments both sums read: the cell, the points and densities (as
/// `f64`), the targets and the outputs asked for.
struct Inputs {
    cell: PeriodicCell,
    sources: Vec<f64>,
    densities: Vec<f64>,
    targets: Option<Vec<f64>>,
    mode: EvalMode,
}

impl Inputs {
    /// The inputs, or the ValueError that names the bad one.
    fn read(
        lengths: &[f64],
        origin: Vec<f64>,
        sources: &Bound<'_, PyAny>,
        (name, densities): (&'static str, &Bound<'_, PyAny>),
        targets: Option<&Bound<'_, PyAny>>,
        gradient: bool,
    ) -> PyResult<Self> {
        Ok(Self {
            cell: cell(lengths, origin)?,
            sources: Floats::from_numpy("sources", sources)?.into_f64(),
            densities: Floats::from_numpy(name, densities)?.into_f64(),
            targets: targets
                .map(|t| Floats::from_numpy("targets", t).map(Floats::into_f64))
                .transpose()?,
            mode: if gradient {
                EvalMode::PotentialGradient
            } else {
                EvalMode::Potential
            },
        })
    }
}

/// The cell `origin + [0, lengths)` of the `box` and `box_origin`
/// arguments, or the ValueError that says what is wrong.
fn cell(lengths: &[f64], origin: Vec<f64>) -> PyResult<PeriodicCell> {
    let lengths = crate::engine::box_lengths(lengths)?;
    let origin: [f64; 3] = origin.try_into().map_err(|o: Vec<f64>| {
        PyValueError::new_err(format!(
            "box_origin takes three numbers (x, y, z), got {} values",
            o.len()
        ))
    })?;
    PeriodicCell::new(origin, lengths).map_err(|e| PyValueError::new_err(format!("box: {e}")))
}
