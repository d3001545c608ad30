//! An mpi4py communicator adopted by rsmpi.
//!
//! The Python side passes the Fortran handle of an mpi4py `Intracomm`
//! (`comm.py2f()`, an integer in every MPI implementation), which
//! `MPI_Comm_f2c` turns back into the C handle. We never use that handle
//! beyond duplicating it: `MPI_Comm_dup` makes our
//! own communicator with the same group, so the library's messages can
//! never match the caller's, and it is freed when the object holding it is
//! dropped (`MPI_Comm_free`), unless MPI was finalized first (mpi4py
//! finalizes at interpreter exit, possibly before Python collects our
//! objects): then the handle is left alone, as MPI no longer exists.

use std::mem::ManuallyDrop;

use mpi::ffi;
use mpi::raw::FromRaw;
use mpi::topology::SimpleCommunicator;
use pyo3::PyResult;
use pyo3::exceptions::PyRuntimeError;

/// A duplicate of the caller's communicator, owned by this library.
pub(crate) struct AdoptedComm(ManuallyDrop<SimpleCommunicator>);

impl AdoptedComm {
    /// Duplicates the communicator whose Fortran handle is `fortran` (a
    /// collective over its ranks, as `MPI_Comm_dup`).
    ///
    /// # Errors
    /// `RuntimeError` when MPI is not initialized or already finalized, or
    /// when `MPI_Comm_dup` fails.
    pub(crate) fn duplicate(fortran: i64) -> PyResult<Self> {
        if !mpi::environment::is_initialized() || mpi::environment::is_finalized() {
            return Err(PyRuntimeError::new_err(
                "MPI is not running in this process: pass a communicator of mpi4py \
                 (from mpi4py import MPI) before MPI.Finalize",
            ));
        }
        let fortran = ffi::RSMPI_Fint::try_from(fortran).map_err(|_| {
            PyRuntimeError::new_err(format!("{fortran} is not a Fortran communicator handle"))
        })?;
        // SAFETY: MPI_Comm_f2c only looks the handle up in MPI's table of
        // communicators (MPI is running: checked above).
        let raw = unsafe { ffi::RSMPI_Comm_f2c(fortran) };
        // SAFETY: reading an extern static of the MPI library (a constant
        // handle it defines).
        if raw == unsafe { ffi::RSMPI_COMM_NULL } {
            return Err(PyRuntimeError::new_err("the communicator is MPI_COMM_NULL"));
        }
        // SAFETY: reading an extern static of the MPI library (a constant
        // handle it defines).
        let mut dup = unsafe { ffi::RSMPI_COMM_NULL };
        // SAFETY: `raw` is the handle of a live intracommunicator: the
        // Python wrapper passes `comm.py2f()` of an mpi4py `Intracomm`, in
        // a process where MPI is running, and it is not COMM_NULL
        // (checked above); `dup` is a valid place for the new handle.
        let rc = unsafe { ffi::MPI_Comm_dup(raw, &mut dup) };
        if rc != ffi::MPI_SUCCESS as i32 {
            return Err(PyRuntimeError::new_err(format!(
                "MPI_Comm_dup failed (error code {rc})"
            )));
        }
        // SAFETY: `dup` is a new intracommunicator that nothing else owns
        // (not COMM_WORLD or COMM_SELF); rsmpi frees it on drop.
        Ok(AdoptedComm(ManuallyDrop::new(unsafe {
            SimpleCommunicator::from_raw(dup)
        })))
    }

    /// The communicator.
    pub(crate) fn comm(&self) -> &SimpleCommunicator {
        &self.0
    }
}

impl Drop for AdoptedComm {
    fn drop(&mut self) {
        if !mpi::environment::is_finalized() {
            // SAFETY: dropped once, here; the field is not used afterwards.
            unsafe { ManuallyDrop::drop(&mut self.0) };
        }
    }
}

// SAFETY: an MPI communicator handle is a process-wide identifier, not tied
// to the thread that made it. The library calls MPI through it only from
// one thread at a time (the objects holding it serialize their calls with a
// mutex) and only from a thread MPI allows: the calling thread, or a rayon
// worker while the caller waits when MPI runs at `MPI_THREAD_SERIALIZED` or
// above (`Work::run`).
unsafe impl Send for AdoptedComm {}
// SAFETY: as above; shared references only read the handle.
unsafe impl Sync for AdoptedComm {}
