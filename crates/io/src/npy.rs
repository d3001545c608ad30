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
//! Writing produces C-order arrays of the run's float type: `(N,)` for one
//! value per target, `(N, 4)` for potential and gradient; complex outputs
//! ([`write_complex`]) `complex128` or `complex64` arrays with one complex
//! value per quantity.

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::ops::Range;
use std::path::Path;

use npyz::num_complex::Complex;
use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};

use super::{Contents, Table, Values};
use crate::error::{FileError, Result};

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

/// The element type of an array we read.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Element {
    F32,
    F64,
    C64,
    C128,
}

impl Element {
    /// Real values per element.
    fn parts(self) -> usize {
        match self {
            Element::F32 | Element::F64 => 1,
            Element::C64 | Element::C128 => 2,
        }
    }
}

/// Rows `pick(n)` of the `n`-row array in `path` (interleaved values, C
/// order; `re, im` pairs for complex contents), `n`, and whether the array
/// was complex. A C-order array in a regular file is read only where the
/// rows lie; a Fortran-order one, or a stream (a pipe), is read whole.
/// More than `limit` bytes of values is [`FileError::TooLarge`].
pub fn read_table(
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
) -> Result<Table> {
    let file = File::open(path).map_err(|e| FileError::io(path, e))?;
    let meta = file.metadata().map_err(|e| FileError::io(path, e))?;
    let bad = |message: String| FileError::Npy {
        path: path.to_path_buf(),
        message,
    };
    let npy = NpyFile::new(BufReader::new(file))
        .map_err(|e| bad(format!("not a valid .npy file ({e})")))?;

    let dtype = npy.dtype();
    let element = match &dtype {
        DType::Plain(ts) => match (ts.type_char(), ts.size_field()) {
            (TypeChar::Float, 4) => Some(Element::F32),
            (TypeChar::Float, 8) => Some(Element::F64),
            (TypeChar::Complex, 8) => Some(Element::C64),
            (TypeChar::Complex, 16) => Some(Element::C128),
            _ => None,
        },
        _ => None,
    };
    let element = match element {
        Some(e) if e.parts() == 1 || contents.is_complex() => e,
        Some(_) => {
            return Err(bad(format!(
                "complex dtype {}: {} are real numbers (use float64 or float32)",
                dtype.descr(),
                contents.noun()
            )));
        }
        None if contents.is_complex() => {
            return Err(bad(format!(
                "unsupported dtype {}: use complex128, complex64, float64 or float32",
                dtype.descr()
            )));
        }
        None => {
            return Err(bad(format!(
                "unsupported dtype {}: use float64 or float32",
                dtype.descr()
            )));
        }
    };
    let width = match element {
        Element::F32 => 4,
        Element::F64 | Element::C64 => 8,
        Element::C128 => 16,
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
    // Elements per row in the file, and whether the values read are the
    // real parts alone (then widened with zero imaginary parts).
    let columns = contents.columns();
    let per_row = columns / element.parts();
    let real_parts = contents.real_parts().filter(|_| element.parts() == 1);
    let fits = |c: u64| c == per_row as u64 || Some(c) == real_parts.map(|r| r as u64);
    let (rows, file_columns) = match *shape.as_slice() {
        [n] if fits(1) => (n, 1),
        [n, c] if fits(c) => (n, c as usize),
        _ => return Err(bad(expected_shape(contents, element, &shape_text))),
    };
    let widen = file_columns * element.parts() != columns;
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
    let fortran = npy.order() == Order::Fortran && file_columns > 1;
    let seekable = meta.is_file() && !fortran;
    let wanted = pick(rows);
    let wanted = wanted.start.min(rows)..wanted.end.min(rows);
    let kept = wanted.end.saturating_sub(wanted.start);
    // Values held at once: the rows kept, or all of them when the file
    // must be read whole (then, for a widened file, the rows read and the
    // rows kept).
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
    let cols = file_columns as u64;
    let (first, count) = if seekable {
        (wanted.start * cols, kept * cols)
    } else {
        (0, rows * cols)
    };
    let raw = match element {
        Element::F64 => take::<f64, _>(npy, first, count, seekable, |v, out| out.push(v)),
        Element::F32 => {
            take::<f32, _>(npy, first, count, seekable, |v, out| out.push(f64::from(v)))
        }
        Element::C128 => take::<Complex<f64>, _>(npy, first, count, seekable, |v, out| {
            out.extend([v.re, v.im])
        }),
        Element::C64 => take::<Complex<f32>, _>(npy, first, count, seekable, |v, out| {
            out.extend([f64::from(v.re), f64::from(v.im)])
        }),
    }
    .map_err(|e| bad(format!("cannot read the data ({e})")))?;

    // Values per row as stored (a complex element is two).
    let stored = file_columns * element.parts();
    let in_rows = if seekable {
        raw
    } else {
        let rows = usize::try_from(rows).map_err(|_| bad("array too large".into()))?;
        let all: Vec<f64> = if fortran {
            // Column-major: element (i, j) at j * rows + i, each of
            // `parts` values.
            let p = element.parts();
            (0..rows * stored)
                .map(|k| {
                    let (i, j, part) = (k / stored, (k % stored) / p, k % p);
                    raw[(j * rows + i) * p + part]
                })
                .collect()
        } else {
            raw
        };
        all[wanted.start as usize * stored..wanted.end as usize * stored].to_vec()
    };

    if let Some(k) = in_rows.iter().position(|v| !v.is_finite()) {
        let row = wanted.start as usize + k / stored;
        let location = if shape.len() == 1 {
            format!("element [{row}]")
        } else {
            format!("element [{row}, {}]", (k % stored) / element.parts())
        };
        return Err(FileError::NonFinite {
            path: path.to_path_buf(),
            location,
            value: in_rows[k],
        });
    }
    let values = if widen {
        // Real parts alone: zero imaginary parts.
        in_rows.iter().flat_map(|&re| [re, 0.0]).collect()
    } else {
        in_rows
    };
    Ok(Table {
        values,
        rows,
        complex: element.parts() == 2,
    })
}

/// The message for an array whose shape does not hold `contents`.
fn expected_shape(contents: Contents, element: Element, found: &str) -> String {
    let complex = element.parts() == 2;
    let expected = match contents {
        Contents::Charges(1) => "an (N,) array of charges".to_string(),
        Contents::ComplexCharges if complex => "an (N,) array of complex charges".to_string(),
        Contents::ComplexCharges => {
            "an (N, 2) array of charges (re, im) or an (N,) array (complex, or real parts alone)"
                .to_string()
        }
        Contents::ComplexDipoles if complex => "an (N, 3) array of complex dipoles".to_string(),
        Contents::ComplexDipoles => {
            "an (N, 6) array of dipoles (nx_re, nx_im, ny_re, ny_im, nz_re, nz_im) or an \
             (N, 3) array (complex, or real parts alone)"
                .to_string()
        }
        _ => format!(
            "an (N, {}) array of {}",
            contents.columns(),
            contents.noun()
        ),
    };
    format!("expected {expected}, found shape {found}")
}

/// `count` elements of type `T` from element `first` on (seeking there
/// when `seekable`, else reading from the start), each turned into `f64`
/// values by `push`. A stream that ends early is an error.
fn take<T, R>(
    npy: NpyFile<BufReader<R>>,
    first: u64,
    count: u64,
    seekable: bool,
    push: impl Fn(T, &mut Vec<f64>),
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
            Some(v) => push(v?, &mut out),
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
    header_of(rows, columns, "<f8")
}

/// [`header_bytes`] for a `complex128` array of `rows` rows of `columns`
/// complex values: the data are `re, im` pairs of little-endian `float64`
/// (16 bytes a value), as a run's complex output holds them.
pub fn complex_header_bytes(rows: u64, columns: u64) -> Vec<u8> {
    header_of(rows, columns, "<c16")
}

fn header_of(rows: u64, columns: u64, descr: &str) -> Vec<u8> {
    let shape = if columns == 1 {
        format!("({rows},)")
    } else {
        format!("({rows}, {columns})")
    };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
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

/// Write `values` (`re, im` pairs) as a C-order complex `.npy` array with
/// `columns` complex columns (`(n,)` when `columns == 1`): `complex128`
/// for `f64` values, `complex64` for `f32`.
pub fn write_complex(path: &Path, values: Values<'_>, columns: usize) -> Result<()> {
    let rows = (values.len() / (2 * columns)) as u64;
    let shape: Vec<u64> = if columns == 1 {
        vec![rows]
    } else {
        vec![rows, columns as u64]
    };
    fn pairs<T: Copy>(v: &[T]) -> Vec<Complex<T>> {
        v.chunks_exact(2)
            .map(|p| Complex::new(p[0], p[1]))
            .collect()
    }
    super::output::write_atomically(path, |out| match values {
        Values::F64(v) => write_typed(out, &pairs(v), &shape),
        Values::F32(v) => write_typed(out, &pairs(v), &shape),
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
