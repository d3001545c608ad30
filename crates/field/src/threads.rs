//! How many threads the precomputation uses: the rayon pool, at most one
//! per core ([`effective_threads`]), and faer's parallelism inside it
//! ([`nested_par`]). Uses nothing else of the crate.

use faer::Par;

/// Worker threads that really run at once: the pool, at most the cores.
pub(crate) fn effective_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    rayon::current_num_threads().clamp(1, cores)
}

/// Parallelism for faer inside the precomputation: sequential when called
/// from a rayon worker (the caller already runs in parallel, and nesting
/// faer's own splitting on top of it oversubscribes the cores), otherwise
/// the current pool's threads, at most one per core (a pool of 64 threads
/// on 2 cores would split every factorisation 64 ways and spend its time
/// waiting; see the `--threads` notes of the CLI).
pub(crate) fn nested_par() -> Par {
    if rayon::current_thread_index().is_some() {
        Par::Seq
    } else {
        Par::rayon(effective_threads())
    }
}
