//! A closed stdout (`ferrofmm ... | true`) is a quiet exit: status 0, no
//! "internal error", and an `eval` output file is still written.

use crate::common;

use std::path::Path;
use std::process::Stdio;

use common::{charges, points, scratch, write_npy};

/// Run `ferrofmm args` with stdout a pipe whose read end is closed at once.
fn with_closed_stdout(args: &[&str]) -> (Option<i32>, String) {
    let mut child = common::command()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the ferrofmm binary runs");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("waits");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

#[test]
fn demo_into_a_closed_pipe_is_quiet() {
    for extra in [&[][..], &["--json"][..]] {
        let mut args = vec!["demo", "-n", "500", "-p", "3", "--check", "0"];
        args.extend_from_slice(extra);
        let (code, stderr) = with_closed_stdout(&args);
        assert_eq!(code, Some(0), "{args:?}: {stderr}");
        assert!(stderr.trim().is_empty(), "{args:?}: {stderr}");
    }
}

#[test]
fn eval_into_a_closed_pipe_is_quiet_and_writes_its_file() {
    let dir = scratch("pipes-eval");
    let n = 500;
    let p = dir.join("p.npy");
    let q = dir.join("q.npy");
    write_npy(&p, &points(n, 1), &[n as u64, 3]);
    let charges = charges(n, 2);
    write_npy(&q, &charges, &[n as u64]);
    for (k, extra) in [&[][..], &["--json"][..]].into_iter().enumerate() {
        let out = dir.join(format!("out{k}.npy"));
        let (ps, qs, os) = (s(&p), s(&q), s(&out));
        let mut args = vec![
            "eval",
            "--sources",
            &ps,
            "--charges",
            &qs,
            "--out",
            &os,
            "-p",
            "3",
        ];
        args.extend_from_slice(extra);
        let (code, stderr) = with_closed_stdout(&args);
        assert_eq!(code, Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("internal error"), "{stderr}");
        assert!(stderr.trim().is_empty(), "{args:?}: {stderr}");
        assert!(out.exists(), "the output file was not written");
    }
}

#[test]
fn sweep_into_a_closed_pipe_is_quiet() {
    let dir = scratch("pipes-sweep");
    let out_dir = dir.join("out");
    let (code, stderr) = with_closed_stdout(&[
        "sweep",
        "--n",
        "500",
        "--orders",
        "3",
        "--schemes",
        "svd",
        "--precision",
        "f64",
        "--leaf-sizes",
        "64",
        "--repeats",
        "1",
        "--out-dir",
        out_dir.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("internal error"), "{stderr}");
    assert!(out_dir.join("results.csv").exists());
}
