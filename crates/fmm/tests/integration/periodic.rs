//! Periodic boundaries (issue 32): lattice sums against known Madelung
//! constants and against the library's Ewald sums, invariances, and the
//! inputs periodic runs refuse.

use ferrofmm_field::FftM2l;
use ferrofmm_fmm::{FmmBuilder, FmmError, Periodic, PeriodicAxes, SurfaceTerm};
use ferrofmm_kernels::{EvalMode, EwaldSum, Helmholtz3d, PeriodicCell, SourceKind};

/// A small deterministic generator (SplitMix64) of uniform `[0, 1)`.
struct Uniform(u64);

impl Uniform {
    fn random(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n^3` copies of a cubic unit cell of side 1 with `basis` (fractional
/// positions and charges): the points of a supercell of side `n`.
fn crystal(basis: &[([f64; 3], f64)], n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut points = Vec::new();
    let mut charges = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                for (p, q) in basis {
                    points.extend([p[0] + i as f64, p[1] + j as f64, p[2] + k as f64]);
                    charges.push(*q);
                }
            }
        }
    }
    (points, charges)
}

/// Fractional positions and charges of a unit cell's ions.
type Basis = Vec<([f64; 3], f64)>;

/// Four cations on the fcc sites of the unit cell and four anions at
/// `anion(site)`.
fn fcc_pairs(anion: impl Fn([f64; 3]) -> [f64; 3]) -> Basis {
    [
        [0.0, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [0.5, 0.0, 0.5],
        [0.0, 0.5, 0.5],
    ]
    .into_iter()
    .flat_map(|f| [(f, 1.0), (anion(f), -1.0)])
    .collect()
}

fn nacl() -> Basis {
    fcc_pairs(|f| [(f[0] + 0.5) % 1.0, f[1], f[2]])
}

fn zincblende() -> Basis {
    fcc_pairs(|f| f.map(|x| x + 0.25))
}

/// `-phi_i q_i 4 pi d` at every ion (`d` the nearest-neighbour distance in
/// a cell of side `side`): the Madelung constant at each site.
fn madelung_sites(phi: &[f64], q: &[f64], d: f64) -> Vec<f64> {
    phi.iter()
        .zip(q)
        .map(|(p, q)| -p * q * 4.0 * std::f64::consts::PI * d)
        .collect()
}

const NACL: f64 = 1.747_564_594_633_182;
const CSCL: f64 = 1.762_674_773_070_99;
const ZNS: f64 = 1.638_055_053_388_8;

#[test]
fn madelung_constants_of_three_lattices() {
    // A supercell deep enough for V, W and X lists across the faces.
    let cases: [(&str, Basis, usize, f64, f64); 3] = [
        ("NaCl", nacl(), 4, 0.5, NACL),
        (
            "CsCl",
            vec![([0.0; 3], 1.0), ([0.5; 3], -1.0)],
            6,
            3f64.sqrt() / 2.0,
            CSCL,
        ),
        ("ZnS", zincblende(), 4, 3f64.sqrt() / 4.0, ZNS),
    ];
    for (name, basis, n, d, known) in cases {
        let (points, q) = crystal(&basis, n);
        let fmm = FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            .periodic(Periodic::cube(n as f64))
            .order(12)
            .leaf_size(16)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap();
        assert!(fmm.tree().depth() >= 2, "{name}: a tree with far field");
        let phi = fmm.evaluate(&q).unwrap();
        for m in madelung_sites(&phi, &q, d) {
            assert!(
                (m - known).abs() <= 1e-8 * known,
                "{name}: {m} against {known} ({:.1e})",
                (m - known).abs() / known
            );
        }
        let energy = fmm.energy(&q, &phi).unwrap();
        let per_pair = -energy * 4.0 * std::f64::consts::PI * d / (q.len() as f64 / 2.0);
        assert!(
            (per_pair - known).abs() <= 1e-8 * known,
            "{name} energy {per_pair}"
        );
    }
}

#[test]
fn madelung_constants_to_the_f64_floor() {
    let cases: [(&str, Basis, f64, f64); 3] = [
        ("NaCl", nacl(), 0.5, NACL),
        (
            "CsCl",
            vec![([0.0; 3], 1.0), ([0.5; 3], -1.0)],
            3f64.sqrt() / 2.0,
            CSCL,
        ),
        ("ZnS", zincblende(), 3f64.sqrt() / 4.0, ZNS),
    ];
    for (name, basis, d, known) in cases {
        let (points, q) = crystal(&basis, 1);
        // The three crystals share the cell, so their order-16 operators:
        // computed once, read from the cache twice.
        let fmm = FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            // Every ion at least an eighth of a cell from the faces (ions on
            // a face converge more slowly: 7.8e-11 for ZnS at order 16).
            .periodic(Periodic::cube(1.0).with_origin([-0.125; 3]))
            .order(16)
            .leaf_size(8)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap();
        let phi = fmm.evaluate(&q).unwrap();
        for m in madelung_sites(&phi, &q, d) {
            assert!(
                (m - known).abs() <= 1e-12 * known,
                "{name}: {m} ({:.1e})",
                (m - known).abs() / known
            );
        }
    }
}

/// `n` points uniform in the cell `[origin, origin + side)` (or in two
/// small balls when `clustered`), zero-mean charges.
pub(crate) fn random_box(
    n: usize,
    side: f64,
    origin: [f64; 3],
    clustered: bool,
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Uniform(seed);
    let mut points = Vec::with_capacity(3 * n);
    for i in 0..n {
        let p: [f64; 3] = if clustered {
            // One ball inside, one straddling the lower x face.
            let c = if i % 2 == 0 {
                [0.6, 0.4, 0.5]
            } else {
                [0.0, 0.7, 0.2]
            };
            std::array::from_fn(|a| c[a] + 0.05 * (rng.random() - 0.5))
        } else {
            std::array::from_fn(|_| rng.random())
        };
        points.extend((0..3).map(|a| origin[a] + side * p[a]));
    }
    let mut q: Vec<f64> = (0..n).map(|_| rng.random() - 0.5).collect();
    let mean = q.iter().sum::<f64>() / n as f64;
    q.iter_mut().for_each(|x| *x -= mean);
    (points, q)
}

pub(crate) fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

/// The potential and gradient errors (relative L2) of a periodic FMM run
/// against the Ewald sum.
fn errors_against_ewald(
    points: &[f64],
    q: &[f64],
    cell: Periodic,
    build: impl FnOnce(
        FmmBuilder<'_, f64, ferrofmm_kernels::Laplace3d>,
    ) -> FmmBuilder<'_, f64, ferrofmm_kernels::Laplace3d>,
) -> (f64, f64) {
    let fmm = build(
        FmmBuilder::new(points)
            .cache_dir(crate::ops_cache())
            .periodic(cell)
            .mode(EvalMode::PotentialGradient),
    )
    .build_with::<FftM2l<f64>>(Default::default())
    .unwrap();
    let out = fmm.evaluate(q).unwrap();
    let ewald = EwaldSum::new(
        PeriodicCell::new(cell.origin(), cell.lengths()).unwrap(),
        points,
        q,
        1e-14,
    )
    .unwrap();
    let truth = ewald.all(EvalMode::PotentialGradient).unwrap();
    split_errors(&out, &truth)
}

/// The potential and gradient errors (relative L2) of `[phi, grad]`
/// values against the truth.
pub(crate) fn split_errors(values: &[f64], truth: &[f64]) -> (f64, f64) {
    let pick = |v: &[f64], grad: bool| -> Vec<f64> {
        v.chunks_exact(4)
            .flat_map(|c| if grad { c[1..].to_vec() } else { vec![c[0]] })
            .collect()
    };
    (
        rel_l2(&pick(values, false), &pick(truth, false)),
        rel_l2(&pick(values, true), &pick(truth, true)),
    )
}

#[test]
fn random_neutral_boxes_against_ewald_at_several_orders() {
    for (clustered, origin) in [(false, [0.0; 3]), (true, [-3.0, 1.0, 1e3])] {
        let (points, q) = random_box(1500, 2.0, origin, clustered, 7);
        let cell = Periodic::cube(2.0).with_origin(origin);
        let mut last = f64::INFINITY;
        for order in [4, 7, 10] {
            let (ep, eg) =
                errors_against_ewald(&points, &q, cell, |b| b.order(order).leaf_size(24));
            // Ten times the free-space rule of thumb (about 10^(1 - p)
            // for the potential at these orders).
            let bound = 10f64.powi(2 - order as i32);
            assert!(
                ep <= bound && eg <= 10.0 * bound,
                "clustered {clustered} p {order}: {ep:e} {eg:e}"
            );
            assert!(ep < last, "the error falls with the order");
            last = ep;
        }
    }
}

#[test]
fn tolerances_are_met_against_ewald() {
    let (points, q) = random_box(1500, 1.0, [0.0; 3], false, 11);
    let cell = Periodic::cube(1.0);
    for eps in [1e-3, 1e-6, 1e-9] {
        let (ep, eg) = errors_against_ewald(&points, &q, cell, |b| b.tolerance(eps));
        assert!(ep <= eps && eg <= eps, "eps {eps:e}: {ep:e} {eg:e}");
    }
}

#[test]
fn points_on_faces_and_corners() {
    // Every point on a face, edge or corner of the cell (and some on the
    // upper faces, which wrap to the lower ones).
    let mut rng = Uniform(3);
    let mut points = Vec::new();
    for i in 0..600 {
        let mut p: [f64; 3] = std::array::from_fn(|_| rng.random());
        p[i % 3] = if i % 2 == 0 { 0.0 } else { 1.0 };
        if i % 7 == 0 {
            p[(i + 1) % 3] = 0.0;
        }
        points.extend(p);
    }
    let q: Vec<f64> = (0..600)
        .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let (ep, eg) = errors_against_ewald(&points, &q, Periodic::cube(1.0), |b| {
        b.order(8).leaf_size(16)
    });
    assert!(ep <= 1e-6 && eg <= 1e-5, "{ep:e} {eg:e}");
}

#[test]
fn lattice_shifts_and_crossing_a_face_change_nothing() {
    let (points, q) = random_box(1500, 1.0, [0.0; 3], false, 5);
    let run = |p: &[f64]| {
        FmmBuilder::new(p)
            .cache_dir(crate::ops_cache())
            .periodic(Periodic::cube(1.0))
            .mode(EvalMode::PotentialGradient)
            .order(8)
            .leaf_size(20)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap()
            .evaluate(&q)
            .unwrap()
    };
    let base = run(&points);
    // Every point by a lattice vector: the same wrapped points.
    let shifted: Vec<f64> = points
        .chunks_exact(3)
        .flat_map(|p| [p[0] + 3.0, p[1] - 2.0, p[2] + 1.0])
        .collect();
    assert!(rel_l2(&run(&shifted), &base) <= 1e-12);
    // One particle across a face.
    let mut moved = points.clone();
    moved[0] += 1.0;
    assert!(rel_l2(&run(&moved), &base) <= 1e-12);
    // A translation by a fraction of a cell: another tree, the same sums
    // to the FMM's accuracy.
    let translated: Vec<f64> = points.iter().map(|x| x + 0.3125).collect();
    assert!(rel_l2(&run(&translated), &base) <= 1e-6);
}

#[test]
fn a_tight_cluster_in_a_huge_box_is_nearly_free_space() {
    let (points, q) = random_box(1000, 1.0, [0.0; 3], false, 9);
    let free = FmmBuilder::new(&points)
        .order(8)
        .leaf_size(20)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap()
        .evaluate(&q)
        .unwrap();
    let periodic = FmmBuilder::new(&points)
        .cache_dir(crate::ops_cache())
        .periodic(Periodic::cube(1e3).with_origin([-500.0; 3]))
        .order(8)
        .leaf_size(20)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap()
        .evaluate(&q)
        .unwrap();
    // Images 1e3 away: their field, and the tin-foil terms, are of
    // relative size (1 / 1e3)^3 at most; the potentials differ by a
    // constant below that too.
    let d = rel_l2(&periodic, &free);
    assert!(d <= 1e-6, "{d:e}");
}

#[test]
fn vacuum_adds_the_dipole_term() {
    let (points, q) = random_box(800, 1.0, [0.0; 3], false, 13);
    let run = |s: SurfaceTerm| {
        FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            .periodic(Periodic::cube(1.0).with_surface(s))
            .mode(EvalMode::PotentialGradient)
            .order(8)
            .leaf_size(20)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap()
            .evaluate(&q)
            .unwrap()
    };
    let (tin, vac) = (run(SurfaceTerm::TinFoil), run(SurfaceTerm::Vacuum));
    let mut d = [0.0; 3];
    for (p, q) in points.chunks_exact(3).zip(&q) {
        for a in 0..3 {
            d[a] += q * (p[a] - 0.5);
        }
    }
    for (k, (t, v)) in tin.chunks_exact(4).zip(vac.chunks_exact(4)).enumerate() {
        let p = &points[3 * k..3 * k + 3];
        let lin: f64 = (0..3).map(|a| d[a] * (p[a] - 0.5)).sum::<f64>() / 3.0;
        assert!((v[0] - t[0] - lin).abs() <= 1e-12 * (1.0 + t[0].abs()));
        for a in 0..3 {
            assert!((v[1 + a] - t[1 + a] - d[a] / 3.0).abs() <= 1e-12 * (1.0 + t[1 + a].abs()));
        }
    }
}

#[test]
fn separate_targets_see_every_image() {
    let (points, q) = random_box(1200, 1.0, [0.0; 3], false, 17);
    let targets: Vec<f64> = random_box(300, 1.0, [0.0; 3], false, 18).0;
    let fmm = FmmBuilder::new(&points)
        .targets(&targets)
        .periodic(Periodic::cube(1.0))
        .order(9)
        .leaf_size(20)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap();
    let phi = fmm.evaluate(&q).unwrap();
    let ewald = EwaldSum::new(
        PeriodicCell::new([0.0; 3], [1.0; 3]).unwrap(),
        &points,
        &q,
        1e-14,
    )
    .unwrap();
    let truth = ewald.at_points(&targets, EvalMode::Potential).unwrap();
    let e = rel_l2(&phi, &truth);
    assert!(e <= 1e-6, "{e:e}");
}

#[test]
fn single_precision_periodic_runs() {
    let (points, q) = random_box(1500, 1.0, [0.0; 3], false, 19);
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    let mut q32 = q32;
    let mean = q32.iter().sum::<f32>() / q32.len() as f32;
    q32.iter_mut().for_each(|x| *x -= mean);
    let fmm = FmmBuilder::<f32, _>::from_f64(&points)
        .periodic(Periodic::cube(1.0))
        .tolerance(1e-4)
        .build_with::<FftM2l<f32>>(Default::default())
        .unwrap();
    let phi = fmm.evaluate(&q32).unwrap();
    let q64: Vec<f64> = q32.iter().map(|&x| f64::from(x)).collect();
    let truth = EwaldSum::new(
        PeriodicCell::new([0.0; 3], [1.0; 3]).unwrap(),
        &points,
        &q64,
        1e-12,
    )
    .unwrap()
    .all(EvalMode::Potential)
    .unwrap();
    let phi: Vec<f64> = phi.iter().map(|&x| f64::from(x)).collect();
    let e = rel_l2(&phi, &truth);
    assert!(e <= 1e-4, "{e:e}");
}

#[test]
fn what_periodic_runs_refuse() {
    let points = [0.1, 0.2, 0.3, 0.6, 0.7, 0.8];
    // A cell that is not neutral.
    let fmm = FmmBuilder::new(&points)
        .cache_dir(crate::ops_cache())
        .periodic(Periodic::cube(1.0))
        .order(4)
        .leaf_size(4)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap();
    assert!(matches!(
        fmm.evaluate(&[1.0, -0.5]),
        Err(FmmError::NotNeutral { .. })
    ));
    assert!(fmm.evaluate(&[1.0, -1.0]).is_ok());
    let refused = |b: FmmBuilder<'_, f64, ferrofmm_kernels::Laplace3d>| {
        matches!(
            b.order(4).leaf_size(4).build_svd(),
            Err(FmmError::InvalidParameter(_))
        )
    };
    assert!(refused(
        FmmBuilder::new(&points).periodic(Periodic::cube(-1.0))
    ));
    assert!(refused(
        FmmBuilder::new(&points).periodic(Periodic::with_lengths([1.0, 2.0, 1.0]))
    ));
    assert!(refused(
        FmmBuilder::new(&points).periodic(
            Periodic::cube(1.0)
                .with_axes(PeriodicAxes::Xy)
                .with_surface(SurfaceTerm::Vacuum)
        )
    ));
    assert!(refused(
        FmmBuilder::new(&points)
            .cache_dir(crate::ops_cache())
            .periodic(Periodic::cube(1.0))
            .source_kind(SourceKind::Dipole)
    ));
    assert!(matches!(
        FmmBuilder::new(&points)
            .kernel(Helmholtz3d::new(1.0).unwrap())
            .periodic(Periodic::cube(1.0))
            .order(4)
            .leaf_size(4)
            .build_svd(),
        Err(FmmError::InvalidParameter(_))
    ));
}

#[test]
fn a_tiny_cell_is_verified_on_every_ion() {
    // Eight ions: the verification samples all of them, so what it
    // measures is the error itself (no noise margin, no endless resampling).
    let (points, q) = crystal(&nacl(), 1);
    let mut fmm = FmmBuilder::new(&points)
        .cache_dir(crate::ops_cache())
        .periodic(Periodic::cube(1.0))
        .tolerance(1e-7)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap();
    let out = fmm.evaluate_verified(&q).unwrap();
    let v = out.verification.unwrap();
    let exact: Vec<f64> = q
        .iter()
        .map(|q| -q * NACL / (4.0 * std::f64::consts::PI * 0.5))
        .collect();
    let error = rel_l2(&out.values, &exact);
    let measured = v.last().measured;
    assert_eq!(measured.n_sampled, 8);
    // The truth is an Ewald sum to a tenth of the tolerance.
    assert!(
        (measured.potential - error).abs() <= 0.1 * 1e-7,
        "measured {:e}, true {error:e}",
        measured.potential
    );
    assert_eq!(v.met, error <= 1e-7, "{error:e}");
}
