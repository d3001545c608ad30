//! `eval --out` never loses a file: an output that is an input (also
//! through links) is refused, an unusable output is found before any work,
//! and a failed write leaves neither a partial output nor a temporary file.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{charges, ferrofmm, points, scratch, texts, write_csv, write_npy};

const N: usize = 1000;

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// Sources `p.npy` and charges `q.csv` with `n` points in `dir`.
fn inputs(dir: &Path, n: usize) -> (PathBuf, PathBuf) {
    let p = dir.join("p.npy");
    let q = dir.join("q.csv");
    write_npy(&p, &points(n, 1), &[n as u64, 3]);
    let charges = charges(n, 2);
    write_csv(&q, &charges, 1, None);
    (p, q)
}

fn eval_args(sources: &Path, charges: &Path, out: &Path) -> Vec<String> {
    [
        "eval",
        "--sources",
        &s(sources),
        "--charges",
        &s(charges),
        "--out",
        &s(out),
        "--order",
        "3",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect()
}

/// Expect exit status 1 with one `error: ...` line holding every needle.
fn expect_one_line_failure(out: &std::process::Output, needles: &[&str]) {
    let (stdout, stderr) = texts(out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "stdout {stdout} stderr {stderr}"
    );
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(!stderr.contains("internal error"), "{stderr}");
    for n in needles {
        assert!(lines[0].contains(n), "'{n}' missing from: {}", lines[0]);
    }
}

fn run(args: &[String]) -> std::process::Output {
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    ferrofmm(&refs)
}

/// Names in `dir` (sorted), to see that no temporary file is left.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn out_naming_an_input_is_refused_and_the_input_kept() {
    let dir = scratch("out-is-input");
    let (p, q) = inputs(&dir, N);
    let p_bytes = std::fs::read(&p).unwrap();
    let q_bytes = std::fs::read(&q).unwrap();

    // The sources themselves.
    let out = run(&eval_args(&p, &q, &p));
    expect_one_line_failure(&out, &["same file as --sources", "p.npy"]);
    // The charges, through another spelling of the path.
    let q_again = dir.join(".").join("q.csv");
    let out = run(&eval_args(&p, &q, &q_again));
    expect_one_line_failure(&out, &["same file as --charges"]);
    // The targets.
    let t = dir.join("t.npy");
    write_npy(&t, &points(10, 3), &[10, 3]);
    let t_bytes = std::fs::read(&t).unwrap();
    let mut args = eval_args(&p, &q, &t);
    args.extend(["--targets".to_string(), s(&t)]);
    expect_one_line_failure(&run(&args), &["same file as --targets"]);

    #[cfg(unix)]
    {
        // A symbolic link to the sources, and a hard link to them.
        let link = dir.join("link.npy");
        std::os::unix::fs::symlink(&p, &link).unwrap();
        expect_one_line_failure(&run(&eval_args(&p, &q, &link)), &["same file as --sources"]);
        let hard = dir.join("hard.npy");
        std::fs::hard_link(&p, &hard).unwrap();
        expect_one_line_failure(&run(&eval_args(&p, &q, &hard)), &["same file as --sources"]);
    }

    assert_eq!(std::fs::read(&p).unwrap(), p_bytes, "sources changed");
    assert_eq!(std::fs::read(&q).unwrap(), q_bytes, "charges changed");
    assert_eq!(std::fs::read(&t).unwrap(), t_bytes, "targets changed");
    assert!(
        listing(&dir).iter().all(|n| !n.contains(".tmp-")),
        "{:?}",
        listing(&dir)
    );
}

#[test]
fn unusable_outputs_are_refused_before_any_work() {
    let dir = scratch("unusable-out");
    let (_, q) = inputs(&dir, 10);
    // The sources do not exist: an error about them would mean the output
    // was checked only after reading the inputs.
    let missing = dir.join("missing.npy");

    let as_dir = dir.join("result.npy");
    std::fs::create_dir(&as_dir).unwrap();
    expect_one_line_failure(
        &run(&eval_args(&missing, &q, &as_dir)),
        &["result.npy", "is a directory"],
    );

    let no_dir = dir.join("nope").join("out.npy");
    expect_one_line_failure(
        &run(&eval_args(&missing, &q, &no_dir)),
        &["out.npy", "nope", "does not exist"],
    );

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.join("ro");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        // Root ignores permissions: nothing to test then.
        let probe = ro.join("probe");
        if std::fs::write(&probe, "x").is_ok() {
            eprintln!("skipping the read-only directory case: permissions are not enforced");
            let _ = std::fs::remove_file(&probe);
        } else {
            expect_one_line_failure(
                &run(&eval_args(&missing, &q, &ro.join("out.npy"))),
                &["cannot write", "ro/out.npy", "Permission denied"],
            );
            assert!(listing(&ro).is_empty());
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();

        // A read-only output file is not replaced.
        let ro_file = dir.join("ro_file.npy");
        std::fs::write(&ro_file, "keep").unwrap();
        std::fs::set_permissions(&ro_file, std::fs::Permissions::from_mode(0o444)).unwrap();
        expect_one_line_failure(
            &run(&eval_args(&missing, &q, &ro_file)),
            &["ro_file.npy", "read-only"],
        );
        assert_eq!(std::fs::read_to_string(&ro_file).unwrap(), "keep");
    }
}

/// `ulimit -f 4`, with `SIGXFSZ` ignored by the shell and with its default
/// disposition (the command catches it): the write fails with EFBIG (the
/// output needs 8128 bytes), the command exits 1 naming the reason, and
/// neither a partial output nor a temporary file is left; an existing
/// output keeps its contents.
#[cfg(unix)]
#[test]
fn a_failed_write_leaves_no_partial_file() {
    let dir = scratch("failed-write");
    let (p, q) = inputs(&dir, N);
    let bin = env!("CARGO_BIN_EXE_ferrofmm");
    let limited_with = |script: &str, out: &Path| {
        Command::new("sh")
            .env("FERROFMM_CACHE", common::test_cache())
            .arg("-c")
            .arg(script)
            .arg(bin)
            .args(eval_args(&p, &q, out))
            .output()
            .expect("sh runs")
    };
    let limited = |out: &Path| limited_with("trap '' XFSZ; ulimit -f 4; exec \"$0\" \"$@\"", out);
    let before = listing(&dir);

    // The default disposition of SIGXFSZ would kill the process mid-write.
    let fresh = dir.join("default-signal.npy");
    let out = limited_with("ulimit -f 4; exec \"$0\" \"$@\"", &fresh);
    assert!(!fresh.exists(), "a partial output was left behind");
    expect_one_line_failure(&out, &["cannot write", "default-signal.npy", "too large"]);
    assert_eq!(listing(&dir), before, "a temporary file was left behind");

    let fresh = dir.join("fresh.npy");
    let out = limited(&fresh);
    assert!(
        !fresh.exists(),
        "a partial output was left behind: {} bytes",
        std::fs::metadata(&fresh).map_or(0, |m| m.len())
    );
    expect_one_line_failure(&out, &["cannot write", "fresh.npy", "too large"]);
    assert_eq!(listing(&dir), before, "a temporary file was left behind");

    let old = dir.join("old.csv");
    std::fs::write(&old, "previous contents\n").unwrap();
    let out = limited(&old);
    expect_one_line_failure(&out, &["cannot write", "old.csv"]);
    assert_eq!(
        std::fs::read_to_string(&old).unwrap(),
        "previous contents\n"
    );

    // Without the limit the same command succeeds and replaces the file.
    let out = run(&eval_args(&p, &q, &old));
    assert!(out.status.success(), "{}", texts(&out).1);
    let text = std::fs::read_to_string(&old).unwrap();
    assert_eq!(text.lines().count(), N + 1);
    let mut expected = before.clone();
    expected.push("old.csv".into());
    expected.sort();
    assert_eq!(listing(&dir), expected);
}

/// Writing through a symbolic link replaces the linked file, not the link.
#[cfg(unix)]
#[test]
fn output_through_a_symlink_keeps_the_link() {
    let dir = scratch("out-symlink");
    let (p, q) = inputs(&dir, 100);
    let real = dir.join("real.csv");
    std::fs::write(&real, "old\n").unwrap();
    let link = dir.join("link.csv");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let out = run(&eval_args(&p, &q, &link));
    assert!(out.status.success(), "{}", texts(&out).1);
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read_to_string(&real).unwrap().lines().count(), 101);
}
