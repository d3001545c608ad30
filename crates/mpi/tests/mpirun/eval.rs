//! The `eval` command: files in slices, kernels, tolerance, cache,
//! targets, quiet runs and the memory limit.

use crate::common::*;
use ferrofmm_testing::errors::relative_l2;

/// `eval` with files: the result of 3 ranks (each reading its rows of a
/// `.npy` file, writing its rows of the output) equals that of 1 rank
/// (reading `.csv`), in the input order; `--check` reports a small error
/// against direct summation; charges that do not match the points are one
/// error on every rank, not a hang.
#[test]
fn eval_command_reads_slices_and_writes_the_input_order() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-eval-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let n = 900;
    let pts: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.618_034).fract()).collect();
    let q: Vec<f64> = (0..n)
        .map(|i| ((i * 37) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let csv = |rows: &mut dyn Iterator<Item = String>| rows.collect::<Vec<_>>().join("\n");
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    // A byte order mark, a header and a comment, as spreadsheets write.
    std::fs::write(
        path("s.csv"),
        "\u{feff}x,y,z\n# points\n".to_string()
            + &csv(&mut pts.chunks(3).map(|p| format!("{},{},{}", p[0], p[1], p[2]))),
    )
    .unwrap();
    std::fs::write(path("q.csv"), csv(&mut q.iter().map(|x| x.to_string()))).unwrap();
    std::fs::write(
        path("short.csv"),
        csv(&mut q[1..].iter().map(|x| x.to_string())),
    )
    .unwrap();
    write_npy(&path("s.npy"), &pts, 3);
    write_npy(&path("q.npy"), &q, 1);
    let common = ["--gradients", "--order", "4", "--leaf-size", "20"];
    let run = |ranks: usize, s: &str, c: &str, out: &str| {
        let mut args = vec!["eval", "--sources", s, "--charges", c, "--out", out];
        args.extend(common);
        mpirun(ranks, &args)
    };
    let (ok, text) = run(1, &path("s.csv"), &path("q.csv"), &path("o1.npy"));
    assert!(ok, "{text}");
    let (ok, text) = run(3, &path("s.npy"), &path("q.npy"), &path("o3.npy"));
    assert!(ok, "{text}");
    let read = |name: &str| read_columns(&path(name), n, 4);
    let (a, b) = (read("o1.npy"), read("o3.npy"));
    let d = relative_l2(&b, &a);
    assert!(d <= 1e-12, "R = 3 differs: {d}");
    // f32 on 2 ranks: the f64 result to the accuracy of order 4 in f32.
    let (ok, text) = mpirun(
        2,
        &[
            "eval",
            "--sources",
            &path("s.npy"),
            "--charges",
            &path("q.npy"),
            "--out",
            &path("o32.npy"),
            "--precision",
            "f32",
            "--gradients",
            "--order",
            "4",
            "--leaf-size",
            "20",
        ],
    );
    assert!(ok, "{text}");
    let c = read("o32.npy");
    // (f32 has its own pseudo-inverse cutoff, so its operators differ too.)
    let d = relative_l2(&c, &a);
    assert!(d <= 1e-3, "f32 differs: {d}");
    // --check: the error against direct summation at a sample, as JSON.
    let (ok, text) = mpirun(
        2,
        &[
            "eval",
            "--sources",
            &path("s.csv"),
            "--charges",
            &path("q.csv"),
            "--order",
            "5",
            "--check",
            "150",
            "--json",
            "--out",
            &path("o5.csv"),
        ],
    );
    let err = text
        .split("\"potential_error\":")
        .nth(1)
        .and_then(|t| t.split([',', '}']).next())
        .and_then(|t| t.parse::<f64>().ok());
    assert!(ok && err.is_some_and(|e| e < 1e-3), "{err:?}\n{text}");
    // The CSV output has the header `ferrofmm eval` writes, in the input
    // order, written by the ranks in turn.
    let o5 = std::fs::read_to_string(path("o5.csv")).unwrap();
    assert!(o5.starts_with("potential\n"), "{}", &o5[..40]);
    let o5 = read_columns(&path("o5.csv"), n, 1);
    let p4: Vec<f64> = a.iter().step_by(4).copied().collect();
    let d = relative_l2(&o5, &p4);
    assert!(d < 1e-3, "order 5 vs 4: {d}");
    let (ok, text) = run(2, &path("s.csv"), &path("short.csv"), &path("bad.npy"));
    assert!(!ok && text.contains("charges"), "{text}");
    assert!(!std::path::Path::new(&path("bad.npy")).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `eval` with a vector kernel (Stokes forces from an `N x 3` file): 1 and
/// 3 ranks agree; `--tolerance` chooses the order and verifies it against
/// direct summation (Helmholtz, complex charges); `--cache-dir` fills a
/// cache on the first run that the second loads, with the same result;
/// an unknown kernel and dipoles for Stokes are errors on every rank.
#[test]
fn eval_command_with_kernels_tolerance_and_cache() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-kernels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 1500;
    let pts: Vec<f64> = (0..3 * n)
        .map(|i| (i as f64 * 0.754_877_666).fract().powi(2))
        .collect();
    let f: Vec<f64> = (0..3 * n)
        .map(|i| ((i * 53) % 97) as f64 / 97.0 - 0.5)
        .collect();
    write_npy(&path("s.npy"), &pts, 3);
    write_npy(&path("f.npy"), &f, 3);
    write_npy(&path("z.npy"), &f[..2 * n], 2);
    let read = |name: &str, cols: usize| read_columns(&path(name), n, cols);
    // Stokes: velocities and their gradients (3 + 9 columns).
    for (ranks, out) in [(1, "u1.npy"), (3, "u3.npy")] {
        let (ok, text) = mpirun(
            ranks,
            &[
                "eval",
                "--sources",
                &path("s.npy"),
                "--charges",
                &path("f.npy"),
                "--kernel",
                "stokes",
                "--gradients",
                "--order",
                "4",
                "--leaf-size",
                "30",
                "--out",
                &path(out),
            ],
        );
        assert!(ok, "R = {ranks}:\n{text}");
    }
    let d = relative_l2(&read("u3.npy", 12), &read("u1.npy", 12));
    assert!(d <= 1e-12, "Stokes on 3 ranks differs by {d}");

    // Helmholtz to a tolerance: chosen, verified, met.
    let (ok, text) = mpirun(
        2,
        &[
            "eval",
            "--sources",
            &path("s.npy"),
            "--charges",
            &path("z.npy"),
            "--kernel",
            "helmholtz:6",
            "--tolerance",
            "1e-5",
            "--json",
        ],
    );
    let err = json_number(&text, "potential_error");
    assert!(
        ok && text.contains("\"tolerance_met\":true") && err.is_some_and(|e| e <= 1e-5),
        "{err:?}\n{text}"
    );
    assert!(
        json_number(&text, "sample_points") == Some(n as f64),
        "{text}"
    );

    // The cache: filled by the first run, read by the second, same values.
    let cache = path("cache");
    for out in ["c1.npy", "c2.npy"] {
        let (ok, text) = mpirun(
            2,
            &[
                "eval",
                "--sources",
                &path("s.npy"),
                "--charges",
                &path("f.npy"),
                "--kernel",
                "stokes",
                "--scheme",
                "svd",
                "--order",
                "3",
                "--leaf-size",
                "30",
                "--cache-dir",
                &cache,
                "--out",
                &path(out),
            ],
        );
        assert!(ok, "{text}");
    }
    let files = std::fs::read_dir(&cache).map(|d| d.count()).unwrap_or(0);
    assert!(files > 0, "no cache files in {cache}");
    assert_eq!(read("c1.npy", 3), read("c2.npy", 3));

    let (s_npy, f_npy) = (path("s.npy"), path("f.npy"));
    for bad in [
        vec!["--kernel", "coulomb"],
        vec!["--kernel", "stokes", "--dipoles", &f_npy],
        vec!["--kernel", "yukawa:-1"],
    ] {
        let mut args = vec!["eval", "--sources", &s_npy, "--charges", &f_npy];
        args.extend(bad.iter().copied());
        let (ok, text) = mpirun(2, &args);
        assert!(!ok && text.contains("error"), "{bad:?}: {text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `eval --targets`: one output row per target in the targets file's
/// order, on 1 and 3 ranks the same, equal to the single-machine FMM with
/// targets (same order and leaf size), and with `--tolerance` the error
/// against a direct sum at every target below it (targets partly outside
/// the sources' cube).
#[test]
fn eval_with_separate_targets() {
    use ferrofmm_kernels::{EvalMode, Laplace3d, SourceKind, direct_sum_sources};
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-targets-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let (n, m) = (800, 500);
    let src: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.618_034).fract()).collect();
    // Targets in a box shifted by half a side: half of them outside.
    let tgt: Vec<f64> = (0..3 * m)
        .map(|i| (i as f64 * 0.414_214).fract() + 0.5)
        .collect();
    let q: Vec<f64> = (0..n)
        .map(|i| ((i * 37) % 101) as f64 / 101.0 - 0.5)
        .collect();
    write_npy(&path("s.npy"), &src, 3);
    write_npy(&path("t.npy"), &tgt, 3);
    write_npy(&path("q.npy"), &q, 1);
    let run = |ranks: usize, out: &str, extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--sources",
            &path("s.npy"),
            "--charges",
            &path("q.npy"),
            "--targets",
            &path("t.npy"),
            "--gradients",
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
        args.push("--out".into());
        args.push(path(out));
        args.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (ok, text) = mpirun(ranks, &args);
        assert!(ok, "{text}");
        read_columns(&path(out), m, 4)
    };
    // Operators computed here, as the single machine's below (a cached SVD
    // basis may have been made for another tree's transfer vectors).
    let fixed = [
        "--order",
        "5",
        "--leaf-size",
        "30",
        "--scheme",
        "svd",
        "--no-cache",
    ];
    let one = run(1, "o1.npy", &fixed);
    let three = run(3, "o3.npy", &fixed);
    assert!(
        relative_l2(&three, &one) <= 1e-12,
        "{}",
        relative_l2(&three, &one)
    );
    // The distributed tree's cube: the bounding cube of sources and targets.
    let domain = ferrofmm_tree::Domain::from_points(&[&src, &tgt]).unwrap();
    let single = ferrofmm_fmm::FmmBuilder::new(&src)
        .targets(&tgt)
        .domain(domain)
        .order(5)
        .leaf_size(30)
        .mode(EvalMode::PotentialGradient)
        .build_svd()
        .unwrap()
        .evaluate(&q)
        .unwrap();
    let mut direct = vec![0.0; 4 * m];
    direct_sum_sources(
        &Laplace3d,
        SourceKind::Charge,
        EvalMode::PotentialGradient,
        &src,
        &q,
        &tgt,
        &mut direct,
    );
    assert!(
        relative_l2(&one, &single) <= 1e-12,
        "{} (against a direct sum: {} and {})",
        relative_l2(&one, &single),
        relative_l2(&one, &direct),
        relative_l2(&single, &direct)
    );
    let eps = 1e-5;
    let checked = run(2, "oe.npy", &["--tolerance", "1e-5"]);
    let pot = |v: &[f64]| v.chunks(4).map(|r| r[0]).collect::<Vec<_>>();
    assert!(relative_l2(&pot(&checked), &pot(&direct)) <= eps);
    assert!(relative_l2(&checked, &direct) <= 2.0 * eps);
}

/// `eval --quiet`: a successful run prints nothing on any rank (its output
/// file is its result); `--json` asked for is still printed, alone; an
/// error still prints.
#[test]
fn eval_quiet_prints_nothing_but_what_is_asked_for() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-quiet-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("v.npy").to_string_lossy().into_owned();
    let base = ["eval", "--generate", "cube", "--n", "3000", "--order", "4"];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let run = |args: Vec<String>| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        mpirun(2, &args)
    };
    let (ok, text) = run(with(&["--quiet", "--out", &out]));
    assert!(ok, "{text}");
    assert!(text.trim().is_empty(), "quiet printed:\n{text}");
    assert!(std::fs::metadata(&out).unwrap().len() > 3000 * 8);
    let (ok, text) = run(with(&["-q", "--json"]));
    assert!(ok, "{text}");
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{text}");
    assert!(lines[0].starts_with('{') && json_number(lines[0], "ranks") == Some(2.0));
    let (ok, text) = run(with(&["--quiet", "--leaf-size", "0"]));
    assert!(!ok);
    assert!(text.contains("error:"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run predicted not to fit a rank's share of the memory limit is
/// refused on every rank before its tree is built: the same error from
/// every rank, no hang (each job is killed after a time limit), and
/// `FERROFMM_MEMORY_LIMIT=unlimited` forces it.
#[test]
fn eval_refuses_a_run_that_cannot_fit_on_every_rank() {
    // 1 MiB on one node of 2 ranks: 512 KiB a rank. Each rank's 15,000
    // points and charges (469 KiB) are made, but their FMM is predicted
    // to need at least 48 bytes a point (703 KiB).
    let args: &[&str] = &["eval", "--generate", "cube", "--n", "30000", "--order", "4"];
    let t = std::time::Instant::now();
    let (ok, text) = mpmd(&[(2, args)], &[("FERROFMM_MEMORY_LIMIT", "1M")]);
    let seconds = t.elapsed().as_secs_f64();
    assert!(!ok, "{text}");
    assert!(
        text.contains("rank 0's part of the distributed run (15000 points")
            && text.contains("is predicted to need at least")
            && text.contains("on a node of 2 ranks that share the limit equally"),
        "{text}"
    );
    // Rank 0 prints the error once; no rank was killed by the time limit.
    assert_eq!(text.matches("error:").count(), 1, "{text}");
    assert!(seconds < 120.0, "took {seconds} s:\n{text}");
    // Forced: it runs.
    let (ok, text) = mpmd(&[(2, args)], &[("FERROFMM_MEMORY_LIMIT", "unlimited")]);
    assert!(ok, "{text}");
    // A DistributedFmm built on a tree (`fmm-check` builds one directly):
    // each rank's points, ghost points and targets, refused on every rank
    // before its local FMM is allocated.
    let check: &[&str] = &[
        "fmm-check",
        "--n",
        "30000",
        "--order",
        "3",
        "--method",
        "laplace-svd",
        "--layout",
        "even",
    ];
    let t = std::time::Instant::now();
    let (ok, text) = mpmd(&[(2, check)], &[("FERROFMM_MEMORY_LIMIT", "1M")]);
    let seconds = t.elapsed().as_secs_f64();
    assert!(
        !ok && text.contains("part of the distributed FMM (")
            && text.contains("is predicted to need at least"),
        "{text}"
    );
    assert!(seconds < 120.0, "took {seconds} s:\n{text}");
}
