//! Kernels with several components ([`Helmholtz3d`] in complex form,
//! [`Stokes3d`]) against independent references: gradients against central
//! differences in the target, dipoles against central differences in the
//! source position, Helmholtz at `k = 0` against Laplace, the assembled
//! matrix against the evaluation, f32 against f64, the Stokes velocity's
//! divergence, and bad input.

use ferrofmm_kernels::{
    EvalMode, Helmholtz3d, Kernel, KernelError, Laplace3d, SimdLevel, SourceKind, Stokes3d,
    check_kernel_inputs, direct_sum_sources_checked, lanes,
};
use ferrofmm_testing::{errors::relative_l2, points::uniform_cube, rng::SplitMix64};

/// Sources in `[-1, 1)^3`, densities in `[-1, 1)`, targets at distance >= 1
/// from every source.
fn separated<K: Kernel>(k: &K, kind: SourceKind, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let s = uniform_cube(23, -1.0, 2.0, seed);
    let mut rng = SplitMix64(seed + 1);
    let d: Vec<f64> = (0..23 * k.values_per_source(kind))
        .map(|_| rng.range(-1.0, 1.0))
        .collect();
    let mut t = uniform_cube(11, -1.0, 2.0, seed + 2);
    for x in t.iter_mut() {
        *x = if *x >= 0.0 { *x + 2.0 } else { *x - 2.0 };
    }
    (s, d, t)
}

fn eval<K: Kernel>(
    k: &K,
    kind: SourceKind,
    mode: EvalMode,
    s: &[f64],
    d: &[f64],
    t: &[f64],
) -> Vec<f64> {
    let mut out = vec![0.0; k.values_per_target(mode) * t.len() / 3];
    k.evaluate_sources(kind, mode, s, d, t, &mut out);
    out
}

/// Gradient columns against central differences of the potential in each
/// target coordinate.
fn check_gradient<K: Kernel>(k: &K, kind: SourceKind, seed: u64) {
    let c = k.components();
    let (s, d, t) = separated(k, kind, seed);
    let full = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &t);
    let h = 1e-5;
    let mut fd = vec![0.0; full.len()];
    let mut got = vec![0.0; full.len()];
    for j in 0..t.len() / 3 {
        for m in 0..3 {
            let mut tp = t[3 * j..3 * j + 3].to_vec();
            let mut tm = tp.clone();
            tp[m] += h;
            tm[m] -= h;
            let up = eval(k, kind, EvalMode::Potential, &s, &d, &tp);
            let um = eval(k, kind, EvalMode::Potential, &s, &d, &tm);
            for a in 0..c {
                let at = 4 * c * j + c * (1 + m) + a;
                fd[at] = (up[a] - um[a]) / (2.0 * h);
                got[at] = full[at];
            }
        }
    }
    let err = relative_l2(&got, &fd);
    assert!(
        err < 1e-7,
        "{} {kind:?} gradient vs differences: {err:e}",
        k.name()
    );
}

/// Real wavenumbers and complex ones (damped waves), `(Re k, Im k)`.
const WAVENUMBERS: [(f64, f64); 5] = [(0.5, 0.0), (3.0, 0.0), (10.0, 0.0), (3.0, 1.0), (0.0, 2.0)];

#[test]
fn helmholtz_gradients_match_differences_for_every_source_kind() {
    for (i, (a, b)) in WAVENUMBERS.into_iter().enumerate() {
        let k = Helmholtz3d::new_complex(a, b).unwrap();
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            check_gradient(&k, kind, 10 * i as u64 + 3);
        }
    }
}

#[test]
fn stokes_gradients_match_differences_and_the_velocity_is_divergence_free() {
    let k = Stokes3d::new(0.7).unwrap();
    check_gradient(&k, SourceKind::Charge, 5);
    let (s, d, t) = separated(&k, SourceKind::Charge, 8);
    let g = eval(
        &k,
        SourceKind::Charge,
        EvalMode::PotentialGradient,
        &s,
        &d,
        &t,
    );
    for o in g.chunks_exact(12) {
        let div = o[3] + o[7] + o[11];
        let scale: f64 = o[3..].iter().map(|v| v.abs()).sum();
        assert!(
            div.abs() <= 1e-13 * scale,
            "div u = {div:e} (scale {scale:e})"
        );
    }
}

/// `n . grad_x G` equals the central difference of the charge potential in
/// the source position along `n`, for each complex dipole component.
#[test]
fn helmholtz_dipoles_are_source_derivatives_of_charges() {
    for k in [Helmholtz3d::new(4.0), Helmholtz3d::new_complex(4.0, 1.5)] {
        dipoles_are_source_derivatives(&k.unwrap());
    }
}

fn dipoles_are_source_derivatives(k: &Helmholtz3d) {
    let k = *k;
    let (s, d, t) = separated(&k, SourceKind::Dipole, 21);
    let got = eval(
        &k,
        SourceKind::Dipole,
        EvalMode::PotentialGradient,
        &s,
        &d,
        &t,
    );
    let h = 1e-5;
    let mut want = vec![0.0; got.len()];
    for i in 0..s.len() / 3 {
        for m in 0..3 {
            let mut sp = s[3 * i..3 * i + 3].to_vec();
            let mut sm = sp.clone();
            sp[m] += h;
            sm[m] -= h;
            // Complex dipole component m of source i, as a complex charge.
            let q = [d[6 * i + 2 * m], d[6 * i + 2 * m + 1]];
            let up = eval(
                &k,
                SourceKind::Charge,
                EvalMode::PotentialGradient,
                &sp,
                &q,
                &t,
            );
            let um = eval(
                &k,
                SourceKind::Charge,
                EvalMode::PotentialGradient,
                &sm,
                &q,
                &t,
            );
            for (w, (a, b)) in want.iter_mut().zip(up.iter().zip(&um)) {
                *w += (a - b) / (2.0 * h);
            }
        }
    }
    let err = relative_l2(&got, &want);
    assert!(err < 1e-7, "{k:?}: dipoles vs source differences: {err:e}");
}

/// The damped kernel against its closed form `e^{-br} e^{iar} / (4 pi r)`
/// (complex charges), and `Im k = 0` is the real-wavenumber kernel (the
/// same value, run on the undamped path).
#[test]
fn damped_helmholtz_is_the_closed_form() {
    let k = Helmholtz3d::new_complex(5.0, 2.0).unwrap();
    let (s, d, t) = separated(&k, SourceKind::Charge, 33);
    let got = eval(&k, SourceKind::Charge, EvalMode::Potential, &s, &d, &t);
    let mut want = vec![0.0; got.len()];
    for (j, y) in t.chunks_exact(3).enumerate() {
        for (x, q) in s.chunks_exact(3).zip(d.chunks_exact(2)) {
            let r = ((y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) + (y[2] - x[2]).powi(2)).sqrt();
            let amp = (-2.0 * r).exp() / (4.0 * std::f64::consts::PI * r);
            let (gr, gi) = (amp * (5.0 * r).cos(), amp * (5.0 * r).sin());
            want[2 * j] += gr * q[0] - gi * q[1];
            want[2 * j + 1] += gr * q[1] + gi * q[0];
        }
    }
    let err = relative_l2(&got, &want);
    assert!(err < 1e-14, "damped potential vs closed form: {err:e}");
    let (a, b) = (
        Helmholtz3d::new(5.0).unwrap(),
        Helmholtz3d::new_complex(5.0, 0.0).unwrap(),
    );
    // The same value, so the real path (`is_damped` false).
    assert_eq!(a, b);
    assert!(!b.is_damped() && Helmholtz3d::new_complex(5.0, 1e-3).unwrap().is_damped());
    assert!(Helmholtz3d::new_complex(1.0, -0.5).is_err());
    assert!(Helmholtz3d::new_complex(1.0, f64::NAN).is_err());
}

/// Hessian columns (complex `H_xx, H_yy, H_zz, H_xy, H_xz, H_yz` after
/// the gradient) against central differences of the gradient in each
/// target coordinate (`h = 1e-4`: truncation `~(k h)^2 / 6` and
/// cancellation `~eps / h` relative, both below `1e-7` for `k <= 7`), with
/// `k r` from 1 to about 50 (separations 1 to 7); the leading eight values
/// are the gradient mode's, and the trace of the Hessian is `-k^2 u`.
fn check_hessian(k: &Helmholtz3d, kind: SourceKind, seed: u64) {
    let (s, d, t) = separated(k, kind, seed);
    let full = eval(k, kind, EvalMode::PotentialGradientHessian, &s, &d, &t);
    let grad = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &t);
    let h = 1e-4;
    let nt = t.len() / 3;
    // dg[j][c][2 a + part]: d/dy_c of gradient component a at target j.
    let mut dg = vec![[[0.0; 6]; 3]; nt];
    for c in 0..3 {
        let (mut tp, mut tm) = (t.clone(), t.clone());
        for j in 0..nt {
            tp[3 * j + c] += h;
            tm[3 * j + c] -= h;
        }
        let gp = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &tp);
        let gm = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &tm);
        for j in 0..nt {
            for v in 0..6 {
                dg[j][c][v] = (gp[8 * j + 2 + v] - gm[8 * j + 2 + v]) / (2.0 * h);
            }
        }
    }
    let (mut got, mut want) = (Vec::new(), Vec::new());
    for j in 0..nt {
        for (slot, (a, b)) in [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
            .into_iter()
            .enumerate()
        {
            for part in 0..2 {
                got.push(full[20 * j + 8 + 2 * slot + part]);
                want.push(0.5 * (dg[j][a][2 * b + part] + dg[j][b][2 * a + part]));
            }
        }
    }
    let err = relative_l2(&got, &want);
    eprintln!("k={} {kind:?} Hessian vs differences: {err:e}", k.k);
    assert!(
        err < 1e-7,
        "k={} {kind:?} Hessian vs differences: {err:e}",
        k.k
    );
    let head: Vec<f64> = full
        .chunks_exact(20)
        .flat_map(|o| o[..8].to_vec())
        .collect();
    let err = relative_l2(&head, &grad);
    assert!(err < 1e-14, "k={} {kind:?}: leading values {err:e}", k.k);
    // The complex k^2 = a^2 - b^2 + 2iab.
    let (k2r, k2i) = (k.k * k.k - k.k_im * k.k_im, 2.0 * k.k * k.k_im);
    let k2 = k2r.abs() + k2i.abs();
    for o in full.chunks_exact(20) {
        let minus_k2u = [-(k2r * o[0] - k2i * o[1]), -(k2r * o[1] + k2i * o[0])];
        for part in 0..2 {
            let tr = o[8 + part] + o[10 + part] + o[12 + part];
            let scale = o[8 + part].abs() + o[10 + part].abs() + o[12 + part].abs();
            assert!(
                (tr - minus_k2u[part]).abs() <= 1e-12 * (scale + k2 * (o[0].abs() + o[1].abs())),
                "k={}+{}i {kind:?}: trace {tr:e} vs -k^2 u = {:e}",
                k.k,
                k.k_im,
                minus_k2u[part]
            );
        }
    }
}

#[test]
fn helmholtz_hessians_match_differences_of_the_gradient() {
    for (i, (a, b)) in [
        (0.0, 0.0),
        (0.5, 0.0),
        (3.0, 0.0),
        (7.0, 0.0),
        (3.0, 1.5),
        (0.0, 2.0),
    ]
    .into_iter()
    .enumerate()
    {
        let k = Helmholtz3d::new_complex(a, b).unwrap();
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            check_hessian(&k, kind, 10 * i as u64 + 71);
        }
    }
}

/// At `k = 0` the real and imaginary parts are Laplace fields of the real
/// and imaginary charges (dipoles), Hessians included.
#[test]
fn helmholtz_hessians_at_zero_wavenumber_are_laplace_per_part() {
    let k = Helmholtz3d::new(0.0).unwrap();
    let mode = EvalMode::PotentialGradientHessian;
    for kind in [
        SourceKind::Charge,
        SourceKind::Dipole,
        SourceKind::ChargeDipole,
    ] {
        let (s, d, t) = separated(&k, kind, 33);
        let got = eval(&k, kind, mode, &s, &d, &t);
        for part in 0..2 {
            let q: Vec<f64> = d.iter().skip(part).step_by(2).copied().collect();
            let want = eval(&Laplace3d, kind, mode, &s, &q, &t);
            let mine: Vec<f64> = got.iter().skip(part).step_by(2).copied().collect();
            let err = relative_l2(&mine, &want);
            assert!(err < 1e-14, "{kind:?} part {part}: {err:e}");
        }
    }
}

/// At `k = 0` the real and imaginary parts are Laplace fields of the real
/// and imaginary charges.
#[test]
fn helmholtz_at_zero_wavenumber_is_laplace_per_part() {
    let k = Helmholtz3d::new(0.0).unwrap();
    let (s, d, t) = separated(&k, SourceKind::Charge, 31);
    let got = eval(
        &k,
        SourceKind::Charge,
        EvalMode::PotentialGradient,
        &s,
        &d,
        &t,
    );
    for part in 0..2 {
        let q: Vec<f64> = d.iter().skip(part).step_by(2).copied().collect();
        let want = eval(
            &Laplace3d,
            SourceKind::Charge,
            EvalMode::PotentialGradient,
            &s,
            &q,
            &t,
        );
        let mine: Vec<f64> = got.iter().skip(part).step_by(2).copied().collect();
        let err = relative_l2(&mine, &want);
        assert!(err < 1e-14, "part {part}: {err:e}");
    }
}

/// `A d` with the assembled block matrix equals the potential evaluation,
/// also with coincident points (zero blocks).
fn check_assembly<K: Kernel>(k: &K) {
    let c = k.components();
    let s = uniform_cube(19, 0.0, 1.0, 41);
    let mut rng = SplitMix64(42);
    let d: Vec<f64> = (0..19 * c).map(|_| rng.range(-1.0, 1.0)).collect();
    let mut t = uniform_cube(13, 0.0, 1.0, 43);
    t[..3].copy_from_slice(&s[..3]);
    let mut a = vec![0.0; 19 * 13 * c * c];
    k.assemble(&s, &t, &mut a);
    let product: Vec<f64> = a
        .chunks_exact(19 * c)
        .map(|row| row.iter().zip(&d).map(|(x, y)| x * y).sum())
        .collect();
    let want = eval(k, SourceKind::Charge, EvalMode::Potential, &s, &d, &t);
    let err = relative_l2(&product, &want);
    assert!(err < 1e-14, "{}: assembled vs evaluated {err:e}", k.name());
    assert!(a.iter().all(|v| v.is_finite()));
    if k.is_complex() {
        // The structure the FFT scheme's complex path relies on, exactly.
        assert_eq!(c, 2);
        let at = |t: usize, s: usize, i: usize, j: usize| a[(2 * t + i) * 38 + 2 * s + j];
        for t in 0..13 {
            for s in 0..19 {
                assert_eq!(at(t, s, 0, 0), at(t, s, 1, 1), "{} ({t}, {s})", k.name());
                assert_eq!(at(t, s, 0, 1), -at(t, s, 1, 0), "{} ({t}, {s})", k.name());
            }
        }
    }
}

#[test]
fn assembled_blocks_reproduce_the_evaluation() {
    check_assembly(&Helmholtz3d::new(6.0).unwrap());
    check_assembly(&Helmholtz3d::new_complex(6.0, 1.5).unwrap());
    check_assembly(&Stokes3d::default());
    assert!(Helmholtz3d::new(1.0).unwrap().is_complex() && !Stokes3d::default().is_complex());
}

/// The generic `f32` path agrees with `f64` to single precision.
#[test]
fn single_precision_follows_double() {
    fn check<K: Kernel>(k: &K, kind: SourceKind) {
        let (s, d, t) = separated(k, kind, 51);
        let want = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &t);
        let f = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let mut out = vec![0.0f32; want.len()];
        k.evaluate_sources(
            kind,
            EvalMode::PotentialGradient,
            &f(&s),
            &f(&d),
            &f(&t),
            &mut out,
        );
        let got: Vec<f64> = out.iter().map(|&x| x as f64).collect();
        let err = relative_l2(&got, &want);
        assert!(err < 1e-5, "{} f32: {err:e}", k.name());
    }
    check(&Helmholtz3d::new(5.0).unwrap(), SourceKind::ChargeDipole);
    check(&Stokes3d::default(), SourceKind::Charge);
    check(&Stokes3d::default(), SourceKind::ChargeDipole);
}

/// Helmholtz Hessians in `f32` follow `f64`, every source kind, at every
/// SIMD level (the scalar reference loop in `f32` too).
#[test]
fn helmholtz_single_precision_hessians_follow_double() {
    let mode = EvalMode::PotentialGradientHessian;
    let f = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    for (kw, b) in [(0.0, 0.0), (5.0, 0.0), (5.0, 1.0)] {
        let k = Helmholtz3d::new_complex(kw, b).unwrap();
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            let (s, d, t) = separated(&k, kind, 57);
            let want = eval(&k, kind, mode, &s, &d, &t);
            let mut out = vec![0.0f32; want.len()];
            k.evaluate_sources_pairwise(kind, mode, &f(&s), &f(&d), &f(&t), &mut out);
            let runs = [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512].map(|level| {
                let mut o = vec![0.0f32; want.len()];
                lanes::evaluate_sources_with(level, &k, kind, mode, &f(&s), &f(&d), &f(&t), &mut o);
                (format!("{level:?}"), o)
            });
            for (label, o) in std::iter::once(("pairwise".to_string(), out)).chain(runs) {
                let got: Vec<f64> = o.iter().map(|&x| x as f64).collect();
                let err = relative_l2(&got, &want);
                assert!(err < 1e-5, "k={kw} {kind:?} {label} f32: {err:e}");
            }
        }
    }
}

#[test]
fn bad_input_is_refused_with_the_component_count() {
    let h = Helmholtz3d::new(1.0).unwrap();
    let s = [0.0; 6];
    let t = [1.0; 3];
    // Real charges (one per source) for a complex kernel.
    let err = check_kernel_inputs(
        &h,
        SourceKind::Charge,
        EvalMode::Potential,
        &s,
        &[1.0, 1.0],
        &t,
        &[0.0; 2],
    );
    assert!(
        matches!(
            err,
            Err(KernelError::DensitiesLength {
                per_source: 2,
                found: 2,
                ..
            })
        ),
        "{err:?}"
    );
    // Dipoles need six values per source (three complex).
    let err = check_kernel_inputs(
        &h,
        SourceKind::Dipole,
        EvalMode::Potential,
        &s,
        &[1.0; 8],
        &t,
        &[0.0; 2],
    );
    assert!(matches!(
        err,
        Err(KernelError::DensitiesLength { per_source: 6, .. })
    ));
    // Outputs: two per target for a potential.
    let err = check_kernel_inputs(
        &h,
        SourceKind::Charge,
        EvalMode::Potential,
        &s,
        &[1.0; 4],
        &t,
        &[0.0; 1],
    );
    assert!(matches!(
        err,
        Err(KernelError::OutputLength { expected: 2, .. })
    ));
    // A Stokes force dipole takes nine values, not three; Stokes has no
    // Hessians; Helmholtz Hessians need 20 values per target.
    let mut out = [0.0; 3];
    let err = direct_sum_sources_checked(
        &Stokes3d::default(),
        SourceKind::Dipole,
        EvalMode::Potential,
        &s,
        &[1.0; 6],
        &t,
        &mut out,
    );
    assert!(
        matches!(
            err,
            Err(KernelError::DensitiesLength {
                per_source: 9,
                found: 6,
                ..
            })
        ),
        "{err:?}"
    );
    let mut out = [0.0; 30];
    let err = direct_sum_sources_checked(
        &Stokes3d::default(),
        SourceKind::Charge,
        EvalMode::PotentialGradientHessian,
        &s,
        &[1.0; 6],
        &t,
        &mut out,
    );
    assert!(
        matches!(err, Err(KernelError::Unsupported { .. })),
        "{err:?}"
    );
    let mut out = [0.0; 10];
    let err = direct_sum_sources_checked(
        &h,
        SourceKind::Charge,
        EvalMode::PotentialGradientHessian,
        &s,
        &[1.0; 4],
        &t,
        &mut out,
    );
    assert!(
        matches!(err, Err(KernelError::OutputLength { expected: 20, .. })),
        "{err:?}"
    );
    assert!(Helmholtz3d::new(-1.0).is_err());
    assert!(Stokes3d::new(f64::INFINITY).is_err());
}

/// The vectorised Helmholtz loop (register `sin`/`cos`, target lanes) at
/// every SIMD level against the scalar pairwise loop with `f64::sin_cos`:
/// every source kind and output, block tails (37 targets), coincident
/// points, and `kr` up to about 90.
#[test]
fn helmholtz_vector_loop_matches_the_pairwise_loop_at_every_level() {
    for (kw, b) in [
        (0.0, 0.0),
        (2.5, 0.0),
        (30.0, 0.0),
        (2.5, 1.5),
        (30.0, 4.0),
        (0.0, 3.0),
    ] {
        let k = Helmholtz3d::new_complex(kw, b).unwrap();
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            let s = uniform_cube(53, -1.5, 3.0, 61);
            let mut rng = SplitMix64(62);
            let d: Vec<f64> = (0..53 * k.values_per_source(kind))
                .map(|_| rng.range(-1.0, 1.0))
                .collect();
            let mut t = uniform_cube(37, -1.5, 3.0, 63);
            t[3..6].copy_from_slice(&s[9..12]);
            for mode in [
                EvalMode::Potential,
                EvalMode::PotentialGradient,
                EvalMode::PotentialGradientHessian,
            ] {
                let mut want = vec![0.0; k.values_per_target(mode) * 37];
                k.evaluate_sources_pairwise(kind, mode, &s, &d, &t, &mut want);
                for level in [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512] {
                    let mut got = vec![0.0; want.len()];
                    lanes::evaluate_sources_with(level, &k, kind, mode, &s, &d, &t, &mut got);
                    assert!(got.iter().all(|v| v.is_finite()));
                    let err = relative_l2(&got, &want);
                    assert!(
                        err < 1e-13,
                        "k={kw}+{b}i {kind:?} {mode:?} {level:?}: {err:e}"
                    );
                }
            }
        }
    }
}

/// The vectorised Stokes loop at every SIMD level against the scalar
/// pairwise loop: both outputs, block tails (37 targets), coincident points.
#[test]
fn stokes_vector_loop_matches_the_pairwise_loop_at_every_level() {
    let k = Stokes3d::new(0.5).unwrap();
    let s = uniform_cube(53, -1.0, 2.0, 71);
    let mut t = uniform_cube(37, -1.0, 2.0, 73);
    t[6..9].copy_from_slice(&s[0..3]);
    for kind in [
        SourceKind::Charge,
        SourceKind::Dipole,
        SourceKind::ChargeDipole,
    ] {
        let mut rng = SplitMix64(72);
        let f: Vec<f64> = (0..k.values_per_source(kind) * 53)
            .map(|_| rng.range(-1.0, 1.0))
            .collect();
        for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
            let mut want = vec![0.0; k.values_per_target(mode) * 37];
            k.evaluate_sources_pairwise(kind, mode, &s, &f, &t, &mut want);
            for level in [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512] {
                let mut got = vec![0.0; want.len()];
                lanes::evaluate_sources_with(level, &k, kind, mode, &s, &f, &t, &mut got);
                assert!(got.iter().all(|v| v.is_finite()));
                let err = relative_l2(&got, &want);
                assert!(err < 1e-14, "{kind:?} {mode:?} {level:?}: {err:e}");
            }
        }
    }
}

/// A force dipole `D` is the limit of opposite forces: `sum_k D_k.` at
/// `x + h e_k` minus at `x - h e_k`, over `2 h` (central differences in the
/// source position), velocities and gradients; its velocity is divergence
/// free, and `D = I` gives no flow.
#[test]
fn stokes_force_dipoles_are_source_derivatives_of_forces() {
    let k = Stokes3d::new(1.3).unwrap();
    let (s, d, t) = separated(&k, SourceKind::Dipole, 31);
    let mode = EvalMode::PotentialGradient;
    let got = eval(&k, SourceKind::Dipole, mode, &s, &d, &t);
    let h = 1e-5;
    let mut want = vec![0.0; got.len()];
    for i in 0..s.len() / 3 {
        for m in 0..3 {
            let mut sp = s[3 * i..3 * i + 3].to_vec();
            let mut sm = sp.clone();
            sp[m] += h;
            sm[m] -= h;
            let f = &d[9 * i + 3 * m..9 * i + 3 * m + 3];
            let up = eval(&k, SourceKind::Charge, mode, &sp, f, &t);
            let um = eval(&k, SourceKind::Charge, mode, &sm, f, &t);
            for (w, (a, b)) in want.iter_mut().zip(up.iter().zip(&um)) {
                *w += (a - b) / (2.0 * h);
            }
        }
    }
    let err = relative_l2(&got, &want);
    assert!(err < 1e-7, "force dipoles vs source differences: {err:e}");
    check_gradient(&k, SourceKind::Dipole, 32);
    check_gradient(&k, SourceKind::ChargeDipole, 33);
    for o in got.chunks_exact(12) {
        let div = o[3] + o[7] + o[11];
        let scale: f64 = o[3..].iter().map(|v| v.abs()).sum();
        assert!(div.abs() <= 1e-13 * scale, "div u = {div:e}");
    }
    let identity: Vec<f64> = (0..s.len() / 3)
        .flat_map(|_| [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
        .collect();
    let none = eval(&k, SourceKind::Dipole, mode, &s, &identity, &t);
    let size: f64 = got.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(none.iter().all(|v| v.abs() <= 1e-15 * size), "{none:?}");
}

/// FMM3D's stresslet `3 d (d . mu)(d . nu) / (4 pi r^5)` (viscosity 1) is
/// the force dipole `mu nu^T + nu mu^T` plus the point-source flow
/// `(mu . nu) d / (4 pi r^3)`, which is minus the gradient of the Laplace
/// potential of charges `mu . nu`.
#[test]
fn the_stresslet_is_a_symmetric_force_dipole_plus_a_laplace_source() {
    let k = Stokes3d::default();
    let mut rng = SplitMix64(41);
    let s = uniform_cube(17, -1.0, 2.0, 42);
    let t = uniform_cube(9, 2.0, 1.0, 43);
    let mu: Vec<f64> = (0..51).map(|_| rng.range(-1.0, 1.0)).collect();
    let nu: Vec<f64> = (0..51).map(|_| rng.range(-1.0, 1.0)).collect();
    let mut dip = Vec::new();
    let mut dots = Vec::new();
    for (m, n) in mu.chunks_exact(3).zip(nu.chunks_exact(3)) {
        for a in 0..3 {
            for c in 0..3 {
                dip.push(m[a] * n[c] + n[a] * m[c]);
            }
        }
        dots.push(m[0] * n[0] + m[1] * n[1] + m[2] * n[2]);
    }
    let mode = EvalMode::PotentialGradient;
    let mut got = eval(&k, SourceKind::Dipole, mode, &s, &dip, &t);
    let lap = eval(&Laplace3d, SourceKind::Charge, mode, &s, &dots, &t);
    for (o, l) in got.chunks_exact_mut(12).zip(lap.chunks_exact(4)) {
        for a in 0..3 {
            o[a] -= l[1 + a];
        }
    }
    let mut want = vec![0.0; got.len()];
    for (j, y) in t.chunks_exact(3).enumerate() {
        for (i, x) in s.chunks_exact(3).enumerate() {
            let d: Vec<f64> = (0..3).map(|a| y[a] - x[a]).collect();
            let r = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            let dm: f64 = (0..3).map(|a| d[a] * mu[3 * i + a]).sum();
            let dn: f64 = (0..3).map(|a| d[a] * nu[3 * i + a]).sum();
            for a in 0..3 {
                want[12 * j + a] += 3.0 * d[a] * dm * dn / (4.0 * std::f64::consts::PI * r.powi(5));
            }
        }
    }
    let velocity: Vec<f64> = got.chunks_exact(12).flat_map(|o| o[..3].to_vec()).collect();
    let want: Vec<f64> = want
        .chunks_exact(12)
        .flat_map(|o| o[..3].to_vec())
        .collect();
    let err = relative_l2(&velocity, &want);
    assert!(err < 1e-14, "stresslet: {err:e}");
}
