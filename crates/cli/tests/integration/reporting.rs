//! What the command says about itself: `--threads` above the cores, the
//! operator cache's fate in the table, the exit codes in `--help` and the
//! README, the coincidence rule in `eval --help`.

use crate::common;

use std::path::Path;

use common::{ferrofmm, scratch, texts};

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// `--threads` far above the cores runs with one thread per core (and says
/// so once): oversubscribed, the M2L precomputation crawled (24 s instead
/// of 0.36 s at 64 threads).
#[test]
fn threads_above_the_cores_are_capped() {
    // A tiny demo with `--threads T`: (threads the report says, stderr).
    let demo = |threads: &str| {
        let out = ferrofmm(&[
            "demo",
            "-n",
            "1000",
            "-p",
            "3",
            "--check",
            "0",
            "--json",
            "--threads",
            threads,
        ]);
        let (stdout, stderr) = texts(&out);
        assert!(out.status.success(), "{stderr}");
        let json: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
        (json["threads"].as_u64(), stderr)
    };
    let many = (cores() * 8).max(64).to_string();
    let (threads, stderr) = demo(&many);
    assert_eq!(threads, Some(cores() as u64), "{stderr}");
    let notes: Vec<&str> = stderr.lines().filter(|l| l.contains("--threads")).collect();
    assert_eq!(notes.len(), 1, "{stderr}");
    assert!(
        notes[0].contains(&many) && notes[0].contains("cores"),
        "{stderr}"
    );

    // At or below the cores: as asked, silently.
    let (threads, stderr) = demo("1");
    assert_eq!(threads, Some(1));
    assert!(stderr.trim().is_empty(), "{stderr}");

    let (help, _) = texts(&ferrofmm(&["--help"]));
    assert!(
        help.to_lowercase()
            .contains("at most one per available core"),
        "{help}"
    );
}

/// The `operator cache` row: a miss, then a hit, then a rebuild of a
/// damaged file, and an unwritable cache directory.
#[test]
fn cache_status_is_in_the_table() {
    let dir = scratch("cache-status");
    let cache = dir.join("cache");
    let demo = |cache: &Path| {
        let out = ferrofmm(&[
            "demo",
            // Enough points for V lists: a tree without them needs no M2L
            // operators and caches none ("M2L not cached").
            "-n",
            "2000",
            "-p",
            "3",
            "--check",
            "0",
            "--cache-dir",
            cache.to_str().unwrap(),
        ]);
        let (stdout, stderr) = texts(&out);
        assert!(out.status.success(), "{stderr}");
        stdout
            .lines()
            .find(|l| l.trim_start().starts_with("operator cache"))
            .unwrap_or_else(|| panic!("no cache row in:\n{stdout}"))
            .to_string()
    };
    let row = demo(&cache);
    assert!(row.contains("miss (computed, saved)"), "{row}");
    let hit = format!(" hit in {}", cache.display());
    let row = demo(&cache);
    assert!(row.ends_with(&hit), "{row}");

    // Damage every cache file: both are rebuilt, and say why.
    for entry in std::fs::read_dir(&cache).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    }
    let row = demo(&cache);
    assert!(
        row.contains("recomputed (cached file rejected: ") && row.contains("saved"),
        "{row}"
    );
    assert!(demo(&cache).ends_with(&hit));

    // A regular file as the cache directory: computed, not saved.
    let file = dir.join("not-a-dir");
    std::fs::write(&file, "x").unwrap();
    let row = demo(&file);
    assert!(row.contains("memory only (computed, not saved"), "{row}");

    // --no-cache: the row says so.
    let out = ferrofmm(&["demo", "-n", "300", "-p", "3", "--check", "0", "--no-cache"]);
    assert!(
        texts(&out)
            .0
            .contains("operator cache     off (--no-cache)\n"),
        "{}",
        texts(&out).0
    );
}

/// `--help` and the README list the same exit codes.
#[test]
fn exit_codes_agree_between_help_and_readme() {
    let (help, _) = texts(&ferrofmm(&["--help"]));
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md"))
            .unwrap();
    let paragraph = |text: &str| -> String {
        let start = text.find("Exit status").expect("an exit status paragraph");
        let rest = &text[start..];
        let end = rest.find("\n\n").unwrap_or(rest.len());
        rest[..end].split_whitespace().collect::<Vec<_>>().join(" ")
    };
    let (h, r) = (paragraph(&help), paragraph(&readme));
    let codes = |p: &str| -> Vec<u32> {
        let mut c: Vec<u32> = p
            .split(|ch: char| !ch.is_ascii_digit())
            .filter_map(|w| w.parse().ok())
            .collect();
        c.sort_unstable();
        c.dedup();
        c
    };
    assert_eq!(codes(&h), vec![0, 1, 2, 101, 130], "help: {h}");
    assert_eq!(codes(&r), codes(&h), "README: {r}\nhelp: {h}");
    for words in ["closed", "syntax", "internal error"] {
        assert!(
            h.contains(words) && r.contains(words),
            "'{words}'\n{h}\n{r}"
        );
    }
}

/// `eval --help` states the coincidence rule.
#[test]
fn eval_help_states_the_coincidence_rule() {
    let (help, _) = texts(&ferrofmm(&["eval", "--help"]));
    assert!(
        help.contains("1.5e-154") && help.contains("1.1e-19"),
        "{help}"
    );
}

/// With `--tolerance` the table shows the requested and the predicted error.
#[test]
fn tolerance_and_predicted_error_are_in_the_table() {
    let out = ferrofmm(&[
        "demo",
        "-n",
        "1000",
        "--tolerance",
        "1e-4",
        "--check",
        "200",
    ]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    let row = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("tolerance"))
        .unwrap_or_else(|| panic!("no tolerance row in:\n{stdout}"));
    assert!(
        row.contains("1.00e-4 requested") && row.contains("predicted error"),
        "{row}"
    );
    assert!(stdout.contains("relative L2 error vs direct summation"));
}
