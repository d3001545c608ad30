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
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::Path;

use npyz::num_complex::Complex;
use npyz::{DType, Endianness, NpyFile, Order, TypeChar, WriterBuilder};

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

/// [`read_table`] from `reader`, the file `path` of `length` bytes when it
/// is a regular file (then read only where the rows lie), else a stream;
/// the data read `chunk` bytes at a time.
fn read_from<R: Read + Seek>(
    reader: R,
    length: Option<u64>,
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
    chunk: usize,
) -> Result<Table> {
    let bad = |message: String| FileError::Npy {
        path: path.to_path_buf(),
        message,
    };
    let npy = NpyFile::new(reader).map_err(|e| bad(format!("not a valid .npy file ({e})")))?;

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
    if let Some(file_len) = length
        && total_bytes.is_none_or(|bytes| bytes > file_len)
    {
        return Err(bad(format!(
            "the header promises shape {shape_text}, more than the file's {file_len} bytes hold"
        )));
    }
    let fortran = npy.order() == Order::Fortran && file_columns > 1;
    let seekable = length.is_some();
    let wanted = pick(rows);
    let wanted = wanted.start.min(rows)..wanted.end.min(rows);
    let kept = wanted.end.saturating_sub(wanted.start);
    // Only the rows kept are held: a regular file is read where they lie,
    // a stream is read through, the other rows passed over.
    let too_large = |held: u64| {
        held.checked_mul(8 * columns as u64)
            .is_none_or(|bytes| limit.is_some_and(|l| bytes > l))
    };
    if too_large(kept) {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            limit: limit.unwrap_or(u64::MAX),
        });
    }
    let big_endian = match &dtype {
        DType::Plain(ts) => ts.endianness() == Endianness::Big,
        _ => false,
    };
    let layout = Layout {
        scalar: width as usize / element.parts(),
        big_endian,
        parts: element.parts(),
        file_columns,
        columns,
        rows,
        fortran,
    };
    let mut reader = npy.into_inner();
    let values = layout
        .read(
            &mut reader,
            wanted.clone(),
            seekable,
            limit.is_some() || seekable,
            chunk,
        )
        .map_err(|e| match e {
            ReadFailure::Memory => FileError::TooLarge {
                path: path.to_path_buf(),
                limit: limit.unwrap_or(u64::MAX),
            },
            ReadFailure::Io(e) => bad(format!("cannot read the data ({e})")),
        })?;

    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        let row = wanted.start as usize + k / columns;
        let location = if shape.len() == 1 {
            format!("element [{row}]")
        } else {
            // The file's column (a widened value and its zero imaginary
            // part come from one column).
            let per = if widen { 2 } else { element.parts() };
            format!("element [{row}, {}]", (k % columns) / per)
        };
        return Err(FileError::NonFinite {
            path: path.to_path_buf(),
            location,
            value: values[k],
        });
    }
    Ok(Table {
        values,
        rows,
        complex: element.parts() == 2,
    })
}

/// Bytes of data read at a time (a multiple of every element size).
pub const CHUNK: usize = 1 << 16;

/// Why the data could not be read.
#[derive(Debug)]
enum ReadFailure {
    /// The array asked for cannot be allocated.
    Memory,
    /// Reading failed, or the data end early.
    Io(std::io::Error),
}

impl From<std::io::Error> for ReadFailure {
    fn from(e: std::io::Error) -> Self {
        ReadFailure::Io(e)
    }
}

/// How the data of an array lie in the file and where its values go.
#[derive(Clone, Copy, Debug)]
struct Layout {
    /// Bytes of one real number (4 or 8).
    scalar: usize,
    big_endian: bool,
    /// Real numbers per element (2 for a complex one).
    parts: usize,
    /// Elements per row in the file.
    file_columns: usize,
    /// Values per row read (`file_columns * parts`, or twice that when
    /// the file holds the real parts alone, widened with zero imaginary
    /// parts).
    columns: usize,
    /// Rows in the file.
    rows: u64,
    /// Stored column by column.
    fortran: bool,
}

impl Layout {
    /// Bytes of one element.
    fn width(&self) -> u64 {
        (self.scalar * self.parts) as u64
    }

    /// Whether each stored real is followed by a zero imaginary part.
    fn widen(&self) -> bool {
        self.file_columns * self.parts != self.columns
    }

    /// The values of rows `wanted` from `reader`, placed at the start of
    /// the data: read straight into the array returned, `chunk` bytes at
    /// a time (converted from the file's type and byte order). A seekable
    /// `reader` is read only where the rows lie; a stream is read through
    /// (the other rows passed over). With `exact`, the whole array is
    /// allocated first (the header's size was checked against the file or
    /// the memory limit); without, it grows as the data arrive.
    fn read<R: Read + Seek>(
        &self,
        reader: &mut R,
        wanted: Range<u64>,
        seekable: bool,
        exact: bool,
        chunk: usize,
    ) -> Result<Vec<f64>, ReadFailure> {
        let width = self.width();
        let chunk = (chunk as u64 / width).max(1) * width;
        let kept = wanted.end - wanted.start;
        let total = usize::try_from(kept)
            .ok()
            .and_then(|k| k.checked_mul(self.columns))
            .ok_or(ReadFailure::Memory)?;
        let mut out: Vec<f64> = Vec::new();
        let mut buf = vec![0u8; chunk as usize];
        let start = if seekable {
            reader.stream_position()?
        } else {
            0
        };
        // Passed over: `bytes` of a stream that are not wanted.
        let skip = |reader: &mut R, bytes: u64, buf: &mut [u8]| -> std::io::Result<()> {
            if seekable {
                reader.seek(SeekFrom::Current(
                    i64::try_from(bytes)
                        .map_err(|_| std::io::Error::other("offset out of range"))?,
                ))?;
                return Ok(());
            }
            let mut left = bytes;
            while left > 0 {
                let n = left.min(buf.len() as u64) as usize;
                read_full(reader, &mut buf[..n])?;
                left -= n as u64;
            }
            Ok(())
        };
        if !self.fortran {
            // Row after row: the rows wanted are one run of bytes.
            let row_bytes = width * self.file_columns as u64;
            if exact {
                out.try_reserve_exact(total)
                    .map_err(|_| ReadFailure::Memory)?;
            }
            if seekable {
                reader.seek(SeekFrom::Start(start + wanted.start * row_bytes))?;
            } else {
                skip(reader, wanted.start * row_bytes, &mut buf)?;
            }
            let mut left = kept * row_bytes;
            while left > 0 {
                let n = left.min(chunk) as usize;
                read_full(reader, &mut buf[..n])?;
                left -= n as u64;
                let added = n / self.scalar * if self.widen() { 2 } else { 1 };
                out.try_reserve(added).map_err(|_| ReadFailure::Memory)?;
                self.convert(&buf[..n], |v| {
                    out.push(v);
                    if self.widen() {
                        out.push(0.0);
                    }
                });
            }
            return Ok(out);
        }
        // Column after column: each element put in its row.
        out.try_reserve_exact(total)
            .map_err(|_| ReadFailure::Memory)?;
        out.resize(total, 0.0);
        let column_bytes = width * self.rows;
        let step = if self.widen() { 2 } else { 1 };
        for j in 0..self.file_columns {
            let column = start + j as u64 * column_bytes;
            if seekable {
                reader.seek(SeekFrom::Start(column + wanted.start * width))?;
            } else {
                skip(reader, wanted.start * width, &mut buf)?;
            }
            // The next value's place: row `i`, this column, part `part`.
            let (mut i, mut part) = (0usize, 0usize);
            let mut left = kept * width;
            while left > 0 {
                let n = left.min(chunk) as usize;
                read_full(reader, &mut buf[..n])?;
                left -= n as u64;
                self.convert(&buf[..n], |v| {
                    out[i * self.columns + (j * self.parts + part) * step] = v;
                    part += 1;
                    if part == self.parts {
                        part = 0;
                        i += 1;
                    }
                });
            }
            if !seekable {
                skip(reader, (self.rows - wanted.end) * width, &mut buf)?;
            }
        }
        Ok(out)
    }

    /// Each real number of `bytes` (whole numbers), in order, as `f64`.
    fn convert(&self, bytes: &[u8], mut put: impl FnMut(f64)) {
        match (self.scalar, self.big_endian) {
            (4, false) => bytes
                .chunks_exact(4)
                .for_each(|b| put(f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))),
            (4, true) => bytes
                .chunks_exact(4)
                .for_each(|b| put(f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])))),
            (_, false) => bytes.chunks_exact(8).for_each(|b| {
                put(f64::from_le_bytes([
                    b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7],
                ]))
            }),
            (_, true) => bytes.chunks_exact(8).for_each(|b| {
                put(f64::from_be_bytes([
                    b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7],
                ]))
            }),
        }
    }
}

/// Fill `buf` from `reader`; data that end first are an error.
fn read_full(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<()> {
    reader.read_exact(buf).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the data ends before the header's shape is filled",
            )
        } else {
            e
        }
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
        Values::F64(v) => write_typed(out, v.iter().copied(), &shape),
        Values::F32(v) => write_typed(out, v.iter().copied(), &shape),
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
    // The pairs are made as they are written: no copy of the values.
    fn pairs<T: Copy>(v: &[T]) -> impl Iterator<Item = Complex<T>> + '_ {
        v.chunks_exact(2).map(|p| Complex::new(p[0], p[1]))
    }
    super::output::write_atomically(path, |out| match values {
        Values::F64(v) => write_typed(out, pairs(v), &shape),
        Values::F32(v) => write_typed(out, pairs(v), &shape),
    })
}

/// `values` as an array of `shape` in `out`, one element at a time
/// (through the caller's buffered writer).
fn write_typed<T, W>(
    out: W,
    values: impl IntoIterator<Item = T>,
    shape: &[u64],
) -> std::io::Result<()>
where
    T: npyz::AutoSerialize,
    W: Write,
{
    let mut writer = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(out)
        .begin_nd()?;
    writer.extend(values)?;
    writer.finish()
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use npyz::num_complex::Complex;

    use super::*;

    /// The bytes of a `.npy` file of `stored` (in storage order) with
    /// dtype `descr`, `shape` and `order`.
    fn npy_bytes<T: npyz::AutoSerialize + Copy>(
        descr: &str,
        stored: &[T],
        shape: &[u64],
        order: Order,
    ) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut w = npyz::WriteOptions::new()
            .dtype(DType::parse(&format!("'{descr}'")).unwrap())
            .shape(shape)
            .order(order)
            .writer(&mut bytes)
            .begin_nd()
            .unwrap();
        w.extend(stored.iter().copied()).unwrap();
        w.finish().unwrap();
        bytes
    }

    /// `rows x cols` values `f(i, j)` in C order, or column by column for
    /// Fortran order.
    fn stored<T>(rows: usize, cols: usize, order: Order, f: impl Fn(usize, usize) -> T) -> Vec<T> {
        match order {
            Order::C => (0..rows * cols).map(|k| f(k / cols, k % cols)).collect(),
            Order::Fortran => (0..rows * cols).map(|k| f(k % rows, k / rows)).collect(),
        }
    }

    /// A value exact in `f32` for element `(i, j)`.
    fn v(i: usize, j: usize) -> f64 {
        (7 * i + j) as f64 * 0.5 - 40.0
    }

    /// Every chunk size (down to one element), a file and a stream, whole
    /// and row ranges that start and end inside chunks: the values of
    /// `expected` (`columns` per row) for the rows asked for.
    fn check_all(bytes: &[u8], contents: Contents, expected: &[f64], complex: bool) {
        let columns = contents.columns();
        let rows = (expected.len() / columns) as u64;
        let path = Path::new("t.npy");
        for chunk in [1, 8, 16, 24, 40, 48, 1000, CHUNK] {
            for length in [Some(bytes.len() as u64), None] {
                for range in [0..rows, 0..1, 1..rows, 5..23, 17..rows, rows..rows, 3..3] {
                    let table = read_from(
                        Cursor::new(bytes),
                        length,
                        path,
                        contents,
                        None,
                        |_| range.clone(),
                        chunk,
                    )
                    .unwrap_or_else(|e| panic!("chunk {chunk}, {length:?}, {range:?}: {e}"));
                    let want =
                        &expected[range.start as usize * columns..range.end as usize * columns];
                    assert_eq!(
                        table.values, want,
                        "chunk {chunk}, length {length:?}, rows {range:?}"
                    );
                    assert_eq!((table.rows, table.complex), (rows, complex));
                }
            }
        }
    }

    #[test]
    fn chunk_boundaries_in_every_type_order_and_byte_order() {
        let n = 37;
        let points: Vec<f64> = (0..3 * n).map(|k| v(k / 3, k % 3)).collect();
        for order in [Order::C, Order::Fortran] {
            for descr in ["<f8", ">f8"] {
                let bytes = npy_bytes(descr, &stored(n, 3, order, v), &[n as u64, 3], order);
                check_all(&bytes, Contents::Points, &points, false);
            }
            for descr in ["<f4", ">f4"] {
                let s = stored(n, 3, order, |i, j| v(i, j) as f32);
                let bytes = npy_bytes(descr, &s, &[n as u64, 3], order);
                check_all(&bytes, Contents::Points, &points, false);
            }
            // Complex dipoles: complex128 / complex64, both byte orders.
            let z = |i: usize, j: usize| Complex::new(v(i, j), -v(j, i));
            let dipoles: Vec<f64> = (0..3 * n)
                .flat_map(|k| {
                    let c = z(k / 3, k % 3);
                    [c.re, c.im]
                })
                .collect();
            for descr in ["<c16", ">c16"] {
                let bytes = npy_bytes(descr, &stored(n, 3, order, z), &[n as u64, 3], order);
                check_all(&bytes, Contents::ComplexDipoles, &dipoles, true);
            }
            for descr in ["<c8", ">c8"] {
                let s = stored(n, 3, order, |i, j| {
                    let c = z(i, j);
                    Complex::new(c.re as f32, c.im as f32)
                });
                let bytes = npy_bytes(descr, &s, &[n as u64, 3], order);
                check_all(&bytes, Contents::ComplexDipoles, &dipoles, true);
            }
            // Real (N, 6) dipoles holding both parts, and (N, 3) real
            // parts alone (zero imaginary parts).
            let both = stored(n, 6, order, |i, j| dipoles[6 * i + j]);
            let bytes = npy_bytes(">f8", &both, &[n as u64, 6], order);
            check_all(&bytes, Contents::ComplexDipoles, &dipoles, false);
            let real: Vec<f64> = (0..3 * n).flat_map(|k| [v(k / 3, k % 3), 0.0]).collect();
            let bytes = npy_bytes(
                "<f4",
                &stored(n, 3, order, |i, j| v(i, j) as f32),
                &[n as u64, 3],
                order,
            );
            check_all(&bytes, Contents::ComplexDipoles, &real, false);
        }
        // Charges: (N,) and (N, 1), complex and real parts alone.
        let q: Vec<f64> = (0..n).map(|i| v(i, 0)).collect();
        check_all(
            &npy_bytes(">f8", &q, &[n as u64], Order::C),
            Contents::Charges(1),
            &q,
            false,
        );
        check_all(
            &npy_bytes("<f8", &q, &[n as u64, 1], Order::Fortran),
            Contents::Charges(1),
            &q,
            false,
        );
        let zq: Vec<Complex<f64>> = (0..n).map(|i| Complex::new(v(i, 0), v(0, i))).collect();
        let pairs: Vec<f64> = zq.iter().flat_map(|c| [c.re, c.im]).collect();
        check_all(
            &npy_bytes(">c16", &zq, &[n as u64], Order::C),
            Contents::ComplexCharges,
            &pairs,
            true,
        );
        let widened: Vec<f64> = q.iter().flat_map(|&x| [x, 0.0]).collect();
        check_all(
            &npy_bytes(">f8", &q, &[n as u64, 1], Order::Fortran),
            Contents::ComplexCharges,
            &widened,
            false,
        );
    }

    #[test]
    fn non_finite_values_are_named_by_their_element_across_chunks() {
        let n = 29;
        let at = |i: usize, j: usize| if (i, j) == (20, 2) { f64::NAN } else { v(i, j) };
        for order in [Order::C, Order::Fortran] {
            let bytes = npy_bytes(">f8", &stored(n, 3, order, at), &[n as u64, 3], order);
            for chunk in [8, 24, 56, CHUNK] {
                for length in [Some(bytes.len() as u64), None] {
                    let e = read_from(
                        Cursor::new(&bytes),
                        length,
                        Path::new("t.npy"),
                        Contents::Points,
                        None,
                        |n| 0..n,
                        chunk,
                    )
                    .unwrap_err()
                    .to_string();
                    assert!(e.contains("element [20, 2] is not finite"), "{e}");
                    // A range without it reads.
                    assert!(
                        read_from(
                            Cursor::new(&bytes),
                            length,
                            Path::new("t.npy"),
                            Contents::Points,
                            None,
                            |_| 0..20,
                            chunk
                        )
                        .is_ok()
                    );
                }
            }
            // Real parts alone of complex dipoles: the file's column.
            let bytes = npy_bytes("<f8", &stored(n, 3, order, at), &[n as u64, 3], order);
            let e = read_from(
                Cursor::new(&bytes),
                None,
                Path::new("t.npy"),
                Contents::ComplexDipoles,
                None,
                |n| 0..n,
                16,
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("element [20, 2] is not finite"), "{e}");
        }
    }

    #[test]
    fn short_data_and_the_memory_limit() {
        let n = 40;
        let bytes = npy_bytes(
            "<f8",
            &stored(n, 3, Order::Fortran, v),
            &[n as u64, 3],
            Order::Fortran,
        );
        let short = &bytes[..bytes.len() - 8];
        for chunk in [8, 48, CHUNK] {
            let e = read_from(
                Cursor::new(short),
                None,
                Path::new("t.npy"),
                Contents::Points,
                None,
                |n| 0..n,
                chunk,
            )
            .unwrap_err()
            .to_string();
            assert!(
                e.contains("cannot read the data (the data ends before"),
                "{e}"
            );
            // Held: the rows kept, not the file.
            let t = read_from(
                Cursor::new(&bytes),
                None,
                Path::new("t.npy"),
                Contents::Points,
                Some(240),
                |_| 10..20,
                chunk,
            )
            .unwrap();
            assert_eq!(t.values.len(), 30);
            let e = read_from(
                Cursor::new(&bytes),
                None,
                Path::new("t.npy"),
                Contents::Points,
                Some(239),
                |_| 10..20,
                chunk,
            )
            .unwrap_err();
            assert!(matches!(e, FileError::TooLarge { limit: 239, .. }), "{e}");
        }
    }
}
