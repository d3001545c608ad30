//! Shared helpers of the integration tests: deterministic random points,
//! direct summation, the driver-side steps (P2M, P2L, L2P, M2P) written out
//! exactly as the crate docs prescribe.
#![allow(dead_code)]

use ferrofmm_field::{M2lInteractions, M2lScheme, Operators, SurfaceKind};
use ferrofmm_kernels::{EvalMode, Kernel, Real};

pub use ferrofmm_testing::SplitMix64;
pub use ferrofmm_testing::charges::positive_from;
pub use ferrofmm_testing::errors::relative_l2;
pub use ferrofmm_testing::points::in_box;

pub fn to_t<T: Real>(x: &[f64]) -> Vec<T> {
    x.iter().map(|&v| T::from_f64(v)).collect()
}

pub fn to_f64<T: Real>(x: &[T]) -> Vec<f64> {
    x.iter().map(|v| v.to_f64()).collect()
}

/// Direct potential in f64 with the scalar reference loop.
pub fn direct<K: Kernel>(kernel: &K, sources: &[f64], q: &[f64], targets: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; targets.len() / 3];
    ferrofmm_kernels::reference::evaluate_pairwise(
        kernel,
        EvalMode::Potential,
        sources,
        q,
        targets,
        &mut out,
    );
    out
}

/// Potential of charges `q` at `sources` on one of a box's check
/// surfaces (`kind` = `UpwardCheck` for P2M, `DownwardCheck` for P2L).
pub fn check_potential<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    kind: SurfaceKind,
    level: u32,
    center: [f64; 3],
    sources: &[f64],
    q: &[f64],
) -> Vec<T> {
    let pts = ops.surface_points(kind, level, center);
    let mut check = vec![T::ZERO; ops.n_surface()];
    kernel.evaluate(
        EvalMode::Potential,
        &to_t::<T>(sources),
        &to_t::<T>(q),
        &pts,
        &mut check,
    );
    check
}

/// Driver P2M: sources -> upward check surface -> UC2E.
pub fn p2m<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    level: u32,
    center: [f64; 3],
    sources: &[f64],
    q: &[f64],
) -> Vec<T> {
    let check = check_potential(
        kernel,
        ops,
        SurfaceKind::UpwardCheck,
        level,
        center,
        sources,
        q,
    );
    let mut equiv = vec![T::ZERO; ops.n_surface()];
    ops.uc2e(level, &check, &mut equiv);
    equiv
}

/// Driver M2P / L2P: potential of a density on one of the box's surfaces.
pub fn eval_density<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    kind: SurfaceKind,
    level: u32,
    center: [f64; 3],
    density: &[T],
    targets: &[f64],
) -> Vec<f64> {
    let pts = ops.surface_points(kind, level, center);
    let mut out = vec![T::ZERO; targets.len() / 3];
    kernel.evaluate(
        EvalMode::Potential,
        &pts,
        density,
        &to_t::<T>(targets),
        &mut out,
    );
    to_f64(&out)
}

/// Center of box `idx` (integer coordinates) at `level` of the unit cube.
pub fn box_center(level: u32, idx: [i32; 3]) -> [f64; 3] {
    let w = 1.0 / (1u64 << level) as f64;
    [
        (idx[0] as f64 + 0.5) * w,
        (idx[1] as f64 + 0.5) * w,
        (idx[2] as f64 + 0.5) * w,
    ]
}

/// M2L of a single pair through a scheme: check potential of the target.
pub fn m2l_pair<T: Real, S: M2lScheme<T>>(
    scheme: &S,
    level: u32,
    n: usize,
    v: [i32; 3],
    multipole: &[T],
) -> Vec<T> {
    let inter = M2lInteractions::new(1, 1, &[(0, 0, v)]);
    let mut check = vec![T::ZERO; n];
    scheme.apply(level, &inter, multipole, &mut check);
    check
}

/// All V-list pairs of a uniform grid of `side^3` boxes (columns indexed
/// `x * side^2 + y * side + z`), sources and targets the same boxes.
pub fn uniform_v_lists(side: i32) -> Vec<(usize, usize, [i32; 3])> {
    let idx = |x: i32, y: i32, z: i32| (x * side * side + y * side + z) as usize;
    let mut pairs = Vec::new();
    for x in 0..side {
        for y in 0..side {
            for z in 0..side {
                // V list: children of the parent's neighbours that are not adjacent.
                let p = [x.div_euclid(2), y.div_euclid(2), z.div_euclid(2)];
                for sx in (2 * (p[0] - 1)).max(0)..(2 * (p[0] + 2)).min(side) {
                    for sy in (2 * (p[1] - 1)).max(0)..(2 * (p[1] + 2)).min(side) {
                        for sz in (2 * (p[2] - 1)).max(0)..(2 * (p[2] + 2)).min(side) {
                            let v = [sx - x, sy - y, sz - z];
                            if v.iter().map(|c| c.abs()).max().unwrap() >= 2 {
                                pairs.push((idx(x, y, z), idx(sx, sy, sz), v));
                            }
                        }
                    }
                }
            }
        }
    }
    pairs
}

/// M2L as the dense scheme defines it, done as a kernel evaluation in `T`:
/// source upward equivalent density -> target downward check potential.
pub fn m2l_eval<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    level: u32,
    source_center: [f64; 3],
    target_center: [f64; 3],
    phi: &[T],
) -> Vec<T> {
    let ue = ops.surface_points(SurfaceKind::UpwardEquivalent, level, source_center);
    let dc = ops.surface_points(SurfaceKind::DownwardCheck, level, target_center);
    let mut check = vec![T::ZERO; ops.n_surface()];
    kernel.evaluate(
        ferrofmm_kernels::EvalMode::Potential,
        &ue,
        phi,
        &dc,
        &mut check,
    );
    check
}

/// The transfer vectors used by the chain tests (closest face, edge and
/// corner neighbours of the V list, and far ones).
pub const CHAIN_VECTORS: [[i32; 3]; 6] = [
    [2, 0, 0],
    [2, 2, 0],
    [2, 2, 2],
    [-2, 1, -1],
    [0, -3, 2],
    [3, 3, 3],
];

/// P2M -> M2L -> DC2E -> L2P at `level` for each of `CHAIN_VECTORS`,
/// `count` sources and targets per box, M2L as the dense scheme defines it
/// ([`m2l_eval`]); returns the worst relative L2 error against direct
/// summation.
pub fn chain_error<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    level: u32,
    count: usize,
    seed: u64,
) -> f64 {
    chain_error_with(
        kernel,
        ops,
        level,
        count,
        seed,
        &CHAIN_VECTORS,
        |_, cs, ct, phi| m2l_eval(kernel, ops, level, cs, ct, phi),
    )
}

/// P2M -> `m2l` -> DC2E -> L2P at `level` for each transfer vector of
/// `vectors` (source box = target box + vector, target box `[3, 3, 3]`),
/// `count` sources and targets per box drawn from `SplitMix64(seed)`;
/// returns the worst relative L2 error against direct summation. `m2l`
/// maps (vector, source centre, target centre, multipole) to the target's
/// downward check potential.
pub fn chain_error_with<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    level: u32,
    count: usize,
    seed: u64,
    vectors: &[[i32; 3]],
    m2l: impl Fn([i32; 3], [f64; 3], [f64; 3], &[T]) -> Vec<T>,
) -> f64 {
    let mut rng = SplitMix64(seed);
    let h = ops.half_width(level);
    let n = ops.n_surface();
    let t_idx = [3, 3, 3];
    let ct = box_center(level, t_idx);
    let mut worst: f64 = 0.0;
    for &v in vectors {
        let cs = box_center(level, [t_idx[0] + v[0], t_idx[1] + v[1], t_idx[2] + v[2]]);
        let src = in_box(&mut rng, count, cs, h);
        let q = positive_from(&mut rng, count);
        let tgt = in_box(&mut rng, count, ct, h);
        let phi = p2m(kernel, ops, level, cs, &src, &q);
        let check = m2l(v, cs, ct, &phi);
        let mut psi = vec![T::ZERO; n];
        ops.dc2e(level, &check, &mut psi);
        let approx = eval_density(
            kernel,
            ops,
            SurfaceKind::DownwardEquivalent,
            level,
            ct,
            &psi,
            &tgt,
        );
        worst = worst.max(relative_l2(&approx, &direct(kernel, &src, &q, &tgt)));
    }
    worst
}

/// The full chain P2M (level l+1) -> M2M -> M2L (level l) -> L2L -> L2P
/// (level l+1), sources in one child of a source box and targets in one
/// child of a target box, for each of `CHAIN_VECTORS` at level `l`; worst
/// relative L2 error.
pub fn full_chain_error<T: Real, K: Kernel>(
    kernel: &K,
    ops: &Operators<T>,
    level: u32,
    count: usize,
    seed: u64,
) -> f64 {
    let mut rng = SplitMix64(seed);
    let h = ops.half_width(level);
    let hc = h / 2.0;
    let n = ops.n_surface();
    let t_idx = [3, 3, 3];
    let ct = box_center(level, t_idx);
    let mut worst: f64 = 0.0;
    for (i, v) in CHAIN_VECTORS.iter().enumerate() {
        let cs = box_center(level, [t_idx[0] + v[0], t_idx[1] + v[1], t_idx[2] + v[2]]);
        // Children closest to each other: the hardest case.
        let so = (0..3).fold(0, |o, d| o | (if v[d] < 0 { 1 << d } else { 0 })) ^ ((i & 1) * 7);
        let to = (0..3).fold(0, |o, d| o | (if v[d] > 0 { 1 << d } else { 0 }));
        let (oso, oto) = (
            ferrofmm_field::octant_offset(so),
            ferrofmm_field::octant_offset(to),
        );
        let csc = [
            cs[0] + hc * oso[0],
            cs[1] + hc * oso[1],
            cs[2] + hc * oso[2],
        ];
        let ctc = [
            ct[0] + hc * oto[0],
            ct[1] + hc * oto[1],
            ct[2] + hc * oto[2],
        ];
        let src = in_box(&mut rng, count, csc, hc);
        let q = positive_from(&mut rng, count);
        let tgt = in_box(&mut rng, count, ctc, hc);
        let phi_c = p2m(kernel, ops, level + 1, csc, &src, &q);
        let mut phi = vec![T::ZERO; n];
        ops.m2m(level + 1, so, &phi_c, &mut phi);
        let check = m2l_eval(kernel, ops, level, cs, ct, &phi);
        let mut psi = vec![T::ZERO; n];
        ops.dc2e(level, &check, &mut psi);
        let mut psi_c = vec![T::ZERO; n];
        ops.l2l(level + 1, to, &psi, &mut psi_c);
        let approx = eval_density(
            kernel,
            ops,
            SurfaceKind::DownwardEquivalent,
            level + 1,
            ctc,
            &psi_c,
            &tgt,
        );
        worst = worst.max(relative_l2(&approx, &direct(kernel, &src, &q, &tgt)));
    }
    worst
}
