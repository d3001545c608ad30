//! Slices of NumPy `.npy` files: each rank reads only its rows of an
//! `(N, 3)` point array or an `(N,)` charge array, and writes its rows of
//! the result array in place (rank 0 writes the header and sizes the file
//! first). Little-endian `float64` or `float32`, C order (what
//! `numpy.save` writes by default); anything else is an error naming what
//! was found.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

/// The header of a `.npy` file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// Bytes per value (8 for `<f8`, 4 for `<f4`).
    pub width: usize,
    /// Rows.
    pub rows: u64,
    /// Values per row (1 for a vector).
    pub columns: u64,
    /// Offset of the data.
    pub data_start: u64,
}

/// Reads and checks the header of `path`.
pub fn header(path: &Path) -> Result<Header, String> {
    let mut f = File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut pre = [0u8; 10];
    f.read_exact(&mut pre)
        .map_err(|_| format!("{}: not a .npy file", path.display()))?;
    if &pre[..6] != b"\x93NUMPY" {
        return Err(format!("{}: not a .npy file", path.display()));
    }
    let (len, start) = match pre[6] {
        1 => (u16::from_le_bytes([pre[8], pre[9]]) as usize, 10),
        2 | 3 => {
            let mut more = [0u8; 2];
            f.read_exact(&mut more)
                .map_err(|_| format!("{}: truncated header", path.display()))?;
            (
                u32::from_le_bytes([pre[8], pre[9], more[0], more[1]]) as usize,
                12,
            )
        }
        v => return Err(format!("{}: unsupported .npy version {v}", path.display())),
    };
    if len > 1 << 20 {
        return Err(format!("{}: header too long", path.display()));
    }
    let mut text = vec![0u8; len];
    f.read_exact(&mut text)
        .map_err(|_| format!("{}: truncated header", path.display()))?;
    let text = String::from_utf8_lossy(&text).replace(' ', "");
    let field = |name: &str| -> Option<String> {
        let at = text.find(&format!("'{name}':"))? + name.len() + 3;
        let rest = &text[at..];
        let end = if rest.starts_with('(') {
            rest.find(')')? + 1
        } else {
            rest.find([',', '}'])?
        };
        Some(rest[..end].trim_matches('\'').to_string())
    };
    let descr = field("descr").unwrap_or_default();
    let width = match descr.as_str() {
        "<f8" => 8,
        "<f4" => 4,
        other => {
            return Err(format!(
                "{}: unsupported dtype {other:?}: use little-endian float64 or float32",
                path.display()
            ));
        }
    };
    if field("fortran_order").as_deref() != Some("False") {
        return Err(format!(
            "{}: Fortran-order arrays cannot be read in slices: save in C order",
            path.display()
        ));
    }
    let shape = field("shape").unwrap_or_default();
    let dims: Vec<u64> = shape
        .trim_matches(['(', ')'])
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<u64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{}: bad shape {shape}", path.display()))?;
    let (rows, columns) = match dims.as_slice() {
        [n] => (*n, 1),
        [n, c] => (*n, *c),
        _ => return Err(format!("{}: unsupported shape {shape}", path.display())),
    };
    let data_start = (start + len) as u64;
    let need = rows
        .checked_mul(columns)
        .and_then(|v| v.checked_mul(width as u64))
        .and_then(|b| b.checked_add(data_start));
    let have = f
        .metadata()
        .map_err(|e| format!("{}: {e}", path.display()))?
        .len();
    if need.is_none_or(|n| n > have) {
        return Err(format!(
            "{}: the header promises shape {shape}, more than the file's {have} bytes hold",
            path.display()
        ));
    }
    Ok(Header {
        width,
        rows,
        columns,
        data_start,
    })
}

/// Rows `rows` of the array in `path` (described by `h`), as `f64`.
pub fn read_rows(path: &Path, h: &Header, rows: std::ops::Range<u64>) -> Result<Vec<f64>, String> {
    let mut f = File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let per_row = h.columns * h.width as u64;
    f.seek(SeekFrom::Start(h.data_start + rows.start * per_row))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut bytes = vec![0u8; ((rows.end - rows.start) * per_row) as usize];
    f.read_exact(&mut bytes)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(match h.width {
        8 => bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
            .collect(),
        _ => bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as f64)
            .collect(),
    })
}

/// The header of a C-order little-endian `float64` array of `rows` rows
/// of `columns` values (`columns == 1`: a vector), padded to 64 bytes.
fn header_bytes(rows: u64, columns: u64) -> Vec<u8> {
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

/// Creates `path` holding the header of a `float64` array of `rows` x
/// `columns` and room for its data (rank 0 does this first).
pub fn create(path: &Path, rows: u64, columns: u64) -> Result<u64, String> {
    let head = header_bytes(rows, columns);
    let mut f = File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    f.write_all(&head)
        .and_then(|_| f.set_len(head.len() as u64 + 8 * rows * columns))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(head.len() as u64)
}

/// Writes `values` (whole rows of `columns`) from row `first_row` on into
/// the file made by [`create`] (whose data start at `data_start`).
pub fn write_rows(
    path: &Path,
    data_start: u64,
    columns: u64,
    first_row: u64,
    values: &[f64],
) -> Result<(), String> {
    let mut f = OpenOptions::new()
        .write(true)
        .open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
    f.seek(SeekFrom::Start(data_start + 8 * columns * first_row))
        .and_then(|_| f.write_all(&bytes))
        .map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_slices_read_back() {
        let dir = std::env::temp_dir().join(format!("ferrofmm-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.npy");
        let start = create(&path, 5, 3).unwrap();
        let all: Vec<f64> = (0..15).map(|i| i as f64 * 0.5).collect();
        write_rows(&path, start, 3, 2, &all[6..]).unwrap();
        write_rows(&path, start, 3, 0, &all[..6]).unwrap();
        let h = header(&path).unwrap();
        assert_eq!((h.rows, h.columns, h.width), (5, 3, 8));
        assert_eq!(read_rows(&path, &h, 1..4).unwrap(), all[3..12]);
        std::fs::write(&path, b"not numpy").unwrap();
        assert!(header(&path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
