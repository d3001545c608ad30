//! Writing `.npy` arrays (real and complex, C order) and the bare headers
//! for writers that fill the data in parts ([`header_bytes`]).

use std::io::Write;
use std::path::Path;

use npyz::WriterBuilder;
use npyz::num_complex::Complex;

use crate::Values;
use crate::error::Result;

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
    crate::output::write_atomically(path, |out| match values {
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
    crate::output::write_atomically(path, |out| match values {
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
