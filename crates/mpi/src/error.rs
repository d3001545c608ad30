//! One error type for the distributed build, the same on every rank.
//!
//! A check that fails on one rank only (a NaN in its share of the points)
//! must not leave the other ranks waiting in the next collective. So every
//! check is followed by `agree`: all ranks gather one code each (an
//! `all_gather` of `R` integers, itself a collective every rank reaches),
//! and if any rank failed, every rank returns the error of the lowest
//! failing rank. After that no rank can be left behind.

use ferrofmm_tree::TreeError;
use mpi::traits::*;

/// What was wrong with the input of one rank.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputProblem {
    /// A coordinate array whose length is not a multiple of 3.
    BadLength,
    /// A NaN or infinite coordinate.
    NonFinite,
    /// `leaf_size` is 0.
    ZeroLeafSize,
    /// The ranks were given different options (leaf size, weights).
    MismatchedOptions,
    /// Point weights: not one per point, or negative / not finite.
    BadWeights,
    /// Charges: not one per input point of the rank, or not finite.
    BadCharges,
    /// A target coordinate array whose length is not a multiple of 3.
    BadTargetLength,
    /// A NaN or infinite target coordinate.
    NonFiniteTarget,
    /// Any other failure of the tree crate on that rank.
    Other,
}

impl InputProblem {
    fn code(self) -> u32 {
        match self {
            InputProblem::BadLength => 1,
            InputProblem::NonFinite => 2,
            InputProblem::ZeroLeafSize => 3,
            InputProblem::MismatchedOptions => 4,
            InputProblem::BadWeights => 5,
            InputProblem::Other => 6,
            InputProblem::BadCharges => 7,
            InputProblem::BadTargetLength => 8,
            InputProblem::NonFiniteTarget => 9,
        }
    }

    fn from_code(c: u32) -> Self {
        match c {
            1 => InputProblem::BadLength,
            2 => InputProblem::NonFinite,
            3 => InputProblem::ZeroLeafSize,
            4 => InputProblem::MismatchedOptions,
            5 => InputProblem::BadWeights,
            7 => InputProblem::BadCharges,
            8 => InputProblem::BadTargetLength,
            9 => InputProblem::NonFiniteTarget,
            _ => InputProblem::Other,
        }
    }
}

impl std::fmt::Display for InputProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            InputProblem::BadLength => "coordinate length not a multiple of 3",
            InputProblem::NonFinite => "a NaN or infinite coordinate",
            InputProblem::ZeroLeafSize => "leaf_size must be at least 1",
            InputProblem::MismatchedOptions => "ranks were given different options",
            InputProblem::BadWeights => "weights: not one finite, non-negative value per point",
            InputProblem::Other => "invalid input",
            InputProblem::BadCharges => "charges: not one finite value per input point",
            InputProblem::BadTargetLength => "target coordinate length not a multiple of 3",
            InputProblem::NonFiniteTarget => "a NaN or infinite target coordinate",
        })
    }
}

/// Everything that can go wrong in a distributed build. Every rank returns
/// the same value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DistError {
    /// Bad input on some rank (the lowest such rank is named).
    #[error("bad input on rank {rank}: {problem}")]
    BadInput {
        /// Lowest rank whose input was bad.
        rank: i32,
        /// What was wrong there.
        problem: InputProblem,
    },
    /// No rank holds a point (a source, in a build with targets).
    #[error("no points on any rank")]
    NoPoints,
    /// A build with separate targets where no rank holds a target.
    #[error("no targets on any rank")]
    NoTargets,
    /// The tree crate failed on the agreed, valid input (a bug).
    #[error("tree error on rank {rank}: {source}")]
    Tree {
        /// The rank that failed.
        rank: i32,
        /// The error.
        source: TreeError,
    },
    /// The FMM setup failed on some rank (operators, memory, domain): the
    /// message of the lowest failing rank.
    #[error("FMM error on rank {rank}: {message}")]
    Fmm {
        /// Lowest rank that failed.
        rank: i32,
        /// Its error, as text.
        message: String,
    },
}

/// The problem of a [`TreeError`] raised while validating input.
pub(crate) fn problem_of(e: &TreeError) -> InputProblem {
    match e {
        TreeError::BadLength { .. } => InputProblem::BadLength,
        TreeError::NonFinite { .. } => InputProblem::NonFinite,
        TreeError::ZeroLeafSize => InputProblem::ZeroLeafSize,
        _ => InputProblem::Other,
    }
}

/// Makes a local outcome global: `Ok` on every rank only if it is `Ok` on
/// every rank; otherwise every rank gets [`DistError::BadInput`] of the
/// lowest failing rank. A collective: every rank must call it.
pub(crate) fn agree<C: Communicator, T>(
    comm: &C,
    local: Result<T, InputProblem>,
) -> Result<T, DistError> {
    let code = match &local {
        Ok(_) => 0u32,
        Err(p) => p.code(),
    };
    let mut all = vec![0u32; comm.size() as usize];
    comm.all_gather_into(&code, &mut all[..]);
    match (all.iter().position(|&c| c != 0), local) {
        (None, Ok(value)) => Ok(value),
        (Some(rank), _) => Err(DistError::BadInput {
            rank: rank as i32,
            problem: InputProblem::from_code(all[rank]),
        }),
        // Not reached: this rank's own code is in `all`.
        (None, Err(problem)) => Err(DistError::BadInput {
            rank: comm.rank(),
            problem,
        }),
    }
}

/// Agreement on a local outcome with an error message: `Ok` on every rank
/// only if it is `Ok` on every rank; otherwise every rank gets
/// [`DistError::Fmm`] with the lowest failing rank's message (broadcast
/// from it). A collective: every rank must call it.
pub fn agree_message<C: Communicator, T>(
    comm: &C,
    local: Result<T, String>,
) -> Result<T, DistError> {
    let failed = u32::from(local.is_err());
    let mut all = vec![0u32; comm.size() as usize];
    comm.all_gather_into(&failed, &mut all[..]);
    let Some(rank) = all.iter().position(|&c| c != 0) else {
        return local.map_err(|message| DistError::Fmm {
            rank: comm.rank(),
            message,
        });
    };
    let mut text = match &local {
        Err(m) if rank == comm.rank() as usize => m.clone().into_bytes(),
        _ => Vec::new(),
    };
    let mut len = text.len() as u64;
    let root = comm.process_at_rank(rank as i32);
    root.broadcast_into(&mut len);
    text.resize(len as usize, 0);
    root.broadcast_into(&mut text[..]);
    Err(DistError::Fmm {
        rank: rank as i32,
        message: String::from_utf8_lossy(&text).into_owned(),
    })
}

/// [`agree_message`] with the message itself as the error: `Ok` on every
/// rank only if it is `Ok` on every rank; otherwise every rank gets the
/// lowest failing rank's message, as it is (a file's problem reads as the
/// file's problem, not as an FMM error). A collective.
pub fn agree_text<C: Communicator, T>(comm: &C, local: Result<T, String>) -> Result<T, String> {
    agree_message(comm, local).map_err(|e| match e {
        DistError::Fmm { message, .. } => message,
        other => other.to_string(),
    })
}

/// Checks that every rank was given the same `options` (pairs of an
/// option's name and its value, in the same order on every rank): a job
/// launched with different options per rank (MPMD, `mpirun -n 1 A : -n 1
/// B`) would otherwise compute a wrong answer, or wait forever in a
/// collective one rank never reaches. Every rank gets the same error,
/// naming the first option that differs from rank 0's. A collective.
pub fn agree_options<C: Communicator>(comm: &C, options: &[(&str, String)]) -> Result<(), String> {
    let text: String = options
        .iter()
        .map(|(name, value)| format!("{name}\u{1f}{value}\u{1e}"))
        .collect();
    let mut bytes = if comm.rank() == 0 {
        text.as_bytes().to_vec()
    } else {
        Vec::new()
    };
    let mut len = bytes.len() as u64;
    let root = comm.process_at_rank(0);
    root.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    let theirs = String::from_utf8_lossy(&bytes).into_owned();
    let local = if theirs == text {
        Ok(())
    } else {
        let parse = |t: &str| -> Vec<(String, String)> {
            t.split('\u{1e}')
                .filter(|r| !r.is_empty())
                .map(|r| {
                    let (n, v) = r.split_once('\u{1f}').unwrap_or((r, ""));
                    (n.to_string(), v.to_string())
                })
                .collect()
        };
        let (mine, zero) = (parse(&text), parse(&theirs));
        let differs = mine
            .iter()
            .zip(&zero)
            .find(|(a, b)| a != b)
            .map(|((name, value), (_, value0))| {
                format!(
                    "{name} is {value0:?} on rank 0 but {value:?} on rank {}",
                    comm.rank()
                )
            })
            .unwrap_or_else(|| format!("rank {} has other options than rank 0", comm.rank()));
        Err(format!(
            "the ranks were given different options ({differs}): give every rank the same command line"
        ))
    };
    agree_text(comm, local)
}
