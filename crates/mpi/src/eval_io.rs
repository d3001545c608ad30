//! Files of the `eval` and `tree` commands, through `ferrofmm-io` (the
//! reader and writer of `ferrofmm eval`, so both commands take and write
//! the same files): each rank's rows of a `.npy` or `.csv` input, and the
//! output written in the input order (each rank its rows of a `.npy`
//! file, or the ranks in turn for `.csv`) into one temporary file that
//! rank 0 renames into place once every rank has written, or removes on
//! any failure.

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

use ferrofmm_io::{Contents, Format, Reader, csv, npy, output};
use ferrofmm_mpi::agree_text;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// This rank's rows `[N r / R, N (r + 1) / R)`.
pub(crate) fn my_rows(n: u64, me: usize, size: usize) -> std::ops::Range<u64> {
    let at = |r: usize| (n as u128 * r as u128 / size as u128) as u64;
    at(me)..at(me + 1)
}

/// The reader of this rank: within its share of the memory limit (the
/// memory available, or FERROFMM_MEMORY_LIMIT, divided among the ranks
/// of the node, which read at the same time).
pub(crate) fn reader(world: &SimpleCommunicator) -> Result<Reader, String> {
    let on_node = world.split_shared(world.rank()).size().max(1) as u64;
    let limit = ferrofmm_field::MemoryLimit::Auto
        .resolve()
        .map_err(|e| e.to_string())?;
    Ok(Reader::new().memory_limit(limit.map(|l| l / on_node)))
}

/// This rank's rows of `path` (`contents` per row), the total number of
/// rows, and whether the file held complex numbers.
pub(crate) fn read_slice(
    reader: &Reader,
    path: &Path,
    contents: Contents,
    me: usize,
    size: usize,
) -> Result<(Vec<f64>, u64, bool), String> {
    reader
        .read_table(path, contents, |n| my_rows(n, me, size))
        .map(|t| (t.values, t.rows, t.complex))
        .map_err(|e| e.to_string())
}

/// The same string on every rank: `text` of rank `root`.
fn broadcast_text(world: &SimpleCommunicator, root: i32, text: &str) -> String {
    let mut bytes = if world.rank() == root {
        text.as_bytes().to_vec()
    } else {
        Vec::new()
    };
    let mut len = bytes.len() as u64;
    let process = world.process_at_rank(root);
    process.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    process.broadcast_into(&mut bytes[..]);
    String::from_utf8_lossy(&bytes).into_owned()
}

/// Writes the values (`names.len()` per point, this rank's input rows from
/// `rows.0`, of `rows.1`) to `out` (a collective); a `.npy` output holds
/// complex numbers when `complex` (`re, im` pairs of values, `complex128`),
/// else `float64`. Rank 0 creates the
/// temporary file (a `.npy` header and room for the data, or the CSV
/// header line); every rank writes its rows into it; only when every rank
/// succeeded does rank 0 rename it onto `out`. On any failure, on any
/// rank, every rank returns the same error and the temporary file is
/// removed: `out` is untouched.
pub(crate) fn write_out(
    world: &SimpleCommunicator,
    out: &Path,
    values: &[f64],
    names: &[&str],
    (first_row, total): (u64, u64),
    complex: bool,
) -> Result<(), String> {
    let me = world.rank();
    let w = names.len();
    let format = Format::of_output(out).map_err(|e| e.to_string())?;
    let failed = |e: std::io::Error| {
        ferrofmm_io::FileError::WriteFailed {
            path: out.to_path_buf(),
            source: e,
        }
        .to_string()
    };
    // Rank 0: the temporary file with its header (removed when dropped).
    let mut tmp = None;
    let created = if me == 0 {
        (|| {
            let mut t = output::Temporary::create(out).map_err(|e| e.to_string())?;
            let f = t.file().map_err(|e| e.to_string())?;
            let start = match format {
                Format::Npy => {
                    let head = if complex {
                        npy::complex_header_bytes(total, w as u64 / 2)
                    } else {
                        npy::header_bytes(total, w as u64)
                    };
                    f.write_all(&head)
                        .and_then(|()| f.set_len(head.len() as u64 + 8 * total * w as u64))
                        .map_err(failed)?;
                    head.len() as u64
                }
                Format::Csv | Format::Raw => {
                    let mut b = std::io::BufWriter::new(&mut *f);
                    csv::write_header(&mut b, names)
                        .and_then(|()| b.flush())
                        .map_err(failed)?;
                    0
                }
            };
            let path = t.path().to_string_lossy().into_owned();
            tmp = Some(t);
            Ok((path, start))
        })()
    } else {
        Ok((String::new(), 0))
    };
    let (path, mut start) = agree_text(world, created)?;
    let path = broadcast_text(world, 0, &path);
    world.process_at_rank(0).broadcast_into(&mut start);

    let open = || std::fs::OpenOptions::new().write(true).open(&path);
    let written = match format {
        Format::Npy => open()
            .and_then(|mut f| {
                f.seek(SeekFrom::Start(start + 8 * w as u64 * first_row))?;
                // Through a bounded buffer: no byte copy of the values.
                let mut f = std::io::BufWriter::new(f);
                for x in values {
                    f.write_all(&x.to_le_bytes())?;
                }
                f.flush()
            })
            .map_err(failed),
        Format::Csv | Format::Raw => {
            // Ranks append their rows in turn (a failure is agreed at the end;
            // a rank after a failed one still takes its turn).
            let mut r = Ok(());
            for turn in 0..world.size() {
                if turn == me {
                    r = open()
                        .and_then(|f| {
                            let mut f = std::io::BufWriter::new(f);
                            f.seek(SeekFrom::End(0))?;
                            csv::write_records(&mut f, values, w)?;
                            f.flush()
                        })
                        .map_err(failed);
                }
                world.barrier();
            }
            r
        }
    };
    agree_text(world, written)?;
    let committed = match tmp {
        Some(t) => t.commit().map_err(|e| e.to_string()),
        None => Ok(()),
    };
    agree_text(world, committed)
}
