//! What the tests share: launching `mpirun` (one job at a time, killed
//! after a time limit), the operator cache they use, and reading and
//! writing the commands' files.

use std::process::Command;
use std::sync::Mutex;

/// One MPI job at a time (the tests of this file run in parallel threads).
static MPI_JOB: Mutex<()> = Mutex::new(());

pub fn mpirun(ranks: usize, args: &[&str]) -> (bool, String) {
    mpmd(&[(ranks, args)], &[])
}

/// One job of several programs (`mpirun -n R1 exe ARGS1 : -n R2 exe
/// ARGS2`), each rank with the arguments of its group, and extra
/// environment variables for every rank.
pub fn mpmd(groups: &[(usize, &[&str])], env: &[(&str, &str)]) -> (bool, String) {
    let _one = MPI_JOB.lock().unwrap_or_else(|e| e.into_inner());
    let exe = env!("CARGO_BIN_EXE_ferrofmm-mpi");
    let mpirun = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let mut cmd = Command::new("timeout");
    cmd.arg("300").arg(&mpirun).arg("--oversubscribe");
    // Open MPI refuses to run as root without these (CI containers).
    cmd.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1")
        // A rank that exits with an error makes mpirun end the job: by
        // default it waits a second between SIGTERM and SIGKILL for each
        // (2.4 s a run instead of 0.4 s here, most of the time of the
        // tests that check errors); the exit status is kept either way.
        .env("OMPI_MCA_odls_base_sigkill_timeout", "0")
        // The operator cache is on by default: never the home folder.
        .env("FERROFMM_CACHE", test_cache());
    for (k, v) in env {
        cmd.env(k, v);
    }
    for (g, (ranks, args)) in groups.iter().enumerate() {
        if g > 0 {
            cmd.arg(":");
        }
        cmd.arg("-n").arg(ranks.to_string()).arg(exe).args(*args);
    }
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot run `timeout {mpirun}` (install openmpi-bin): {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// The default operator cache of these tests, under Cargo's temporary
/// folder for integration tests.
pub fn test_cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("mpi-operator-cache")
}

/// `values` as a float64 `.npy` array of `columns` columns, through the
/// commands' own writer.
pub fn write_npy(path: &str, values: &[f64], columns: usize) {
    let names = vec!["v"; columns];
    ferrofmm_io::write(
        std::path::Path::new(path),
        ferrofmm_io::Values::F64(values),
        &names,
    )
    .unwrap();
}

/// The `n` records of `columns` values of an output file (.npy or .csv).
pub fn read_columns(path: &str, n: usize, columns: usize) -> Vec<f64> {
    let v = ferrofmm_io::read(
        std::path::Path::new(path),
        ferrofmm_io::Contents::Charges(columns),
    )
    .unwrap();
    assert_eq!(v.len(), n * columns, "{path}");
    v
}

/// The value of `"key":` in `text` (the first occurrence), as a number.
pub fn json_number(text: &str, key: &str) -> Option<f64> {
    text.split(&format!("\"{key}\":"))
        .nth(1)
        .and_then(|t| t.split([',', '}']).next())
        .and_then(|t| t.parse::<f64>().ok())
}
/// Files in `dir` (names), sorted.
pub fn listing(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
