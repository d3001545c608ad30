//! NumPy `.npy` files (via `npyz`).
//!
//! Reading accepts `float64` and `float32` arrays in either byte order and
//! in C or Fortran order: points as an `(N, 3)` array, charges as `(N,)` or
//! `(N, 1)`. The densities of a complex kernel
//! ([`Contents::ComplexCharges`], [`Contents::ComplexDipoles`]) may also be
//! `complex128` or `complex64` arrays (`(N,)` / `(N, 1)` charges, `(N, 3)`
//! dipoles), real arrays of both parts (`(N, 2)`, `(N, 6)`: `re, im`
//! interleaved) or real arrays of the real parts alone (`(N,)`, `(N, 3)`:
//! the imaginary parts are zero). Anything else (integers, complex values
//! for real contents, other shapes, pickled objects) is rejected with a
//! message naming the dtype or shape found.
//!
//! Reading streams the data into the final array in bounded chunks
//! ([`read_table`]); writing streams the values through the output's
//! buffered writer: neither holds a second copy of the array.
//!
//! Writing produces C-order arrays of the run's float type: `(N,)` for one
//! value per target, `(N, 4)` for potential and gradient; complex outputs
//! ([`write_complex`]) `complex128` or `complex64` arrays with one complex
//! value per quantity.

use std::fs::File;
use std::io::BufReader;
use std::ops::Range;
use std::path::Path;

use crate::error::{FileError, Result};
use crate::{Contents, Table};

mod decode;
mod layout;
mod write;

pub use layout::CHUNK;
pub use write::{complex_header_bytes, header_bytes, write, write_complex};

use decode::read_from;

/// Read `contents` from the `.npy` file `path` (interleaved values, C
/// order), without a memory limit.
pub fn read(path: &Path, contents: Contents) -> Result<Vec<f64>> {
    read_rows(path, contents, None, |n| 0..n).map(|(v, _)| v)
}

/// Rows `pick(n)` of the `n`-row array in `path` (interleaved values, C
/// order) and `n`; see [`read_table`].
pub fn read_rows(
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
) -> Result<(Vec<f64>, u64)> {
    read_table(path, contents, limit, pick).map(|t| (t.values, t.rows))
}

/// Rows `pick(n)` of the `n`-row array in `path` (interleaved values, C
/// order; `re, im` pairs for complex contents), `n`, and whether the array
/// was complex. The header is read (by `npyz`), then the data straight
/// into the array returned, [`CHUNK`] bytes at a time, converted from the
/// file's type and byte order as they come (a Fortran-order array column
/// by column, each value put in its row): the memory taken is that of the
/// rows kept and one chunk. A regular file is read only where the rows
/// lie; a stream (a pipe) is read through, the other rows passed over.
/// More than `limit` bytes of values kept is [`FileError::TooLarge`].
pub fn read_table(
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
) -> Result<Table> {
    let file = File::open(path).map_err(|e| FileError::io(path, e))?;
    let meta = file.metadata().map_err(|e| FileError::io(path, e))?;
    let length = meta.is_file().then_some(meta.len());
    read_from(
        BufReader::new(file),
        length,
        path,
        contents,
        limit,
        pick,
        CHUNK,
    )
}
