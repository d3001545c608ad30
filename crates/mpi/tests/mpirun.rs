//! Runs the `ferrofmm-mpi` binary under `mpirun` with 1 to 4 ranks
//! (`--oversubscribe`: CI machines have 2 cores): the distributed tree must
//! equal the single-machine tree for every input and layout, and bad input
//! on one rank must be the same error on every rank, without a hang (each
//! run is killed after a time limit).

use std::process::Command;
use std::sync::Mutex;

/// One MPI job at a time (the tests of this file run in parallel threads).
static MPI_JOB: Mutex<()> = Mutex::new(());

fn mpirun(ranks: usize, args: &[&str]) -> (bool, String) {
    mpmd(&[(ranks, args)], &[])
}

/// One job of several programs (`mpirun -n R1 exe ARGS1 : -n R2 exe
/// ARGS2`), each rank with the arguments of its group, and extra
/// environment variables for every rank.
fn mpmd(groups: &[(usize, &[&str])], env: &[(&str, &str)]) -> (bool, String) {
    let _one = MPI_JOB.lock().unwrap_or_else(|e| e.into_inner());
    let exe = env!("CARGO_BIN_EXE_ferrofmm-mpi");
    let mpirun = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let mut cmd = Command::new("timeout");
    cmd.arg("300").arg(&mpirun).arg("--oversubscribe");
    // Open MPI refuses to run as root without these (CI containers).
    cmd.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1")
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
fn test_cache() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("mpi-operator-cache")
}

/// The default cache on 3 ranks (`FERROFMM_CACHE`): rank 0 fills it, the
/// others and the next run read it, with the same values; the report
/// names the folder; `--no-cache` and `FERROFMM_CACHE=off` write nothing.
#[test]
fn default_cache_is_shared_by_the_ranks() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let cache = dir.join("cache");
    let cache_s = cache.to_string_lossy().into_owned();
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let (o1, o2, o3) = (out("o1.npy"), out("o2.npy"), out("o3.npy"));
    let args = |o: &str, extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = [
            "eval",
            "--generate",
            "uniform",
            "--n",
            "3000",
            "--order",
            "4",
            "--leaf-size",
            "40",
            "--scheme",
            "svd",
            "--json",
            "--out",
            o,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |o: &str, extra: &[&str], env: &[(&str, &str)]| {
        let a = args(o, extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let (ok, text) = mpmd(&[(3, &a)], env);
        assert!(ok, "{text}");
        text
    };
    let with_cache = [("FERROFMM_CACHE", cache_s.as_str())];
    let first = run(&o1, &[], &with_cache);
    assert!(
        first.contains(r#""cache":"miss (computed, saved)""#)
            && first.contains(&format!(r#""cache_dir":"{cache_s}""#)),
        "{first}"
    );
    let names = listing(&cache);
    assert_eq!(names.len(), 2, "operators and M2L, no temporary: {names:?}");
    let second = run(&o2, &[], &with_cache);
    assert!(second.contains(r#""cache":"hit""#), "{second}");
    assert_eq!(std::fs::read(&o1).unwrap(), std::fs::read(&o2).unwrap());

    let off_dir = dir.join("off");
    let off_s = off_dir.to_string_lossy().into_owned();
    let text = run(&o3, &["--no-cache"], &[("FERROFMM_CACHE", off_s.as_str())]);
    assert!(text.contains(r#""cache":"off (--no-cache)""#), "{text}");
    let text = run(&o3, &[], &[("FERROFMM_CACHE", "off")]);
    assert!(
        text.contains(r#""cache":"off (FERROFMM_CACHE=off)""#),
        "{text}"
    );
    assert!(!off_dir.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn distributed_tree_equals_the_single_machine_tree_on_1_to_4_ranks() {
    for ranks in 1..=4 {
        let (ok, out) = mpirun(ranks, &["check", "--n", "6000", "--leaf-size", "1,20,150"]);
        assert!(ok && out.contains("CHECK PASSED"), "R = {ranks}:\n{out}");
    }
}

/// Fewer points than ranks, and all points in one leaf (the root).
#[test]
fn tiny_inputs_and_a_single_leaf() {
    for ranks in 1..=4 {
        for n in ["3", "100"] {
            let (ok, out) = mpirun(ranks, &["check", "--n", n, "--leaf-size", "1,150"]);
            assert!(
                ok && out.contains("CHECK PASSED"),
                "R = {ranks}, n = {n}:\n{out}"
            );
        }
    }
}

#[test]
fn bad_input_on_one_rank_is_the_same_error_on_every_rank() {
    for ranks in 1..=4 {
        for case in [
            "nan", "infinite", "length", "empty", "leaf0", "options", "weights",
        ] {
            let (ok, out) = mpirun(ranks, &["bad", "--case", case]);
            assert!(
                ok && out.contains("ERROR AGREED"),
                "R = {ranks}, {case}:\n{out}"
            );
        }
    }
}

/// The distributed FMM equals the single-machine FMM on the same tree and
/// operators (relative L2 difference <= 1e-12 of potentials and
/// gradients), for four geometries, inputs spread evenly or with the first
/// rank empty; Laplace and modified Helmholtz with the SVD, dense and FFT
/// M2L schemes spread over the rank counts (the SVD precomputation is the
/// slow part of a debug build); two charge vectors on one build (input
/// order) and one in tree order; bad charges on one rank are the same
/// error everywhere.
#[test]
fn distributed_fmm_equals_the_single_machine_fmm_on_1_to_4_ranks() {
    let methods = [
        "laplace-svd,laplace-fft",
        "laplace-dense,helmholtz-svd",
        "laplace-svd,helmholtz-fft",
        "laplace-fft,laplace-dense,helmholtz-svd",
    ];
    for (ranks, method) in (1..=4).zip(methods) {
        let args = [
            "fmm-check",
            "--n",
            "1500",
            "--order",
            "3",
            "--method",
            method,
        ];
        let (ok, out) = mpirun(ranks, &args);
        assert!(
            ok && out.contains("FMM CHECK PASSED"),
            "R = {ranks}:\n{out}"
        );
    }
}

/// Ranks that hold no point of the tree (fewer points than ranks), and a
/// tree that is one leaf.
#[test]
fn distributed_fmm_with_empty_ranks_and_a_single_leaf() {
    for ranks in [2, 4] {
        for n in ["3", "30"] {
            let (ok, out) = mpirun(
                ranks,
                &[
                    "fmm-check",
                    "--n",
                    n,
                    "--geometry",
                    "uniform,two-clusters",
                    "--method",
                    "laplace-svd,helmholtz-fft",
                ],
            );
            assert!(
                ok && out.contains("FMM CHECK PASSED"),
                "R = {ranks}, n = {n}:\n{out}"
            );
        }
    }
}

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
    let num: f64 = a.iter().zip(&b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = a.iter().map(|x| x * x).sum();
    assert!(
        (num / den).sqrt() <= 1e-12,
        "R = 3 differs: {}",
        (num / den).sqrt()
    );
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
    let num: f64 = a.iter().zip(&c).map(|(x, y)| (x - y) * (x - y)).sum();
    // (f32 has its own pseudo-inverse cutoff, so its operators differ too.)
    assert!(
        (num / den).sqrt() <= 1e-3,
        "f32 differs: {}",
        (num / den).sqrt()
    );
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
    let num: f64 = o5.iter().zip(&p4).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = p4.iter().map(|x| x * x).sum();
    assert!(
        (num / den).sqrt() < 1e-3,
        "order 5 vs 4: {}",
        (num / den).sqrt()
    );
    let (ok, text) = run(2, &path("s.csv"), &path("short.csv"), &path("bad.npy"));
    assert!(!ok && text.contains("charges"), "{text}");
    assert!(!std::path::Path::new(&path("bad.npy")).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Kernels with several components (complex Helmholtz, Stokes) and dipole
/// sources: the distributed FMM equals the single-machine FMM (1e-12) on
/// 2 to 4 ranks, with the SVD and FFT schemes.
#[test]
fn distributed_fmm_with_vector_kernels_and_dipoles() {
    let methods = [
        (2, "oscillatory-svd,stokes-fft,dipoles-svd"),
        (3, "oscillatory-fft,stokes-svd"),
        (4, "stokes-fft,dipoles-svd,oscillatory-fft"),
    ];
    for (ranks, method) in methods {
        let args = [
            "fmm-check",
            "--n",
            "1200",
            "--order",
            "3",
            "--geometry",
            "plummer,two-clusters",
            "--method",
            method,
        ];
        let (ok, out) = mpirun(ranks, &args);
        assert!(
            ok && out.contains("FMM CHECK PASSED"),
            "R = {ranks}:\n{out}"
        );
    }
}

/// `values` as a float64 `.npy` array of `columns` columns, through the
/// commands' own writer.
fn write_npy(path: &str, values: &[f64], columns: usize) {
    let names = vec!["v"; columns];
    ferrofmm_io::write(
        std::path::Path::new(path),
        ferrofmm_io::Values::F64(values),
        &names,
    )
    .unwrap();
}

/// The `n` records of `columns` values of an output file (.npy or .csv).
fn read_columns(path: &str, n: usize, columns: usize) -> Vec<f64> {
    let v = ferrofmm_io::read(
        std::path::Path::new(path),
        ferrofmm_io::Contents::Charges(columns),
    )
    .unwrap();
    assert_eq!(v.len(), n * columns, "{path}");
    v
}

/// The value of `"key":` in `text` (the first occurrence), as a number.
fn json_number(text: &str, key: &str) -> Option<f64> {
    text.split(&format!("\"{key}\":"))
        .nth(1)
        .and_then(|t| t.split([',', '}']).next())
        .and_then(|t| t.parse::<f64>().ok())
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
    let rel = |a: &[f64], b: &[f64]| {
        let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
        let den: f64 = a.iter().map(|x| x * x).sum();
        (num / den).sqrt()
    };
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
    let d = rel(&read("u1.npy", 12), &read("u3.npy", 12));
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

/// Files in `dir` (names), sorted.
fn listing(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Hostile input to `eval` (issue 37): each failure is one clear error on
/// every rank, printed once, before any work, with no hang and nothing
/// left behind (no temporary file, no partial output); a thread request
/// beyond the cores is lowered with a note.
#[test]
fn eval_refuses_hostile_input_on_every_rank() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-hostile-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("outdir")).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 1500;
    let pts: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.618_034).fract()).collect();
    let q: Vec<f64> = (0..n)
        .map(|i| ((i * 37) % 101) as f64 / 101.0 - 0.5)
        .collect();
    write_npy(&path("s.npy"), &pts, 3);
    write_npy(&path("q.npy"), &q, 1);
    write_npy(&path("f.npy"), &pts, 3);
    let before = listing(&dir);
    let (s, c) = (path("s.npy"), path("q.npy"));
    let base = |extra: &[&'static str]| -> Vec<String> {
        let mut v: Vec<String> = ["eval", "--sources", &s, "--charges", &c, "--order", "3"]
            .iter()
            .map(|x| x.to_string())
            .collect();
        v.extend(extra.iter().map(|x| x.to_string()));
        v
    };
    fn refs(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    let expect_error = |label: &str, (ok, text): (bool, String), needle: &str| {
        assert!(!ok, "{label}: succeeded\n{text}");
        assert!(text.contains(needle), "{label}: no {needle:?}\n{text}");
        assert_eq!(
            text.lines().filter(|l| l.starts_with("error:")).count(),
            1,
            "{label}: not one error line\n{text}"
        );
        // (The overflow names the value it found, which may be NaN.)
        assert!(
            !text.contains("NaN") || label.contains("1e307"),
            "{label}: {text}"
        );
    };
    let outdir = path("outdir");
    // Row 2: --out names a directory (1 and 2 ranks).
    for ranks in [1, 2] {
        let args = base(&[]);
        let mut args = refs(&args);
        args.extend(["--out", &outdir]);
        expect_error("--out DIR", mpirun(ranks, &args), "is a directory");
    }
    // Row 7: a missing folder, and a different --out per rank.
    let missing = path("no/such/o.npy");
    let args = base(&[]);
    let mut args = refs(&args);
    args.extend(["--out", &missing]);
    expect_error("missing folder", mpirun(2, &args), "does not exist");
    let (o1, o2) = (path("o1.npy"), path("o2.npy"));
    let (mut a1, mut a2) = (args.clone(), args.clone());
    let k = a1.len() - 1;
    a1[k] = &o1;
    a2[k] = &o2;
    expect_error(
        "--out per rank",
        mpmd(&[(1, &a1), (1, &a2)], &[]),
        "--out is \"",
    );
    // Row 5: a different kernel per rank (MPMD).
    let (k1, k2) = (
        base(&["--kernel", "laplace"]),
        base(&["--kernel", "yukawa:1"]),
    );
    let text = mpmd(&[(1, &refs(&k1)), (1, &refs(&k2))], &[]);
    expect_error(
        "--kernel per rank",
        text,
        "--kernel is \"laplace\" on rank 0",
    );
    // Row 13: dipoles for Stokes, as on one machine.
    let f = path("f.npy");
    let args = base(&["--kernel", "stokes"]);
    let mut args = refs(&args);
    args.extend(["--dipoles", &f]);
    expect_error(
        "stokes dipoles",
        mpirun(2, &args),
        "does not support dipole sources",
    );
    // Row 3: RAYON_NUM_THREADS that is not a number.
    let args = base(&[]);
    expect_error(
        "RAYON_NUM_THREADS=abc",
        mpmd(&[(2, &refs(&args))], &[("RAYON_NUM_THREADS", "abc")]),
        "RAYON_NUM_THREADS=\"abc\" is not a thread count",
    );
    // Row 8: charges near f64's largest value overflow the sums: an error
    // naming it on every rank, no output written.
    let huge: Vec<f64> = q.iter().map(|x| x * 1e307).collect();
    write_npy(&path("huge.npy"), &huge, 1);
    let never = path("never.npy");
    let h = path("huge.npy");
    let args = base(&[]);
    let mut args = refs(&args);
    args[4] = &h;
    args.extend(["--out", &never]);
    expect_error("charges x 1e307", mpirun(2, &args), "overflowed f64");
    std::fs::remove_file(&h).unwrap();
    assert_eq!(listing(&dir), before, "files left behind");
    assert!(listing(&dir.join("outdir")).is_empty());
    // Row 3: --threads 10000 runs with the cores there are, and says so.
    let out = path("o.npy");
    // (--check beyond the points compares, and reports, every point.)
    let args = base(&[
        "--threads",
        "10000",
        "--leaf-size",
        "60",
        "--check",
        "100000",
        "--json",
    ]);
    let mut args = refs(&args);
    args.extend(["--out", &out]);
    let t0 = std::time::Instant::now();
    let (ok, text) = mpirun(2, &args);
    assert!(ok, "{text}");
    assert!(
        text.contains("note: --threads 10000 is more than"),
        "{text}"
    );
    let threads = json_number(&text, "threads_per_rank");
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    assert!(
        threads.is_some_and(|t| t >= 1.0 && t <= cores as f64),
        "{threads:?}\n{text}"
    );
    assert!(t0.elapsed().as_secs() < 120, "{:?}", t0.elapsed());
    assert_eq!(json_number(&text, "samples"), Some(n as f64), "{text}");
    assert_eq!(read_columns(&out, n, 1).len(), n);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `tree --points` reads what `ferrofmm eval` reads (issue 37): a comma
/// CSV with a header and a `.npy` file build the same tree; ragged rows
/// are an error naming the line; a binary file, a directory and a missing
/// file are their own one error, not a NaN coordinate.
#[test]
fn tree_reads_the_files_eval_reads() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-tree-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("d.csv")).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 1500;
    let pts: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.381_966).fract()).collect();
    write_npy(&path("p.npy"), &pts, 3);
    std::fs::write(
        path("p.csv"),
        pts.chunks(3).fold("x,y,z\n".to_string(), |s, p| {
            s + &format!("{},{},{}\n", p[0], p[1], p[2])
        }),
    )
    .unwrap();
    std::fs::copy(path("p.npy"), path("binary.csv")).unwrap();
    std::fs::write(path("ragged.csv"), "0.1 0.2\n0.3 0.4 0.5 0.6\n").unwrap();
    std::fs::write(path("six.csv"), "0.1,0.2,0.3\n0.1,0.2,0.3,0.4,0.5,0.6\n").unwrap();
    let mut totals = Vec::new();
    // Raw little-endian f64 (what `tree --points` read before it took
    // .csv and .npy): read again, the same tree.
    std::fs::write(
        path("p.f64"),
        pts.iter()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    std::fs::write(path("short.f64"), [0u8; 40]).unwrap();
    for file in ["p.npy", "p.csv", "p.f64"] {
        let (ok, text) = mpirun(2, &["tree", "--points", &path(file), "--leaf-size", "30"]);
        assert!(
            ok && text.contains(&format!("total {n} points")),
            "{file}: {text}"
        );
        let leaves: Vec<&str> = text.lines().filter(|l| l.contains("leaves")).collect();
        totals.push(leaves.len());
    }
    assert_eq!(totals, [2, 2, 2]);
    for (file, needle) in [
        (
            "ragged.csv",
            "ragged.csv, line 1: expected 3 values (x, y, z), found 2",
        ),
        (
            "six.csv",
            "six.csv, line 2: expected 3 values (x, y, z), found 6",
        ),
        ("binary.csv", "not UTF-8"),
        (
            "short.f64",
            "short.f64: 40 bytes are not a whole number of points (raw .f64: 24 bytes each",
        ),
        ("d.csv", "is a directory"),
        ("missing.npy", "No such file"),
    ] {
        let (ok, text) = mpirun(2, &["tree", "--points", &path(file)]);
        assert!(!ok && text.contains(needle), "{file}: {text}");
        let errors = text.lines().filter(|l| l.starts_with("error:")).count();
        assert_eq!(errors, 1, "{file}: {text}");
        assert!(!text.contains("NaN"), "{file}: {text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `ferrofmm-mpi eval` on every file form `ferrofmm eval` reads
/// (`ferrofmm_testing::files`, as in the CLI's `file_forms` tests): on 1
/// rank, each form of points and charges (real for Laplace, complex for
/// Helmholtz) gives the same values, those of a direct sum; a complex
/// `.npy` of charges gives a complex128 output; on 2 ranks, a big-endian
/// Fortran-order complex64 file and raw points give the 1-rank values.
/// Every malformed file of the shared table gets its message, once.
#[test]
fn eval_reads_every_file_form_as_ferrofmm_eval_does() {
    use ferrofmm_testing::errors::relative_l2;
    use ferrofmm_testing::files::{Table, direct, f32_exact, malformed, write_forms};
    let scratch = ferrofmm_testing::TempDir::new("mpi-file-forms");
    let dir: &std::path::Path = &scratch;
    let n = 240;
    let k = 2.0;
    let points = f32_exact(&ferrofmm_testing::points::uniform_cube(n, 0.0, 1.0, 21));
    let charges = f32_exact(&ferrofmm_testing::charges::uniform_in(n, -0.5, 0.5, 22));
    let complex = f32_exact(&ferrofmm_testing::charges::uniform_in(2 * n, -0.5, 0.5, 23));
    let point_forms = write_forms(dir, "p", &points, Table::Real(3));
    let charge_forms = write_forms(dir, "q", &charges, Table::Real(1));
    let complex_forms = write_forms(dir, "z", &complex, Table::Complex);
    let out = dir.join("out.npy");
    let cache = dir.join("cache");
    let eval = |ranks: usize, p: &std::path::Path, q: &std::path::Path, kernel: &str| {
        let _ = std::fs::remove_file(&out);
        let args = [
            "eval",
            "--sources",
            p.to_str().unwrap(),
            "--charges",
            q.to_str().unwrap(),
            "--kernel",
            kernel,
            "--order",
            "6",
            "--leaf-size",
            "40",
            "--scheme",
            "fft",
            "--cache-dir",
            cache.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        let (ok, text) = mpirun(ranks, &args);
        assert!(ok, "{args:?}: {text}");
        let npy = npyz::NpyFile::new(std::fs::File::open(&out).unwrap()).unwrap();
        let shape = npy.shape().to_vec();
        let complex_output = npy.dtype().descr() == "'<c16'";
        let values: Vec<f64> = if complex_output {
            npy.into_vec::<npyz::num_complex::Complex<f64>>()
                .unwrap()
                .iter()
                .flat_map(|c| [c.re, c.im])
                .collect()
        } else {
            npy.into_vec::<f64>().unwrap()
        };
        (complex_output, shape, values)
    };
    let cycle = |forms: &[(String, std::path::PathBuf)], i: usize| forms[i % forms.len()].clone();

    let reference = direct(&points, &charges, None);
    for i in 0..point_forms.len().max(charge_forms.len()) {
        let ((p_label, p), (q_label, q)) = (cycle(&point_forms, i), cycle(&charge_forms, i));
        let (complex_output, shape, values) = eval(1, &p, &q, "laplace");
        assert!(!complex_output && shape == [n as u64], "{shape:?}");
        let e = relative_l2(&values, &reference);
        assert!(e < 1e-4, "points {p_label}, charges {q_label}: {e:e}");
    }
    let kernel = format!("helmholtz:{k}");
    let real_parts: Vec<f64> = complex.iter().step_by(2).flat_map(|&r| [r, 0.0]).collect();
    let references = [
        direct(&points, &complex, Some(k)),
        direct(&points, &real_parts, Some(k)),
    ];
    let mut one_rank = None;
    for (i, (label, q)) in complex_forms.iter().enumerate() {
        let (p_label, p) = cycle(&point_forms, i);
        let (complex_output, shape, values) = eval(1, &p, q, &kernel);
        let complex_dtype = label.contains("c16") || label.contains("c8");
        assert_eq!(complex_output, complex_dtype, "{label}");
        let rows = if complex_dtype {
            vec![n as u64]
        } else {
            vec![n as u64, 2]
        };
        assert_eq!(shape, rows, "{label}");
        let which = usize::from(label.starts_with("real-"));
        let e = relative_l2(&values, &references[which]);
        assert!(e < 1e-4, "points {p_label}, charges {label}: {e:e}");
        if label == "npy-bec8-f" {
            one_rank = Some((p, q.clone(), values));
        }
    }
    let (_, q, one) = one_rank.expect("a big-endian Fortran complex64 form");
    let raw = dir.join("p-raw.f64");
    let (complex_output, _, two) = eval(2, &raw, &q, &kernel);
    assert!(complex_output);
    let d = relative_l2(&two, &one);
    assert!(d < 1e-12, "2 ranks differ from 1: {d:e}");

    let good_points = dir.join("good-p.csv");
    let good_charges = dir.join("good-q.csv");
    std::fs::write(&good_points, "0,0,0\n1,0,0\n0,1,0\n0,0,1\n").unwrap();
    std::fs::write(&good_charges, "1\n2\n3\n4\n").unwrap();
    for case in malformed(dir) {
        let bad = case.path.to_str().unwrap();
        let (sources, charges) = match case.what.as_str() {
            "points" => (bad, good_charges.to_str().unwrap()),
            _ => (good_points.to_str().unwrap(), bad),
        };
        let args = [
            "eval",
            "--sources",
            sources,
            "--charges",
            charges,
            "--kernel",
            &case.kernel,
            "--out",
            out.to_str().unwrap(),
        ];
        let _ = std::fs::remove_file(&out);
        let (ok, text) = mpirun(1, &args);
        let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
        assert!(
            !ok && errors.len() == 1
                && errors[0].starts_with(&format!("error: {bad}"))
                && errors[0].contains(&case.message),
            "{args:?}: '{}' expected in {text}",
            case.message
        );
        assert!(!out.exists());
    }
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
    let rel = |a: &[f64], b: &[f64]| {
        let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
        let den: f64 = b.iter().map(|x| x * x).sum();
        (num / den).sqrt()
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
    assert!(rel(&three, &one) <= 1e-12, "{}", rel(&three, &one));
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
        rel(&one, &single) <= 1e-12,
        "{} (against a direct sum: {} and {})",
        rel(&one, &single),
        rel(&one, &direct),
        rel(&single, &direct)
    );
    let eps = 1e-5;
    let checked = run(2, "oe.npy", &["--tolerance", "1e-5"]);
    let pot = |v: &[f64]| v.chunks(4).map(|r| r[0]).collect::<Vec<_>>();
    assert!(rel(&pot(&checked), &pot(&direct)) <= eps);
    assert!(rel(&checked, &direct) <= 2.0 * eps);
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
