//! Where an array's data lie in the file ([`Layout`]: type, byte order,
//! C or Fortran order) and their reading, [`CHUNK`] bytes at a time, into
//! the rows kept.

use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;

use crate::error::Result;

/// Bytes of data read at a time (a multiple of every element size).
pub const CHUNK: usize = 1 << 16;

/// Why the data could not be read.
#[derive(Debug)]
pub(super) enum ReadFailure {
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
pub(super) struct Layout {
    /// Bytes of one real number (4 or 8).
    pub(super) scalar: usize,
    pub(super) big_endian: bool,
    /// Real numbers per element (2 for a complex one).
    pub(super) parts: usize,
    /// Elements per row in the file.
    pub(super) file_columns: usize,
    /// Values per row read (`file_columns * parts`, or twice that when
    /// the file holds the real parts alone, widened with zero imaginary
    /// parts).
    pub(super) columns: usize,
    /// Rows in the file.
    pub(super) rows: u64,
    /// Stored column by column.
    pub(super) fortran: bool,
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
    pub(super) fn read<R: Read + Seek>(
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
