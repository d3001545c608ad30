//! `ferrofmm calibrate`: the cost model measured on this machine and saved
//! in the cache folder; a later `demo` with that folder chooses with it and
//! says so; no folder to save in is a clear error.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

use common::{scratch, texts};

/// `ferrofmm args` with the cache variables removed (no run writes into
/// the home folder), then `env` set.
fn run(args: &[&str], env: &[(&str, &Path)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ferrofmm"));
    cmd.args(args)
        .env_remove("FERROFMM_CACHE")
        .env_remove("XDG_CACHE_HOME")
        .env_remove("HOME");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("the ferrofmm binary runs")
}

#[test]
fn a_calibration_is_saved_and_the_next_run_chooses_with_it() {
    let dir = scratch("calibrate");
    let folder = dir.path().join("cache");
    let folder_arg = folder.to_str().unwrap();
    let out = run(
        &[
            "calibrate",
            "-n",
            "20000",
            "--cache-dir",
            folder_arg,
            "--json",
        ],
        &[],
    );
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).expect("JSON");
    for group in ["p2p", "far", "m2l_compressed", "m2l_fft", "tree"] {
        let s = v["scales"][group].as_f64().expect(group);
        assert!(s.is_finite() && s > 0.0, "{group}: {s}");
    }
    assert_eq!(v["runs"].as_array().map(Vec::len), Some(6));
    assert!(folder.join("machine-calibration.txt").is_file());

    // The next run with that folder chooses with it; the table says so.
    let demo = |cache: &str| {
        run(
            &[
                "demo",
                "-n",
                "20000",
                "--tolerance",
                "1e-4",
                "--check",
                "0",
                "--cache-dir",
                cache,
            ],
            &[],
        )
    };
    let out = demo(folder_arg);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("calibrated on this machine (ferrofmm calibrate)"),
        "{stdout}"
    );
    let other = dir.path().join("other");
    let out = demo(other.to_str().unwrap());
    let (stdout, _) = texts(&out);
    assert!(stdout.contains("built-in (ferrofmm calibrate"), "{stdout}");

    // The human-readable report names the scales and the file.
    let out = run(&["calibrate", "-n", "5000", "--cache-dir", folder_arg], &[]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("measured / model: p2p"), "{stdout}");
    assert!(stdout.contains("machine-calibration.txt"), "{stdout}");
}

#[test]
fn no_folder_or_too_few_points_is_a_clear_error() {
    let off = Path::new("off");
    let out = run(&["calibrate"], &[("FERROFMM_CACHE", off)]);
    let (_, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("no folder to keep the calibration in"),
        "{stderr}"
    );
    let dir = scratch("calibrate-few");
    let out = run(
        &[
            "calibrate",
            "-n",
            "10",
            "--cache-dir",
            dir.path().to_str().unwrap(),
        ],
        &[],
    );
    let (_, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("at least 1000 points"), "{stderr}");
}
