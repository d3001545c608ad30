//! # ferrofmm-io
//!
//! Reading points and charges, writing results: `.csv` and `.npy` files,
//! the one reader and writer of the `ferrofmm` and `ferrofmm-mpi`
//! commands.
//!
//! The format follows the file's extension (case-insensitive):
//!
//! * `.csv`: text, one record per line — see [`csv`] for the exact rules
//!   (optional header line, `#` comments, blank lines ignored, a UTF-8
//!   byte order mark skipped).
//! * `.npy`: NumPy arrays, `float64`, `float32`, `complex128` or
//!   `complex64` (complex values for a complex kernel's densities), either
//!   byte order, C or Fortran order — see [`npy`].
//! * `.f64`: raw little-endian `float64` values, one record after the
//!   other, without a header (3 values per point) — see [`raw`].
//!
//! The densities of a complex kernel (Helmholtz) are read as `re, im`
//! pairs ([`Contents::ComplexCharges`], [`Contents::ComplexDipoles`]): from
//! a complex `.npy` array, from real arrays or CSV records holding both
//! parts, or from real values alone (the imaginary parts are then zero).
//!
//! Points are returned interleaved (`x0, y0, z0, x1, ...`) as `f64`; every
//! value is checked to be finite, and an empty file is an error. A
//! [`Reader`] can bound the memory a read may take (an endless stream such
//! as `/dev/zero` is then an error, not an out-of-memory kill) and read
//! only a range of rows (each MPI rank its share). Inputs may be pipes
//! (`<(...)`, FIFOs) as well as regular files.
//!
//! Writing ([`write()`], [`output`]) is atomic: through a temporary file in
//! the output's directory, renamed into place when complete.
#![warn(missing_docs)]

pub mod csv;
mod error;
pub mod npy;
pub mod output;
pub mod raw;
pub mod threads;

pub use error::{FileError, Result, human_bytes};

use std::path::Path;

/// What a file holds, which fixes its shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Contents {
    /// Points: three coordinates per record.
    Points,
    /// Charges: one value per record for a scalar kernel, `c` for a kernel
    /// with `c` components (`re, im` for Helmholtz, `fx, fy, fz` for
    /// Stokes).
    Charges(usize),
    /// Dipole vectors: three values per record for a scalar kernel, `3 c`
    /// for one with `c` real components.
    Dipoles(usize),
    /// Complex charges, read as `re, im` per record: from a complex `.npy`
    /// array `(N,)` or `(N, 1)`, a real `(N, 2)` array or CSV records of
    /// two values, or real charges alone (`(N,)`, `(N, 1)`, one value per
    /// CSV record), whose imaginary parts are then zero.
    ComplexCharges,
    /// Complex dipole vectors, read as `nx_re, nx_im, ny_re, ny_im, nz_re,
    /// nz_im` per record: from a complex `(N, 3)` `.npy` array, a real
    /// `(N, 6)` array or CSV records of six values, or real vectors alone
    /// (`(N, 3)`, three values per CSV record) with zero imaginary parts.
    ComplexDipoles,
}

impl Contents {
    /// The charges of a kernel with `components` components per value,
    /// complex (`re, im`) when `complex` (see `KernelDescription::complex`
    /// in ferrofmm-kernels).
    pub fn charges(components: usize, complex: bool) -> Contents {
        if complex {
            Contents::ComplexCharges
        } else {
            Contents::Charges(components)
        }
    }

    /// The dipole vectors of a kernel with `components` components per
    /// value, complex when `complex`.
    pub fn dipoles(components: usize, complex: bool) -> Contents {
        if complex {
            Contents::ComplexDipoles
        } else {
            Contents::Dipoles(components)
        }
    }

    /// Values per record (as read: a complex value is two, `re, im`).
    pub fn columns(self) -> usize {
        match self {
            Contents::Points => 3,
            Contents::Dipoles(c) => 3 * c,
            Contents::Charges(c) => c,
            Contents::ComplexCharges => 2,
            Contents::ComplexDipoles => 6,
        }
    }

    /// Whether the records are complex values (`re, im` pairs).
    pub fn is_complex(self) -> bool {
        matches!(self, Contents::ComplexCharges | Contents::ComplexDipoles)
    }

    /// Real values per record in a file that holds only the real parts of
    /// complex records (1 for charges, 3 for dipoles); `None` for real
    /// contents.
    pub fn real_parts(self) -> Option<usize> {
        self.is_complex().then(|| self.columns() / 2)
    }

    /// Plural noun for messages.
    pub fn noun(self) -> &'static str {
        match self {
            Contents::Points => "points",
            Contents::Charges(_) | Contents::ComplexCharges => "charges",
            Contents::Dipoles(_) | Contents::ComplexDipoles => "dipoles",
        }
    }
}

/// What a read returned: the values, interleaved (`Contents::columns` per
/// record; `re, im` pairs for complex contents), and what the file held.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The values of the rows asked for.
    pub values: Vec<f64>,
    /// Rows (records) in the whole file.
    pub rows: u64,
    /// The file held complex numbers (a `complex64` / `complex128` `.npy`
    /// array): the output of a run on it is complex too
    /// ([`write_complex`]).
    pub complex: bool,
}

/// A file format, chosen by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated text.
    Csv,
    /// NumPy `.npy`.
    Npy,
    /// Raw little-endian `float64` values (`.f64`), read only.
    Raw,
}

impl Format {
    /// The format of the input `path` from its extension (`.csv`, `.npy`
    /// or `.f64`, any case).
    pub fn of(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("csv") => Ok(Format::Csv),
            Some("npy") => Ok(Format::Npy),
            Some("f64") => Ok(Format::Raw),
            _ => Err(FileError::UnknownExtension(path.to_path_buf())),
        }
    }

    /// The format of the output `path`: `.csv` or `.npy` (any case); raw
    /// `.f64` files are read, never written.
    pub fn of_output(path: &Path) -> Result<Format> {
        match Format::of(path) {
            Ok(Format::Raw) | Err(FileError::UnknownExtension(_)) => {
                Err(FileError::UnknownOutputType(path.to_path_buf()))
            }
            other => other,
        }
    }
}

/// Output values in the run's float type.
#[derive(Clone, Copy, Debug)]
pub enum Values<'a> {
    /// Double precision.
    F64(&'a [f64]),
    /// Single precision.
    F32(&'a [f32]),
}

impl Values<'_> {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Values::F64(v) => v.len(),
            Values::F32(v) => v.len(),
        }
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Read points (interleaved, `3 n` values) from a `.csv` or `.npy` file.
pub fn read_points(path: &Path) -> Result<Vec<f64>> {
    read(path, Contents::Points)
}

/// Read `contents` from `path`, whatever its format, without a memory
/// limit (see [`Reader`]).
pub fn read(path: &Path, contents: Contents) -> Result<Vec<f64>> {
    Reader::new().read(path, contents)
}

/// Reads `.csv` and `.npy` files: whole, or a range of their rows, within
/// a memory limit.
#[derive(Clone, Copy, Debug, Default)]
pub struct Reader {
    limit: Option<u64>,
}

impl Reader {
    /// A reader without a memory limit.
    pub fn new() -> Reader {
        Reader::default()
    }

    /// Refuse, with [`FileError::TooLarge`], a read whose values (and, for
    /// text, its longest line) would take more than `bytes` (`None`: no
    /// limit). The values a file holds are counted as they arrive, so an
    /// endless stream stops at the limit.
    pub fn memory_limit(mut self, bytes: Option<u64>) -> Reader {
        self.limit = bytes;
        self
    }

    /// The memory limit in bytes (`None`: none).
    pub fn limit(&self) -> Option<u64> {
        self.limit
    }

    /// Read all of `contents` from `path`.
    pub fn read(&self, path: &Path, contents: Contents) -> Result<Vec<f64>> {
        self.read_rows(path, contents, |n| 0..n).map(|(v, _)| v)
    }

    /// Read the rows `pick(n)` of `path`, whose `n` records are `contents`
    /// (`pick` gets the number of records and returns a range within
    /// them); returns those rows' values and `n`. See [`Reader::read_table`].
    pub fn read_rows(
        &self,
        path: &Path,
        contents: Contents,
        pick: impl FnOnce(u64) -> std::ops::Range<u64>,
    ) -> Result<(Vec<f64>, u64)> {
        self.read_table(path, contents, pick)
            .map(|t| (t.values, t.rows))
    }

    /// Read the rows `pick(n)` of `path`, whose `n` records are `contents`
    /// (`pick` gets the number of records and returns a range within
    /// them): those rows' values, `n`, and whether the file held complex
    /// numbers. A `.npy` (C or Fortran order) or a raw `.f64` regular file
    /// is read only where the rows lie (and `n` may be 0 records for a rank
    /// with none); a `.npy` stream is read through, keeping only the rows
    /// asked for; a `.csv` file or a raw stream is read whole, keeping the
    /// rows asked for. Binary data are read straight into the array
    /// returned, a bounded chunk at a time: the memory taken is that of the
    /// rows asked for and a small buffer, never a second full-size copy.
    /// Every value read is checked to be finite, and a file without records
    /// is [`FileError::Empty`].
    pub fn read_table(
        &self,
        path: &Path,
        contents: Contents,
        pick: impl FnOnce(u64) -> std::ops::Range<u64>,
    ) -> Result<Table> {
        let format = Format::of(path)?;
        if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
            return Err(FileError::IsDirectory(path.to_path_buf()));
        }
        let table = match format {
            Format::Csv => {
                let all = csv::read(path, contents, self.limit)?;
                let n = (all.len() / contents.columns()) as u64;
                Table {
                    values: slice_rows(all, contents.columns(), pick(n), n),
                    rows: n,
                    complex: false,
                }
            }
            Format::Npy => npy::read_table(path, contents, self.limit, pick)?,
            Format::Raw => raw::read_table(path, contents, self.limit, pick)?,
        };
        if table.rows == 0 {
            return Err(FileError::Empty {
                path: path.to_path_buf(),
                what: contents.noun(),
            });
        }
        Ok(table)
    }
}

/// Rows `rows` (clamped to the `n` there are) of `all`, `columns` values each.
fn slice_rows(mut all: Vec<f64>, columns: usize, rows: std::ops::Range<u64>, n: u64) -> Vec<f64> {
    let end = rows.end.min(n) as usize * columns;
    let start = (rows.start as usize * columns).min(end);
    if start == 0 && end == all.len() {
        return all;
    }
    all.truncate(end);
    all.drain(..start);
    all
}

/// Write `values` (`columns` per record, named by `names`) to `path` in the
/// format its extension asks for. A `.npy` file gets shape `(n,)` for one
/// column and `(n, columns)` otherwise, in the values' float type; a `.csv`
/// file gets a header line of `names` and then one record per line.
///
/// The file is written atomically ([`output::write_atomically`]): on
/// failure nothing is left behind and an existing file is untouched.
///
/// # Errors
/// [`FileError::UnknownOutputType`] for a name that is not `.csv` or
/// `.npy`, [`FileError::Shape`] when `names` is empty or the values do not
/// fill whole records, and the write's own failures.
pub fn write(path: &Path, values: Values<'_>, names: &[&str]) -> Result<()> {
    write_as(path, values, names, false)
}

/// [`write()`] for complex values: `values` hold `re, im` pairs and
/// `names` name each real column (`potential_re, potential_im, ...`). A
/// `.csv` file gets those columns; a `.npy` file gets a complex array
/// (`complex128` for [`Values::F64`], `complex64` for [`Values::F32`]) of
/// shape `(n,)` for one complex column and `(n, names.len() / 2)`
/// otherwise.
///
/// # Errors
/// As [`write()`]; also [`FileError::Shape`] for an odd number of columns.
pub fn write_complex(path: &Path, values: Values<'_>, names: &[&str]) -> Result<()> {
    write_as(path, values, names, true)
}

fn write_as(path: &Path, values: Values<'_>, names: &[&str], complex: bool) -> Result<()> {
    let columns = names.len();
    let format = Format::of_output(path)?;
    let shape_error = |message: String| FileError::Shape {
        path: path.to_path_buf(),
        message,
    };
    if columns == 0 || !values.len().is_multiple_of(columns) {
        return Err(shape_error(format!(
            "{} values do not fill records of {columns} columns",
            values.len()
        )));
    }
    if complex && !columns.is_multiple_of(2) {
        return Err(shape_error(format!(
            "{columns} columns are not re, im pairs"
        )));
    }
    match format {
        Format::Csv => csv::write(path, values, names),
        Format::Npy if complex => npy::write_complex(path, values, columns / 2),
        Format::Npy => npy::write(path, values, columns),
        Format::Raw => Err(FileError::UnknownOutputType(path.to_path_buf())),
    }
}

/// Column names of an output with `values_per_target` quantities
/// (`potential`, then `grad_x, grad_y, grad_z`, then `hess_xx, hess_yy,
/// hess_zz, hess_xy, hess_xz, hess_yz`) for a kernel whose values have the
/// components `component_names` (none for a scalar kernel): each quantity
/// once per component, suffixed (`potential_re, potential_im, grad_x_re,
/// ...` for Helmholtz; `potential_x, ..., grad_x_y, ...` for Stokes, where
/// `grad_x_y` is `d u_y / d x`). The header of every `.csv` output.
pub fn column_names(values_per_target: usize, component_names: &[&str]) -> Vec<String> {
    const ALL: [&str; 10] = [
        "potential",
        "grad_x",
        "grad_y",
        "grad_z",
        "hess_xx",
        "hess_yy",
        "hess_zz",
        "hess_xy",
        "hess_xz",
        "hess_yz",
    ];
    let quantities = &ALL[..values_per_target.min(ALL.len())];
    match component_names {
        [] => quantities.iter().map(|q| q.to_string()).collect(),
        comps => quantities
            .iter()
            .flat_map(|q| comps.iter().map(move |c| format!("{q}_{c}")))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use npyz::WriterBuilder;

    use super::*;

    /// A fresh directory under the system temp dir.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ferrofmm-io-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn points(n: usize) -> Vec<f64> {
        (0..3 * n)
            .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.25 + 1e-13 * i as f64)
            .collect()
    }

    #[test]
    fn csv_and_npy_round_trip_in_both_precisions() {
        let dir = scratch("roundtrip");
        let p = points(50);
        let q: Vec<f64> = p.iter().step_by(3).map(|x| x * 1e-7).collect();
        for ext in ["csv", "npy", "CSV"] {
            let pp = dir.join(format!("p.{ext}"));
            let qp = dir.join(format!("q.{ext}"));
            write(&pp, Values::F64(&p), &["x", "y", "z"]).unwrap();
            write(&qp, Values::F64(&q), &["charge"]).unwrap();
            assert_eq!(read_points(&pp).unwrap(), p, "{ext}: f64 points exact");
            assert_eq!(
                read(&qp, Contents::Charges(1)).unwrap(),
                q,
                "{ext}: f64 charges exact"
            );
            let p32: Vec<f32> = p.iter().map(|&x| x as f32).collect();
            write(&pp, Values::F32(&p32), &["x", "y", "z"]).unwrap();
            let back: Vec<f32> = read_points(&pp)
                .unwrap()
                .iter()
                .map(|&x| x as f32)
                .collect();
            assert_eq!(back, p32, "{ext}: f32 points exact");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn npy_shapes_orders_and_types() {
        let dir = scratch("npy");
        let path = dir.join("a.npy");
        // (N, 4) output, and (N,) output.
        let v: Vec<f64> = (0..40).map(f64::from).collect();
        write(&path, Values::F64(&v), &["a", "b", "c", "d"]).unwrap();
        let npy = npyz::NpyFile::new(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!(npy.shape(), &[10, 4]);
        write(&path, Values::F32(&[1.0, 2.0]), &["a"]).unwrap();
        let npy = npyz::NpyFile::new(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!(npy.shape(), &[2]);
        assert_eq!(npy.into_vec::<f32>().unwrap(), vec![1.0, 2.0]);

        // Fortran order: stored column by column.
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[2, 3])
            .order(npyz::Order::Fortran)
            .writer(std::fs::File::create(&path).unwrap())
            .begin_nd()
            .unwrap();
        w.extend([1.0f64, 4.0, 2.0, 5.0, 3.0, 6.0]).unwrap();
        w.finish().unwrap();
        assert_eq!(
            read_points(&path).unwrap(),
            vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
        );

        // Charges as (N, 1).
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[3, 1])
            .writer(std::fs::File::create(&path).unwrap())
            .begin_nd()
            .unwrap();
        w.extend([1.0f32, 2.0, 3.0]).unwrap();
        w.finish().unwrap();
        assert_eq!(
            read(&path, Contents::Charges(1)).unwrap(),
            vec![1.0, 2.0, 3.0]
        );

        // Integers are refused with the dtype named.
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[3])
            .writer(std::fs::File::create(&path).unwrap())
            .begin_nd()
            .unwrap();
        w.extend([1i64, 2, 3]).unwrap();
        w.finish().unwrap();
        let e = read(&path, Contents::Charges(1)).unwrap_err().to_string();
        assert!(e.contains("unsupported dtype '<i8'"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn format_by_extension() {
        assert_eq!(Format::of(Path::new("a/b.NPY")).unwrap(), Format::Npy);
        assert_eq!(Format::of(Path::new("b.csv")).unwrap(), Format::Csv);
        assert!(matches!(
            Format::of(Path::new("b.txt")),
            Err(FileError::UnknownExtension(_))
        ));
        assert!(matches!(
            Format::of(Path::new("npy")),
            Err(FileError::UnknownExtension(_))
        ));
        assert_eq!(Format::of(Path::new("p.F64")).unwrap(), Format::Raw);
        for out in ["p.f64", "p.txt"] {
            assert!(matches!(
                Format::of_output(Path::new(out)),
                Err(FileError::UnknownOutputType(_))
            ));
        }
    }
}
