//! NumPy `.npy` files (via `npyz`).
//!
//! Reading accepts `float64` and `float32` arrays in either byte order and
//! in C or Fortran order: points as an `(N, 3)` array, charges as `(N,)` or
//! `(N, 1)`. Anything else (integers, other shapes, pickled objects) is
//! rejected with a message naming the dtype or shape found.
//!
//! Writing produces C-order arrays of the run's float type: `(N,)` for one
//! value per target, `(N, 4)` for potential and gradient.

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::ops::Range;
use std::path::Path;

use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};

use super::{Contents, Values};
use crate::error::{FileError, Result};

/// Read `contents` from the `.npy` file `path` (interleaved values, C
/// order), without a memory limit.
pub fn read(path: &Path, contents: Contents) -> Result<Vec<f64>> {
    read_rows(path, contents, None, |n| 0..n).map(|(v, _)| v)
}

/// Rows `pick(n)` of the `n`-row array in `path` (interleaved values, C
/// order) and `n`. A C-order array in a regular file is read only where
/// the rows lie; a Fortran-order one, or a stream (a pipe), is read whole.
/// More than `limit` bytes of values is [`FileError::TooLarge`].
pub fn read_rows(
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
) -> Result<(Vec<f64>, u64)> {
    let file = File::open(path).map_err(|e| FileError::io(path, e))?;
    let meta = file.metadata().map_err(|e| FileError::io(path, e))?;
    let bad = |message: String| FileError::Npy {
        path: path.to_path_buf(),
        message,
    };
    let npy = NpyFile::new(BufReader::new(file))
        .map_err(|e| bad(format!("not a valid .npy file ({e})")))?;

    let dtype = npy.dtype();
    let width = match &dtype {
        DType::Plain(ts)
            if ts.type_char() == TypeChar::Float && matches!(ts.size_field(), 4 | 8) =>
        {
            ts.size_field()
        }
        other => {
            return Err(bad(format!(
                "unsupported dtype {}: use float64 or float32",
                other.descr()
            )));
        }
    };

    let shape = npy.shape().to_vec();
    let shape_text = format!(
        "({})",
        shape
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", ")
    );
    let (rows, columns) = match (contents, shape.as_slice()) {
        (Contents::Charges(1), &[n]) => (n, 1),
        (_, &[n, c]) if c == contents.columns() as u64 => (n, contents.columns()),
        (Contents::Charges(1), _) => {
            return Err(bad(format!(
                "expected an (N,) array of charges, found shape {shape_text}"
            )));
        }
        _ => {
            return Err(bad(format!(
                "expected an (N, {}) array of {}, found shape {shape_text}",
                contents.columns(),
                contents.noun()
            )));
        }
    };
    // A header promising more data than a regular file holds is caught
    // before anything is allocated for it (a pipe has no length: there
    // the memory limit bounds what is read).
    let total_bytes = npy.len().checked_mul(width);
    if meta.is_file() {
        let file_len = meta.len();
        if total_bytes.is_none_or(|bytes| bytes > file_len) {
            return Err(bad(format!(
                "the header promises shape {shape_text}, more than the file's {file_len} bytes hold"
            )));
        }
    }
    let fortran = npy.order() == Order::Fortran && columns > 1;
    let seekable = meta.is_file() && !fortran;
    let wanted = pick(rows);
    let wanted = wanted.start.min(rows)..wanted.end.min(rows);
    let kept = wanted.end.saturating_sub(wanted.start);
    // Values held at once: the rows kept, or all of them when the file
    // must be read whole.
    let held = if seekable { kept } else { rows };
    let too_large = |held: u64| {
        held.checked_mul(8 * columns as u64)
            .is_none_or(|bytes| limit.is_some_and(|l| bytes > l))
    };
    if too_large(held) {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            limit: limit.unwrap_or(u64::MAX),
        });
    }
    let cols = columns as u64;
    let (first, count) = if seekable {
        (wanted.start * cols, kept * cols)
    } else {
        (0, rows * cols)
    };
    let raw = if width == 8 {
        take::<f64, _>(npy, first, count, seekable, f64::from)
    } else {
        take::<f32, _>(npy, first, count, seekable, f64::from)
    }
    .map_err(|e| bad(format!("cannot read the data ({e})")))?;

    let values = if seekable {
        raw
    } else {
        let rows = usize::try_from(rows).map_err(|_| bad("array too large".into()))?;
        let all: Vec<f64> = if fortran {
            // Column-major: element (i, j) at j * rows + i.
            (0..rows * columns)
                .map(|k| raw[(k % columns) * rows + k / columns])
                .collect()
        } else {
            raw
        };
        all[wanted.start as usize * columns..wanted.end as usize * columns].to_vec()
    };

    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        let row = wanted.start as usize + k / columns;
        let location = if columns == 1 {
            format!("element [{row}]")
        } else {
            format!("element [{row}, {}]", k % columns)
        };
        return Err(FileError::NonFinite {
            path: path.to_path_buf(),
            location,
            value: values[k],
        });
    }
    Ok((values, rows))
}

/// `count` values of type `T` from element `first` on (seeking there when
/// `seekable`, else reading from the start), converted to `f64`. A stream
/// that ends early is an error.
fn take<T, R>(
    npy: NpyFile<BufReader<R>>,
    first: u64,
    count: u64,
    seekable: bool,
    to_f64: impl Fn(T) -> f64,
) -> std::io::Result<Vec<f64>>
where
    T: npyz::Deserialize,
    R: Read + std::io::Seek,
{
    let mut data = npy.data::<T>().map_err(std::io::Error::other)?;
    if seekable && first > 0 {
        data.seek_to(first)?;
    }
    let mut out = Vec::with_capacity(usize::try_from(count).unwrap_or(0).min(1 << 24));
    for _ in 0..count {
        match data.next() {
            Some(v) => out.push(to_f64(v?)),
            None => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "the data ends before the header's shape is filled",
                ));
            }
        }
    }
    Ok(out)
}

/// The header of a C-order little-endian `float64` `.npy` array of `rows`
/// rows of `columns` values (`columns == 1`: shape `(rows,)`), padded so
/// that the data start at a multiple of 64 bytes: what [`write()`] writes,
/// for writers that fill the data in parts (each MPI rank its rows, at
/// `header.len() + 8 * columns * first_row`).
pub fn header_bytes(rows: u64, columns: u64) -> Vec<u8> {
    let shape = if columns == 1 {
        format!("({rows},)")
    } else {
        format!("({rows}, {columns})")
    };
    let mut dict = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    let total = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((dict.len() as u16).to_le_bytes());
    out.extend(dict.as_bytes());
    out
}

/// Write `values` as a C-order `.npy` array with `columns` columns
/// (`(n,)` when `columns == 1`).
pub fn write(path: &Path, values: Values<'_>, columns: usize) -> Result<()> {
    let rows = (values.len() / columns) as u64;
    let shape: Vec<u64> = if columns == 1 {
        vec![rows]
    } else {
        vec![rows, columns as u64]
    };
    super::output::write_atomically(path, |out| match values {
        Values::F64(v) => write_typed(out, v, &shape),
        Values::F32(v) => write_typed(out, v, &shape),
    })
}

fn write_typed<T, W>(out: W, values: &[T], shape: &[u64]) -> std::io::Result<()>
where
    T: npyz::AutoSerialize + Copy,
    W: Write,
{
    let mut writer = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(out)
        .begin_nd()?;
    writer.extend(values.iter().copied())?;
    writer.finish()
}
