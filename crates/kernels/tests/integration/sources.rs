//! Dipole sources and Hessians ([`SourceKind`], [`EvalMode::PotentialGradientHessian`])
//! against independent references: Hessians against central differences of
//! the gradient of the tuned charge loop, dipoles against central
//! differences in the **source** position of the charge outputs, the
//! composed loop against the tuned one for charges, every SIMD level against
//! the portable one, and bad input.

use crate::common;

use common::{levels, random_points, to_t};
use ferrofmm_kernels::lanes::composed_with;
use ferrofmm_kernels::{
    EvalMode, Kernel, KernelError, Laplace3d, ModifiedHelmholtz3d, Real, SimdLevel, SourceKind,
    direct_sum_sources, direct_sum_sources_checked,
};

const KINDS: [SourceKind; 3] = [
    SourceKind::Charge,
    SourceKind::Dipole,
    SourceKind::ChargeDipole,
];
const MODES: [EvalMode; 3] = [
    EvalMode::Potential,
    EvalMode::PotentialGradient,
    EvalMode::PotentialGradientHessian,
];

/// Sources in `[-1, 1)^3` with random densities for `kind`, and targets at
/// distance >= 1 from all of them (so central differences with `h = 1e-4`
/// have truncation `~h^2` and cancellation `~eps / h`, both `<< 1e-6`
/// relative to the values).
fn separated(kind: SourceKind, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (s, _) = random_points::<f64>(seed, 29);
    let (_, dens) = random_points::<f64>(seed + 1, 29 * kind.values_per_source());
    let (mut t, _) = random_points::<f64>(seed + 2, 17);
    for x in t.iter_mut() {
        *x = if *x >= 0.0 { *x + 2.0 } else { *x - 2.0 };
    }
    (s, dens, t)
}

fn eval<K: Kernel>(
    k: &K,
    kind: SourceKind,
    mode: EvalMode,
    s: &[f64],
    d: &[f64],
    t: &[f64],
) -> Vec<f64> {
    let mut out = vec![0.0; mode.values_per_target() * t.len() / 3];
    k.evaluate_sources(kind, mode, s, d, t, &mut out);
    out
}

/// `max |a - b| / max |b|` (componentwise over all values).
fn rel_max(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// The Hessian `[H11, H22, H33, H12, H13, H23]` per target from central
/// differences of the gradient (outputs 1..4 of `PotentialGradient`).
fn fd_hessian<K: Kernel>(
    k: &K,
    kind: SourceKind,
    s: &[f64],
    d: &[f64],
    t: &[f64],
) -> Vec<[f64; 6]> {
    let h = 1e-4;
    let nt = t.len() / 3;
    // g[c][j][a] = d/dy_c of gradient component a at target j.
    let mut dg = vec![[[0.0; 3]; 3]; nt];
    for c in 0..3 {
        let (mut plus, mut minus) = (t.to_vec(), t.to_vec());
        for j in 0..nt {
            plus[3 * j + c] += h;
            minus[3 * j + c] -= h;
        }
        let gp = eval(k, kind, EvalMode::PotentialGradient, s, d, &plus);
        let gm = eval(k, kind, EvalMode::PotentialGradient, s, d, &minus);
        for j in 0..nt {
            for a in 0..3 {
                dg[j][c][a] = (gp[4 * j + 1 + a] - gm[4 * j + 1 + a]) / (2.0 * h);
            }
        }
    }
    dg.iter()
        .map(|m| {
            [
                m[0][0],
                m[1][1],
                m[2][2],
                0.5 * (m[0][1] + m[1][0]),
                0.5 * (m[0][2] + m[2][0]),
                0.5 * (m[1][2] + m[2][1]),
            ]
        })
        .collect()
}

fn kernels() -> (Laplace3d, ModifiedHelmholtz3d) {
    (Laplace3d, ModifiedHelmholtz3d::new(1.7).unwrap())
}

fn check_hessians<K: Kernel>(k: &K) {
    for kind in KINDS {
        let (s, d, t) = separated(kind, 5);
        let full = eval(k, kind, EvalMode::PotentialGradientHessian, &s, &d, &t);
        let grad = eval(k, kind, EvalMode::PotentialGradient, &s, &d, &t);
        let fd = fd_hessian(k, kind, &s, &d, &t);
        let got: Vec<f64> = full
            .chunks_exact(10)
            .flat_map(|o| o[4..].to_vec())
            .collect();
        let want: Vec<f64> = fd.iter().flatten().copied().collect();
        let e = rel_max(&got, &want);
        assert!(
            e < 1e-6,
            "{} {}: Hessian vs differences {e:e}",
            k.name(),
            kind.name()
        );
        // The first four outputs are those of the gradient mode.
        let head: Vec<f64> = full
            .chunks_exact(10)
            .flat_map(|o| o[..4].to_vec())
            .collect();
        assert!(
            rel_max(&head, &grad) < 1e-14,
            "{} {}",
            k.name(),
            kind.name()
        );
        // Laplace: the trace of the Hessian (the Laplacian) is zero away
        // from the sources; modified Helmholtz: it is k^2 u.
        let k2 = k.parameters().first().map_or(0.0, |k| k * k);
        for o in full.chunks_exact(10) {
            let lap = o[4] + o[5] + o[6];
            let scale = o[4].abs() + o[5].abs() + o[6].abs() + k2 * o[0].abs();
            assert!(
                (lap - k2 * o[0]).abs() <= 1e-12 * scale,
                "{} trace {lap} vs {}",
                k.name(),
                k2 * o[0]
            );
        }
    }
}

#[test]
fn hessians_match_differences_of_gradients() {
    let (l, y) = kernels();
    check_hessians(&l);
    check_hessians(&y);
}

/// Dipole outputs are the derivative of the charge outputs in the source
/// position along `n`: `u_n(y) = d/dh [q K(x + h n, y)]` at `h = 0`, `q = 1`.
fn check_dipoles_as_differences<K: Kernel>(k: &K) {
    let (s, d, t) = separated(SourceKind::Dipole, 9);
    let ns = s.len() / 3;
    let h = 1e-4;
    for mode in MODES {
        let got = eval(k, SourceKind::Dipole, mode, &s, &d, &t);
        let mut want = vec![0.0; got.len()];
        for i in 0..ns {
            let n = &d[3 * i..3 * i + 3];
            let at = |sign: f64| {
                let x: Vec<f64> = (0..3).map(|c| s[3 * i + c] + sign * h * n[c]).collect();
                eval(k, SourceKind::Charge, mode, &x, &[1.0], &t)
            };
            let (p, m) = (at(1.0), at(-1.0));
            for (w, (a, b)) in want.iter_mut().zip(p.iter().zip(&m)) {
                *w += (a - b) / (2.0 * h);
            }
        }
        let e = rel_max(&got, &want);
        assert!(e < 1e-6, "{} dipole {}: {e:e}", k.name(), mode.name());
        // Charge + dipole is the sum of the two.
        let (_, q, _) = separated(SourceKind::Charge, 9);
        let both: Vec<f64> = (0..ns)
            .flat_map(|i| [q[i], d[3 * i], d[3 * i + 1], d[3 * i + 2]])
            .collect();
        let sum = eval(k, SourceKind::ChargeDipole, mode, &s, &both, &t);
        let charge = eval(k, SourceKind::Charge, mode, &s, &q, &t);
        let parts: Vec<f64> = charge.iter().zip(&got).map(|(a, b)| a + b).collect();
        assert!(
            rel_max(&sum, &parts) < 1e-13,
            "{} {}",
            k.name(),
            mode.name()
        );
    }
}

#[test]
fn dipoles_match_differences_in_the_source_position() {
    let (l, y) = kernels();
    check_dipoles_as_differences(&l);
    check_dipoles_as_differences(&y);
}

/// The composed loop for charges agrees with the kernel's tuned `pair`,
/// at every level and in both precisions, with coincident points present.
fn check_composed_charges<T: Real, K: ferrofmm_kernels::lanes::RadialLaneKernel>(k: &K, tol: f64) {
    let (s, q) = random_points::<T>(31, 70);
    let mut t = s.clone();
    t.extend(to_t::<T>(&[0.3, -0.2, 0.9]));
    for level in levels() {
        for mode in [EvalMode::Potential, EvalMode::PotentialGradient] {
            let w = mode.values_per_target();
            let mut tuned = vec![T::ZERO; w * t.len() / 3];
            let mut composed = tuned.clone();
            k.evaluate(mode, &s, &q, &t, &mut tuned);
            composed_with(
                level,
                k,
                SourceKind::Charge,
                mode,
                &s,
                &q,
                &t,
                &mut composed,
            );
            let a: Vec<f64> = composed.iter().map(|v| v.to_f64()).collect();
            let b: Vec<f64> = tuned.iter().map(|v| v.to_f64()).collect();
            assert!(a.iter().all(|v| v.is_finite()));
            let e = rel_max(&a, &b);
            assert!(e < tol, "{} {level:?} {}: {e:e}", k.name(), mode.name());
        }
    }
}

#[test]
fn composed_loop_agrees_with_the_tuned_one_for_charges() {
    let (l, y) = kernels();
    check_composed_charges::<f64, _>(&l, 1e-13);
    check_composed_charges::<f64, _>(&y, 1e-13);
    check_composed_charges::<f32, _>(&l, 1e-4);
    check_composed_charges::<f32, _>(&y, 1e-4);
}

/// Every level gives the portable result, for every kind and mode, with
/// sources coinciding with targets (which must add exactly nothing, so the
/// outputs stay finite); `f32` follows `f64`.
#[test]
fn levels_agree_and_coincident_points_add_nothing() {
    let (l, y) = kernels();
    for kind in KINDS {
        let (s, _) = random_points::<f64>(41, 45);
        let (_, d) = random_points::<f64>(42, 45 * kind.values_per_source());
        let t = s.clone();
        for mode in MODES {
            let w = mode.values_per_target();
            let run = |level: SimdLevel, lap: bool| {
                let mut out = vec![0.0; w * t.len() / 3];
                if lap {
                    composed_with(level, &l, kind, mode, &s, &d, &t, &mut out);
                } else {
                    composed_with(level, &y, kind, mode, &s, &d, &t, &mut out);
                }
                out
            };
            for lap in [true, false] {
                let base = run(SimdLevel::Scalar, lap);
                assert!(
                    base.iter().all(|v| v.is_finite()),
                    "{} {}",
                    kind.name(),
                    mode.name()
                );
                for level in levels() {
                    let e = rel_max(&run(level, lap), &base);
                    assert!(
                        e < 1e-12,
                        "{level:?} {} {}: {e:e}",
                        kind.name(),
                        mode.name()
                    );
                }
                // f32 against f64.
                let (s32, d32, t32) = (to_t::<f32>(&s), to_t::<f32>(&d), to_t::<f32>(&t));
                let mut out32 = vec![0.0f32; w * t.len() / 3];
                if lap {
                    l.evaluate_sources(kind, mode, &s32, &d32, &t32, &mut out32);
                } else {
                    y.evaluate_sources(kind, mode, &s32, &d32, &t32, &mut out32);
                }
                let a: Vec<f64> = out32.iter().map(|&v| v as f64).collect();
                let e = rel_max(&a, &base);
                assert!(e < 2e-3, "f32 {} {}: {e:e}", kind.name(), mode.name());
            }
        }
    }
}

/// A kernel that implements only values and gradients.
#[derive(Clone)]
struct Plain;

impl Kernel for Plain {
    fn name(&self) -> String {
        "plain".into()
    }
    fn homogeneity(&self) -> Option<f64> {
        Some(-1.0)
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        Laplace3d.kernel_value(d)
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        Laplace3d.kernel_gradient(d)
    }
}

#[test]
fn bad_densities_and_unsupported_kinds_are_errors() {
    let s = [0.0f64; 6];
    let t = [1.0f64; 3];
    let mut out = [0.0f64; 4];
    // Two dipole sources need 6 values.
    let e = direct_sum_sources_checked(
        &Laplace3d,
        SourceKind::Dipole,
        EvalMode::PotentialGradient,
        &s,
        &[1.0; 4],
        &t,
        &mut out,
    );
    assert!(
        matches!(
            e,
            Err(KernelError::DensitiesLength {
                n_sources: 2,
                per_source: 3,
                found: 4,
                ..
            })
        ),
        "{e:?}"
    );
    let msg = e.unwrap_err().to_string();
    assert!(msg.contains("dipole") && msg.contains("6"), "{msg}");
    // Hessians need ten outputs per target.
    let e = direct_sum_sources_checked(
        &Laplace3d,
        SourceKind::Charge,
        EvalMode::PotentialGradientHessian,
        &s,
        &[1.0; 2],
        &t,
        &mut out,
    );
    assert!(
        matches!(e, Err(KernelError::OutputLength { expected: 10, .. })),
        "{e:?}"
    );
    // A kernel without dipoles says so, and leaves `out` alone.
    let e = direct_sum_sources_checked(
        &Plain,
        SourceKind::Dipole,
        EvalMode::Potential,
        &s,
        &[1.0; 6],
        &t,
        &mut out[..1],
    );
    assert!(matches!(e, Err(KernelError::Unsupported { .. })), "{e:?}");
    assert!(e.unwrap_err().to_string().contains("plain"));
    assert_eq!(out, [0.0; 4]);
    // Non-finite dipoles are named.
    let e = direct_sum_sources_checked(
        &Laplace3d,
        SourceKind::Dipole,
        EvalMode::Potential,
        &s,
        &[1.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
        &t,
        &mut out[..1],
    );
    assert!(
        matches!(
            e,
            Err(KernelError::NonFinite {
                what: "dipoles",
                index: 1,
                ..
            })
        ),
        "{e:?}"
    );
    // The default method (charges) still works for the plain kernel.
    let mut phi = [0.0f64];
    direct_sum_sources(
        &Plain,
        SourceKind::Charge,
        EvalMode::Potential,
        &s,
        &[1.0; 2],
        &t,
        &mut phi,
    );
    assert!(phi[0] > 0.0);
}

#[test]
#[should_panic(expected = "not supported")]
fn the_default_method_refuses_dipoles() {
    let mut out = [0.0f64];
    Plain.evaluate_sources(
        SourceKind::Dipole,
        EvalMode::Potential,
        &[0.0; 3],
        &[1.0; 3],
        &[1.0; 3],
        &mut out,
    );
}
