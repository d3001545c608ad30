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
use std::io::{BufReader, Write};
use std::path::Path;

use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};

use super::{Contents, Values};
use crate::error::{CliError, Result};

/// Read `contents` from the `.npy` file `path` (interleaved values, C order).
pub fn read(path: &Path, contents: Contents) -> Result<Vec<f64>> {
    let file = File::open(path).map_err(|e| CliError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| CliError::io(path, e))?.len();
    let bad = |message: String| CliError::Npy {
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
    // A header promising more data than the file holds is caught before
    // anything is allocated for it.
    if npy
        .len()
        .checked_mul(width)
        .is_none_or(|bytes| bytes > file_len)
    {
        return Err(bad(format!(
            "the header promises shape {shape_text}, more than the file's {file_len} bytes hold"
        )));
    }
    let fortran = npy.order() == Order::Fortran;

    let raw: Vec<f64> = if width == 8 {
        npy.into_vec::<f64>()
    } else {
        npy.into_vec::<f32>()
            .map(|v| v.into_iter().map(f64::from).collect())
    }
    .map_err(|e| bad(format!("cannot read the data ({e})")))?;
    let rows = usize::try_from(rows).map_err(|_| bad("array too large".into()))?;
    if raw.len() != rows * columns {
        return Err(bad(format!(
            "the data holds {} values, the header promises {}",
            raw.len(),
            rows * columns
        )));
    }

    let values = if fortran && columns > 1 {
        // Column-major: element (i, j) at j * rows + i.
        (0..rows * columns)
            .map(|k| raw[(k % columns) * rows + k / columns])
            .collect()
    } else {
        raw
    };

    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        let location = if columns == 1 {
            format!("element [{k}]")
        } else {
            format!("element [{}, {}]", k / columns, k % columns)
        };
        return Err(CliError::NonFinite {
            path: path.to_path_buf(),
            location,
            value: values[k],
        });
    }
    Ok(values)
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
