//! Per-rank counters of a distributed build: phase times and bytes sent.

use std::time::Instant;

/// The phases of [`DistributedTree::build`](crate::DistributedTree::build).
pub const PHASES: [&str; 6] = [
    "validate+bbox",
    "sort",
    "partition",
    "refine",
    "balance",
    "ghosts",
];

/// Time (seconds) and bytes sent by this rank in each phase (indexed as
/// [`PHASES`]), and the number of 2:1 balance rounds.
#[derive(Clone, Debug, Default)]
pub struct BuildStats {
    /// Wall time of each phase on this rank, seconds.
    pub seconds: [f64; 6],
    /// Payload bytes this rank sent to other ranks in each phase
    /// (collective buffers count the parts addressed to other ranks).
    pub bytes_sent: [u64; 6],
    /// Rounds of the distributed balance (exchange, balance, agree).
    pub balance_rounds: usize,
}

/// Times one phase: `let t = Timer::start(); ...; t.stop(&mut stats, i)`.
pub(crate) struct Timer(Instant);

impl Timer {
    pub(crate) fn start() -> Self {
        Timer(Instant::now())
    }

    pub(crate) fn stop(self, stats: &mut BuildStats, phase: usize) {
        stats.seconds[phase] += self.0.elapsed().as_secs_f64();
    }
}
