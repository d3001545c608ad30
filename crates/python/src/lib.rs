//! # ferrofmm-python
//!
//! The native part (`ferrofmm._ferrofmm`) of the Python package
//! `ferrofmm`: the FMM driver ([`ferrofmm_fmm::Fmm`]) and the octree
//! ([`ferrofmm_tree::Octree`]) behind two classes that take and return
//! flat, C-contiguous NumPy arrays.
//!
//! Files are read and written by `ferrofmm-io`, the commands' own reader
//! and writer (module `files`: `ferrofmm.load`, `ferrofmm.save`).
//!
//! The public Python API (`ferrofmm.laplace`, `ferrofmm.yukawa`,
//! `ferrofmm.Fmm`, `ferrofmm.Octree`, `ferrofmm.ewald`) lives in `python/ferrofmm/__init__.py`:
//! it turns whatever the caller passes (any float dtype the run accepts, C
//! or Fortran order, any strides) into the flat arrays this module reads,
//! and shapes the results. Everything that can fail on values (NaN
//! coordinates, bad orders or tolerances, memory limits) is checked here,
//! by the same library code as the command line, and raised as
//! `ValueError` with the library's message.
//!
//! Every build and evaluation runs on a worker thread with the GIL
//! released (`run::interruptible`); the calling thread wakes every
//! 100 ms to let Python handle signals, so Ctrl-C raises
//! `KeyboardInterrupt` at once (a precomputation in progress is cancelled;
//! an evaluation in progress finishes in the background and is dropped).

mod calibration;
#[cfg(feature = "mpi")]
mod distributed;
mod engine;
mod errors;
mod ewald;
mod files;
mod limits;
mod octree;
mod run;

use pyo3::prelude::*;

/// The native module `ferrofmm._ferrofmm`.
#[pymodule]
fn _ferrofmm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<engine::NativeFmm>()?;
    m.add_class::<octree::NativeOctree>()?;
    m.add_function(wrap_pyfunction!(limits::check_run_memory, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(ewald::ewald_sum, m)?)?;
    m.add_function(wrap_pyfunction!(ewald::stokes_ewald_sum, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_file, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_file, m)?)?;
    m.add_function(wrap_pyfunction!(files::column_names, m)?)?;
    m.add("KERNELS", kernels(m.py())?)?;
    m.add(
        "SCHEMES",
        ferrofmm_fmm::SchemeChoice::ALL
            .map(ferrofmm_fmm::SchemeChoice::name)
            .to_vec(),
    )?;
    #[cfg(feature = "mpi")]
    distributed::register(m)?;
    #[cfg(not(feature = "mpi"))]
    m.add("HAS_MPI", false)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MIN_ORDER", ferrofmm_fmm::MIN_ORDER)?;
    m.add("MAX_ORDER", ferrofmm_fmm::MAX_ORDER)?;
    m.add("DEFAULT_LEAF_SIZE", ferrofmm_fmm::DEFAULT_LEAF_SIZE)?;
    m.add("DEFAULT_TOLERANCE", ferrofmm_fmm::DEFAULT_TOLERANCE)?;
    m.add("DEFAULT_F32_TOLERANCE", ferrofmm_fmm::DEFAULT_F32_TOLERANCE)?;
    m.add("DEEPEST_LEVEL", ferrofmm_tree::DEEPEST_LEVEL)?;
    Ok(())
}

/// The kernel registry as a dict for the Python package: name -> {
/// "components", "component_names", "complex", "parameter" (its keyword,
/// or None), "parameter_meaning", "parameter_complex" (whether it may be a
/// Python complex, or None), "density_name", "dipoles", "summary" }. The package reads its kernel rules from here only.
fn kernels(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    use pyo3::types::PyDict;
    let all = PyDict::new(py);
    for d in ferrofmm_kernels::KernelChoice::registered() {
        let e = PyDict::new(py);
        e.set_item("components", d.component_names.len().max(1))?;
        e.set_item("component_names", d.component_names.to_vec())?;
        e.set_item("complex", d.complex)?;
        e.set_item("parameter", d.parameter.map(|p| p.name))?;
        e.set_item("parameter_meaning", d.parameter.map(|p| p.meaning))?;
        e.set_item("parameter_complex", d.parameter.map(|p| p.complex))?;
        e.set_item("density_name", d.density_name)?;
        e.set_item(
            "dipoles",
            d.source_kinds
                .contains(&ferrofmm_kernels::SourceKind::Dipole),
        )?;
        e.set_item("summary", d.summary)?;
        all.set_item(d.name, e)?;
    }
    Ok(all)
}
