//! What `eval` reads: every file form, and hostile input refused on
//! every rank.

use crate::common::*;

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
    // A periodic cell: refused with where it runs, not as an unknown
    // argument (round 3, issue 32).
    for (ranks, extra) in [(1, ["--box", "1"]), (2, ["--periodic", "xyz"])] {
        let args = base(&extra);
        let label = extra[0];
        expect_error(
            label,
            mpirun(ranks, &refs(&args)),
            "not in the distributed FMM yet",
        );
    }
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
    // Row 13: dipoles for Stokes are force dipoles, nine values per
    // source, as on one machine (f.npy holds three).
    let f = path("f.npy");
    let args = [
        "eval",
        "--sources",
        &s,
        "--charges",
        &f,
        "--order",
        "3",
        "--kernel",
        "stokes",
        "--dipoles",
        &f,
    ];
    expect_error(
        "stokes dipoles",
        mpirun(2, &args),
        "(N, 9) array of dipoles",
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
    use ferrofmm_testing::files::{Table, direct, eval_args, f32_exact, malformed, write_forms};
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
        let args = eval_args(p, q, kernel, &cache, &out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
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
