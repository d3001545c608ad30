//! Issue 35: Stokes double layers (stresslets) and the pressure
//! ([`StokesLayers`]) against direct sums of FMM3D's formulas written out
//! here, their gradients against central differences of those sums, the
//! stresslet's integral identity on a sphere, the Stokes equations
//! `grad p = mu Laplacian u` and `div u = 0` on the FMM's own outputs, and
//! the refusals.

use std::f64::consts::PI;

use ferrofmm_field::FftM2l;
use ferrofmm_fmm::{
    Charges, FmmBuilder, FmmError, Geometry, Periodic, StokesLayers, StokesRequest, StokesValues,
};
use ferrofmm_kernels::{EvalMode, Stokes3d};
use ferrofmm_testing::errors::relative_l2;

type Layers = StokesLayers<f64, FftM2l<f64>>;

/// `[u (3), grad u (9, d_c u_a at 3 c + a), p, grad p (3)]` at source `j`
/// of forces `f` and stresslets `(m, n)` at the other sources, by direct
/// summation of FMM3D's `stfmm3d` formulas (viscosity 1) and their
/// derivatives, written out here.
fn direct(x: &[f64], f: Option<&[f64]>, mn: Option<(&[f64], &[f64])>, j: usize) -> [f64; 16] {
    let mut out = [0.0; 16];
    let delta = |a: usize, c: usize| if a == c { 1.0 } else { 0.0 };
    for i in 0..x.len() / 3 {
        let d: [f64; 3] = std::array::from_fn(|a| x[3 * j + a] - x[3 * i + a]);
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if i == j || r2 == 0.0 {
            continue;
        }
        let r = r2.sqrt();
        let (r3, r5) = (r * r2, r * r2 * r2);
        let r7 = r5 * r2;
        let v = |v: &[f64], a: usize| v[3 * i + a];
        let dot = |w: &[f64]| d[0] * v(w, 0) + d[1] * v(w, 1) + d[2] * v(w, 2);
        if let Some(f) = f {
            let df = dot(f);
            for a in 0..3 {
                out[a] += (v(f, a) / r + d[a] * df / r3) / (8.0 * PI);
                for c in 0..3 {
                    out[3 + 3 * c + a] += (-v(f, a) * d[c] + delta(a, c) * df + d[a] * v(f, c)
                        - 3.0 * d[a] * d[c] * df / r2)
                        / (8.0 * PI * r3);
                }
            }
            out[12] += df / (4.0 * PI * r3);
            for c in 0..3 {
                out[13 + c] += (v(f, c) / r3 - 3.0 * df * d[c] / r5) / (4.0 * PI);
            }
        }
        if let Some((m, n)) = mn {
            let (dm, dn) = (dot(m), dot(n));
            let mn: f64 = (0..3).map(|a| v(m, a) * v(n, a)).sum();
            for a in 0..3 {
                out[a] += 3.0 * d[a] * dm * dn / (4.0 * PI * r5);
                for c in 0..3 {
                    out[3 + 3 * c + a] += 3.0
                        * (delta(a, c) * dm * dn / r5 + d[a] * (v(m, c) * dn + v(n, c) * dm) / r5
                            - 5.0 * d[a] * d[c] * dm * dn / r7)
                        / (4.0 * PI);
                }
            }
            out[12] += (6.0 * dm * dn / r5 - 2.0 * mn / r3) / (4.0 * PI);
            for c in 0..3 {
                out[13 + c] += (6.0 * (v(m, c) * dn + v(n, c) * dm) / r5
                    - 30.0 * dm * dn * d[c] / r7
                    + 6.0 * mn * d[c] / r5)
                    / (4.0 * PI);
            }
        }
    }
    out
}

/// Relative L2 errors of velocity, velocity gradient, pressure and
/// pressure gradient at the first `k` targets (the sources).
fn errors(
    x: &[f64],
    f: Option<&[f64]>,
    mn: Option<(&[f64], &[f64])>,
    got: &StokesValues<f64>,
    k: usize,
) -> [f64; 4] {
    let p = got.pressure.as_ref().expect("pressure asked for");
    let (mut want, mut have) = (vec![Vec::new(); 4], vec![Vec::new(); 4]);
    let step = x.len() / 3 / k;
    for j in (0..x.len() / 3).step_by(step).take(k) {
        let w = direct(x, f, mn, j);
        let u = &got.velocity[12 * j..12 * j + 12];
        let pj = &p[4 * j..4 * j + 4];
        for (q, (lo, hi, from)) in [(0, 3, 0), (3, 12, 3), (12, 13, 0), (13, 16, 1)]
            .into_iter()
            .enumerate()
        {
            want[q].extend_from_slice(&w[lo..hi]);
            let src = if q < 2 { u } else { pj };
            have[q].extend_from_slice(&src[from..from + hi - lo]);
        }
    }
    std::array::from_fn(|q| relative_l2(&have[q], &want[q]))
}

/// Forces and stresslets together, zero-mean and positive densities, at a
/// tolerance (leaf 64, so that the far field carries most of the work):
/// every output (velocity, its gradient, pressure, its gradient) within the
/// tolerance of the direct sums.
#[test]
fn forces_and_stresslets_with_the_pressure_meet_the_tolerance() {
    let n = 3000;
    for (geometry, sign, eps) in [
        (Geometry::Cube, Charges::Signed, 1e-5),
        (Geometry::Plummer, Charges::Positive, 1e-6),
    ] {
        let x: Vec<f64> = geometry.points(n, 3);
        let f: Vec<f64> = sign.generate(3 * n, 4);
        let m: Vec<f64> = sign.generate(3 * n, 5);
        let nu: Vec<f64> = Charges::Signed.generate(3 * n, 6);
        let builder = FmmBuilder::new(&x)
            .cache_dir(crate::ops_cache())
            .kernel(Stokes3d::default())
            .mode(EvalMode::PotentialGradient)
            .leaf_size(64)
            .tolerance(eps);
        let request = StokesRequest {
            forces: true,
            stresslets: true,
            pressure: true,
        };
        let mut layers = Layers::build(builder, request).unwrap();
        let out = layers.evaluate_verified(Some(&f), Some((&m, &nu))).unwrap();
        assert!(
            out.stokes.as_ref().is_some_and(|v| v.met),
            "{:?}",
            out.stokes
        );
        assert!(
            out.laplace.as_ref().is_some_and(|v| v.met),
            "{:?}",
            out.laplace
        );
        // What is delivered was checked too, at the Laplace order kept.
        let delivered = out.delivered.as_ref().expect("the delivered check");
        assert!(delivered.met, "{delivered:?}");
        assert_eq!(
            delivered.attempts.last().map(|a| a.order),
            Some(layers.laplace().unwrap().order())
        );
        assert!(delivered.attempts[0].measured.potential > 0.0);
        let e = errors(&x, Some(&f), Some((&m, &nu)), &out.values, 60);
        eprintln!(
            "{} {} eps {eps:e}: orders {} / {}; u {:.2e}, grad u {:.2e}, p {:.2e}, grad p {:.2e}",
            geometry.name(),
            sign.name(),
            layers.stokes().order(),
            layers.laplace().unwrap().order(),
            e[0],
            e[1],
            e[2],
            e[3]
        );
        for (what, err) in [
            "velocity",
            "velocity gradient",
            "pressure",
            "pressure gradient",
        ]
        .iter()
        .zip(e)
        {
            assert!(err > 0.0 && err <= eps, "{what}: {err:e} above {eps:e}");
        }
        // The library's own check (direct sums of the pieces) agrees with
        // the formulas written out here, on the same targets.
        let sample: Vec<usize> = (0..n).step_by(n / 60).take(60).collect();
        let check = layers
            .relative_errors(Some(&f), Some((&m, &nu)), &out.values, &sample)
            .unwrap();
        let theirs = [
            Some(check.velocity),
            check.velocity_gradient,
            check.pressure,
            check.pressure_gradient,
        ];
        for (mine, theirs) in e.iter().zip(theirs) {
            let theirs = theirs.expect("every output checked");
            assert!(
                (theirs / mine - 1.0).abs() < 1e-3,
                "{check:?} against {e:?}"
            );
        }
        assert!(check.worst() <= eps);
        // The same evaluation again, unverified, gives the same values.
        let again = layers.evaluate(Some(&f), Some((&m, &nu))).unwrap();
        assert_eq!(again, out.values);
    }
}

/// The stresslet's analogue of Gauss's law: a constant strength `m` on a
/// sphere with outward normals `n` (quadrature weights folded into `m`)
/// gives `u = -m` inside and `u = 0` outside; and the pressure of a
/// force-only run is the Stokes equations' `grad p = mu Laplacian u`
/// (central differences of the FMM's own velocity gradients) with
/// `div u = 0`.
#[test]
fn the_sphere_identity_and_the_stokes_equations_hold() {
    // Gauss-Legendre in cos(theta) times the trapezoid rule in phi.
    let (nt, np) = (48, 96);
    let (nodes, weights) = gauss_legendre(nt);
    let mu = [0.3, -0.7, 0.5];
    let (mut x, mut m, mut nrm) = (Vec::new(), Vec::new(), Vec::new());
    for (c, w) in nodes.iter().zip(&weights) {
        let s = (1.0 - c * c).sqrt();
        for k in 0..np {
            let phi = 2.0 * PI * k as f64 / np as f64;
            let y = [s * phi.cos(), s * phi.sin(), *c];
            let area = w * 2.0 * PI / np as f64;
            x.extend_from_slice(&y);
            nrm.extend_from_slice(&y);
            m.extend(mu.iter().map(|v| v * area));
        }
    }
    let targets = [
        [0.1, 0.2, -0.3],
        [0.0, 0.0, 0.0],
        [-0.4, 0.1, 0.2],
        [1.6, 0.3, 0.2],
        [0.2, -2.0, 0.5],
        [0.0, 0.0, -1.5],
    ];
    let t: Vec<f64> = targets.iter().flatten().copied().collect();
    let builder = FmmBuilder::new(&x)
        .cache_dir(crate::ops_cache())
        .targets(&t)
        .kernel(Stokes3d::default())
        .allow_direct(false)
        .tolerance(1e-6);
    let request = StokesRequest {
        forces: false,
        stresslets: true,
        pressure: false,
    };
    let layers = Layers::build(builder, request).unwrap();
    let out = layers.evaluate(None, Some((&m, &nrm))).unwrap();
    for (j, y) in targets.iter().enumerate() {
        let inside = y.iter().map(|v| v * v).sum::<f64>() < 1.0;
        let u = &out.velocity[3 * j..3 * j + 3];
        for a in 0..3 {
            let want = if inside { -mu[a] } else { 0.0 };
            // |mu| ~ 0.9: a tolerance of 1e-6 leaves about 1e-6.
            assert!(
                (u[a] - want).abs() < 1e-5,
                "target {y:?}: u = {u:?}, want {want} in component {a}"
            );
        }
    }

    // Forces in a cube; targets away from them, each with six neighbours
    // at +-h along the axes.
    let n = 2000;
    let x: Vec<f64> = Geometry::Cube.points(n, 9);
    let f: Vec<f64> = Charges::Signed.generate(3 * n, 10);
    let centres = [[0.5, 0.5, 1.3], [-0.3, 0.4, 0.5], [0.5, 1.4, 0.2]];
    let h = 1e-3;
    let mut t = Vec::new();
    for c in centres {
        t.extend_from_slice(&c);
        for axis in 0..3 {
            for sign in [1.0, -1.0] {
                let mut y = c;
                y[axis] += sign * h;
                t.extend_from_slice(&y);
            }
        }
    }
    let viscosity = 0.8;
    let builder = FmmBuilder::new(&x)
        .cache_dir(crate::ops_cache())
        .targets(&t)
        .kernel(Stokes3d::new(viscosity).unwrap())
        .mode(EvalMode::PotentialGradient)
        .allow_direct(false)
        .tolerance(2e-8);
    let request = StokesRequest {
        forces: true,
        stresslets: false,
        pressure: true,
    };
    let out = Layers::build(builder, request)
        .unwrap()
        .evaluate(Some(&f), None)
        .unwrap();
    let p = out.pressure.unwrap();
    let grad = |j: usize| &out.velocity[12 * j + 3..12 * j + 12];
    for (i, _) in centres.iter().enumerate() {
        let base = 7 * i;
        let g = grad(base);
        let div = g[0] + g[4] + g[8];
        let size: f64 = g.iter().map(|v| v.abs()).sum();
        assert!(div.abs() < 1e-9 * size, "div u = {div:e}");
        for a in 0..3 {
            // Laplacian of u_a: sum over c of d_c (d_c u_a), by differences
            // of the gradient at y +- h e_c.
            let lap: f64 = (0..3)
                .map(|c| {
                    (grad(base + 1 + 2 * c)[3 * c + a] - grad(base + 2 + 2 * c)[3 * c + a])
                        / (2.0 * h)
                })
                .sum();
            let dp = p[4 * base + 1 + a];
            // Differences of the FMM's gradients at h = 1e-3 amplify its
            // error (2e-8) about 1000x: measured 5e-5 relative.
            assert!(
                (viscosity * lap - dp).abs() < 1e-3 * dp.abs().max(1e-3 * size),
                "centre {i}, a = {a}: mu lap u = {:e}, d p = {dp:e}",
                viscosity * lap
            );
        }
    }
}

/// Nodes and weights of `n`-point Gauss-Legendre on `[-1, 1]` (Newton on
/// the Legendre recurrence).
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for i in 0..n {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                let w = 2.0 / ((1.0 - z * z) * dp * dp);
                nodes.push(z);
                weights.push(w);
                break;
            }
        }
    }
    (nodes, weights)
}

#[test]
fn what_the_layers_cannot_take_is_a_clear_error() {
    let x: Vec<f64> = Geometry::Cube.points(400, 1);
    let f = vec![0.1; 1200];
    let builder = || FmmBuilder::new(&x).kernel(Stokes3d::default()).order(4);
    let nothing = StokesRequest::default();
    let err = Layers::build(builder(), nothing).err().expect("refused");
    assert!(
        err.to_string().contains("forces, stresslets or both"),
        "{err}"
    );
    let with_pressure = StokesRequest {
        forces: true,
        stresslets: false,
        pressure: true,
    };
    let cell = Periodic::cube(1.0);
    let err = Layers::build(builder().periodic(cell), with_pressure)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("free space only"), "{err}");
    let layers = Layers::build(builder(), with_pressure).unwrap();
    let err = layers.evaluate(None, None).unwrap_err();
    assert!(err.to_string().contains("carry forces: give them"), "{err}");
    let err = layers.evaluate(Some(&f), Some((&f, &f))).unwrap_err();
    assert!(err.to_string().contains("carry no stresslets"), "{err}");
    let err = layers.evaluate(Some(&f[..600]), None).unwrap_err();
    assert!(
        matches!(
            err,
            FmmError::DensityCount {
                expected: 1200,
                got: 600,
                ..
            }
        ),
        "{err}"
    );
    // Forces alone with the pressure: one Laplace vector of dipoles.
    let out = layers.evaluate(Some(&f), None).unwrap();
    assert_eq!(out.pressure.map(|p| p.len()), Some(400));
    assert!(layers.laplace().is_some());
    let plain = Layers::build(
        builder(),
        StokesRequest {
            forces: true,
            ..StokesRequest::default()
        },
    )
    .unwrap();
    assert!(plain.laplace().is_none());
    assert!(plain.evaluate(Some(&f), None).unwrap().pressure.is_none());
}

/// Velocity and pressure at targets `y` (not sources) of stresslets
/// `(m, n)` at `x`, by FMM3D's formulas written out here.
fn stresslets_at(x: &[f64], m: &[f64], n: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut u = vec![0.0; y.len()];
    let mut p = vec![0.0; y.len() / 3];
    for (j, t) in y.chunks_exact(3).enumerate() {
        for i in 0..x.len() / 3 {
            let d: [f64; 3] = std::array::from_fn(|a| t[a] - x[3 * i + a]);
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let (r, mi, ni) = (r2.sqrt(), &m[3 * i..3 * i + 3], &n[3 * i..3 * i + 3]);
            let dot = |a: &[f64]| d[0] * a[0] + d[1] * a[1] + d[2] * a[2];
            let (dm, dn, mn) = (
                dot(mi),
                dot(ni),
                mi[0] * ni[0] + mi[1] * ni[1] + mi[2] * ni[2],
            );
            let r5 = r2 * r2 * r;
            for a in 0..3 {
                u[3 * j + a] += 3.0 * d[a] * dm * dn / (4.0 * PI * r5);
            }
            p[j] += (6.0 * dm * dn / r5 - 2.0 * mn / (r2 * r)) / (4.0 * PI);
        }
    }
    (u, p)
}

/// Each FMM meeting the tolerance on its own densities is not enough: the
/// pressure of stresslets sums derivatives of three Laplace dipole fields.
/// At targets around the sources, starting from order 3, the Laplace FMM
/// meets 1e-5 on its first vector at order 7 while the delivered pressure
/// misses (1.7e-5 measured when this test was written); the check of what
/// is delivered raises the Laplace FMM until velocity and pressure meet
/// the tolerance against the formulas.
#[test]
fn what_is_delivered_is_checked_and_the_laplace_fmm_raised() {
    let n = 1200;
    let x: Vec<f64> = (0..3 * n)
        .map(|i| (i as f64 * 0.754_877_666).fract())
        .collect();
    let t: Vec<f64> = (0..3 * 500)
        .map(|i| 1.2 * (i as f64 * 0.569_840_29).fract() - 0.1)
        .collect();
    let m: Vec<f64> = Charges::Signed.generate(3 * n, 8);
    let mut nv: Vec<f64> = Charges::Signed.generate(3 * n, 9);
    for v in nv.chunks_exact_mut(3) {
        let s = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-3);
        v.iter_mut().for_each(|c| *c /= s);
    }
    let eps = 1e-5;
    let builder = FmmBuilder::new(&x)
        .targets(&t)
        .cache_dir(crate::ops_cache())
        .kernel(Stokes3d::default())
        .order(3)
        .leaf_size(60)
        .tolerance(eps);
    let request = StokesRequest {
        forces: false,
        stresslets: true,
        pressure: true,
    };
    let mut layers = Layers::build(builder, request).unwrap();
    let out = layers.evaluate_verified(None, Some((&m, &nv))).unwrap();
    let delivered = out.delivered.as_ref().expect("the delivered check");
    let orders: Vec<usize> = delivered.attempts.iter().map(|a| a.order).collect();
    eprintln!(
        "laplace {:?}, delivered {:?}",
        out.laplace.as_ref().map(|l| l
            .attempts
            .iter()
            .map(|a| (a.order, a.measured.worst()))
            .collect::<Vec<_>>()),
        delivered
            .attempts
            .iter()
            .map(|a| (a.order, a.measured.worst()))
            .collect::<Vec<_>>()
    );
    assert!(delivered.met, "{delivered:?}");
    assert!(
        orders.len() >= 2,
        "the raise was not needed here: {orders:?}"
    );
    assert!(orders.windows(2).all(|w| w[1] == w[0] + 1), "{orders:?}");
    assert_eq!(orders.last(), Some(&layers.laplace().unwrap().order()));
    assert!(out.verification().is_some_and(|v| v.met));
    let (u, p) = stresslets_at(&x, &m, &nv, &t);
    let eu = relative_l2(&out.values.velocity, &u);
    let ep = relative_l2(out.values.pressure.as_ref().unwrap(), &p);
    assert!(eu <= eps && ep <= eps, "velocity {eu:e}, pressure {ep:e}");
}
