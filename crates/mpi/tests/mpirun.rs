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
    let _one = MPI_JOB.lock().unwrap_or_else(|e| e.into_inner());
    let exe = env!("CARGO_BIN_EXE_ferrofmm-mpi");
    let mpirun = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let mut cmd = Command::new("timeout");
    cmd.arg("300").arg(&mpirun).arg("--oversubscribe");
    // Open MPI refuses to run as root without these (CI containers).
    cmd.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1");
    cmd.arg("-n").arg(ranks.to_string()).arg(exe).args(args);
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
    use ferrofmm_mpi::npy;
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-eval-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let n = 900;
    let pts: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.618_034).fract()).collect();
    let q: Vec<f64> = (0..n)
        .map(|i| ((i * 37) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let csv = |rows: &mut dyn Iterator<Item = String>| rows.collect::<Vec<_>>().join("\n");
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    std::fs::write(
        path("s.csv"),
        csv(&mut pts.chunks(3).map(|p| format!("{},{},{}", p[0], p[1], p[2]))),
    )
    .unwrap();
    std::fs::write(path("q.csv"), csv(&mut q.iter().map(|x| x.to_string()))).unwrap();
    std::fs::write(
        path("short.csv"),
        csv(&mut q[1..].iter().map(|x| x.to_string())),
    )
    .unwrap();
    for (name, values, cols) in [("s.npy", &pts, 3), ("q.npy", &q, 1)] {
        let start = npy::create(std::path::Path::new(&path(name)), n as u64, cols).unwrap();
        npy::write_rows(std::path::Path::new(&path(name)), start, cols, 0, values).unwrap();
    }
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
    let read = |name: &str| {
        let p = std::path::PathBuf::from(path(name));
        let h = npy::header(&p).unwrap();
        assert_eq!((h.rows, h.columns), (n as u64, 4));
        npy::read_rows(&p, &h, 0..h.rows).unwrap()
    };
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
        ],
    );
    let err = text
        .split("\"potential_error\":")
        .nth(1)
        .and_then(|t| t.split([',', '}']).next())
        .and_then(|t| t.parse::<f64>().ok());
    assert!(ok && err.is_some_and(|e| e < 1e-3), "{err:?}\n{text}");
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
    use ferrofmm_mpi::npy;
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
    for (name, values, cols) in [
        ("s.npy", &pts, 3),
        ("f.npy", &f, 3),
        ("z.npy", &f[..2 * n].to_vec(), 2),
    ] {
        let p = std::path::PathBuf::from(path(name));
        let start = npy::create(&p, n as u64, cols).unwrap();
        npy::write_rows(&p, start, cols, 0, values).unwrap();
    }
    let read = |name: &str, cols: u64| {
        let p = std::path::PathBuf::from(path(name));
        let h = npy::header(&p).unwrap();
        assert_eq!((h.rows, h.columns), (n as u64, cols));
        npy::read_rows(&p, &h, 0..h.rows).unwrap()
    };
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
