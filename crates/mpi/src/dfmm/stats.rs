//! Per-rank figures of a distributed FMM: setup, and each evaluation's
//! phase times and bytes sent.

use std::time::Instant;

use ferrofmm_fmm::EvalTimings;

/// The phases of one evaluation ([`super::DistributedFmm::evaluate`]).
pub const EVAL_PHASES: [&str; 8] = [
    "charges to owners",
    "upward",
    "ghost exchange",
    "coarse multipoles",
    "downward",
    "coarse checks",
    "leaf passes",
    "values back",
];

/// Time (seconds) and bytes sent by this rank in each phase of one
/// evaluation (indexed as [`EVAL_PHASES`]), and the single-machine
/// operator times of its passes. Bytes count the payload addressed to
/// other ranks, for the coarse tree's sums (phases 3 and 5) too: `8 n`
/// bytes per coarse box in each share sent to a root and in each sum a
/// root sends (point to point, only to the ranks that need it).
#[derive(Clone, Debug, Default)]
pub struct EvalStats {
    /// Wall time of each phase, seconds.
    pub seconds: [f64; 8],
    /// Bytes sent in each phase.
    pub bytes_sent: [u64; 8],
    /// Time per operator (P2M, M2M, M2L, ...) on this rank.
    pub passes: EvalTimings,
    /// CPU time (user + system, all threads of the process) of the
    /// compute phases (upward, downward without its `all_reduce`s, leaf
    /// passes): the work, whatever else shares the cores (0 where
    /// `/proc/self/stat` cannot be read).
    pub compute_cpu_seconds: f64,
}

/// CPU time of this process (user + system, all threads), seconds, from
/// `/proc/self/stat` (in ticks of 1/100 s); 0 where it cannot be read.
pub(crate) fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // The fields after the command name (which may hold spaces) follow ')';
    // utime and stime (fields 14 and 15 of the line) are 11 and 12 there.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

impl EvalStats {
    pub(crate) fn add(&mut self, phase: usize, since: Instant, bytes: u64) {
        self.seconds[phase] += since.elapsed().as_secs_f64();
        self.bytes_sent[phase] += bytes;
    }

    /// Adds `other`'s times, bytes and operator times to these (two
    /// evaluations' figures as one).
    pub fn merge(&mut self, other: &EvalStats) {
        for i in 0..8 {
            self.seconds[i] += other.seconds[i];
            self.bytes_sent[i] += other.bytes_sent[i];
        }
        self.passes.accumulate(&other.passes);
        self.compute_cpu_seconds += other.compute_cpu_seconds;
    }

    /// Total time, seconds.
    pub fn total_seconds(&self) -> f64 {
        self.seconds.iter().sum()
    }

    /// Total bytes sent.
    pub fn total_bytes(&self) -> u64 {
        self.bytes_sent.iter().sum()
    }
}

/// What [`super::DistributedFmm::build`] did on this rank.
#[derive(Clone, Debug, Default)]
pub struct SetupStats {
    /// Seconds: ghost points and plans; local tree; operators.
    pub seconds: [f64; 3],
    /// Bytes sent while making the plans and the routing.
    pub bytes_sent: u64,
    /// Points of other ranks this rank holds (U and X lists).
    pub ghost_points: usize,
    /// Boxes of the local tree (own, coarse, ghosts and their ancestors).
    pub boxes: usize,
    /// Boxes whose expansions this rank computes: its own and the coarse
    /// boxes above them ([`ferrofmm_fmm::TreeFmm::with_active_boxes`]).
    pub active_boxes: usize,
    /// Ranks this one sends to at each evaluation.
    pub send_partners: usize,
    /// Ranks this one receives from at each evaluation.
    pub recv_partners: usize,
    /// Ranks this one sends to in the coarse tree's sums of an evaluation
    /// (shares to roots, sums from the roots it is; `dfmm/coarse_plan.rs`).
    pub coarse_send_partners: usize,
    /// Ranks this one receives from in the coarse tree's sums.
    pub coarse_recv_partners: usize,
}
