//! Inputs that are not regular files, and the thread count from the
//! environment (issue 37): `.npy` and `.csv` through a pipe work; an
//! endless stream (`/dev/zero` named `.csv`) is an error at the memory
//! limit, not an out-of-memory kill; `RAYON_NUM_THREADS` that is not a
//! number is an error, not silently ignored.

use crate::common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::{charges, points, scratch, texts, write_npy};

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// `sh -c script` in the background (a writer into a FIFO; killed by the
/// test when done, so that a failure cannot leave it blocked).
fn shell(script: &str) -> std::process::Child {
    Command::new("sh")
        .arg("-c")
        .arg(script)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("sh runs")
}

/// `ferrofmm args` with extra environment variables.
fn ferrofmm_env(args: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    let mut cmd = common::command();
    cmd.args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("the ferrofmm binary runs")
}

#[cfg(unix)]
#[test]
fn npy_through_a_fifo_and_endless_streams() {
    let dir = scratch("streams");
    let n = 300;
    let (p, q) = (dir.join("p.npy"), dir.join("q.npy"));
    write_npy(&p, &points(n, 1), &[n as u64, 3]);
    write_npy(&q, &charges(n, 2), &[n as u64]);
    let fifo = dir.join("fifo.npy");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let mut feeder = shell(&format!("exec cat '{}' > '{}'", s(&p), s(&fifo)));
    let (out_fifo, out_file) = (dir.join("a.npy"), dir.join("b.npy"));
    let run = |sources: &Path, out: &Path| {
        ferrofmm_env(
            &[
                "eval",
                "--sources",
                &s(sources),
                "--charges",
                &s(&q),
                "--out",
                &s(out),
                "--order",
                "3",
            ],
            &[],
        )
    };
    let o = run(&fifo, &out_fifo);
    let _ = feeder.kill();
    let _ = feeder.wait();
    assert!(o.status.success(), "{:?}", texts(&o));
    let o = run(&p, &out_file);
    assert!(o.status.success(), "{:?}", texts(&o));
    assert_eq!(
        std::fs::read(&out_fifo).unwrap(),
        std::fs::read(&out_file).unwrap()
    );

    // /dev/zero named .csv: stops at once (no line break), and a stream of
    // valid lines stops at the memory limit.
    let zero = dir.join("zero.csv");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let lines = dir.join("lines.csv");
    assert!(
        Command::new("mkfifo")
            .arg(&lines)
            .status()
            .unwrap()
            .success()
    );
    let mut yes = shell(&format!("exec yes 0.5,0.25,0.125 > '{}'", s(&lines)));
    for (source, needle) in [
        (&lines, "the memory available, or FERROFMM_MEMORY_LIMIT"),
        (&zero, "without a line break"),
    ] {
        let t0 = std::time::Instant::now();
        let o = ferrofmm_env(
            &[
                "eval",
                "--sources",
                &s(source),
                "--charges",
                &s(&q),
                "--out",
                &s(&dir.join("never.npy")),
            ],
            &[("FERROFMM_MEMORY_LIMIT", "4M")],
        );
        let (_, stderr) = texts(&o);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.contains(needle),
            "{stderr}"
        );
        assert!(t0.elapsed().as_secs() < 60);
    }
    let _ = yes.kill();
    let _ = yes.wait();
    assert!(!dir.join("never.npy").exists());
}

#[test]
fn rayon_num_threads_must_be_a_number() {
    let o = ferrofmm_env(
        &["demo", "--n", "200", "-p", "3"],
        &[("RAYON_NUM_THREADS", "abc")],
    );
    let (_, stderr) = texts(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("RAYON_NUM_THREADS=\"abc\" is not a thread count"),
        "{stderr}"
    );
    let o = ferrofmm_env(
        &["demo", "--n", "200", "-p", "3", "--check", "0"],
        &[("RAYON_NUM_THREADS", "100000")],
    );
    let (_, stderr) = texts(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("note: RAYON_NUM_THREADS=100000 is more than"),
        "{stderr}"
    );
}
