//! Test and benchmark point sets: uniform cube, sphere surface, Plummer
//! sphere, two clusters of very different sizes; deterministic by seed.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// A point distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Geometry {
    /// Uniform in the unit cube.
    Uniform,
    /// Uniform on the unit sphere.
    Sphere,
    /// Plummer profile (scale 0.01, truncated at radius 1): strongly
    /// clustered at the centre.
    Plummer,
    /// Half the points in a cube of side 0.1 at the origin, half in one of
    /// side 1e-4 at (1, 1, 1).
    TwoClusters,
}

impl Geometry {
    /// All geometries.
    pub const ALL: [Geometry; 4] = [
        Geometry::Uniform,
        Geometry::Sphere,
        Geometry::Plummer,
        Geometry::TwoClusters,
    ];

    /// Name as parsed by [`Geometry::from_name`].
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Uniform => "uniform",
            Geometry::Sphere => "sphere",
            Geometry::Plummer => "plummer",
            Geometry::TwoClusters => "two-clusters",
        }
    }

    /// The geometry called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|g| g.name() == name)
    }

    /// `n` interleaved `xyz` points.
    pub fn points(self, n: usize, seed: u64) -> Vec<f64> {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(3 * n);
        for i in 0..n {
            let p = match self {
                Geometry::Uniform => [rng.random::<f64>(), rng.random(), rng.random()],
                Geometry::Sphere => direction(&mut rng),
                Geometry::Plummer => loop {
                    let m: f64 = rng.random_range(1e-9..0.999);
                    let r = 0.01 / (m.powf(-2.0 / 3.0) - 1.0).sqrt();
                    if r < 1.0 {
                        break direction(&mut rng).map(|x| x * r);
                    }
                },
                Geometry::TwoClusters => {
                    let (c, s) = if i % 2 == 0 { (0.0, 0.1) } else { (1.0, 1e-4) };
                    [0; 3].map(|_| c + s * rng.random::<f64>())
                }
            };
            out.extend_from_slice(&p);
        }
        out
    }
}

fn direction(rng: &mut StdRng) -> [f64; 3] {
    loop {
        let v: [f64; 3] = [0; 3].map(|_| StandardNormal.sample(rng));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 1e-12 {
            return v.map(|x| x / n);
        }
    }
}
