//! `ferrofmm eval` on small problems matches direct summation to the
//! accuracy of the expansion order, in every file format and precision.

use crate::common;

use common::{charges, ferrofmm, points, read_npy, scratch, texts, write_csv, write_npy};
use ferrofmm_kernels::{EvalMode, Laplace3d, direct_sum};
use ferrofmm_testing::errors::relative_l2_columns;

const N: usize = 2000;

/// Read the output file (either format) as (rows, columns, values).
fn read_output(path: &std::path::Path) -> (usize, usize, Vec<f64>) {
    if path.extension().unwrap() == "npy" {
        let (shape, v) = read_npy(path);
        let cols = if shape.len() == 1 {
            1
        } else {
            shape[1] as usize
        };
        (shape[0] as usize, cols, v)
    } else {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        let cols = header.split(',').count();
        let v: Vec<f64> = lines
            .flat_map(|l| {
                l.split(',')
                    .map(|f| f.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect();
        (v.len() / cols, cols, v)
    }
}

#[test]
fn eval_matches_direct_summation() {
    let dir = scratch("eval");
    let sources = points(N, 1);
    let q = charges(N, 99);
    let targets = points(700, 2);
    // A target on a source: the coincident pair must be skipped, not blow up.
    let mut targets = targets;
    targets[..3].copy_from_slice(&sources[30..33]);

    let src_csv = dir.join("sources.csv");
    let src_npy = dir.join("sources.npy");
    let q_csv = dir.join("charges.csv");
    let q_npy = dir.join("charges.npy");
    let tgt_npy = dir.join("targets.npy");
    write_csv(&src_csv, &sources, 3, Some("x,y,z"));
    write_npy(&src_npy, &sources, &[N as u64, 3]);
    write_csv(&q_csv, &q, 1, Some("charge"));
    write_npy(&q_npy, &q, &[N as u64]);
    write_npy(&tgt_npy, &targets, &[700, 3]);

    let mut reference_self = vec![0.0; 4 * N];
    direct_sum(
        &Laplace3d,
        EvalMode::PotentialGradient,
        &sources,
        &q,
        &sources,
        &mut reference_self,
    );
    let mut reference_tgt = vec![0.0; 4 * 700];
    direct_sum(
        &Laplace3d,
        EvalMode::PotentialGradient,
        &sources,
        &q,
        &targets,
        &mut reference_tgt,
    );

    // (sources, charges, targets, out, precision, scheme, gradients, potential bound, gradient bound)
    let cases = [
        (
            &src_csv, &q_csv, None, "a.npy", "f64", "svd", true, 1e-4, 1e-3,
        ),
        (
            &src_npy, &q_npy, None, "b.csv", "f64", "dense", false, 1e-4, 0.0,
        ),
        (
            &src_npy,
            &q_csv,
            Some(&tgt_npy),
            "c.npy",
            "f32",
            "svd",
            true,
            1e-4,
            1e-3,
        ),
        (
            &src_csv,
            &q_npy,
            Some(&tgt_npy),
            "d.csv",
            "f64",
            "svd",
            true,
            1e-4,
            1e-3,
        ),
    ];
    for (src, chg, tgt, out, precision, scheme, gradients, pot_bound, grad_bound) in cases {
        let out_path = dir.join(out);
        let mut args = vec![
            "eval".to_string(),
            "--sources".into(),
            src.to_str().unwrap().into(),
            "--charges".into(),
            chg.to_str().unwrap().into(),
            "--out".into(),
            out_path.to_str().unwrap().into(),
            "--order".into(),
            "6".into(),
            "--leaf-size".into(),
            "64".into(),
            "--precision".into(),
            precision.into(),
            "--scheme".into(),
            scheme.into(),
            "--json".into(),
        ];
        if let Some(t) = tgt {
            args.extend(["--targets".into(), t.to_str().unwrap().into()]);
        }
        if gradients {
            args.push("--gradients".into());
        }
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let result = ferrofmm(&refs);
        let (stdout, stderr) = texts(&result);
        assert!(result.status.success(), "{args:?}: {stderr}");

        // --json: the last line is the report.
        let report: serde_json::Value =
            serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
        assert_eq!(report["command"], "eval");
        assert_eq!(report["precision"], precision);
        assert_eq!(report["scheme"], scheme);
        assert_eq!(report["order"], 6);
        assert!(report["tree"]["n_leaves"].as_u64().unwrap() > 1);
        assert!(report["setup"]["total_s"].as_f64().unwrap() > 0.0);

        let (reference, n_targets) = match tgt {
            Some(_) => (&reference_tgt, 700),
            None => (&reference_self, N),
        };
        let (rows, cols, values) = read_output(&out_path);
        assert_eq!(rows, n_targets, "{out}");
        assert_eq!(cols, if gradients { 4 } else { 1 }, "{out}");
        if out.ends_with(".npy") {
            let (_, raw) = read_npy(&out_path);
            assert_eq!(raw.len(), rows * cols);
            let dtype = npyz::NpyFile::new(std::fs::File::open(&out_path).unwrap())
                .unwrap()
                .dtype();
            let expect = if precision == "f32" { "'<f4'" } else { "'<f8'" };
            assert_eq!(dtype.descr(), expect, "output in the run's precision");
        }
        let reference: Vec<f64> = if gradients {
            reference.clone()
        } else {
            reference.iter().step_by(4).copied().collect()
        };
        let e_pot = relative_l2_columns(&values, &reference, cols, 0..1);
        assert!(
            e_pot <= pot_bound,
            "{out}: potential error {e_pot:.2e} > {pot_bound:.0e}"
        );
        assert!(values.iter().all(|v| v.is_finite()));
        if gradients {
            let e_grad = relative_l2_columns(&values, &reference, 4, 1..4);
            assert!(
                e_grad <= grad_bound,
                "{out}: gradient error {e_grad:.2e} > {grad_bound:.0e}"
            );
        }
    }
}

#[test]
fn eval_error_falls_with_order_and_check_reports_it() {
    // A low order must be measurably worse than a high one: the comparison
    // against direct summation can fail.
    let dir = scratch("eval-orders");
    let sources = points(N, 5);
    let q = charges(N, 99);
    let src = dir.join("s.npy");
    let chg = dir.join("q.npy");
    write_npy(&src, &sources, &[N as u64, 3]);
    write_npy(&chg, &q, &[N as u64]);
    let mut reference = vec![0.0; N];
    direct_sum(
        &Laplace3d,
        EvalMode::Potential,
        &sources,
        &q,
        &sources,
        &mut reference,
    );
    let mut errors = Vec::new();
    for order in ["3", "7"] {
        let out = dir.join(format!("o{order}.npy"));
        let result = ferrofmm(&[
            "eval",
            "--sources",
            src.to_str().unwrap(),
            "--charges",
            chg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--order",
            order,
            "--leaf-size",
            "32",
            "--check",
            "500",
        ]);
        let (stdout, stderr) = texts(&result);
        assert!(result.status.success(), "{stderr}");
        assert!(
            stdout.contains("relative L2 error vs direct summation (500 sampled targets"),
            "{stdout}"
        );
        let (_, values) = read_npy(&out);
        errors.push(relative_l2_columns(&values, &reference, 1, 0..1));
    }
    assert!(
        errors[1] < errors[0] / 100.0,
        "errors do not fall with the order: {errors:?}"
    );
}
