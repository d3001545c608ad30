//! Helpers shared by the command-line tests: run the binary, scratch
//! directories, simple input files.

#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

pub use ferrofmm_testing::TempDir;

/// The operator cache of the tests' runs: a folder under Cargo's
/// temporary directory for integration tests (`target/tmp`), never the
/// user's home. Shared by every test (the cache is built for that).
pub fn test_cache() -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-operator-cache")
}

/// The `ferrofmm` binary as a command, its default cache pointed at
/// [`test_cache`] (`FERROFMM_CACHE`).
pub fn command() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ferrofmm"));
    cmd.env("FERROFMM_CACHE", test_cache());
    cmd
}

/// Run `ferrofmm` with `args`; stderr is not a terminal, so no progress bars.
pub fn ferrofmm(args: &[&str]) -> Output {
    command()
        .args(args)
        .output()
        .expect("the ferrofmm binary runs")
}

/// stdout and stderr as text.
pub fn texts(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A fresh, empty directory for one test, removed when dropped.
pub fn scratch(name: &str) -> TempDir {
    TempDir::new(&format!("cli-{name}"))
}

/// Deterministic pseudo-random points in the unit cube (interleaved).
pub fn points(n: usize, seed: u64) -> Vec<f64> {
    ferrofmm_testing::points::uniform_cube(n, 0.0, 1.0, seed)
}

/// `n` charges uniform in `[0, 1)`.
pub fn charges(n: usize, seed: u64) -> Vec<f64> {
    ferrofmm_testing::charges::uniform_in(n, 0.0, 1.0, seed)
}

/// Write `values` as CSV, `columns` per line, with an optional header.
pub fn write_csv(path: &Path, values: &[f64], columns: usize, header: Option<&str>) {
    let mut text = String::new();
    if let Some(h) = header {
        text.push_str(h);
        text.push('\n');
    }
    for row in values.chunks(columns) {
        let fields: Vec<String> = row.iter().map(|v| format!("{v:e}")).collect();
        text.push_str(&fields.join(","));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// Write `values` as a `.npy` array of the given shape.
pub fn write_npy<T: npyz::AutoSerialize + Copy>(path: &Path, values: &[T], shape: &[u64]) {
    use npyz::WriterBuilder;
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .begin_nd()
        .unwrap();
    w.extend(values.iter().copied()).unwrap();
    w.finish().unwrap();
}

/// Read a `.npy` file: shape and values as f64.
pub fn read_npy(path: &Path) -> (Vec<u64>, Vec<f64>) {
    let npy = npyz::NpyFile::new(std::fs::File::open(path).unwrap()).unwrap();
    let shape = npy.shape().to_vec();
    let values = match npy.dtype().descr().as_str() {
        "'<f8'" => npy.into_vec::<f64>().unwrap(),
        "'<f4'" => npy
            .into_vec::<f32>()
            .unwrap()
            .into_iter()
            .map(f64::from)
            .collect(),
        other => panic!("unexpected dtype {other}"),
    };
    (shape, values)
}
