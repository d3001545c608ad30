//! The refusal of a distributed run that cannot fit, before anything is
//! allocated for it: each rank predicts its own share with the
//! single-machine prediction ([`MemoryReport::predict`], the lower bound
//! [`ferrofmm_fmm::FmmBuilder`] checks) and checks it against its share
//! of the memory limit ([`ferrofmm_fmm::check_memory`]); the outcome is
//! agreed, so that a rank that cannot fit makes every rank return the
//! same error instead of leaving the others waiting in a collective.

use ferrofmm_field::MemoryLimit;
use ferrofmm_fmm::{MemoryReport, RunSize, check_memory};
use ferrofmm_kernels::Real;
use mpi::traits::*;

use crate::error::{DistError, agree_message};

/// Refuse, on every rank, a run in which some rank's buffers (`size`: its
/// points, its separate targets, its densities and results, in `T`) are
/// predicted not to fit its share of the memory limit: the limit
/// ([`MemoryLimit::Auto`]: `FERROFMM_MEMORY_LIMIT`, else the memory
/// available) divided among the ranks of its node, which share that
/// memory. `what` names the run in the message. A collective: every rank
/// calls it, with its own `size`.
///
/// # Errors
/// The same [`DistError::Fmm`] on every rank, with the lowest failing
/// rank's [`ferrofmm_fmm::FmmError::RunMemory`] message (or its limit's
/// error, for a `FERROFMM_MEMORY_LIMIT` that does not parse).
pub fn check_rank_memory<C: Communicator, T: Real>(
    comm: &C,
    size: &RunSize,
    what: &str,
) -> Result<(), DistError> {
    // Collective: called by every rank before any local outcome.
    let on_node = comm.split_shared(comm.rank()).size().max(1) as u64;
    let local = MemoryLimit::Auto
        .resolve()
        .map_err(|e| e.to_string())
        .and_then(|limit| {
            let Some(limit) = limit else { return Ok(()) };
            let points = size.n_sources + size.n_targets.unwrap_or(0);
            let share = if on_node > 1 {
                format!(", on a node of {on_node} ranks that share the limit equally")
            } else {
                String::new()
            };
            check_memory(
                MemoryReport::predict::<T>(size),
                MemoryLimit::Bytes(limit / on_node),
                &format!(
                    "rank {}'s part of {what} ({points} points{share})",
                    comm.rank()
                ),
            )
            .map_err(|e| e.to_string())
        });
    agree_message(comm, local)
}
