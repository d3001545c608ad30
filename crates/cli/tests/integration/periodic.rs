//! `--box`: periodic runs from the command line (issue 32).

use crate::common;

use common::{ferrofmm, scratch, texts, write_csv};

/// `ferrofmm demo --n 3000 --box 1 --check 300 --json` with `extra`
/// arguments and tolerance `eps`: its JSON report, after checking that the
/// sampled errors (against the Ewald sum) meet `eps`.
fn periodic_demo(extra: &[&str], eps: &str) -> serde_json::Value {
    let mut args = vec!["demo", "--n", "3000", "--box", "1", "--tolerance", eps];
    args.extend_from_slice(extra);
    args.extend(["--check", "300", "--json"]);
    let out = ferrofmm(&args);
    let (stdout, stderr) = texts(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value =
        serde_json::from_str(stdout.lines().last().expect("output")).expect("JSON");
    let eps: f64 = eps.parse().unwrap();
    let errors = &v["errors"];
    assert!(errors["potential"].as_f64().unwrap() <= eps, "{errors}");
    assert!(errors["gradient"].as_f64().unwrap() <= eps, "{errors}");
    v
}

#[test]
fn a_periodic_demo_meets_its_tolerance_against_ewald() {
    let v = periodic_demo(&[], "1e-5");
    let periodic = v["periodic"].as_str().expect("a periodic row");
    assert!(
        periodic.contains("xyz") && periodic.contains("tin-foil"),
        "{periodic}"
    );
    assert!(v["energy"].as_f64().expect("an energy").is_finite());
}

/// A slab and a rod, checked against their pairwise sums.
#[test]
fn slab_and_rod_demos_meet_their_tolerance() {
    for (axes, kind) in [("xy", "slab"), ("x", "rod")] {
        let v = periodic_demo(&["--periodic", axes], "1e-6");
        let periodic = v["periodic"].as_str().expect("a periodic row");
        assert!(
            periodic.contains(kind) && periodic.contains("no surface term"),
            "{periodic}"
        );
    }
}

/// Yukawa in a periodic cell with positive (not neutral) charges, checked
/// against the screened Ewald sum.
#[test]
fn a_periodic_yukawa_demo_with_positive_charges() {
    let v = periodic_demo(&["--kernel", "yukawa:4", "--charges", "positive"], "1e-6");
    let periodic = v["periodic"].as_str().expect("a periodic row");
    assert!(periodic.contains("screened"), "{periodic}");
}

/// Stokes in a periodic cell with positive forces (a net force, balanced
/// by the pressure), checked against Hasimoto's sum.
#[test]
fn a_periodic_stokes_demo_with_a_net_force() {
    let v = periodic_demo(&["--kernel", "stokes", "--charges", "positive"], "1e-4");
    let periodic = v["periodic"].as_str().expect("a periodic row");
    assert!(periodic.contains("Hasimoto"), "{periodic}");
}

#[test]
fn bad_boxes_and_charged_cells_are_refused() {
    for args in [
        vec!["demo", "--n", "100", "--box", "1,2,1"],
        vec!["demo", "--n", "100", "--box", "0"],
        vec!["demo", "--n", "100", "--box", "x"],
        vec![
            "demo",
            "--n",
            "100",
            "--box",
            "1",
            "--periodic",
            "xy",
            "--surface",
            "vacuum",
        ],
        vec![
            "demo",
            "--n",
            "100",
            "--box",
            "1",
            "--periodic",
            "x",
            "--kernel",
            "stokes",
        ],
        // The demo's points fill [0, 1)^3: outside a cell of side 0.5
        // along the open axis z.
        vec!["demo", "--n", "100", "--box", "0.5", "--periodic", "xy"],
        vec!["demo", "--n", "100", "--periodic", "xyz"],
        vec!["demo", "--n", "100", "--box", "1", "--surface", "metal"],
        vec![
            "demo",
            "--n",
            "100",
            "--box",
            "1",
            "--kernel",
            "helmholtz:2",
        ],
        vec![
            "demo",
            "--n",
            "100",
            "--box",
            "1",
            "--kernel",
            "yukawa:2",
            "--surface",
            "vacuum",
        ],
    ] {
        let out = ferrofmm(&args);
        let (_, stderr) = texts(&out);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(!stderr.trim().is_empty(), "{args:?}: no message");
    }
    // Given charges that do not sum to zero.
    let dir = scratch("periodic-charged");
    let points = dir.path().join("p.csv");
    let charges = dir.path().join("q.csv");
    write_csv(&points, &[0.1, 0.2, 0.3, 0.6, 0.7, 0.8], 3, None);
    write_csv(&charges, &[1.0, -0.5], 1, None);
    let out_path = dir.path().join("out.csv");
    let out = ferrofmm(&[
        "eval",
        "--sources",
        points.to_str().unwrap(),
        "--charges",
        charges.to_str().unwrap(),
        "--box",
        "1",
        "--out",
        out_path.to_str().unwrap(),
    ]);
    let (_, stderr) = texts(&out);
    assert!(!out.status.success());
    assert!(stderr.contains("not neutral"), "{stderr}");
}
