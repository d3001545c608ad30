//! Issue 18 rows 5 and 8 and "Pipes and signals": only the operators the
//! tree needs, a memory estimate before precomputing, threads above the
//! core count, Ctrl-C during a long precomputation.

use crate::common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{ferrofmm, points, scratch, texts, write_csv};

/// 1,000 points in one level of leaves: no V list, so no M2L operator at
/// all (it took 39 s and 4.4 GB at p = 14 before).
#[test]
fn no_v_list_precomputes_no_m2l_operator() {
    let start = Instant::now();
    let out = ferrofmm(&[
        "demo",
        "-n",
        "1000",
        "-p",
        "14",
        "--leaf-size",
        "150",
        "--scheme",
        "svd",
        "--check",
        "0",
        "--json",
    ]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("\"m2l_bytes\":0"), "{stdout}");
    assert!(
        start.elapsed() < Duration::from_secs(30),
        "took {:?}",
        start.elapsed()
    );
}

/// A precomputation predicted beyond the limit is refused before any work,
/// with the estimate; `--force` runs it.
#[test]
fn memory_estimate_refuses_unless_forced() {
    let args = [
        "demo",
        "-n",
        "3000",
        "-p",
        "5",
        "--leaf-size",
        "20",
        "--check",
        "0",
    ];
    let out = common::command()
        .args(args)
        .env("FERROFMM_MEMORY_LIMIT", "1M")
        .output()
        .unwrap();
    let (_, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("predicted to need"), "{stderr}");
    assert!(stderr.contains("1.0 MiB"), "{stderr}");
    assert!(stderr.contains("--force"), "{stderr}");
    let forced = common::command()
        .args(args)
        .arg("--force")
        .env("FERROFMM_MEMORY_LIMIT", "1M")
        .output()
        .unwrap();
    assert!(forced.status.success(), "{}", texts(&forced).1);
    let bad = common::command()
        .args(args)
        .env("FERROFMM_MEMORY_LIMIT", "lots")
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(texts(&bad).1.contains("FERROFMM_MEMORY_LIMIT"));
}

/// A run whose points alone cannot fit is refused before they are made:
/// a billion points against a 1 GiB limit fail at once with the estimate
/// (at least 32 bytes a point kept, 40 more while evaluating), having
/// allocated nothing of the 24 GB they would take.
#[test]
fn points_beyond_the_limit_are_refused_before_they_are_made() {
    let t = std::time::Instant::now();
    let out = common::command()
        .args(["demo", "-n", "1000000000", "--check", "0"])
        .env("FERROFMM_MEMORY_LIMIT", "1G")
        .output()
        .unwrap();
    let (_, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("a demo of 1000000000 points is predicted to need at least"),
        "{stderr}"
    );
    assert!(stderr.contains("1.0 GiB"), "{stderr}");
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
}

fn timed(args: &[&str], env: Option<(&str, &str)>) -> f64 {
    let mut cmd = common::command();
    cmd.args(args).env_remove("RAYON_NUM_THREADS");
    if let Some((k, v)) = env {
        cmd.env(k, v);
    }
    let start = Instant::now();
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}", texts(&out).1);
    start.elapsed().as_secs_f64()
}

/// More threads than cores (`--threads 64`, or `RAYON_NUM_THREADS=64`)
/// cost no more than a small margin (it was 24 s instead of 0.36 s).
#[test]
fn threads_above_the_cores_do_not_slow_down() {
    let base = [
        "demo",
        "-n",
        "2000",
        "-p",
        "6",
        "--leaf-size",
        "30",
        "--check",
        "0",
    ];
    let with = |t: &'static str| {
        let mut a = base.to_vec();
        a.extend(["--threads", t]);
        a
    };
    let t2 = timed(&with("2"), None).min(timed(&with("2"), None));
    let t64 = timed(&with("64"), None);
    let env64 = timed(&base, Some(("RAYON_NUM_THREADS", "64")));
    // Generous: timing noise on a busy CI machine, not the 60x of before.
    let bound = 1.5 * t2 + 1.0;
    assert!(
        t64 <= bound,
        "--threads 64: {t64:.2} s, --threads 2: {t2:.2} s"
    );
    assert!(
        env64 <= bound,
        "RAYON_NUM_THREADS=64: {env64:.2} s, --threads 2: {t2:.2} s"
    );
}

/// Ctrl-C in the middle of a long precomputation ends the command within
/// a second, with status 130 and no output or temporary file left.
#[test]
fn sigint_stops_a_long_precompute_with_130() {
    let dir = scratch("sigint");
    let (s, q, out) = (dir.join("s.csv"), dir.join("q.csv"), dir.join("out.npy"));
    write_csv(&s, &points(4000, 3), 3, None);
    write_csv(&q, &vec![0.25; 4000], 1, None);
    let mut child = common::command()
        .args(["eval", "--sources"])
        .arg(&s)
        .arg("--charges")
        .arg(&q)
        .arg("--out")
        .arg(&out)
        .args([
            "-p",
            "12",
            "--leaf-size",
            "40",
            "--scheme",
            "svd",
            "--force",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Reading the files, the tree and the small operators take well under
    // this; the M2L precomputation then runs for tens of seconds.
    std::thread::sleep(Duration::from_millis(2500));
    assert!(child.try_wait().unwrap().is_none(), "finished too early");
    let sent = Instant::now();
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if sent.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            panic!("still running 10 s after SIGINT");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let waited = sent.elapsed();
    assert_eq!(status.code(), Some(130));
    assert!(waited < Duration::from_millis(1500), "exit took {waited:?}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("out.npy"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn help_lists_exit_130_and_explains_threads() {
    let out = ferrofmm(&["--help"]);
    let (stdout, _) = texts(&out);
    assert!(stdout.contains("130 when"), "{stdout}");
    assert!(stdout.contains("more than the number of cores") || stdout.contains("one per core"));
    assert!(stdout.contains("FERROFMM_MEMORY_LIMIT"));
}
