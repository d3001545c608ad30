//! `--kernel`, `--dipoles` and `--hessians`: the outputs, column by column,
//! against direct summation, and bad input.

mod common;

use common::{charges, ferrofmm, points, read_npy, scratch, texts, write_csv, write_npy};
use ferrofmm_kernels::{EvalMode, Laplace3d, ModifiedHelmholtz3d, SourceKind, direct_sum_sources};
use ferrofmm_testing::errors::relative_l2_columns;

const N: usize = 3000;

#[test]
fn dipoles_charges_and_hessians_match_direct_summation() {
    let dir = scratch("physics");
    let sources = points(N, 3);
    let q = charges(N, 4);
    let n = charges(3 * N, 5);
    let targets = points(500, 6);
    let (src, chg_path, dip, tgt) = (
        dir.join("s.npy"),
        dir.join("q.npy"),
        dir.join("n.csv"),
        dir.join("t.npy"),
    );
    write_npy(&src, &sources, &[N as u64, 3]);
    write_npy(&chg_path, &q, &[N as u64]);
    write_csv(&dip, &n, 3, Some("nx,ny,nz"));
    write_npy(&tgt, &targets, &[500, 3]);
    let both: Vec<f64> = (0..N)
        .flat_map(|i| [q[i], n[3 * i], n[3 * i + 1], n[3 * i + 2]])
        .collect();
    let yukawa = ModifiedHelmholtz3d::new(3.0).unwrap();
    let mode = EvalMode::PotentialGradientHessian;
    for (kernel, with_charges) in [("laplace", true), ("yukawa:3", false)] {
        let out = dir.join(format!("{kernel}.npy").replace(':', "_"));
        let mut args = vec![
            "eval",
            "--sources",
            src.to_str().unwrap(),
            "--targets",
            tgt.to_str().unwrap(),
            "--dipoles",
            dip.to_str().unwrap(),
            "--kernel",
            kernel,
            "--hessians",
            "--order",
            "7",
            "--check",
            "200",
            "--json",
            "--out",
            out.to_str().unwrap(),
        ];
        if with_charges {
            args.extend(["--charges", chg_path.to_str().unwrap()]);
        }
        let o = ferrofmm(&args);
        let (stdout, stderr) = texts(&o);
        assert!(o.status.success(), "{kernel}: {stderr}");
        let json = stdout.lines().last().unwrap();
        let kind = if with_charges {
            "charge+dipole"
        } else {
            "dipole"
        };
        assert!(json.contains(&format!("\"sources\":\"{kind}\"")), "{json}");
        assert!(json.contains("\"hessians\":true"), "{json}");
        assert!(json.contains(&format!("\"kernel\":\"{kernel}\"")), "{json}");
        let (shape, values) = read_npy(&out);
        assert_eq!(shape, vec![500, 10]);
        let (kind, dens) = if with_charges {
            (SourceKind::ChargeDipole, &both)
        } else {
            (SourceKind::Dipole, &n)
        };
        let mut reference = vec![0.0; 10 * 500];
        if kernel == "laplace" {
            direct_sum_sources(
                &Laplace3d,
                kind,
                mode,
                &sources,
                dens,
                &targets,
                &mut reference,
            );
        } else {
            direct_sum_sources(
                &yukawa,
                kind,
                mode,
                &sources,
                dens,
                &targets,
                &mut reference,
            );
        }
        // Column by column: potential, gradient, Hessian (order 7: ~1e-6).
        for c in 0..10 {
            let e = relative_l2_columns(&values, &reference, 10, c..c + 1);
            assert!(e < 1e-4, "{kernel} column {c}: {e:e}");
        }
    }
}

#[test]
fn demo_runs_yukawa_with_hessians_and_reports_the_error() {
    let o = ferrofmm(&[
        "demo",
        "--n",
        "4000",
        "--kernel",
        "yukawa:2",
        "--hessians",
        "--order",
        "6",
        "--check",
        "100",
    ]);
    let (stdout, stderr) = texts(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("modified Helmholtz"), "{stdout}");
    let line = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("Hessian"))
        .expect(&stdout);
    let e: f64 = line.split_whitespace().last().unwrap().parse().unwrap();
    assert!(e < 1e-3, "{line}");
}

#[test]
fn bad_kernels_and_dipole_files_are_clear_errors() {
    let dir = scratch("physics-bad");
    let sources = points(50, 1);
    let src = dir.join("s.npy");
    write_npy(&src, &sources, &[50, 3]);
    let short = dir.join("short.npy");
    write_npy(&short, &charges(3 * 49, 2), &[49, 3]);
    let flat = dir.join("flat.npy");
    write_npy(&flat, &charges(50, 2), &[50]);
    let out = dir.join("o.npy");
    let base = [
        "eval",
        "--sources",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    for (extra, needle) in [
        (vec!["--dipoles", short.to_str().unwrap()], "49 dipoles"),
        (
            vec!["--dipoles", flat.to_str().unwrap()],
            "(N, 3) array of dipoles",
        ),
        (
            vec![
                "--dipoles",
                short.to_str().unwrap(),
                "--kernel",
                "helmholtz:3",
            ],
            "not available yet",
        ),
        (
            vec![
                "--dipoles",
                short.to_str().unwrap(),
                "--kernel",
                "yukawa:-1",
            ],
            "yukawa:-1",
        ),
        (
            vec!["--dipoles", short.to_str().unwrap(), "--kernel", "yukawa"],
            "wavenumber",
        ),
        (vec![], "--charges"),
    ] {
        let mut args = base.to_vec();
        args.extend(extra.iter().copied());
        let o = ferrofmm(&args);
        let (_, stderr) = texts(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!out.exists());
    }
}
