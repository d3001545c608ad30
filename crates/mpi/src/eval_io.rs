//! Files of the `eval` command: each rank's rows of a `.npy` or `.csv`
//! input, and the output written in the input order (each rank its rows of
//! a `.npy` file, or the ranks in turn for `.csv`).

use std::path::Path;

use ferrofmm_mpi::{agree_message, npy};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// This rank's rows `[N r / R, N (r + 1) / R)`.
pub(crate) fn my_rows(n: u64, me: usize, size: usize) -> std::ops::Range<u64> {
    let at = |r: usize| (n as u128 * r as u128 / size as u128) as u64;
    at(me)..at(me + 1)
}

/// Values of a .csv file: numbers separated by commas or spaces, `#`
/// comments and blank lines skipped; every row must have `columns`.
fn read_csv(path: &Path, columns: usize) -> Result<Vec<f64>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let row: Vec<f64> = line
            .split([',', ' ', '\t'])
            .filter(|s| !s.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{}: line {}: {e}", path.display(), i + 1))?;
        if row.len() != columns {
            return Err(format!(
                "{}: line {}: {} values, expected {columns}",
                path.display(),
                i + 1,
                row.len()
            ));
        }
        out.extend(row);
    }
    Ok(out)
}

pub(crate) fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// This rank's rows of `path` (`columns` values per row) and the total
/// number of rows.
pub(crate) fn read_slice(
    path: &Path,
    columns: u64,
    me: usize,
    size: usize,
) -> Result<(Vec<f64>, u64), String> {
    if is_npy(path) {
        let h = npy::header(path)?;
        if h.columns != columns {
            return Err(format!(
                "{}: {} values per row, expected {columns}",
                path.display(),
                h.columns
            ));
        }
        let rows = my_rows(h.rows, me, size);
        Ok((npy::read_rows(path, &h, rows)?, h.rows))
    } else {
        let all = read_csv(path, columns as usize)?;
        let n = (all.len() as u64) / columns;
        let r = my_rows(n, me, size);
        let c = columns as usize;
        Ok((all[r.start as usize * c..r.end as usize * c].to_vec(), n))
    }
}

/// Writes the values (`w` per point, this rank's input rows from
/// `first_row`) to `out`, through a temporary file renamed at the end.
pub(crate) fn write_out(
    world: &SimpleCommunicator,
    out: &Path,
    values: &[f64],
    w: usize,
    first_row: u64,
    total: u64,
) -> Result<(), String> {
    let me = world.rank();
    let tmp = out.with_extension(format!(
        "{}.part",
        out.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    let result = if is_npy(out) {
        let start = if me == 0 {
            npy::create(&tmp, total, w as u64)
        } else {
            Ok(0)
        };
        let start = agree_message(world, start).map_err(|e| e.to_string())?;
        let mut s = start;
        world.process_at_rank(0).broadcast_into(&mut s);
        npy::write_rows(&tmp, s, w as u64, first_row, values)
    } else {
        // Ranks append their rows in turn.
        let mut r = Ok(());
        for turn in 0..world.size() {
            if turn == me {
                let text: String = values
                    .chunks_exact(w)
                    .map(|row| {
                        row.iter()
                            .map(|x| format!("{x:e}"))
                            .collect::<Vec<_>>()
                            .join(",")
                            + "\n"
                    })
                    .collect();
                r = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .truncate(false)
                    .open(&tmp)
                    .and_then(|mut f| {
                        if me == 0 {
                            f.set_len(0)?;
                        }
                        std::io::Write::write_all(&mut f, text.as_bytes())
                    })
                    .map_err(|e| format!("{}: {e}", tmp.display()));
            }
            world.barrier();
        }
        r
    };
    agree_message(world, result).map_err(|e| e.to_string())?;
    if me == 0 {
        std::fs::rename(&tmp, out).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    Ok(())
}
