//! Raw `.f64` files: little-endian `float64` values one record after the
//! other, without a header (`x, y, z` per point; `re, im` pairs for
//! complex contents). The file's length must be a whole number of
//! records (24 bytes per point). Read only: outputs are `.csv` or `.npy`.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::Path;

use super::{Contents, Table};
use crate::error::{FileError, Result};

/// Rows `pick(n)` of the `n` records in the raw file `path`, and `n`. A
/// regular file is read only where the rows lie; a stream (a pipe) is
/// read whole, within `limit` bytes.
pub fn read_table(
    path: &Path,
    contents: Contents,
    limit: Option<u64>,
    pick: impl FnOnce(u64) -> Range<u64>,
) -> Result<Table> {
    let columns = contents.columns();
    let record = 8 * columns as u64;
    let mut file = File::open(path).map_err(|e| FileError::io(path, e))?;
    let meta = file.metadata().map_err(|e| FileError::io(path, e))?;
    let too_large = || FileError::TooLarge {
        path: path.to_path_buf(),
        limit: limit.unwrap_or(u64::MAX),
    };
    let exceeds = |bytes: u64| limit.is_some_and(|l| bytes > l);

    let (bytes, rows, first_row) = if meta.is_file() {
        let len = meta.len();
        check_length(path, contents, len)?;
        let rows = len / record;
        let wanted = pick(rows);
        let wanted = wanted.start.min(rows)..wanted.end.min(rows);
        let count = wanted.end.saturating_sub(wanted.start) * record;
        if exceeds(count) {
            return Err(too_large());
        }
        file.seek(SeekFrom::Start(wanted.start * record))
            .map_err(|e| FileError::io(path, e))?;
        let mut bytes = vec![0u8; usize::try_from(count).map_err(|_| too_large())?];
        file.read_exact(&mut bytes)
            .map_err(|e| FileError::io(path, e))?;
        (bytes, rows, wanted.start)
    } else {
        // A stream: everything, up to the limit (one byte more tells).
        let mut bytes = Vec::new();
        BufReader::new(file)
            .take(limit.map_or(u64::MAX, |l| l.saturating_add(1)))
            .read_to_end(&mut bytes)
            .map_err(|e| FileError::io(path, e))?;
        if exceeds(bytes.len() as u64) {
            return Err(too_large());
        }
        check_length(path, contents, bytes.len() as u64)?;
        let rows = bytes.len() as u64 / record;
        let wanted = pick(rows);
        let wanted = wanted.start.min(rows)..wanted.end.min(rows);
        let kept = bytes[(wanted.start * record) as usize..(wanted.end * record) as usize].to_vec();
        (kept, rows, wanted.start)
    };

    let values: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
        .collect();
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        let row = first_row as usize + k / columns;
        let location = if columns == 1 {
            format!("record {row}")
        } else {
            format!("record {row}, value {}", k % columns)
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
        complex: false,
    })
}

/// A length of `len` bytes that is not a whole number of records is an
/// error naming the record size.
fn check_length(path: &Path, contents: Contents, len: u64) -> Result<()> {
    let columns = contents.columns();
    let record = 8 * columns as u64;
    if len.is_multiple_of(record) {
        return Ok(());
    }
    let what = match contents {
        Contents::Points => "x, y, z".to_string(),
        _ if contents.is_complex() => format!("{} re, im pairs", columns / 2),
        _ if columns == 1 => "one value".to_string(),
        _ => format!("{columns} values"),
    };
    Err(FileError::Raw {
        path: path.to_path_buf(),
        message: format!(
            "{len} bytes are not a whole number of {} (raw .f64: {record} bytes each, {what} as \
             little-endian float64)",
            contents.noun()
        ),
    })
}
