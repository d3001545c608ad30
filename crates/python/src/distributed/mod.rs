//! `ferrofmm.distributed`'s native part: the distributed octree and FMM of
//! `ferrofmm-mpi` on an mpi4py communicator (built with the `mpi` feature).
//!
//! Every call is a collective over the communicator: each rank passes its
//! own points (and densities) and gets its own results. Failures are
//! agreed by the library ([`ferrofmm_mpi::DistError`] is the same on every
//! rank) and raised as the same Python exception on every rank; the Python
//! wrapper agrees on its own argument checks before calling here, so no
//! rank enters a collective alone.

mod comm;
mod fmm;
mod layers;
mod octree;

use ferrofmm_mpi::{DistError, DistRequest, agree_text};
use mpi::Threading;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use numpy::PyReadonlyArray1;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

use comm::AdoptedComm;
pub(crate) use fmm::NativeDistFmm;
pub(crate) use layers::NativeDistStokesLayers;
pub(crate) use octree::NativeDistOctree;

/// Registers the classes (called by the module's init).
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeDistFmm>()?;
    m.add_class::<NativeDistOctree>()?;
    m.add_class::<NativeDistStokesLayers>()?;
    m.add("HAS_MPI", true)?;
    m.add(
        "MPI_LIBRARY",
        mpi::environment::library_version().unwrap_or_default(),
    )?;
    Ok(())
}

/// Every distributed error is the same on every rank; all of them are bad
/// input, bad parameters or a failed setup, so `ValueError`.
pub(crate) fn dist_error(e: DistError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// What a distributed build starts from on this rank: the request (the
/// local checks of the Python arguments, agreed on every rank), a
/// communicator of our own with the threads, and this rank's points and
/// targets copied out of the arrays.
pub(crate) struct Start {
    pub(crate) request: DistRequest,
    pub(crate) work: Work,
    pub(crate) points: Vec<f64>,
    pub(crate) targets: Option<Vec<f64>>,
}

impl Start {
    /// The communicator `comm` adopted first (a collective every rank
    /// reaches: the Python wrapper agreed on its own checks), then the
    /// outcome of the local checks `local` agreed on it, so that no rank
    /// goes on alone; then the threads and the copies.
    pub(crate) fn new(
        comm: i64,
        local: PyResult<DistRequest>,
        threads: Option<usize>,
        sources: PyReadonlyArray1<'_, f64>,
        targets: Option<PyReadonlyArray1<'_, f64>>,
    ) -> PyResult<Self> {
        let adopted = AdoptedComm::duplicate(comm)?;
        let request = agree_text(adopted.comm(), local.map_err(|e| e.to_string()))
            .map_err(PyValueError::new_err)?;
        let work = Work::new(adopted, threads)?;
        Ok(Start {
            request,
            work,
            points: sources.as_slice()?.to_vec(),
            targets: targets
                .map(|t| t.as_slice().map(<[f64]>::to_vec))
                .transpose()?,
        })
    }
}

/// A communicator of our own and the threads this rank's passes run on.
pub(crate) struct Work {
    pool: Option<rayon::ThreadPool>,
    threads: usize,
    size: usize,
    comm: AdoptedComm,
}

impl Work {
    /// `threads` per rank (`None`: `RAYON_NUM_THREADS`, else the node's
    /// cores shared evenly among the ranks on it, as `ferrofmm-mpi`). A
    /// collective (the ranks on each node are counted).
    fn new(comm: AdoptedComm, threads: Option<usize>) -> PyResult<Self> {
        let world = comm.comm();
        let on_node = world.split_shared(world.rank()).size().max(1) as usize;
        let chosen = ferrofmm_io::threads::choose(threads, on_node).map_err(|e| e.to_string());
        let count = agree_text(world, chosen)
            .map_err(PyValueError::new_err)?
            .count;
        // The passes run in a pool of their own when MPI may be called
        // from a thread other than the caller's (the pool's worker, while
        // the caller waits); at MPI_THREAD_SINGLE or FUNNELED they stay on
        // the calling thread and use rayon's global pool.
        let pool = if mpi::environment::threading_support() >= Threading::Serialized {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(count)
                    .thread_name(|i| format!("ferrofmm-dist-{i}"))
                    .build()
                    .map_err(|e| {
                        PyRuntimeError::new_err(format!("cannot start {count} threads: {e}"))
                    })?,
            )
        } else {
            None
        };
        let threads = pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
        let size = world.size() as usize;
        Ok(Work {
            pool,
            threads,
            size,
            comm,
        })
    }

    /// Runs `job` on the communicator with the GIL released.
    fn run<R, F>(&self, py: Python<'_>, job: F) -> R
    where
        R: Send,
        F: FnOnce(&SimpleCommunicator) -> R + Send,
    {
        let comm = &self.comm;
        py.detach(|| match &self.pool {
            Some(pool) => pool.install(|| job(comm.comm())),
            None => job(comm.comm()),
        })
    }

    fn threads(&self) -> usize {
        self.threads
    }

    fn size(&self) -> usize {
        self.size
    }
}
