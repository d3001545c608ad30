//! The operator cache on by default: where it lives (`FERROFMM_CACHE`,
//! `XDG_CACHE_HOME`, `HOME`), how to turn it off, two processes filling
//! one entry at once, an unusable folder, the size cap. Every run here
//! names its cache folder through the environment: none writes into the
//! home folder of the machine running the tests.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{charges, points, scratch, texts, write_npy};

/// A tree (a leaf size given): 2,000 points alone would be a direct sum.
const DEMO: [&str; 10] = [
    "demo",
    "-n",
    "2000",
    "-p",
    "3",
    "--leaf-size",
    "150",
    "--check",
    "0",
    "--json",
];

/// `ferrofmm args` with `FERROFMM_CACHE`, `XDG_CACHE_HOME` and `HOME`
/// removed, then `env` set.
fn run(args: &[&str], env: &[(&str, &Path)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ferrofmm"));
    cmd.args(args)
        .env_remove("FERROFMM_CACHE")
        .env_remove("FERROFMM_CACHE_SIZE")
        .env_remove("XDG_CACHE_HOME")
        .env_remove("HOME");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("the ferrofmm binary runs")
}

/// The JSON report of a successful run.
fn report(out: &Output) -> serde_json::Value {
    let (stdout, stderr) = texts(out);
    assert!(out.status.success(), "{stderr}");
    serde_json::from_str(stdout.lines().last().expect("output")).expect("JSON")
}

/// The cache files in `dir` (none when it does not exist), sorted.
fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn default_folder_from_the_environment() {
    let dir = scratch("cache-where");
    let env_dir = dir.join("env");
    let xdg = dir.join("xdg");
    let home = dir.join("home");
    // FERROFMM_CACHE first ...
    let r = report(&run(
        &DEMO,
        &[
            ("FERROFMM_CACHE", &env_dir),
            ("XDG_CACHE_HOME", &xdg),
            ("HOME", &home),
        ],
    ));
    assert_eq!(r["cache_dir"], env_dir.to_str().unwrap());
    assert_eq!(r["cache"], "miss (computed, saved)");
    assert_eq!(files(&env_dir).len(), 2, "operators and M2L");
    // ... then XDG_CACHE_HOME/ferrofmm ...
    let r = report(&run(&DEMO, &[("XDG_CACHE_HOME", &xdg), ("HOME", &home)]));
    let in_xdg = xdg.join("ferrofmm");
    assert_eq!(r["cache_dir"], in_xdg.to_str().unwrap());
    assert_eq!(files(&in_xdg).len(), 2);
    // ... then HOME/.cache/ferrofmm ...
    let r = report(&run(&DEMO, &[("HOME", &home)]));
    let in_home = home.join(".cache").join("ferrofmm");
    assert_eq!(r["cache_dir"], in_home.to_str().unwrap());
    assert_eq!(files(&in_home).len(), 2);
    let r = report(&run(&DEMO, &[("HOME", &home)]));
    assert_eq!(r["cache"], "hit");
    // ... else memory only.
    let r = report(&run(&DEMO, &[]));
    assert!(r["cache_dir"].is_null());
    assert!(
        r["cache"]
            .as_str()
            .unwrap()
            .starts_with("memory only: no cache folder"),
        "{}",
        r["cache"]
    );
    // --cache-dir wins over all of them.
    let mine = dir.join("mine");
    let mut args = DEMO.to_vec();
    args.extend(["--cache-dir", mine.to_str().unwrap()]);
    let r = report(&run(&args, &[("FERROFMM_CACHE", Path::new("off"))]));
    assert_eq!(r["cache_dir"], mine.to_str().unwrap());
    // With --cache-dir the auto scheme counts no SVD precomputation and
    // takes the SVD: its bases are a third file.
    assert_eq!(files(&mine).len(), 3);
}

#[test]
fn no_cache_and_off_write_nothing() {
    let dir = scratch("cache-off");
    let cache = dir.join("cache");
    let xdg = dir.join("xdg");
    let home = dir.join("home");
    let mut args = DEMO.to_vec();
    args.push("--no-cache");
    let everything: [(&str, &Path); 3] = [
        ("FERROFMM_CACHE", &cache),
        ("XDG_CACHE_HOME", &xdg),
        ("HOME", &home),
    ];
    let r = report(&run(&args, &everything));
    assert_eq!(r["cache"], "off (--no-cache)");
    assert!(r["cache_dir"].is_null());
    for word in ["off", "0", "false", "NO"] {
        let r = report(&run(
            &DEMO,
            &[
                ("FERROFMM_CACHE", Path::new(word)),
                ("XDG_CACHE_HOME", &xdg),
                ("HOME", &home),
            ],
        ));
        assert_eq!(r["cache"], format!("off (FERROFMM_CACHE={word})"));
    }
    assert!(!cache.exists() && !xdg.exists() && !home.exists());
    // Nor were the words taken as folders (relative to the working
    // directory).
    for word in ["off", "0", "false", "NO"] {
        assert!(!Path::new(word).exists(), "{word}");
    }
    // --no-cache and --cache-dir contradict each other.
    args.extend(["--cache-dir", cache.to_str().unwrap()]);
    let out = run(&args, &everything);
    assert_eq!(out.status.code(), Some(2), "{}", texts(&out).1);
    assert!(texts(&out).1.contains("cannot be used with"));
}

/// Two processes fill the same entries of one folder at once: both give
/// the same values, one valid file per entry is left (no temporary), and
/// the next run loads them.
#[test]
fn two_processes_fill_one_entry_at_once() {
    let dir = scratch("cache-two");
    let cache = dir.join("cache");
    let (s, q) = (dir.join("s.npy"), dir.join("q.npy"));
    write_npy(&s, &points(3000, 7), &[3000, 3]);
    write_npy(&q, &charges(3000, 8), &[3000]);
    let eval = |out: &Path| -> Command {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_ferrofmm"));
        cmd.args(["eval", "--sources"])
            .arg(&s)
            .arg("--charges")
            .arg(&q)
            .args([
                "-p",
                "5",
                "--leaf-size",
                "150",
                "--check",
                "0",
                "--json",
                "--out",
            ])
            .arg(out)
            .env("FERROFMM_CACHE", &cache);
        cmd
    };
    let outs: Vec<PathBuf> = (0..3).map(|k| dir.join(format!("o{k}.npy"))).collect();
    let children: Vec<_> = outs[..2]
        .iter()
        .map(|o| {
            eval(o)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        let out = child.wait_with_output().unwrap();
        let r = report(&out);
        assert_eq!(r["cache_dir"], cache.to_str().unwrap());
        // Each either computed and saved, or found the other's file.
        let word = r["cache"].as_str().unwrap();
        assert!(
            !word.contains("not saved") && !word.contains("rejected"),
            "{word}"
        );
    }
    let names = files(&cache);
    assert_eq!(names.len(), 2, "{names:?}");
    assert!(names.iter().all(|n| n.ends_with(".ffmm")), "{names:?}");
    let r = report(&eval(&outs[2]).output().unwrap());
    assert_eq!(r["cache"], "hit");
    let a = std::fs::read(&outs[0]).unwrap();
    assert_eq!(a, std::fs::read(&outs[1]).unwrap());
    assert_eq!(a, std::fs::read(&outs[2]).unwrap());
}

/// A folder that cannot be created (below a regular file) or written:
/// the run goes on in memory and the report says so.
#[test]
fn unusable_folder_runs_in_memory() {
    let dir = scratch("cache-unusable");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let below = file.join("cache");
    let r = report(&run(&DEMO, &[("FERROFMM_CACHE", &below)]));
    let word = r["cache"].as_str().unwrap();
    assert!(
        word.starts_with("memory only (computed, not saved: "),
        "{word}"
    );
    assert_eq!(r["cache_dir"], below.to_str().unwrap());

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.join("read-only");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        // Root writes anyway: only check what a normal user gets.
        let permissions_bite = std::fs::write(ro.join("probe"), "x").is_err();
        let r = report(&run(&DEMO, &[("FERROFMM_CACHE", &ro)]));
        if permissions_bite {
            let word = r["cache"].as_str().unwrap();
            assert!(word.starts_with("memory only"), "{word}");
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// `FERROFMM_CACHE_SIZE`: a cap of one byte keeps only the newest file;
/// a value that is not a size stops the run with a message naming it.
#[test]
fn size_cap_from_the_environment() {
    let dir = scratch("cache-size");
    let cache = dir.join("cache");
    let one = Path::new("1");
    for p in ["3", "4"] {
        let mut args = DEMO.to_vec();
        args[4] = p;
        report(&run(
            &args,
            &[("FERROFMM_CACHE", &cache), ("FERROFMM_CACHE_SIZE", one)],
        ));
    }
    let names = files(&cache);
    assert_eq!(names.len(), 1, "{names:?}");
    assert!(names[0].contains("_p4_"), "{names:?}");

    let out = run(
        &DEMO,
        &[
            ("FERROFMM_CACHE", &cache),
            ("FERROFMM_CACHE_SIZE", Path::new("lots")),
        ],
    );
    assert!(!out.status.success());
    let stderr = texts(&out).1;
    assert!(
        stderr.contains("FERROFMM_CACHE_SIZE=\"lots\" is not a size"),
        "{stderr}"
    );
}
