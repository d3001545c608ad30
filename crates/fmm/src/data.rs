//! Point sets and charges for demos, tests, benches and sweeps.
//!
//! All generators are deterministic for a given seed and return interleaved
//! `x, y, z` coordinates.

use ferrofmm_kernels::Real;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// The point distributions used by the benchmarks everyone quotes, plus two
/// strongly non-uniform ones that exercise adaptivity.
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
}

impl Geometry {
    /// All geometries.
    pub const ALL: [Geometry; 4] = [
        Geometry::Cube,
        Geometry::Sphere,
        Geometry::Plummer,
        Geometry::TwoClusters,
    ];

    /// Lower-case name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Cube => "cube",
            Geometry::Sphere => "sphere",
            Geometry::Plummer => "plummer",
            Geometry::TwoClusters => "two-clusters",
        }
    }

    /// Parse a name given by [`Geometry::name`] (`clustered` is accepted for Plummer).
    pub fn from_name(name: &str) -> Option<Geometry> {
        match name {
            "cube" => Some(Geometry::Cube),
            "sphere" => Some(Geometry::Sphere),
            "plummer" | "clustered" => Some(Geometry::Plummer),
            "two-clusters" | "twoclusters" => Some(Geometry::TwoClusters),
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

/// `n` charges uniform in `[0, 1)`.
pub fn charges<T: Real>(n: usize, seed: u64) -> Vec<T> {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    (0..n).map(|_| T::from_f64(rng.random::<f64>())).collect()
}
