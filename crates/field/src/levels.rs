//! Which operator set serves which tree level, and the homogeneous scaling.
//!
//! A level-`l` box of a domain of width `W` has half-width
//! `h_l = W / 2^(l+1)`; for a kernel homogeneous of degree `d`,
//! `K(s x, s y) = s^d K(x, y)`, so an operator computed at `h_ref` serves
//! every level scaled by `(h_l / h_ref)^(power d)`. Uses only
//! [`FieldError`].

use crate::FieldError;

/// First tree level with V-list interactions (boxes of level 1 are all
/// neighbours of each other): the shallowest level an M2L operator set
/// serves.
pub const FIRST_M2L_LEVEL: u32 = 2;

/// Half-width of the reference box at which the operators of a homogeneous
/// kernel are computed (independent of the domain, so cache files are too).
pub const REFERENCE_HALF_WIDTH: f64 = 1.0;

/// Maps tree levels to precomputed operator sets.
///
/// For a kernel homogeneous of degree `d` there is one set, computed at half
/// width `h_ref = 1`; a level with half-width `h` uses it scaled by
/// `(h / h_ref)^(power * d)` (kernel matrices: `power = 1`, pseudo-inverses:
/// `power = -1`). Otherwise there is one set per level in
/// `first_level..=depth`, each computed at its own half-width.
///
/// ```
/// use ferrofmm_field::plumbing::LevelMap;
/// // Laplace (degree -1), levels 2..=5 of a domain of width 8.
/// let map = LevelMap::new(Some(-1.0), 8.0, 5, 2).unwrap();
/// assert_eq!(map.n_sets(), 1);
/// assert_eq!(map.half_width(3), 0.5);
/// // Kernel matrices at level 3 are those at h = 1 times 0.5^-1.
/// assert_eq!(map.lookup(3, 1.0), (0, 2.0));
/// // A non-homogeneous kernel: one set per level 2..=5.
/// let map = LevelMap::new(None, 8.0, 5, 2).unwrap();
/// assert_eq!((map.n_sets(), map.lookup(4, 1.0)), (4, (2, 1.0)));
/// ```
#[derive(Clone, Debug)]
pub struct LevelMap {
    /// Degree `d` of homogeneity (`K(s x, s y) = s^d K(x, y)`), `None` for
    /// a kernel that has none.
    pub homogeneity: Option<f64>,
    /// Width of the cubic domain (the root box).
    pub domain_width: f64,
    /// Deepest level served.
    pub depth: u32,
    /// Shallowest level served (2 for M2L, see
    /// [`FIRST_M2L_LEVEL`]).
    pub first_level: u32,
}

impl LevelMap {
    /// The map for a kernel of `homogeneity` on a domain of
    /// `domain_width`, levels `first_level..=depth`.
    ///
    /// # Errors
    /// [`FieldError::InvalidGeometry`] for a width that is not finite and
    /// positive, a depth above 30 or a non-finite degree.
    pub fn new(
        homogeneity: Option<f64>,
        domain_width: f64,
        depth: u32,
        first_level: u32,
    ) -> Result<Self, FieldError> {
        if !(domain_width.is_finite() && domain_width > 0.0) {
            return Err(FieldError::InvalidGeometry(format!(
                "domain width must be finite and positive, got {domain_width}"
            )));
        }
        if depth > 30 {
            return Err(FieldError::InvalidGeometry(format!(
                "depth must be at most 30, got {depth}"
            )));
        }
        if let Some(d) = homogeneity
            && !d.is_finite()
        {
            return Err(FieldError::InvalidGeometry(format!(
                "kernel homogeneity degree must be finite, got {d}"
            )));
        }
        Ok(LevelMap {
            homogeneity,
            domain_width,
            depth,
            first_level,
        })
    }

    /// Half-width of a box at `level`: `domain_width / 2^(level + 1)`.
    pub fn half_width(&self, level: u32) -> f64 {
        half_width(self.domain_width, level)
    }

    /// Number of operator sets to compute.
    pub fn n_sets(&self) -> usize {
        match self.homogeneity {
            Some(_) => 1,
            None => (self.depth + 1).saturating_sub(self.first_level) as usize,
        }
    }

    /// Half-width at which set `s` is computed.
    pub fn set_half_width(&self, s: usize) -> f64 {
        match self.homogeneity {
            Some(_) => REFERENCE_HALF_WIDTH,
            None => self.half_width(self.first_level + s as u32),
        }
    }

    /// The set serving `level` and the factor `(h / h_set)^(power d)`.
    ///
    /// # Panics
    /// For a non-homogeneous kernel when `level` is outside
    /// `first_level..=depth`.
    pub fn lookup(&self, level: u32, power: f64) -> (usize, f64) {
        match self.homogeneity {
            Some(d) => {
                let s = self.half_width(level) / REFERENCE_HALF_WIDTH;
                (0, s.powf(power * d))
            }
            None => {
                assert!(
                    level >= self.first_level && level <= self.depth,
                    "level {level} has no operators (computed for levels {}..={})",
                    self.first_level,
                    self.depth
                );
                ((level - self.first_level) as usize, 1.0)
            }
        }
    }
}

/// Half-width of a box at `level` of a cubic domain of width `domain_width`.
pub fn half_width(domain_width: f64, level: u32) -> f64 {
    domain_width / f64::powi(2.0, level as i32 + 1)
}
