//! The command's typed errors.
//!
//! Every failure the user can cause (a missing or malformed file, an
//! impossible parameter, an FMM that rejects its input) ends in a
//! [`CliError`]; `main` prints it as one line, `error: {e}`, and exits with
//! status 1. (Command-line syntax errors are reported by clap, status 2.)

use std::path::{Path, PathBuf};

use ferrofmm_fmm::FmmError;
use ferrofmm_io::FileError;

/// Everything that can go wrong in a `ferrofmm` command.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The number of charges (or dipoles) differs from the number of sources.
    #[error("{} holds {charges} {what} but {} holds {sources} points: give one {} per source", charges_path.display(), sources_path.display(), what.trim_end_matches('s'))]
    CountMismatch {
        /// `"charges"` or `"dipoles"`.
        what: &'static str,
        /// The charges file.
        charges_path: PathBuf,
        /// Number of charges.
        charges: usize,
        /// The sources file.
        sources_path: PathBuf,
        /// Number of sources.
        sources: usize,
    },
    /// A command-line value that cannot work.
    #[error("{0}")]
    InvalidArgument(String),
    /// An input or output file (see [`ferrofmm_io`]), or a thread count.
    #[error(transparent)]
    File(#[from] FileError),
    /// The FMM rejected the problem.
    #[error("{0}")]
    Fmm(#[from] FmmError),
    /// A chart could not be drawn.
    #[error("chart {}: {source}", path.display())]
    Chart {
        /// The chart file.
        path: PathBuf,
        /// The drawing library's error (backend or layout).
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Stdout was closed before the report could be printed (`... | head`):
    /// ends the command quietly with status 0.
    #[error("stdout is closed")]
    StdoutClosed,
    /// `--tolerance` was checked after evaluating (`--verify on`) and not
    /// met, even after raising the order: nothing is written.
    #[error(
        "tolerance {tolerance:e} not met: the error measured on sampled targets is \
         {measured:.2e} after {attempts} attempt(s) (last order {order}); no output written \
         (ask for a larger tolerance{}, or --verify off to take the unchecked result){why}",
        if *precision == "f32" { ", use --precision f64" } else { "" }
    )]
    ToleranceNotMet {
        /// The tolerance asked for.
        tolerance: f64,
        /// The worst error measured on the last attempt.
        measured: f64,
        /// Evaluations tried.
        attempts: usize,
        /// Order of the last attempt.
        order: usize,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
        /// Why the problem reaches less than usual (`"; ..."`), or empty.
        why: String,
    },
    /// A child run of a sweep failed.
    #[error("sweep configuration {config} failed: {message}")]
    SweepRun {
        /// The configuration, in words.
        config: String,
        /// Why.
        message: String,
    },
}

impl CliError {
    /// An [`CliError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> CliError {
        CliError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = CliError> = std::result::Result<T, E>;
