//! Bad files and impossible parameters: a one-line `error: ...` naming the
//! problem, exit status 1 (2 for command-line syntax), never a panic.

use crate::common;

use std::path::Path;

use common::{ferrofmm, points, scratch, texts, write_csv, write_npy};

/// Run `eval` with these files and expect failure mentioning every `needle`.
fn expect_failure(args: &[&str], needles: &[&str]) {
    let out = ferrofmm(args);
    let (stdout, stderr) = texts(&out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "args {args:?}: stdout {stdout} stderr {stderr}"
    );
    assert!(
        !stderr.contains("panicked") && !stderr.contains("internal error"),
        "panic for {args:?}: {stderr}"
    );
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected for {args:?}: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    for n in needles {
        assert!(lines[0].contains(n), "'{n}' missing from: {}", lines[0]);
    }
}

fn eval_args<'a>(sources: &'a str, charges: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "eval",
        "--sources",
        sources,
        "--charges",
        charges,
        "--out",
        out,
        "--order",
        "3",
    ]
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

#[test]
fn bad_files_are_named_with_the_problem() {
    let dir = scratch("bad-files");
    let good_p = dir.join("p.csv");
    let good_q = dir.join("q.csv");
    write_csv(&good_p, &points(4, 1), 3, Some("x,y,z"));
    write_csv(&good_q, &[1.0, 2.0, 3.0, 4.0], 1, None);
    let out = s(&dir.join("out.npy"));
    let (gp, gq) = (s(&good_p), s(&good_q));

    // Missing file.
    let missing = s(&dir.join("nope.csv"));
    expect_failure(
        &eval_args(&missing, &gq, &out),
        &["nope.csv", "No such file"],
    );

    // Ragged rows.
    let ragged = dir.join("ragged.csv");
    std::fs::write(&ragged, "x,y,z\n0,0,0\n1,1\n2,2,2\n").unwrap();
    expect_failure(
        &eval_args(&s(&ragged), &gq, &out),
        &[
            "ragged.csv",
            "line 3",
            "expected 3 values (x, y, z), found 2",
        ],
    );

    // Not a number.
    let text = dir.join("text.csv");
    std::fs::write(&text, "0,0,0\n1,one,1\n").unwrap();
    expect_failure(
        &eval_args(&s(&text), &gq, &out),
        &["line 2", "'one' is not a number"],
    );

    // NaN and Inf, in CSV and in NPY.
    let nan = dir.join("nan.csv");
    std::fs::write(&nan, "0,0,0\n1,1,1\n2,NaN,2\n3,3,3\n").unwrap();
    expect_failure(
        &eval_args(&s(&nan), &gq, &out),
        &["nan.csv", "line 3, column 2", "not finite"],
    );
    let inf_q = dir.join("inf.csv");
    std::fs::write(&inf_q, "1\n2\ninf\n4\n").unwrap();
    expect_failure(
        &eval_args(&gp, &s(&inf_q), &out),
        &["inf.csv", "line 3", "not finite (inf)"],
    );
    let nan_npy = dir.join("nan.npy");
    let mut p = points(4, 2);
    p[7] = f64::NAN;
    write_npy(&nan_npy, &p, &[4, 3]);
    expect_failure(
        &eval_args(&s(&nan_npy), &gq, &out),
        &["nan.npy", "element [2, 1]", "not finite"],
    );

    // Mismatched counts.
    let three = dir.join("three.csv");
    write_csv(&three, &[1.0, 2.0, 3.0], 1, Some("charge"));
    expect_failure(
        &eval_args(&gp, &s(&three), &out),
        &["three.csv holds 3 charges", "p.csv holds 4 points"],
    );

    // Empty files (nothing at all; only a header; an empty array).
    let empty = dir.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    expect_failure(
        &eval_args(&s(&empty), &gq, &out),
        &["empty.csv", "holds no points"],
    );
    let header_only = dir.join("header.csv");
    std::fs::write(&header_only, "charge\n\n").unwrap();
    expect_failure(
        &eval_args(&gp, &s(&header_only), &out),
        &["header.csv", "holds no charges"],
    );
    let empty_npy = dir.join("empty.npy");
    write_npy::<f64>(&empty_npy, &[], &[0, 3]);
    expect_failure(
        &eval_args(&s(&empty_npy), &gq, &out),
        &["empty.npy", "holds no points"],
    );

    // NPY of the wrong dtype, shape, or not NPY at all, or cut short.
    let ints = dir.join("ints.npy");
    write_npy(&ints, &[1i32, 2, 3, 4], &[4]);
    expect_failure(
        &eval_args(&gp, &s(&ints), &out),
        &["ints.npy", "unsupported dtype", "float64"],
    );
    let flat = dir.join("flat.npy");
    write_npy(&flat, &points(4, 3), &[12]);
    expect_failure(
        &eval_args(&s(&flat), &gq, &out),
        &["flat.npy", "(N, 3)", "shape (12)"],
    );
    let garbage = dir.join("garbage.npy");
    std::fs::write(&garbage, "x,y,z\n1,2,3\n").unwrap();
    expect_failure(
        &eval_args(&s(&garbage), &gq, &out),
        &["garbage.npy", "not a valid .npy file"],
    );
    let cut = dir.join("cut.npy");
    write_npy(&cut, &points(100, 4), &[100, 3]);
    let bytes = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() - 100]).unwrap();
    expect_failure(&eval_args(&s(&cut), &gq, &out), &["cut.npy"]);

    // Unknown extensions, in and out; an output directory that does not exist.
    let txt = dir.join("p.txt");
    std::fs::write(&txt, "1,2,3\n").unwrap();
    expect_failure(
        &eval_args(&s(&txt), &gq, &out),
        &["p.txt", "unknown file type"],
    );
    expect_failure(
        &eval_args(&gp, &gq, &s(&dir.join("out.dat"))),
        &["out.dat", "unknown file type"],
    );
    expect_failure(
        &eval_args(&gp, &gq, &s(&dir.join("no/such/dir/out.csv"))),
        &["does not exist"],
    );

    // Coordinates the tree cannot take still fail cleanly (targets file).
    let mut args = eval_args(&gp, &gq, &out);
    let bad_targets = s(&ragged);
    args.extend(["--targets", &bad_targets]);
    expect_failure(&args, &["ragged.csv", "line 3"]);
}

#[test]
fn impossible_parameters() {
    let dir = scratch("bad-params");
    let p = dir.join("p.csv");
    let q = dir.join("q.csv");
    write_csv(&p, &points(50, 1), 3, None);
    write_csv(&q, &[1.0; 50], 1, None);
    let (ps, qs, out) = (s(&p), s(&q), s(&dir.join("o.csv")));
    let eval = |extra: &[&str]| {
        let mut a = vec!["eval", "--sources", &ps, "--charges", &qs, "--out", &out];
        a.extend_from_slice(extra);
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |args: Vec<String>, needles: &[&str]| {
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        expect_failure(&refs, needles);
    };
    run(
        eval(&["--order", "1"]),
        &["expansion order 1 is not supported"],
    );
    run(
        eval(&["--order", "99"]),
        &["expansion order 99 is not supported"],
    );
    run(
        eval(&["--leaf-size", "0"]),
        &["leaf size must be at least 1"],
    );
    run(eval(&["--threads", "0"]), &["--threads must be at least 1"]);
    expect_failure(&["demo", "--n", "0"], &["--n must be at least 1"]);
    expect_failure(
        &["demo", "--n", "100", "--repeats", "0"],
        &["--repeats must be at least 1"],
    );
    let sweep_dir = s(&dir.join("sweep"));
    expect_failure(
        &[
            "sweep",
            "--n",
            "100",
            "--orders",
            "2,50",
            "--out-dir",
            &sweep_dir,
        ],
        &["order 50 is not supported"],
    );

    // Bad values of --charges, --verify and --tolerance: one line, status 1.
    expect_failure(
        &["demo", "--n", "100", "--charges", "negative"],
        &["--charges must be `signed` or `positive`", "negative"],
    );
    run(
        eval(&["--tolerance", "1e-4", "--verify", "maybe"]),
        &["--verify must be `on` or `off`", "maybe"],
    );
    for eps in ["0", "1", "1.5", "nan", "1e-30"] {
        run(eval(&["--tolerance", eps]), &["tolerance"]);
    }
    expect_failure(
        &[
            "sweep",
            "--n",
            "100",
            "--charges",
            "both",
            "--out-dir",
            &sweep_dir,
        ],
        &["--charges must be"],
    );
    assert!(
        !dir.join("o.csv").exists(),
        "nothing is written on bad input"
    );

    // Syntax errors are clap's: status 2, no panic.
    for args in [
        vec!["demo", "--order", "six"],
        vec!["demo", "--geometry", "donut"],
        vec!["sweep", "--orders", "9..3", "--out-dir", "x"],
        vec!["eval", "--sources", "p.csv"],
        vec!["frobnicate"],
    ] {
        let out = ferrofmm(&args);
        let (_, stderr) = texts(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("panicked") && !stderr.contains("internal error"),
            "{stderr}"
        );
    }
}
