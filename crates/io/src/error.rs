//! The crate's typed errors: every problem with a file names the file and
//! says what is wrong, in one line.

use std::path::{Path, PathBuf};

/// Everything that can go wrong reading or writing a file (and choosing
/// the thread count, see [`crate::threads`]).
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// An input names a directory.
    #[error("{}: is a directory, not a file", .0.display())]
    IsDirectory(PathBuf),
    /// A line of a CSV file could not be understood.
    #[error("{}, line {line}: {message}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        message: String,
    },
    /// A `.npy` file has a type, shape or layout we cannot use.
    #[error("{}: {message}", path.display())]
    Npy {
        /// The file.
        path: PathBuf,
        /// What is wrong with the file.
        message: String,
    },
    /// A file holds no values.
    #[error("{}: the file holds no {what}", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
        /// "points", "charges" or "dipoles".
        what: &'static str,
    },
    /// A NaN or infinite value in an input file.
    #[error("{}: {location} is not finite ({value})", path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// Where, in words ("line 4, column 2", "element [17, 2]").
        location: String,
        /// The value.
        value: f64,
    },
    /// Reading the file would take more memory than the limit allows (an
    /// endless stream such as `/dev/zero`, or a file too large for the
    /// machine).
    #[error(
        "{}: the input needs more than {} of memory, the limit (the memory available, or \
         FERROFMM_MEMORY_LIMIT): give a smaller file",
        path.display(),
        human_bytes(*limit)
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The limit in bytes.
        limit: u64,
    },
    /// An input file name whose extension is not `.csv`, `.npy` or `.f64`.
    #[error(
        "{}: unknown file type (use a .csv or .npy file, or .f64 for raw little-endian float64)",
        .0.display()
    )]
    UnknownExtension(PathBuf),
    /// An output file name whose extension is neither `.csv` nor `.npy`.
    #[error("{}: unknown file type for an output (write a .csv or .npy file)", .0.display())]
    UnknownOutputType(PathBuf),
    /// A raw `.f64` file whose length or contents do not fit.
    #[error("{}: {message}", path.display())]
    Raw {
        /// The file.
        path: PathBuf,
        /// What is wrong with the file.
        message: String,
    },
    /// Values to write that do not fill the records their column names
    /// describe.
    #[error("cannot write {}: {message}", path.display())]
    Shape {
        /// The output file.
        path: PathBuf,
        /// What does not fit.
        message: String,
    },
    /// The output names one of the input files (also through a link).
    #[error("--out {} is the same file as {option} {}: refusing to overwrite an input", out.display(), input.display())]
    OutputIsInput {
        /// The output file.
        out: PathBuf,
        /// The option naming the input (`--sources`, `--targets`, `--charges`).
        option: &'static str,
        /// The input file.
        input: PathBuf,
    },
    /// The output file cannot be created (found before any work).
    #[error("cannot write {}: {reason}", path.display())]
    OutputUnusable {
        /// The output file.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// Writing an output file failed; nothing was left behind.
    #[error("cannot write {}: {source} (no file written)", path.display())]
    WriteFailed {
        /// The output file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A thread count (`--threads`, `RAYON_NUM_THREADS`) that cannot work.
    #[error("{0}")]
    Threads(String),
}

impl FileError {
    /// A [`FileError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> FileError {
        FileError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// [`FileError::NonFinite`] for the first value of `values` (read from
/// `path`) that is not finite, its place named by `location(index)`.
pub(crate) fn check_finite(
    path: &Path,
    values: &[f64],
    location: impl FnOnce(usize) -> String,
) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(k) => Err(FileError::NonFinite {
            path: path.to_path_buf(),
            location: location(k),
            value: values[k],
        }),
        None => Ok(()),
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = FileError> = std::result::Result<T, E>;

/// `bytes` in binary units, three significant digits (`1.50 GiB`).
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.3} {}", UNITS[unit])
    }
}
