//! `eval --kernel stokes --strslet --strsvec --pressure` (issue 35): the
//! output's columns against FMM3D's formulas summed directly here, the
//! report's own check, and the refusals.

use std::f64::consts::PI;

use crate::common;

use common::{charges, ferrofmm, points, read_npy, scratch, texts, write_csv, write_npy};

const N: usize = 4000;

/// `[u (3), p]` at `y` of forces `f` and stresslets `(m, n)` at `x` (all
/// sources but coincident ones), FMM3D's `stfmm3d` at viscosity 1.
fn direct(x: &[f64], f: &[f64], m: &[f64], n: &[f64], y: &[f64]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for i in 0..x.len() / 3 {
        let d: Vec<f64> = (0..3).map(|a| y[a] - x[3 * i + a]).collect();
        let r2: f64 = d.iter().map(|v| v * v).sum();
        if r2 == 0.0 {
            continue;
        }
        let r = r2.sqrt();
        let dot = |v: &[f64]| (0..3).map(|a| d[a] * v[3 * i + a]).sum::<f64>();
        let (df, dm, dn) = (dot(f), dot(m), dot(n));
        let mn: f64 = (0..3).map(|a| m[3 * i + a] * n[3 * i + a]).sum();
        for a in 0..3 {
            out[a] += (f[3 * i + a] / r + d[a] * df / (r * r2)) / (8.0 * PI)
                + 3.0 * d[a] * dm * dn / (4.0 * PI * r2 * r2 * r);
        }
        out[3] += df / (4.0 * PI * r * r2)
            + (6.0 * dm * dn / (r2 * r2 * r) - 2.0 * mn / (r * r2)) / (4.0 * PI);
    }
    out
}

#[test]
fn forces_stresslets_and_the_pressure_meet_the_tolerance() {
    let dir = scratch("stokes-layers");
    let x = points(N, 11);
    let f = charges(3 * N, 12);
    let m = charges(3 * N, 13);
    let n = charges(3 * N, 14);
    let (src, fp, mp, np_, out) = (
        dir.join("x.npy"),
        dir.join("f.npy"),
        dir.join("m.csv"),
        dir.join("n.npy"),
        dir.join("o.npy"),
    );
    write_npy(&src, &x, &[N as u64, 3]);
    write_npy(&fp, &f, &[N as u64, 3]);
    write_csv(&mp, &m, 3, Some("mx,my,mz"));
    write_npy(&np_, &n, &[N as u64, 3]);
    let o = ferrofmm(&[
        "eval",
        "--kernel",
        "stokes",
        "--sources",
        src.to_str().unwrap(),
        "--charges",
        fp.to_str().unwrap(),
        "--strslet",
        mp.to_str().unwrap(),
        "--strsvec",
        np_.to_str().unwrap(),
        "--pressure",
        "--gradients",
        "--tolerance",
        "1e-5",
        "--leaf-size",
        "64",
        "--check",
        "50",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = texts(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("force+stresslet sources"), "{stdout}");
    // The report's own check, every output within the tolerance.
    for name in ["potential", "gradient", "pressure", "pressure gradient"] {
        let line = stdout
            .lines()
            .find(|l| l.trim_start().starts_with(name) && l.contains("e-"))
            .unwrap_or_else(|| panic!("no {name} error in\n{stdout}"));
        let e: f64 = line.split_whitespace().last().unwrap().parse().unwrap();
        assert!(e > 0.0 && e <= 1e-5, "{line}");
    }
    // The columns: velocity (3), its gradient (9), pressure, its gradient.
    let (shape, values) = read_npy(&out);
    assert_eq!(shape, vec![N as u64, 16]);
    let (mut got, mut want) = (Vec::new(), Vec::new());
    for j in (0..N).step_by(97) {
        let row = &values[16 * j..16 * j + 16];
        got.extend_from_slice(&row[..3]);
        got.push(row[12]);
        want.extend(direct(&x, &f, &m, &n, &x[3 * j..3 * j + 3]));
    }
    let err = ferrofmm_testing::errors::relative_l2(&got, &want);
    assert!(
        err > 0.0 && err <= 1e-5,
        "velocity and pressure columns: {err:e}"
    );
}

#[test]
fn what_the_layers_refuse_is_a_clear_error() {
    let dir = scratch("stokes-layers-bad");
    let x = points(100, 1);
    let src = dir.join("x.npy");
    let v = dir.join("v.npy");
    let short = dir.join("short.npy");
    write_npy(&src, &x, &[100, 3]);
    write_npy(&v, &charges(300, 2), &[100, 3]);
    write_npy(&short, &charges(297, 3), &[99, 3]);
    let out = dir.join("o.npy");
    let base = [
        "eval",
        "--sources",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--order",
        "4",
    ];
    let v = v.to_str().unwrap();
    for (extra, needle) in [
        (
            vec!["--kernel", "laplace", "--charges", v, "--pressure"],
            "belong to --kernel stokes",
        ),
        (
            vec![
                "--kernel",
                "stokes",
                "--charges",
                v,
                "--pressure",
                "--box",
                "2",
            ],
            "free space only",
        ),
        (
            vec![
                "--kernel",
                "stokes",
                "--strslet",
                v,
                "--pressure",
                "--hessians",
            ],
            "--strsvec",
        ),
        (
            vec![
                "--kernel",
                "stokes",
                "--strslet",
                v,
                "--strsvec",
                v,
                "--hessians",
            ],
            "no Hessians",
        ),
        (
            vec![
                "--kernel",
                "stokes",
                "--strslet",
                short.to_str().unwrap(),
                "--strsvec",
                v,
            ],
            "99 stresslet strengths",
        ),
    ] {
        let mut args = base.to_vec();
        args.extend(extra.iter().copied());
        let o = ferrofmm(&args);
        let (_, stderr) = texts(&o);
        assert!(!o.status.success(), "{extra:?} succeeded");
        assert!(
            stderr.contains(needle),
            "{extra:?}: no {needle:?} in\n{stderr}"
        );
        assert!(!out.exists(), "{extra:?} wrote an output");
    }
}
