//! Periodic boundaries for kernels the library has no lattice sum of
//! (issue 32, "user kernels where their lattice sum converges"): a user's
//! own kernel and damped Helmholtz waves, their far images summed over
//! super-cells ([`LatticeSum::Images`]). A user kernel that is Yukawa in
//! disguise is checked against the library's screened Ewald sum (a truth
//! that knows nothing of images); the others against the image sum.

use super::periodic::{random_box, split_errors as errors};
use ferrofmm_field::FftM2l;
use ferrofmm_fmm::periodic::{LatticeSum, lattice_sum};
use ferrofmm_fmm::{
    FmmBuilder, FmmError, Periodic, PeriodicAxes, relative_errors, relative_errors_periodic,
};
use ferrofmm_kernels::{
    EvalMode, EwaldOptions, EwaldSum, Helmholtz3d, Kernel, PeriodicCell, Real, SlabGreen,
};

/// `e^{-r / a} / (4 pi r)`: the Yukawa kernel, written as a user would
/// (pairwise values and gradients only), unknown to the library's lattice
/// sums.
#[derive(Clone)]
struct Screened {
    a: f64,
}

impl Kernel for Screened {
    fn name(&self) -> String {
        "test-screened".into()
    }
    fn parameters(&self) -> Vec<f64> {
        vec![self.a]
    }
    fn homogeneity(&self) -> Option<f64> {
        None
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().to_f64();
        T::from_f64((-r / self.a).exp() / (4.0 * std::f64::consts::PI * r))
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().to_f64();
        // d/dr (e^{-r/a} / (4 pi r)) = -e^{-r/a} (1 + r/a) / (4 pi r^2).
        let dk = -(-r / self.a).exp() * (1.0 + r / self.a) / (4.0 * std::f64::consts::PI * r * r);
        d.map(|x| T::from_f64(dk * x.to_f64() / r))
    }
}

/// `1 / r^p`: homogeneous of degree `-p`; its bulk lattice sum converges
/// for `p > 3` only.
#[derive(Clone)]
struct Power {
    p: f64,
}

impl Kernel for Power {
    fn name(&self) -> String {
        "test-power".into()
    }
    fn parameters(&self) -> Vec<f64> {
        vec![self.p]
    }
    fn homogeneity(&self) -> Option<f64> {
        Some(-self.p)
    }
    fn kernel_value<T: Real>(&self, d: [T; 3]) -> T {
        let r2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).to_f64();
        T::from_f64(r2.powf(-0.5 * self.p))
    }
    fn kernel_gradient<T: Real>(&self, d: [T; 3]) -> [T; 3] {
        let r2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).to_f64();
        let f = -self.p * r2.powf(-0.5 * self.p - 1.0);
        d.map(|x| T::from_f64(f * x.to_f64()))
    }
}

fn run<K: Kernel>(kernel: K, points: &[f64], q: &[f64], cell: Periodic, order: usize) -> Vec<f64> {
    FmmBuilder::new(points)
        .kernel(kernel)
        .periodic(cell)
        .mode(EvalMode::PotentialGradient)
        .order(order)
        .leaf_size(32)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap()
        .evaluate(q)
        .unwrap()
}

/// Positive charges in `[0.5, 1.5)` (far from neutral).
fn positive(n: usize, seed: u64) -> Vec<f64> {
    let (_, q) = random_box(n, 1.0, [0.0; 3], false, seed);
    q.iter().map(|x| x + 1.0).collect()
}

/// A user's kernel goes through the super-cells; written to be Yukawa, it
/// meets the library's screened Ewald sum as the built-in Yukawa does: the
/// error falls with the order, to the free-space rule of thumb, for
/// positive charges, weak (`L / a = 1`, orders 3 and 5) and strong (`L / a
/// = 8`, a clustered box, order 5) screening.
#[test]
fn a_user_kernel_meets_the_screened_ewald_sum() {
    let screened = Screened { a: 1.0 };
    assert_eq!(
        lattice_sum(&screened),
        Some(LatticeSum::Images { components: 1 })
    );
    for (clustered, a, n, orders) in [(false, 1.0, 800, &[3, 5][..]), (true, 0.125, 600, &[5])] {
        let (points, _) = random_box(n, 1.0, [0.0; 3], clustered, 3);
        let q = positive(n, 4);
        let cell = Periodic::cube(1.0);
        let ewald = PeriodicCell::new([0.0; 3], [1.0; 3]).unwrap();
        let truth = EwaldSum::with_options(
            ewald,
            &points,
            &q,
            EwaldOptions::new(1e-14).screening(1.0 / a),
        )
        .unwrap()
        .all(EvalMode::PotentialGradient)
        .unwrap();
        let mut last = f64::INFINITY;
        for &order in orders {
            let out = run(Screened { a }, &points, &q, cell, order);
            let (ep, eg) = errors(&out, &truth);
            let bound = 10f64.powi(2 - order as i32);
            assert!(
                ep <= bound && eg <= 10.0 * bound,
                "a {a} p {order}: {ep:e} {eg:e}"
            );
            assert!(ep < last, "a {a}: the error falls with the order");
            last = ep;
        }
    }
}

/// A slab of the same user kernel against the library's screened slab sum.
#[test]
fn a_user_kernel_in_a_slab() {
    let n = 800;
    let (points, _) = random_box(n, 1.0, [0.0; 3], false, 9);
    let q = positive(n, 10);
    let cell = Periodic::cube(1.0).with_axes(PeriodicAxes::Xy);
    let green =
        SlabGreen::screened(PeriodicCell::new([0.0; 3], [1.0; 3]).unwrap(), 2.0, 1e-14).unwrap();
    let all: Vec<usize> = (0..n).collect();
    let truth = green
        .sum_at_sources(&points, &q, &all, EvalMode::PotentialGradient)
        .unwrap();
    let out = run(Screened { a: 0.5 }, &points, &q, cell, 8);
    let (ep, eg) = errors(&out, &truth);
    assert!(ep <= 1e-6 && eg <= 1e-5, "{ep:e} {eg:e}");
}

/// A dispersion-like `r^-6` kernel and damped Helmholtz waves against
/// their image sums (the library's [`relative_errors_periodic`], zero-mean
/// and positive charges). The `r^-6` FMM is no more accurate in free space
/// (its check matrices are far worse conditioned than Laplace's, and its
/// error grows from order 6 on): the periodic run is held to its
/// free-space error at the same order.
#[test]
fn power_law_and_damped_waves_against_image_sums() {
    let n = 600;
    let (points, zero_mean) = random_box(n, 1.0, [0.0; 3], false, 5);
    let cell = Periodic::cube(1.0);
    let sample: Vec<usize> = (0..n).step_by(5).collect();
    let kernel = Power { p: 6.0 };
    {
        let order = 4;
        let out = run(kernel.clone(), &points, &zero_mean, cell, order);
        let periodic = relative_errors_periodic(
            &kernel,
            &cell,
            EvalMode::PotentialGradient,
            &points,
            &zero_mean,
            None,
            &out,
            &sample,
        )
        .unwrap();
        let free = FmmBuilder::new(&points)
            .kernel(kernel.clone())
            .mode(EvalMode::PotentialGradient)
            .order(order)
            .leaf_size(32)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap()
            .evaluate(&zero_mean)
            .unwrap();
        let free = relative_errors(
            &kernel,
            EvalMode::PotentialGradient,
            &points,
            &zero_mean,
            &points,
            &free,
            &sample,
        );
        assert!(
            periodic.worst() <= 3.0 * free.worst() + 1e-12,
            "r^-6 p {order}: {periodic:?} against free space {free:?}"
        );
    }
    // Complex charges for a complex kernel: [re, im] per source.
    let q: Vec<f64> = positive(n, 6)
        .iter()
        .zip(&zero_mean)
        .flat_map(|(a, b)| [*a, *b])
        .collect();
    let kernel = Helmholtz3d::new_complex(6.0, 8.0).unwrap();
    let mut last = f64::INFINITY;
    for order in [3, 5] {
        let out = run(kernel, &points, &q, cell, order);
        let e = relative_errors_periodic(
            &kernel,
            &cell,
            EvalMode::PotentialGradient,
            &points,
            &q,
            None,
            &out,
            &sample,
        )
        .unwrap();
        let bound = 10f64.powi(2 - order as i32);
        assert!(e.worst() <= 10.0 * bound, "damped p {order}: {e:?}");
        assert!(e.worst() < last);
        last = e.worst();
    }
}

/// A tolerance is chosen and verified against the image sum, and met
/// against the screened Ewald sum.
#[test]
fn a_user_kernel_takes_a_tolerance() {
    let n = 300;
    let (points, _) = random_box(n, 1.0, [0.0; 3], false, 13);
    let q = positive(n, 14);
    let cell = Periodic::cube(1.0);
    let ewald = PeriodicCell::new([0.0; 3], [1.0; 3]).unwrap();
    let truth =
        EwaldSum::with_options(ewald, &points, &q, EwaldOptions::new(1e-14).screening(10.0))
            .unwrap()
            .all(EvalMode::PotentialGradient)
            .unwrap();
    {
        let eps = 1e-4;
        let mut fmm = FmmBuilder::new(&points)
            .kernel(Screened { a: 0.1 })
            .periodic(cell)
            .mode(EvalMode::PotentialGradient)
            .tolerance(eps)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap();
        let out = fmm.evaluate_verified(&q).unwrap();
        let measured = out.verification.expect("verified").measured();
        assert!(
            measured.n_sampled > 0 && measured.worst() <= eps,
            "{measured:?}"
        );
        let (ep, eg) = errors(&out.values, &truth);
        assert!(ep <= eps && eg <= eps, "eps {eps:e}: {ep:e} {eg:e}");
    }
}

/// Sums that do not converge are refused when building, with the reason:
/// `r^-2` and `r^-3` in bulk, undamped waves; `r^-2` converges in a rod.
#[test]
fn sums_that_do_not_converge_are_refused() {
    let (points, q) = random_box(300, 1.0, [0.0; 3], false, 1);
    for p in [2.0, 3.0] {
        let e = FmmBuilder::new(&points)
            .kernel(Power { p })
            .periodic(Periodic::cube(1.0))
            .order(4)
            .build_with::<FftM2l<f64>>(Default::default())
            .err()
            .expect("refused");
        assert!(
            matches!(e, FmmError::InvalidParameter(_)) && e.to_string().contains("converge"),
            "p {p}: {e}"
        );
    }
    let e = FmmBuilder::new(&points)
        .kernel(Helmholtz3d::new(3.0).unwrap())
        .periodic(Periodic::cube(1.0))
        .order(4)
        .build_with::<FftM2l<f64>>(Default::default())
        .err()
        .expect("refused");
    assert!(e.to_string().contains("damped"), "{e}");
    // A rod of r^-3 sources converges (one periodic axis).
    let fmm = FmmBuilder::new(&points)
        .kernel(Power { p: 3.0 })
        .periodic(Periodic::cube(1.0).with_axes(PeriodicAxes::X))
        .mode(EvalMode::Potential)
        .order(4)
        .build_with::<FftM2l<f64>>(Default::default())
        .unwrap();
    assert_eq!(fmm.evaluate(&q).unwrap().len(), 300);
}

/// Weakly damped waves need super-cells too many wavelengths wide: refused
/// with the reason, never summed wrongly; strongly damped ones stop after
/// the rings their decay leaves.
#[test]
fn weakly_damped_waves_are_refused() {
    let (points, _) = random_box(200, 1.0, [0.0; 3], false, 2);
    let e = FmmBuilder::new(&points)
        .kernel(Helmholtz3d::new_complex(6.0, 0.05).unwrap())
        .periodic(Periodic::cube(1.0))
        .order(4)
        .build_with::<FftM2l<f64>>(Default::default())
        .err()
        .expect("refused");
    assert!(e.to_string().contains("damped too weakly"), "{e}");
}
