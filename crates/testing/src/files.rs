//! Input files in every form the front ends read, and the malformed files
//! they must all refuse with the same message.
//!
//! [`write_forms`] writes one table of values as CSV (with and without a
//! header, commas, spaces, tabs, CRLF line ends), as `.npy` (`float64`,
//! `float32`, `complex128`, `complex64`, little- and big-endian, C and
//! Fortran order) and as raw `.f64`; every form holds the same numbers
//! when the values are `f32`-exact ([`f32_exact`]). [`malformed`] writes
//! the cases of `data/malformed.json`, the one table of bad files and the
//! message each front end (`ferrofmm`, `ferrofmm-mpi`, the Python module)
//! must print for them.

use std::path::{Path, PathBuf};

/// `values` rounded to `f32` (and back), so that every float type holds
/// them exactly.
pub fn f32_exact(values: &[f64]) -> Vec<f64> {
    values.iter().map(|&v| f64::from(v as f32)).collect()
}

/// What a table of values is, which fixes the forms it is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Table {
    /// Real records of this many values (points: 3, charges: 1).
    Real(usize),
    /// Complex values, one per record, given as `re, im` pairs.
    Complex,
}

/// The `.npy` file of `data` (raw element bytes in the file's order) with
/// the header `descr` (`'<f8'`, `'>c16'`, ...), `fortran_order` and
/// `shape`, as NumPy writes it (version 1.0, the data 64-byte aligned).
pub fn npy_bytes(descr: &str, fortran: bool, shape: &[u64], data: &[u8]) -> Vec<u8> {
    let shape = match shape {
        [n] => format!("({n},)"),
        dims => format!(
            "({})",
            dims.iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let order = if fortran { "True" } else { "False" };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': {shape}, }}");
    let total = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((dict.len() as u16).to_le_bytes());
    out.extend(dict.as_bytes());
    out.extend(data);
    out
}

/// The bytes of `elements` (`rows` x `columns` elements of `parts` values
/// each, row-major) in the order and type of a `.npy` array: `f32` or
/// `f64`, `big`-endian or not, column-major when `fortran`.
fn element_bytes(
    values: &[f64],
    rows: usize,
    columns: usize,
    parts: usize,
    single: bool,
    big: bool,
    fortran: bool,
) -> Vec<u8> {
    let mut out = Vec::with_capacity(values.len() * 8);
    let mut push = |v: f64| match (single, big) {
        (true, true) => out.extend((v as f32).to_be_bytes()),
        (true, false) => out.extend((v as f32).to_le_bytes()),
        (false, true) => out.extend(v.to_be_bytes()),
        (false, false) => out.extend(v.to_le_bytes()),
    };
    for k in 0..rows * columns {
        let (i, j) = if fortran {
            (k % rows, k / rows)
        } else {
            (k / columns, k % columns)
        };
        for p in 0..parts {
            push(values[(i * columns + j) * parts + p]);
        }
    }
    out
}

/// CSV text of `values`, `columns` per record, with `header`, the
/// separator `sep` and the line end `end`.
fn csv_text(values: &[f64], columns: usize, header: Option<&str>, sep: &str, end: &str) -> String {
    let mut text = header.map(|h| format!("{h}{end}")).unwrap_or_default();
    for row in values.chunks(columns) {
        let fields: Vec<String> = row.iter().map(|v| format!("{v:e}")).collect();
        text.push_str(&fields.join(sep));
        text.push_str(end);
    }
    text
}

/// Write `values` (a [`Table`]) in every form the readers take, as
/// `dir/STEM-LABEL.EXT`; returns `(label, path)` per form. The forms of a
/// complex table also include its real parts alone (labelled `real-...`:
/// they read as zero imaginary parts, so they hold other numbers).
pub fn write_forms(dir: &Path, stem: &str, values: &[f64], table: Table) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let mut put = |label: &str, ext: &str, bytes: Vec<u8>| {
        let path = dir.join(format!("{stem}-{label}.{ext}"));
        std::fs::write(&path, bytes).expect("a test file can be written");
        out.push((label.to_string(), path));
    };
    let (columns, parts) = match table {
        Table::Real(c) => (c, 1),
        Table::Complex => (1, 2),
    };
    let stored = columns * parts;
    let rows = values.len() / stored;
    let header = match table {
        Table::Real(3) => "x,y,z".to_string(),
        Table::Real(1) => "charge".to_string(),
        Table::Real(c) => (0..c)
            .map(|k| format!("c{k}"))
            .collect::<Vec<_>>()
            .join(","),
        Table::Complex => "re,im".to_string(),
    };
    // CSV: the values as records of `stored` fields.
    put(
        "csv-header",
        "csv",
        csv_text(values, stored, Some(&header), ",", "\n").into_bytes(),
    );
    put(
        "csv-spaces",
        "csv",
        csv_text(values, stored, None, " ", "\n").into_bytes(),
    );
    put(
        "csv-tabs",
        "csv",
        csv_text(values, stored, None, "\t", "\n").into_bytes(),
    );
    put(
        "csv-crlf",
        "csv",
        csv_text(values, stored, Some(&header), " , ", "\r\n").into_bytes(),
    );
    // .npy in each type, byte order and memory order.
    let kinds: &[(&str, bool)] = match table {
        Table::Real(_) => &[("f8", false), ("f4", true)],
        Table::Complex => &[("c16", false), ("c8", true)],
    };
    for &(code, single) in kinds {
        for big in [false, true] {
            for fortran in [false, true] {
                let descr = format!("{}{code}", if big { '>' } else { '<' });
                // A single column as (N,) in C order, (N, 1) in Fortran
                // order: both are read.
                let shape: Vec<u64> = if columns == 1 && !fortran {
                    vec![rows as u64]
                } else {
                    vec![rows as u64, columns as u64]
                };
                let data = element_bytes(values, rows, columns, parts, single, big, fortran);
                let label = format!(
                    "npy-{}{code}-{}",
                    if big { "be" } else { "le" },
                    if fortran { "f" } else { "c" }
                );
                put(&label, "npy", npy_bytes(&descr, fortran, &shape, &data));
            }
        }
    }
    if table == Table::Complex {
        // A real (N, 2) array of re, im; and the real parts alone.
        let data = element_bytes(values, rows, 2, 1, false, false, true);
        put(
            "npy-re-im-f",
            "npy",
            npy_bytes("<f8", true, &[rows as u64, 2], &data),
        );
        let re: Vec<f64> = values.iter().step_by(2).copied().collect();
        let data = element_bytes(&re, rows, 1, 1, true, true, false);
        put(
            "real-npy-bef4",
            "npy",
            npy_bytes(">f4", false, &[rows as u64], &data),
        );
        put(
            "real-csv",
            "csv",
            csv_text(&re, 1, Some("charge"), ",", "\n").into_bytes(),
        );
    }
    // Raw little-endian f64, record after record.
    put(
        "raw",
        "f64",
        values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    );
    out
}

/// One malformed file of `data/malformed.json` and the message it gets.
#[derive(Clone, Debug)]
pub struct Malformed {
    /// The file written.
    pub path: PathBuf,
    /// `"points"` or `"charges"`: which input it is given as.
    pub what: String,
    /// The kernel (`laplace`, `helmholtz:2`): its charges decide their shape.
    pub kernel: String,
    /// The text every front end's message must contain.
    pub message: String,
}

/// The shared table of malformed files (JSON, read by the Python tests too).
pub const MALFORMED_JSON: &str = include_str!("../data/malformed.json");

/// The `eval` arguments both commands run on every file form (order 6,
/// leaf 40, FFT M2L, operators cached in `cache`), so that `ferrofmm` and
/// `ferrofmm-mpi` are checked on the same run.
pub fn eval_args(
    sources: &Path,
    charges: &Path,
    kernel: &str,
    cache: &Path,
    out: &Path,
) -> Vec<String> {
    let path = |p: &Path| p.to_string_lossy().into_owned();
    [
        "eval",
        "--sources",
        &path(sources),
        "--charges",
        &path(charges),
        "--kernel",
        kernel,
        "--order",
        "6",
        "--leaf-size",
        "40",
        "--scheme",
        "fft",
        "--cache-dir",
        &path(cache),
        "--out",
        &path(out),
    ]
    .map(String::from)
    .to_vec()
}

/// Write the files of [`MALFORMED_JSON`] into `dir`.
pub fn malformed(dir: &Path) -> Vec<Malformed> {
    let cases: Vec<serde_json::Value> =
        serde_json::from_str(MALFORMED_JSON).expect("data/malformed.json is a JSON list");
    cases
        .iter()
        .map(|case| {
            let text = |key: &str| case[key].as_str().map(str::to_string);
            let name = text("name").expect("every case has a name");
            let bytes = if let Some(t) = text("text") {
                t.into_bytes()
            } else {
                let npy = &case["npy"];
                let shape: Vec<u64> = npy["shape"]
                    .as_array()
                    .expect("npy.shape")
                    .iter()
                    .filter_map(serde_json::Value::as_u64)
                    .collect();
                let data = vec![0u8; npy["data_bytes"].as_u64().expect("npy.data_bytes") as usize];
                npy_bytes(
                    npy["descr"].as_str().expect("npy.descr"),
                    npy["fortran"].as_bool().unwrap_or(false),
                    &shape,
                    &data,
                )
            };
            let path = dir.join(&name);
            std::fs::write(&path, bytes).expect("a test file can be written");
            Malformed {
                path,
                what: text("what").expect("every case says what it is"),
                kernel: text("kernel").unwrap_or_else(|| "laplace".into()),
                message: text("message").expect("every case has its message"),
            }
        })
        .collect()
}

/// Potentials at the points themselves (each excluding itself) by direct
/// summation, the reference of the file tests: Laplace `1 / (4 pi r)` for
/// `k = None` (`q` one real charge per point), Helmholtz `exp(i k r) / (4
/// pi r)` for `Some(k)` (`q` and the result `re, im` pairs).
pub fn direct(points: &[f64], q: &[f64], k: Option<f64>) -> Vec<f64> {
    let n = points.len() / 3;
    let mut out = Vec::with_capacity(2 * n);
    for j in 0..n {
        let (mut re, mut im) = (0.0, 0.0);
        for i in (0..n).filter(|&i| i != j) {
            let d: f64 = (0..3)
                .map(|c| (points[3 * i + c] - points[3 * j + c]).powi(2))
                .sum::<f64>()
                .sqrt();
            let g = 1.0 / (4.0 * std::f64::consts::PI * d);
            match k {
                None => re += q[i] * g,
                Some(k) => {
                    let (s, c) = (k * d).sin_cos();
                    let (qr, qi) = (q[2 * i], q[2 * i + 1]);
                    re += g * (qr * c - qi * s);
                    im += g * (qr * s + qi * c);
                }
            }
        }
        match k {
            None => out.push(re),
            Some(_) => out.extend([re, im]),
        }
    }
    out
}
