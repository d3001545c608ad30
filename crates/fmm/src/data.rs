//! Point sets and charges for demos, tests, benches and sweeps.
//!
//! All generators are deterministic for a given seed and return interleaved
//! `x, y, z` coordinates.

use ferrofmm_kernels::Real;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// The point distributions used by the benchmarks everyone quotes, two
/// strongly non-uniform ones that exercise adaptivity, and three thin sets
/// (a plane, a curve, a surface with a hole) whose trees are far from the
/// uniform case: boxes occupied in one or two dimensions only.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Geometry {
    /// Uniform in the unit cube `[0, 1)^3`.
    Cube,
    /// Uniform on the unit sphere's surface.
    Sphere,
    /// A Plummer sphere (scale radius 0.01, truncated at radius 1): density
    /// falling as `(1 + r^2 / a^2)^(-5/2)`, a deep, very non-uniform tree.
    Plummer,
    /// Two clusters of equal counts but sizes differing 1000x, far apart.
    TwoClusters,
    /// Uniform on the unit square `[0, 1)^2` in the plane `z = 0`: a flat
    /// sheet (a tree one box thick at every level).
    Plane,
    /// Uniform along a trefoil knot of diameter about 1: a closed space
    /// curve (a tree one box thick in two directions).
    Curve,
    /// Uniform on a torus surface (radii 0.5 and 0.15): a thin closed
    /// surface with a hole.
    Torus,
}

impl Geometry {
    /// All geometries.
    pub const ALL: [Geometry; 7] = [
        Geometry::Cube,
        Geometry::Sphere,
        Geometry::Plummer,
        Geometry::TwoClusters,
        Geometry::Plane,
        Geometry::Curve,
        Geometry::Torus,
    ];

    /// Lower-case name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Cube => "cube",
            Geometry::Sphere => "sphere",
            Geometry::Plummer => "plummer",
            Geometry::TwoClusters => "two-clusters",
            Geometry::Plane => "plane",
            Geometry::Curve => "curve",
            Geometry::Torus => "torus",
        }
    }

    /// Parse a name given by [`Geometry::name`] (`uniform` is accepted for
    /// the cube, `clustered` for Plummer).
    pub fn from_name(name: &str) -> Option<Geometry> {
        match name {
            "cube" | "uniform" => Some(Geometry::Cube),
            "sphere" => Some(Geometry::Sphere),
            "plummer" | "clustered" => Some(Geometry::Plummer),
            "two-clusters" | "twoclusters" => Some(Geometry::TwoClusters),
            "plane" => Some(Geometry::Plane),
            "curve" => Some(Geometry::Curve),
            "torus" => Some(Geometry::Torus),
            _ => None,
        }
    }

    /// `n` points of this geometry.
    pub fn points<T: Real>(self, n: usize, seed: u64) -> Vec<T> {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(3 * n);
        for i in 0..n {
            let p = match self {
                Geometry::Cube => [rng.random::<f64>(), rng.random(), rng.random()],
                Geometry::Sphere => unit_vector(&mut rng),
                Geometry::Plummer => {
                    // Inverse CDF of the Plummer mass profile, truncated at r = 1.
                    let a = 0.01;
                    loop {
                        let m: f64 = rng.random_range(1e-9..0.999);
                        let r = a / (m.powf(-2.0 / 3.0) - 1.0).sqrt();
                        if r < 1.0 {
                            let u = unit_vector(&mut rng);
                            break [u[0] * r, u[1] * r, u[2] * r];
                        }
                    }
                }
                Geometry::TwoClusters => {
                    let (c, s) = if i % 2 == 0 { (0.0, 1e-1) } else { (1.0, 1e-4) };
                    [
                        c + s * rng.random::<f64>(),
                        c + s * rng.random::<f64>(),
                        c + s * rng.random::<f64>(),
                    ]
                }
                Geometry::Plane => [rng.random::<f64>(), rng.random(), 0.0],
                Geometry::Curve => {
                    // Trefoil knot: (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t) / 6,
                    // uniform in the parameter (the speed varies by about 2x).
                    let t = std::f64::consts::TAU * rng.random::<f64>();
                    [
                        (t.sin() + 2.0 * (2.0 * t).sin()) / 6.0,
                        (t.cos() - 2.0 * (2.0 * t).cos()) / 6.0,
                        -(3.0 * t).sin() / 6.0,
                    ]
                }
                Geometry::Torus => {
                    // Uniform in area: accept the tube angle with
                    // probability (R + r cos v) / (R + r).
                    let (big, small) = (0.5, 0.15);
                    let u = std::f64::consts::TAU * rng.random::<f64>();
                    let v = loop {
                        let v = std::f64::consts::TAU * rng.random::<f64>();
                        if rng.random::<f64>() * (big + small) <= big + small * v.cos() {
                            break v;
                        }
                    };
                    let w = big + small * v.cos();
                    [w * u.cos(), w * u.sin(), small * v.sin()]
                }
            };
            out.extend(p.map(T::from_f64));
        }
        out
    }
}

fn unit_vector(rng: &mut StdRng) -> [f64; 3] {
    loop {
        let v: [f64; 3] = [
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
        ];
        let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if r > 1e-12 {
            return [v[0] / r, v[1] / r, v[2] / r];
        }
    }
}

/// How built-in charges are drawn.
///
/// The choice changes what an accuracy figure means. With all-positive
/// charges the potential is dominated by its smooth mean, `sum q / r`,
/// which every FMM gets almost right, so the relative error of the
/// potential looks about 8x smaller than with zero-mean charges (and that
/// of the gradient larger, since the mean field of a uniform cloud vanishes
/// near its centre). Zero-mean charges are what the peers' tests use
/// (ExaFMM-T: uniform in `[-0.5, 0.5)`; FMM3D: random signs) and what ions,
/// dipole layers and most electrostatics look like; they are the default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Charges {
    /// Zero-mean: uniform in `[-0.5, 0.5)` (the default).
    #[default]
    Signed,
    /// All positive: uniform in `[0, 1)`.
    Positive,
}

impl Charges {
    /// Both kinds, zero-mean first.
    pub const ALL: [Charges; 2] = [Charges::Signed, Charges::Positive];

    /// `"signed"` or `"positive"`, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Charges::Signed => "signed",
            Charges::Positive => "positive",
        }
    }

    /// Parse a name given by [`Charges::name`] (`zero-mean` is accepted for
    /// [`Charges::Signed`]).
    pub fn from_name(name: &str) -> Option<Charges> {
        match name {
            "signed" | "zero-mean" => Some(Charges::Signed),
            "positive" => Some(Charges::Positive),
            _ => None,
        }
    }

    /// `n` charges of this kind (deterministic for a seed; the two kinds
    /// differ by the constant 0.5 for the same seed).
    pub fn generate<T: Real>(self, n: usize, seed: u64) -> Vec<T> {
        let shift = match self {
            Charges::Signed => -0.5,
            Charges::Positive => 0.0,
        };
        let mut rng = StdRng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
        (0..n)
            .map(|_| T::from_f64(rng.random::<f64>() + shift))
            .collect()
    }
}

/// `n` zero-mean charges, uniform in `[-0.5, 0.5)` ([`Charges::Signed`],
/// the peers' workload); [`Charges::generate`] gives the other kind.
pub fn charges<T: Real>(n: usize, seed: u64) -> Vec<T> {
    Charges::Signed.generate(n, seed)
}
