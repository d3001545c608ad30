//! Printing reports on stdout without panicking when nobody reads them.
//!
//! `println!` panics when stdout is a closed pipe (`ferrofmm demo | head
//! -0`, `... | true`). [`print()`] writes and flushes instead and turns a
//! broken pipe into [`CliError::StdoutClosed`], which `main` ends as a
//! quiet success: the work is done (and any output file written); only the
//! report had no reader.

use std::io::Write;
use std::path::PathBuf;

use crate::error::{CliError, Result};

/// Write `text` to stdout and flush it.
pub fn print(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                CliError::StdoutClosed
            } else {
                CliError::Io {
                    path: PathBuf::from("<stdout>"),
                    source: e,
                }
            }
        })
}

/// [`print()`] a human-readable report, unless `--quiet` silences it
/// (machine-readable output asked for explicitly, `--json`, goes through
/// [`println()`] and always prints).
pub fn report(text: &str) -> Result<()> {
    if crate::progress::quiet() {
        Ok(())
    } else {
        print(text)
    }
}

/// [`print()`] `text` followed by a newline.
pub fn println(text: &str) -> Result<()> {
    print(&format!("{text}\n"))
}
