//! `eval --kernel stokes` with stresslets and the pressure: two
//! distributed FMMs (the Stokeslet and its Laplace companion) whose values
//! combine at each rank's targets.

use std::f64::consts::PI;

use crate::common::*;
use ferrofmm_testing::errors::relative_l2;

/// Velocity and pressure at `y` of forces `f` and stresslets `(m, n)` at
/// `x`, by FMM3D's `stfmm3d` formulas (viscosity 1), written out here,
/// independently of the FMM's decomposition into a Stokeslet and a
/// Laplace part.
fn direct(
    x: &[f64],
    f: Option<&[f64]>,
    mn: Option<(&[f64], &[f64])>,
    y: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let mut u = vec![0.0; y.len()];
    let mut p = vec![0.0; y.len() / 3];
    for (j, t) in y.chunks_exact(3).enumerate() {
        for (i, s) in x.chunks_exact(3).enumerate() {
            let d = [t[0] - s[0], t[1] - s[1], t[2] - s[2]];
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if r2 == 0.0 {
                continue;
            }
            let r = r2.sqrt();
            let dot = |a: &[f64]| d[0] * a[0] + d[1] * a[1] + d[2] * a[2];
            if let Some(f) = f {
                let fi = &f[3 * i..3 * i + 3];
                let df = dot(fi);
                for a in 0..3 {
                    u[3 * j + a] += (fi[a] / r + d[a] * df / (r2 * r)) / (8.0 * PI);
                }
                p[j] += df / (4.0 * PI * r2 * r);
            }
            if let Some((m, n)) = mn {
                let (mi, ni) = (&m[3 * i..3 * i + 3], &n[3 * i..3 * i + 3]);
                let (dm, dn) = (dot(mi), dot(ni));
                let r5 = r2 * r2 * r;
                for a in 0..3 {
                    u[3 * j + a] += 3.0 * d[a] * dm * dn / (4.0 * PI * r5);
                }
                let mn_dot = mi[0] * ni[0] + mi[1] * ni[1] + mi[2] * ni[2];
                p[j] += (6.0 * dm * dn / r5 - 2.0 * mn_dot / (r2 * r)) / (4.0 * PI);
            }
        }
    }
    (u, p)
}

/// Columns `lo..hi` of rows of `w` values.
fn columns(v: &[f64], w: usize, lo: usize, hi: usize) -> Vec<f64> {
    v.chunks_exact(w).flat_map(|r| r[lo..hi].to_vec()).collect()
}

/// Forces and stresslets with the pressure and gradients on 3 ranks equal
/// 1 rank's to rounding and direct sums to the order's accuracy, with the
/// pressure's columns after the velocity's; stresslets alone at separate
/// targets on 2 ranks meet a tolerance; flags for another kernel, with
/// force dipoles, or files of the wrong length are one error on every
/// rank.
#[test]
fn eval_runs_stresslets_and_the_pressure_on_every_rank() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 1200;
    let x: Vec<f64> = (0..3 * n)
        .map(|i| (i as f64 * 0.754_877_666).fract())
        .collect();
    let wave = |k: usize, c: f64| -> Vec<f64> {
        (0..3 * n)
            .map(|i| ((i * k) % 101) as f64 / 101.0 - c)
            .collect()
    };
    let f = wave(53, 0.5);
    let m = wave(37, 0.4);
    // Unit orientations (surface normals).
    let mut nv = wave(29, 0.5);
    for v in nv.chunks_exact_mut(3) {
        let s = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-3);
        v.iter_mut().for_each(|c| *c /= s);
    }
    for (name, v) in [("s", &x), ("f", &f), ("m", &m), ("n", &nv)] {
        write_npy(&path(&format!("{name}.npy")), v, 3);
    }
    let run = |ranks: usize, out: &str| {
        let (s, fp, mp, np, o) = (
            path("s.npy"),
            path("f.npy"),
            path("m.npy"),
            path("n.npy"),
            path(out),
        );
        let args = [
            "eval",
            "--kernel",
            "stokes",
            "--sources",
            &s,
            "--charges",
            &fp,
            "--strslet",
            &mp,
            "--strsvec",
            &np,
            "--pressure",
            "--gradients",
            "--order",
            "7",
            "--leaf-size",
            "60",
            "--check",
            "100",
            "--json",
            "--out",
            &o,
        ];
        let (ok, text) = mpirun(ranks, &args);
        assert!(ok, "{text}");
        text
    };
    let text = run(3, "o3.npy");
    // The layers' own check: velocity, its gradient, pressure and its
    // gradient against direct sums of the same pieces.
    let worst = json_number(&text, "worst").expect("layers check in the JSON");
    assert!(worst < 1e-4, "worst {worst}\n{text}");
    run(1, "o1.csv");
    // The columns `ferrofmm eval` writes: the velocity's, then the
    // pressure's.
    let head = std::fs::read_to_string(path("o1.csv")).unwrap();
    let head = head.lines().next().unwrap_or_default();
    assert!(
        head.starts_with("potential_x,")
            && head.ends_with(",pressure,pressure_grad_x,pressure_grad_y,pressure_grad_z"),
        "{head}"
    );
    let w = 12 + 4;
    let (a, b) = (
        read_columns(&path("o1.csv"), n, w),
        read_columns(&path("o3.npy"), n, w),
    );
    let d = relative_l2(&b, &a);
    // (The CSV holds 17 significant digits.)
    assert!(d <= 1e-12, "3 ranks differ from 1: {d}");
    // Velocity and pressure against the formulas at every 7th point.
    let sample: Vec<usize> = (0..n).step_by(7).collect();
    let y: Vec<f64> = sample
        .iter()
        .flat_map(|&j| x[3 * j..3 * j + 3].to_vec())
        .collect();
    let (u, p) = direct(&x, Some(&f), Some((&m, &nv)), &y);
    let rows: Vec<f64> = sample
        .iter()
        .flat_map(|&j| b[w * j..w * (j + 1)].to_vec())
        .collect();
    let eu = relative_l2(&columns(&rows, w, 0, 3), &u);
    let ep = relative_l2(&columns(&rows, w, 12, 13), &p);
    assert!(eu < 1e-4 && ep < 1e-4, "velocity {eu}, pressure {ep}");
    assert!(eu > 1e-12, "a far field was computed: {eu}");

    // Stresslets alone at separate targets, at a tolerance, on 2 ranks.
    let nt = 500;
    let t: Vec<f64> = (0..3 * nt)
        .map(|i| 1.2 * (i as f64 * 0.569_840_29).fract() - 0.1)
        .collect();
    write_npy(&path("t.npy"), &t, 3);
    let (s, mp, np, tp, o) = (
        path("s.npy"),
        path("m.npy"),
        path("n.npy"),
        path("t.npy"),
        path("ot.npy"),
    );
    let (ok, text) = mpirun(
        2,
        &[
            "eval",
            "--kernel",
            "stokes",
            "--sources",
            &s,
            "--strslet",
            &mp,
            "--strsvec",
            &np,
            "--targets",
            &tp,
            "--pressure",
            "--tolerance",
            "1e-5",
            "--out",
            &o,
        ],
    );
    assert!(ok, "{text}");
    assert!(text.contains("Laplace FMM"), "{text}");
    let got = read_columns(&o, nt, 4);
    let (u, p) = direct(&x, None, Some((&m, &nv)), &t);
    let eu = relative_l2(&columns(&got, 4, 0, 3), &u);
    let ep = relative_l2(&columns(&got, 4, 3, 4), &p);
    assert!(eu < 1e-5 && ep < 1e-5, "velocity {eu}, pressure {ep}");

    // Errors, the same on every rank and with no output.
    let bad = |args: &[&str], what: &str| {
        let (ok, text) = mpirun(2, args);
        assert!(!ok && text.contains(what), "{what}: {text}");
    };
    bad(
        &[
            "eval",
            "--sources",
            &s,
            "--charges",
            &mp,
            "--strslet",
            &mp,
            "--strsvec",
            &np,
        ],
        "belong to --kernel stokes",
    );
    bad(
        &[
            "eval",
            "--kernel",
            "stokes",
            "--sources",
            &s,
            "--dipoles",
            &mp,
            "--pressure",
        ],
        "do not combine",
    );
    write_npy(&path("short.npy"), &m[..3 * (n - 1)], 3);
    let short = path("short.npy");
    bad(
        &[
            "eval",
            "--kernel",
            "stokes",
            "--sources",
            &s,
            "--strslet",
            &short,
            "--strsvec",
            &np,
            "--out",
            &o,
        ],
        "give one per point",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
