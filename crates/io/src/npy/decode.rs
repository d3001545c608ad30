//! The data of a `.npy` array, decoded: its element type and shape checked
//! against the contents asked for ([`read_from`]), then read in chunks
//! ([`super::layout`]) into the rows kept.

use std::io::{Read, Seek};
use std::ops::Range;
use std::path::Path;

use npyz::{DType, Endianness, NpyFile, Order, TypeChar};

use crate::error::{FileError, Result, check_finite};
use crate::{Contents, Table};

use super::layout::{Layout, ReadFailure};

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

/// [`read_table`](super::read_table) from `reader`, the file `path` of `length` bytes when it
/// is a regular file (then read only where the rows lie), else a stream;
/// the data read `chunk` bytes at a time.
pub(super) fn read_from<R: Read + Seek>(
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

    check_finite(path, &values, |k| {
        let row = wanted.start as usize + k / columns;
        if shape.len() == 1 {
            format!("element [{row}]")
        } else {
            // The file's column (a widened value and its zero imaginary
            // part come from one column).
            let per = if widen { 2 } else { element.parts() };
            format!("element [{row}, {}]", (k % columns) / per)
        }
    })?;
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

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use npyz::WriterBuilder;
    use npyz::num_complex::Complex;

    use super::*;
    use crate::npy::CHUNK;

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

    /// [`read_from`] on `bytes` as `t.npy` (a regular file of `length`
    /// bytes, or a stream when `None`): the rows `rows` (all when `None`)
    /// within `limit` bytes, `chunk` bytes at a time.
    fn read_bytes(
        bytes: &[u8],
        length: Option<u64>,
        contents: Contents,
        rows: Option<Range<u64>>,
        limit: Option<u64>,
        chunk: usize,
    ) -> Result<Table> {
        let pick = |n| rows.unwrap_or(0..n);
        read_from(
            Cursor::new(bytes),
            length,
            Path::new("t.npy"),
            contents,
            limit,
            pick,
            chunk,
        )
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
        for chunk in [1, 8, 16, 24, 40, 48, 1000, CHUNK] {
            for length in [Some(bytes.len() as u64), None] {
                for range in [0..rows, 0..1, 1..rows, 5..23, 17..rows, rows..rows, 3..3] {
                    let table =
                        read_bytes(bytes, length, contents, Some(range.clone()), None, chunk)
                            .unwrap_or_else(|e| {
                                panic!("chunk {chunk}, {length:?}, {range:?}: {e}")
                            });
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
                    let e = read_bytes(&bytes, length, Contents::Points, None, None, chunk)
                        .unwrap_err()
                        .to_string();
                    assert!(e.contains("element [20, 2] is not finite"), "{e}");
                    // A range without it reads.
                    assert!(
                        read_bytes(&bytes, length, Contents::Points, Some(0..20), None, chunk)
                            .is_ok()
                    );
                }
            }
            // Real parts alone of complex dipoles: the file's column.
            let bytes = npy_bytes("<f8", &stored(n, 3, order, at), &[n as u64, 3], order);
            let e = read_bytes(&bytes, None, Contents::ComplexDipoles, None, None, 16)
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
            let e = read_bytes(short, None, Contents::Points, None, None, chunk)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("cannot read the data (the data ends before"),
                "{e}"
            );
            // Held: the rows kept, not the file.
            let t = read_bytes(
                &bytes,
                None,
                Contents::Points,
                Some(10..20),
                Some(240),
                chunk,
            )
            .unwrap();
            assert_eq!(t.values.len(), 30);
            let e = read_bytes(
                &bytes,
                None,
                Contents::Points,
                Some(10..20),
                Some(239),
                chunk,
            )
            .unwrap_err();
            assert!(matches!(e, FileError::TooLarge { limit: 239, .. }), "{e}");
        }
    }
}
