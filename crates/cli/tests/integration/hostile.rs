//! Hostile inputs that once gave a silent wrong answer or exit status 0:
//! `--precision f32` on points far from the origin (every potential 0 at
//! 1e8, and `--check` agreeing), sums that overflow (NaN written, exit 0),
//! and a wavenumber limit printed as `0.0000`.

use crate::common;

use common::{ferrofmm, read_npy, scratch, texts, write_npy};
use ferrofmm_kernels::{EvalMode, Laplace3d, direct_sum};
use ferrofmm_testing::errors::relative_l2;

fn s(p: &std::path::Path) -> String {
    p.to_str().unwrap().to_string()
}

/// The unit cube shifted by `shift`, and zero-mean charges.
fn shifted_cube(n: usize, shift: f64) -> (Vec<f64>, Vec<f64>) {
    let p = ferrofmm_testing::points::uniform_cube(n, shift, 1.0, 11);
    let q = ferrofmm_testing::charges::uniform_in(n, -0.5, 0.5, 12);
    (p, q)
}

#[test]
fn f32_on_points_far_from_the_origin_is_right_and_checked_against_the_truth() {
    let dir = scratch("hostile-f32-offset");
    let n = 2000;
    for shift in [1e4, 1e8] {
        let (p, q) = shifted_cube(n, shift);
        let (pp, qp, op) = (dir.join("p.npy"), dir.join("q.npy"), dir.join("o.npy"));
        write_npy(&pp, &p, &[n as u64, 3]);
        write_npy(&qp, &q, &[n as u64]);
        let out = ferrofmm(&[
            "eval",
            "--sources",
            &s(&pp),
            "--charges",
            &s(&qp),
            "--out",
            &s(&op),
            "--precision",
            "f32",
            "--order",
            "5",
            "--leaf-size",
            "64",
            "--check",
            "300",
            "--json",
        ]);
        let (stdout, stderr) = texts(&out);
        assert!(out.status.success(), "shift {shift}: {stderr}");
        let mut want = vec![0.0; n];
        direct_sum(&Laplace3d, EvalMode::Potential, &p, &q, &p, &mut want);
        let (_, got) = read_npy(&op);
        let truth = relative_l2(&got, &want);
        assert!(truth < 1e-3, "shift {shift}: true error {truth:e}");
        let report: serde_json::Value =
            serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
        let checked = report["errors"]["potential"].as_f64().unwrap();
        // --check samples 300 targets of the same truth: same size.
        assert!(
            checked > 0.0 && checked < 3.0 * truth + 1e-7 && truth < 3.0 * checked + 1e-7,
            "shift {shift}: --check says {checked:e}, the truth is {truth:e}"
        );
    }
}

#[test]
fn overflowing_sums_fail_without_writing() {
    let dir = scratch("hostile-overflow");
    let n = 800;
    let (p, q) = shifted_cube(n, 0.0);
    let huge: Vec<f64> = q.iter().map(|x| (x.abs() + 0.5) * 1e307).collect();
    let (pp, qp, op) = (dir.join("p.npy"), dir.join("q.npy"), dir.join("o.npy"));
    write_npy(&pp, &p, &[n as u64, 3]);
    write_npy(&qp, &huge, &[n as u64]);
    for precision in ["f64", "f32"] {
        let out = ferrofmm(&[
            "eval",
            "--sources",
            &s(&pp),
            "--charges",
            &s(&qp),
            "--out",
            &s(&op),
            "--order",
            "4",
            "--precision",
            precision,
        ]);
        let (_, stderr) = texts(&out);
        assert_eq!(out.status.code(), Some(1), "{precision}: {stderr}");
        assert!(
            stderr.contains("overflowed f64") || stderr.contains("exceeds the largest f32"),
            "{precision}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!op.exists(), "{precision}: output written");
    }
}

#[test]
fn the_wavenumber_limit_is_printed_in_scientific_notation() {
    let out = ferrofmm(&[
        "demo",
        "--n",
        "2000",
        "--kernel",
        "helmholtz:1e6",
        "--order",
        "4",
    ]);
    let (_, stderr) = texts(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("narrower than 1.000e-4"), "{stderr}");
    assert!(!stderr.contains("0.0000"), "{stderr}");
}
