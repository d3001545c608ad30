//! `ferrofmm demo`: the table and the JSON report.

use crate::common;

use common::{ferrofmm, texts};

#[test]
fn demo_json_last_line_has_the_expected_keys() {
    let out = ferrofmm(&[
        "demo",
        "--n",
        "2000",
        "--order",
        "4",
        "--leaf-size",
        "64",
        "--json",
        "--repeats",
        "2",
    ]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    let last = stdout.lines().last().expect("output");
    let v: serde_json::Value = serde_json::from_str(last).expect("the last line is JSON");
    for key in [
        "command",
        "geometry",
        "n_sources",
        "n_targets",
        "order",
        "leaf_size",
        "scheme",
        "precision",
        "gradients",
        "threads",
        "tree",
        "setup",
        "evaluation",
        "errors",
        "direct_check_s",
        "peak_rss_bytes",
        "wall_s",
    ] {
        assert!(v.get(key).is_some(), "key {key} missing from {last}");
    }
    assert_eq!(v["command"], "demo");
    assert_eq!(v["n_sources"], 2000);
    assert_eq!(v["geometry"], "cube");
    assert_eq!(v["gradients"], true);
    for key in [
        "depth",
        "n_leaves",
        "n_boxes",
        "n_surface",
        "u_list",
        "v_list",
        "w_list",
        "x_list",
        "m2l_bytes",
    ] {
        assert!(v["tree"][key].is_u64(), "tree.{key}");
    }
    for key in [
        "tree_s",
        "operators_s",
        "m2l_precompute_s",
        "layout_s",
        "total_s",
    ] {
        assert!(v["setup"][key].as_f64().unwrap() >= 0.0, "setup.{key}");
    }
    assert_eq!(v["evaluation"]["repeats"], 2);
    assert!(
        v["evaluation"]["best_s"].as_f64().unwrap()
            <= v["evaluation"]["median_s"].as_f64().unwrap()
    );
    for key in ["p2m", "m2m", "m2l", "p2l", "l2l", "l2p", "m2p", "p2p"] {
        assert!(
            v["evaluation"]["operators_s"][key].as_f64().unwrap() >= 0.0,
            "operators_s.{key}"
        );
    }
    assert_eq!(v["errors"]["n_sampled"], 1000);
    let pot = v["errors"]["potential"].as_f64().unwrap();
    let grad = v["errors"]["gradient"].as_f64().unwrap();
    assert!(pot > 0.0 && pot < 1e-3, "order 4 potential error {pot}");
    assert!(grad > 0.0 && grad < 1e-1, "order 4 gradient error {grad}");
    if cfg!(target_os = "linux") {
        assert!(v["peak_rss_bytes"].as_u64().unwrap() > 1 << 20);
    }
    // Memory by component: the parts add up to the total, per point too;
    // in f64 the FMM's points (one sorted copy, one permutation: 32 bytes
    // a point) stand in for the caller's, which are not kept.
    let m = &v["memory"];
    assert_eq!(m["n_points"], 2000);
    let parts: u64 = [
        "points",
        "tree",
        "expansions",
        "evaluation_scratch",
        "m2l_interactions",
        "operators",
        "m2l",
        "inputs",
    ]
    .iter()
    .map(|k| m[k].as_u64().unwrap_or_else(|| panic!("memory.{k}")))
    .sum();
    assert_eq!(parts, m["total"].as_u64().unwrap());
    assert_eq!(m["points"], 2000 * 32);
    assert_eq!(m["inputs"], 2000 * 8, "the charges only");
    let per = m["bytes_per_point"].as_f64().unwrap();
    assert!((per - parts as f64 / 2000.0).abs() < 1e-9);
}

#[test]
fn demo_table_is_readable() {
    let out = ferrofmm(&[
        "demo",
        "--n",
        "2000",
        "--order",
        "3",
        "--geometry",
        "sphere",
        "--precision",
        "f32",
        "--scheme",
        "dense",
        "--no-gradients",
        "--threads",
        "1",
    ]);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    for needle in [
        "ferrofmm demo: Laplace 1/(4 pi r), potential, f32",
        "2,000 (sphere)",
        "dense M2L",
        "threads            1",
        "M2L precompute",
        "P2P",
        "relative L2 error vs direct summation (1000 sampled targets",
        "potential",
        "peak memory",
        "memory by component   bytes a point (MiB), 2,000 points",
        "  points                   20.0", // f32 points and a permutation
        "  inputs                   28.0", // f32 charges and the f64 points
    ] {
        assert!(
            stdout.contains(needle),
            "'{needle}' missing from:\n{stdout}"
        );
    }
    assert!(
        !stdout.contains("gradient "),
        "no gradient without gradients:\n{stdout}"
    );
}

#[test]
fn help_is_readable() {
    let out = ferrofmm(&["--help"]);
    let (stdout, _) = texts(&out);
    assert!(out.status.success());
    for needle in ["demo", "eval", "sweep", "--threads", "Exit status"] {
        assert!(
            stdout.contains(needle),
            "'{needle}' missing from --help:\n{stdout}"
        );
    }
    for (cmd, needles) in [
        (
            "demo",
            vec![
                "--n",
                "--geometry",
                "--order",
                "--precision",
                "--leaf-size",
                "--scheme",
                "--no-gradients",
                "--json",
            ],
        ),
        (
            "eval",
            vec![
                "--sources",
                "--targets",
                "--charges",
                "--out",
                "--gradients",
                ".npy",
                "header",
            ],
        ),
        (
            "sweep",
            vec![
                "--orders",
                "--schemes",
                "--leaf-sizes",
                "--repeats",
                "--out-dir",
                "results.csv",
            ],
        ),
    ] {
        let out = ferrofmm(&[cmd, "--help"]);
        let (stdout, _) = texts(&out);
        assert!(out.status.success());
        for n in needles {
            assert!(
                stdout.contains(n),
                "'{n}' missing from {cmd} --help:\n{stdout}"
            );
        }
    }
}

#[test]
fn demo_tolerance_chooses_parameters_that_meet_it() {
    for (eps, precision) in [("1e-3", "f32"), ("1e-7", "f64")] {
        let out = ferrofmm(&[
            "demo",
            "--n",
            "3000",
            "--tolerance",
            eps,
            "--precision",
            "auto",
            "--json",
        ]);
        let (stdout, stderr) = texts(&out);
        assert!(out.status.success(), "{stderr}");
        let v: serde_json::Value =
            serde_json::from_str(stdout.lines().last().expect("output")).expect("JSON");
        let eps: f64 = eps.parse().unwrap();
        assert_eq!(v["tolerance"].as_f64(), Some(eps));
        assert_eq!(v["precision"], precision, "auto precision for {eps}");
        let achieved = v["errors"]["potential"].as_f64().expect("error");
        assert!(achieved <= eps, "asked {eps}, got {achieved}");
        assert!(v["predicted_error"].as_f64().expect("prediction") <= eps);
    }
    let out = ferrofmm(&["demo", "--n", "100", "--tolerance", "0"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(texts(&out).1.contains("tolerance"));
}

/// Every kernel of the registry by its name on the command line: parsed,
/// run with the scheme its `auto` resolves to, checked against direct
/// summation, and named back in the report; a kernel registered tomorrow
/// is run here without a new line.
#[test]
fn every_registered_kernel_runs_by_name() {
    for d in ferrofmm_kernels::KernelChoice::registered() {
        let name = d.example().name();
        let out = ferrofmm(&[
            "demo",
            "--n",
            "2000",
            "--kernel",
            &name,
            "--tolerance",
            "1e-4",
            "--json",
        ]);
        let (stdout, stderr) = texts(&out);
        assert!(out.status.success(), "{name}: {stderr}");
        let v: serde_json::Value =
            serde_json::from_str(stdout.lines().last().expect("output")).expect("JSON");
        let achieved = v["errors"]["potential"].as_f64().expect("error");
        assert!(achieved <= 1e-4, "{name}: asked 1e-4, got {achieved}");
        let expected = ferrofmm_fmm::SchemeChoice::Auto
            .resolve(
                d.example(),
                None,
                None,
                None,
                ferrofmm_kernels::EvalMode::Potential,
                ferrofmm_kernels::Precision::F64,
                false,
                None,
            )
            .unwrap();
        if expected == ferrofmm_fmm::SchemeChoice::Fft {
            assert_eq!(v["scheme"], "fft", "{name}");
        }
        for alias in d.aliases {
            let renamed = name.replacen(d.name, alias, 1);
            assert!(
                ferrofmm_kernels::KernelChoice::parse(&renamed).is_ok(),
                "{renamed}"
            );
        }
    }
    let out = ferrofmm(&["demo", "--n", "100", "--kernel", "coulomb"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        texts(&out).1.contains("laplace"),
        "the message lists the kernels"
    );
}
