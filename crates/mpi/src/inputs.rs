//! Test and benchmark point sets of the distributed commands: the
//! single-machine driver's [`Geometry`] (`ferrofmm_fmm::data`), one
//! generator for both, so that a distributed run and its single-machine
//! reference draw the same points from the same seed.

pub use ferrofmm_fmm::Geometry;

/// The geometries the `check` and `fmm-check` commands run when none is
/// named: a uniform cube, a sphere surface, a Plummer sphere and two
/// clusters of very different sizes (a uniform, a thin, a strongly graded
/// and a two-scale tree).
pub const CHECK_GEOMETRIES: [Geometry; 4] = [
    Geometry::Cube,
    Geometry::Sphere,
    Geometry::Plummer,
    Geometry::TwoClusters,
];
