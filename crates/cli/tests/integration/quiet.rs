//! `--quiet` and progress output (issue 36): progress (the evaluation's a
//! bar with the time left) is drawn on stderr only when it is a terminal;
//! `--quiet` silences progress and the report, never errors or warnings,
//! and keeps the JSON asked for with `--json`.

use crate::common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::{charges, ferrofmm, points, scratch, texts, write_npy};

/// A tiny demo's arguments (p = 3, no check), then `extra`.
fn demo_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["demo", "-n", "2000", "-p", "3", "--check", "0"];
    args.extend_from_slice(extra);
    args
}

#[test]
fn quiet_demo_prints_nothing_and_keeps_the_json() {
    let out = ferrofmm(&demo_args(&["--quiet", "--threads", "1"]));
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stdout, "");
    assert_eq!(stderr, "");

    let out = ferrofmm(&demo_args(&["-q", "--json", "--threads", "1"]));
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr, "");
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    let json: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(json["order"].as_u64(), Some(3));

    // Without a terminal there is no progress even without --quiet: stderr
    // stays empty, stdout holds the report.
    let out = ferrofmm(&demo_args(&["--threads", "1"]));
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr, "");
    assert!(!stdout.trim().is_empty());
}

#[test]
fn quiet_eval_writes_its_file_and_still_reports_errors() {
    let dir = scratch("quiet-eval");
    let n = 500;
    let (p, q, out_path) = (dir.join("p.npy"), dir.join("q.npy"), dir.join("out.npy"));
    write_npy(&p, &points(n, 1), &[n as u64, 3]);
    write_npy(&q, &charges(n, 2), &[n as u64]);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (ps, qs, os) = (s(&p), s(&q), s(&out_path));
    let eval = |sources: &str, extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--sources",
            sources,
            "--charges",
            &qs,
            "--out",
            &os,
            "-p",
            "3",
            "--quiet",
        ];
        args.extend_from_slice(extra);
        ferrofmm(&args)
    };
    let out = eval(&ps, &[]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!((stdout.as_str(), stderr.as_str()), ("", ""));
    assert!(out_path.is_file());

    // An error still prints (one `error:` line) and fails.
    let missing = s(&dir.join("missing.npy"));
    let out = eval(&missing, &[]);
    let (stdout, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stdout, "");
    assert!(stderr.starts_with("error: "), "{stderr}");

    // A warning still prints: --threads above the cores is lowered, with
    // a note.
    let many = (std::thread::available_parallelism().map_or(1, |c| c.get()) * 8).to_string();
    let out = eval(&ps, &["--threads", &many]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stdout, "");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("--threads"), "{stderr}");
}

/// `ferrofmm args` with stdout and stderr on a pseudo-terminal (through
/// util-linux `script`), `None` where `script` cannot run: what the
/// terminal showed.
fn on_a_terminal(args: &[&str]) -> Option<String> {
    let exe = env!("CARGO_BIN_EXE_ferrofmm");
    let line = std::iter::once(exe)
        .chain(args.iter().copied())
        .map(|a| format!("'{a}'"))
        .collect::<Vec<_>>()
        .join(" ");
    let out = Command::new("script")
        .args(["-q", "-e", "-c", &line, "/dev/null"])
        .env("FERROFMM_CACHE", common::test_cache())
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .ok()?;
    assert!(out.status.success(), "{:?}", texts(&out));
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

#[cfg(unix)]
#[test]
fn progress_on_a_terminal_and_none_with_quiet() {
    // Fresh operators (no cache), a tree and a few repeats: long enough
    // to draw.
    let args = [
        "demo",
        "-n",
        "20000",
        "-p",
        "4",
        "--leaf-size",
        "64",
        "--check",
        "0",
        "--json",
        "--no-cache",
        "--repeats",
        "3",
        "-t",
        "1",
    ];
    let Some(shown) = on_a_terminal(&args) else {
        eprintln!("skipped: util-linux `script` is not available");
        return;
    };
    assert!(shown.contains("\"order\""), "{shown}");
    let rest = outside_json(&shown);
    assert!(
        rest.contains("setup"),
        "no progress on a terminal: {shown:?}"
    );
    // The passes report their progress: the evaluation is a bar with a
    // percentage and the time left.
    assert!(
        rest.split(['\r', '\n'])
            .any(|l| l.contains("evaluation") && l.contains('%') && l.contains(" < ")),
        "no evaluation bar: {shown:?}"
    );

    let mut quiet = args.to_vec();
    quiet.push("--quiet");
    let shown = on_a_terminal(&quiet).unwrap_or_default();
    assert!(shown.contains("\"order\""), "{shown}");
    let rest = outside_json(&shown);
    assert!(
        rest.chars().all(|c| c.is_whitespace() || c.is_control()),
        "{shown:?}"
    );
}

/// What a terminal showed besides the JSON object (which names `setup`
/// too): each line without its span from the first `{` to the last `}`.
fn outside_json(text: &str) -> String {
    text.lines()
        .map(|l| match (l.find('{'), l.rfind('}')) {
            (Some(a), Some(b)) if a < b => format!("{}{}", &l[..a], &l[b + 1..]),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}
