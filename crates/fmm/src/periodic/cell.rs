//! The periodic cell a user gives: its size, origin, repeating axes and
//! how the Laplace lattice sum is closed at infinity.

use std::fmt;
use std::str::FromStr;

use ferrofmm_tree::Domain;

use crate::FmmError;

/// Which axes repeat: all three (bulk), `x` and `y` (a slab) or `x` (a
/// rod). In a slab or rod the other axes are free space, and the points
/// must lie within the cell along them (the octree's root is the cell).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PeriodicAxes {
    /// Fully periodic: `x`, `y` and `z` (bulk systems).
    #[default]
    Xyz,
    /// A slab: `x` and `y` repeat, `z` is free space.
    Xy,
    /// A rod: `x` repeats, `y` and `z` are free space.
    X,
}

impl PeriodicAxes {
    /// Whether each of `x`, `y`, `z` repeats.
    pub fn mask(self) -> [bool; 3] {
        match self {
            PeriodicAxes::Xyz => [true; 3],
            PeriodicAxes::Xy => [true, true, false],
            PeriodicAxes::X => [true, false, false],
        }
    }

    /// `"bulk"`, `"slab"` or `"rod"`.
    pub fn kind(self) -> &'static str {
        match self {
            PeriodicAxes::Xyz => "bulk",
            PeriodicAxes::Xy => "slab",
            PeriodicAxes::X => "rod",
        }
    }

    /// `"xyz"`, `"xy"` or `"x"`.
    pub fn name(self) -> &'static str {
        match self {
            PeriodicAxes::Xyz => "xyz",
            PeriodicAxes::Xy => "xy",
            PeriodicAxes::X => "x",
        }
    }
}

impl fmt::Display for PeriodicAxes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for PeriodicAxes {
    type Err = FmmError;

    /// `"xyz"`, `"xy"` or `"x"` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, FmmError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "xyz" => Ok(PeriodicAxes::Xyz),
            "xy" => Ok(PeriodicAxes::Xy),
            "x" => Ok(PeriodicAxes::X),
            other => Err(FmmError::InvalidParameter(format!(
                "periodic axes {other:?}: use \"xyz\" (bulk), \"xy\" (slab) or \"x\" (rod)"
            ))),
        }
    }
}

/// How the conditionally convergent Laplace lattice sum is closed at
/// infinity (see the [module docs](super)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SurfaceTerm {
    /// Conducting surroundings: Ewald's sum without its `k = 0` term, what
    /// particle-mesh Ewald codes compute by default.
    #[default]
    TinFoil,
    /// A sphere of cells in vacuum: tin-foil plus the dipole term
    /// `D . (y - c) / (3 V)` (potential) and `D / (3 V)` (gradient).
    Vacuum,
}

impl FromStr for SurfaceTerm {
    type Err = FmmError;

    /// `"tin-foil"` (or `"tinfoil"`, `"conducting"`) or `"vacuum"`.
    fn from_str(s: &str) -> Result<Self, FmmError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "tin-foil" | "tinfoil" | "conducting" => Ok(SurfaceTerm::TinFoil),
            "vacuum" => Ok(SurfaceTerm::Vacuum),
            other => Err(FmmError::InvalidParameter(format!(
                "surface term {other:?}: use \"tin-foil\" or \"vacuum\""
            ))),
        }
    }
}

/// A periodic boundary condition: the cell `[origin, origin + L)` that
/// repeats along [`PeriodicAxes`], and the [`SurfaceTerm`].
///
/// Points anywhere are accepted and wrapped into the cell (as molecular
/// dynamics codes do); the results are in the caller's order.
///
/// ```
/// use ferrofmm_fmm::{Periodic, PeriodicAxes, SurfaceTerm};
/// let cell = Periodic::cube(2.0).with_origin([-1.0; 3]);
/// assert_eq!(cell.wrap([1.5, -1.0, 0.25]), [-0.5, -1.0, 0.25]);
/// assert_eq!(cell.axes(), PeriodicAxes::Xyz);
/// assert_eq!(cell.surface(), SurfaceTerm::TinFoil);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Periodic {
    origin: [f64; 3],
    lengths: [f64; 3],
    axes: PeriodicAxes,
    surface: SurfaceTerm,
}

impl Periodic {
    /// A cubic cell of side `width` at the origin, periodic in `x`, `y`
    /// and `z`, tin-foil surroundings.
    pub fn cube(width: f64) -> Self {
        Periodic {
            origin: [0.0; 3],
            lengths: [width; 3],
            axes: PeriodicAxes::Xyz,
            surface: SurfaceTerm::TinFoil,
        }
    }

    /// A box of side lengths `lengths` (`x`, `y`, `z`). Only cubes run in
    /// this release ([`Periodic::validate`] refuses other boxes): the
    /// octree's root is the cell.
    pub fn with_lengths(lengths: [f64; 3]) -> Self {
        Periodic {
            lengths,
            ..Periodic::cube(lengths[0])
        }
    }

    /// The same cell with its lower corner at `origin`.
    pub fn with_origin(mut self, origin: [f64; 3]) -> Self {
        self.origin = origin;
        self
    }

    /// The same cell repeating along `axes`.
    pub fn with_axes(mut self, axes: PeriodicAxes) -> Self {
        self.axes = axes;
        self
    }

    /// The same cell with the surface term `surface`.
    pub fn with_surface(mut self, surface: SurfaceTerm) -> Self {
        self.surface = surface;
        self
    }

    /// The cell's lower corner.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// The cell's side (of a cube).
    pub fn width(&self) -> f64 {
        self.lengths[0]
    }

    /// The cell's side lengths.
    pub fn lengths(&self) -> [f64; 3] {
        self.lengths
    }

    /// The repeating axes.
    pub fn axes(&self) -> PeriodicAxes {
        self.axes
    }

    /// The surface term.
    pub fn surface(&self) -> SurfaceTerm {
        self.surface
    }

    /// The cell's volume `L^3`.
    pub fn volume(&self) -> f64 {
        self.lengths.iter().product()
    }

    /// The cell's centre.
    pub fn centre(&self) -> [f64; 3] {
        std::array::from_fn(|a| self.origin[a] + 0.5 * self.lengths[a])
    }

    /// Checks the cell.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] for a side that is not finite and
    /// positive, an origin that is not finite, a box that is not a cube,
    /// or the vacuum surface term with a slab or rod (their lattice sums
    /// converge without one).
    pub fn validate(&self) -> Result<(), FmmError> {
        if let Some(l) = self.lengths.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
            return Err(FmmError::InvalidParameter(format!(
                "periodic box side {l}: it must be finite and positive"
            )));
        }
        if let Some(o) = self.origin.iter().find(|o| !o.is_finite()) {
            return Err(FmmError::InvalidParameter(format!(
                "periodic box origin {o} is not finite"
            )));
        }
        let [a, b, c] = self.lengths;
        if a != b || a != c {
            return Err(FmmError::InvalidParameter(format!(
                "periodic box {a} x {b} x {c}: only cubic cells are supported (the octree's \
                 root is the cell); give one side, or scale the coordinates to a cube"
            )));
        }
        if self.axes != PeriodicAxes::Xyz && self.surface == SurfaceTerm::Vacuum {
            return Err(FmmError::InvalidParameter(format!(
                "the vacuum surface term closes the conditionally convergent bulk (\"xyz\") \
                 lattice sum; a {}'s converges without one: leave the surface term at its \
                 default",
                self.axes.kind()
            )));
        }
        Ok(())
    }

    /// Refuse points outside the cell along the axes that do not repeat
    /// (interleaved, already wrapped along those that do).
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] naming the first such point.
    pub fn check_open_axes(&self, what: &str, points: &[f64]) -> Result<(), FmmError> {
        let mask = self.axes.mask();
        for (i, p) in points.chunks_exact(3).enumerate() {
            for a in (0..3).filter(|&a| !mask[a]) {
                let (lo, hi) = (self.origin[a], self.origin[a] + self.lengths[a]);
                if !(p[a] >= lo && p[a] < hi) {
                    return Err(FmmError::InvalidParameter(format!(
                        "{what} point {i} has {} = {}, outside the {} cell [{lo}, {hi}) along \
                         its open axis: a {}'s points must lie within the cell along the axes \
                         that do not repeat (the octree's root is the cell); give a larger \
                         box or another origin",
                        ["x", "y", "z"][a],
                        p[a],
                        self.axes.kind(),
                        self.axes.kind()
                    )));
                }
            }
        }
        Ok(())
    }

    /// The octree domain of the cell.
    pub(crate) fn domain(&self) -> Result<Domain, FmmError> {
        Ok(Domain::new(self.origin, self.width())?)
    }

    /// `p` moved by whole cells along the periodic axes into
    /// `[origin, origin + L)`.
    pub fn wrap(&self, p: [f64; 3]) -> [f64; 3] {
        let mask = self.axes.mask();
        std::array::from_fn(|a| {
            if !mask[a] {
                return p[a];
            }
            let l = self.lengths[a];
            let mut t = (p[a] - self.origin[a]).rem_euclid(l);
            // `rem_euclid` of a tiny negative number rounds to `l` itself.
            if t >= l {
                t = 0.0;
            }
            let w = self.origin[a] + t;
            // `origin + t` may round up to the upper face.
            if w >= self.origin[a] + l {
                self.origin[a]
            } else {
                w
            }
        })
    }

    /// Every point of `points` (interleaved) wrapped into the cell.
    pub fn wrap_all(&self, points: &[f64]) -> Vec<f64> {
        points
            .chunks_exact(3)
            .flat_map(|p| self.wrap([p[0], p[1], p[2]]))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_lands_inside_the_cell() {
        let cell = Periodic::cube(1.0).with_origin([0.5, -2.0, 1e8]);
        for p in [
            [0.5, -2.0, 1e8],
            [1.5, -1.0, 1e8 + 1.0],
            [-1e-17, 7.25, -3.0],
            [0.5 - 1e-17, -2.0 - 1e-300, 1e8 - 1e-9],
        ] {
            let w = cell.wrap(p);
            for a in 0..3 {
                assert!(
                    w[a] >= cell.origin[a] && w[a] < cell.origin[a] + 1.0,
                    "{p:?} -> {w:?}"
                );
            }
        }
    }

    #[test]
    fn bad_cells_are_refused() {
        assert!(Periodic::cube(0.0).validate().is_err());
        assert!(Periodic::cube(f64::NAN).validate().is_err());
        assert!(
            Periodic::cube(1.0)
                .with_origin([f64::INFINITY, 0.0, 0.0])
                .validate()
                .is_err()
        );
        assert!(Periodic::with_lengths([1.0, 2.0, 1.0]).validate().is_err());
        assert!(
            Periodic::cube(1.0)
                .with_axes(PeriodicAxes::Xy)
                .validate()
                .is_ok()
        );
        assert!(
            Periodic::cube(1.0)
                .with_axes(PeriodicAxes::X)
                .with_surface(SurfaceTerm::Vacuum)
                .validate()
                .is_err()
        );
        assert!(Periodic::cube(1.0).validate().is_ok());
        assert!("xz".parse::<PeriodicAxes>().is_err());
        assert_eq!("XY".parse::<PeriodicAxes>().unwrap(), PeriodicAxes::Xy);
        assert_eq!(
            "vacuum".parse::<SurfaceTerm>().unwrap(),
            SurfaceTerm::Vacuum
        );
    }
}
