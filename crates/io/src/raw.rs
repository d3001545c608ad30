//! Raw `.f64` files: little-endian `float64` values one record after the
//! other, without a header (`x, y, z` per point; `re, im` pairs for
//! complex contents). The file's length must be a whole number of
//! records (24 bytes per point). Read only: outputs are `.csv` or `.npy`.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::Path;

use super::{Contents, Table};
use crate::error::{FileError, Result, check_finite};

/// Rows `pick(n)` of the `n` records in the raw file `path`, and `n`. A
/// regular file is read only where the rows lie; a stream (a pipe) is
/// read whole, within `limit` bytes, and the rows asked for kept in
/// place. The bytes are converted as they are read, a bounded chunk at a
/// time, straight into the array returned.
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

    // Values are converted as they are read, `CHUNK` bytes at a time,
    // straight into the array returned.
    let mut buf = vec![0u8; CHUNK];
    let mut values: Vec<f64> = Vec::new();
    let (rows, first_row) = if meta.is_file() {
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
        values
            .try_reserve_exact(usize::try_from(count / 8).map_err(|_| too_large())?)
            .map_err(|_| too_large())?;
        let mut left = count;
        while left > 0 {
            let n = left.min(CHUNK as u64) as usize;
            file.read_exact(&mut buf[..n])
                .map_err(|e| FileError::io(path, e))?;
            left -= n as u64;
            push_values(&buf[..n], &mut values);
        }
        (rows, wanted.start)
    } else {
        // A stream: everything, up to the limit (one byte more tells),
        // then the rows asked for kept in place.
        let mut reader = BufReader::new(file).take(limit.map_or(u64::MAX, |l| l.saturating_add(1)));
        let mut len = 0u64;
        let mut filled = 0;
        loop {
            let n = match reader.read(&mut buf[filled..]) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(FileError::io(path, e)),
            };
            len += n as u64;
            filled += n;
            if exceeds(len) {
                return Err(too_large());
            }
            // Whole values converted; a partial one waits for its rest.
            let whole = filled / 8 * 8;
            if n == 0 || whole == buf.len() {
                values.try_reserve(whole / 8).map_err(|_| too_large())?;
                push_values(&buf[..whole], &mut values);
                buf.copy_within(whole..filled, 0);
                filled -= whole;
            }
            if n == 0 {
                break;
            }
        }
        check_length(path, contents, len)?;
        let rows = len / record;
        let wanted = pick(rows);
        let wanted = wanted.start.min(rows)..wanted.end.min(rows);
        values.truncate(wanted.end as usize * columns);
        values.drain(..wanted.start as usize * columns);
        (rows, wanted.start)
    };
    drop(buf);

    check_finite(path, &values, |k| {
        let row = first_row as usize + k / columns;
        if columns == 1 {
            format!("record {row}")
        } else {
            format!("record {row}, value {}", k % columns)
        }
    })?;
    Ok(Table {
        values,
        rows,
        complex: false,
    })
}

/// Bytes read at a time (a whole number of values).
const CHUNK: usize = 1 << 16;

/// The little-endian `float64` values of `bytes` (whole values) onto `out`.
fn push_values(bytes: &[u8], out: &mut Vec<f64>) {
    out.extend(
        bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])),
    );
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
