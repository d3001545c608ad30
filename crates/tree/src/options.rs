//! Options controlling how an [`Octree`](crate::Octree) is refined.
//!
//! **Adaptive trees** (the default): starting from the root, a box is split
//! while it holds more than `leaf_size` points and is above `max_level`.
//! With separate source and target sets a box's size is
//! `max(#sources, #targets)` — the larger of the two counts, so that neither
//! side of a leaf-to-leaf (P2P) interaction exceeds `leaf_size` points; when
//! sources are targets it is simply the number of points. Only the non-empty
//! children of a split box are created. Afterwards the tree is 2:1 balanced
//! (see [`balance`](crate::balance)), which may split a few more leaves,
//! unless `balance` is off: then the refined tree is kept as it is and no
//! interaction lists are built (their construction relies on the balance).
//!
//! **Uniform trees** (`uniform_depth = Some(d)`): every non-empty box above
//! level `d` is split, whatever it holds, so every leaf is at level `d`;
//! `leaf_size` and `max_level` are not used for refinement and no balancing
//! is needed.

use crate::domain::Domain;
use crate::error::TreeError;
use crate::morton::DEEPEST_LEVEL;

/// How to build an [`Octree`](crate::Octree).
#[derive(Clone, Debug)]
pub struct TreeOptions {
    /// A leaf is split while it holds more than this many points (counted as
    /// `max(#sources, #targets)`). Must be at least 1. Default 150.
    pub leaf_size: usize,
    /// No box deeper than this level is created; leaves at this level may
    /// hold more than `leaf_size` points. At most [`DEEPEST_LEVEL`] (the
    /// default).
    pub max_level: u32,
    /// The domain to use, or `None` (default) for the bounding cube of the
    /// sources and targets together ([`Domain::from_points`]). A given domain
    /// must contain every point (upper faces included).
    pub domain: Option<Domain>,
    /// `Some(d)`: a uniform tree whose leaves are all at level `d` (still
    /// without empty boxes). Default `None` (adaptive).
    pub uniform_depth: Option<u32>,
    /// 2:1-balance an adaptive tree (default `true`). Off, the tree is the
    /// plain refinement of the points, and its interaction lists are empty
    /// ([`Octree::has_lists`](crate::Octree::has_lists) is `false`): the
    /// lists, and so the FMM, need a balanced tree.
    pub balance: bool,
    /// Periodic axes (x, y, z); default all `false` (free space). Along a
    /// periodic axis the cell (the given [`domain`](Self::domain), which is
    /// then required and is the root box) repeats: the 2:1 balance, the
    /// colleague table and every interaction list wrap around its faces,
    /// and each list entry carries the image shift of its source box (see
    /// [`lists`](crate::lists)). Points must lie in the half-open
    /// `[origin, origin + width)` along periodic axes: a point on the upper
    /// face is refused ([`TreeError::OnPeriodicFace`]; wrap it to the lower
    /// face first).
    pub periodic: [bool; 3],
}

impl Default for TreeOptions {
    fn default() -> Self {
        TreeOptions {
            leaf_size: 150,
            max_level: DEEPEST_LEVEL,
            domain: None,
            uniform_depth: None,
            balance: true,
            periodic: [false; 3],
        }
    }
}

impl TreeOptions {
    /// Adaptive tree with the given leaf size, other options default.
    ///
    /// ```
    /// use ferrofmm_tree::TreeOptions;
    /// let o = TreeOptions::adaptive(64);
    /// assert_eq!(o.leaf_size, 64);
    /// assert!(o.uniform_depth.is_none());
    /// ```
    pub fn adaptive(leaf_size: usize) -> Self {
        TreeOptions {
            leaf_size,
            ..Default::default()
        }
    }

    /// Uniform tree of the given depth, other options default.
    pub fn uniform(depth: u32) -> Self {
        TreeOptions {
            uniform_depth: Some(depth),
            ..Default::default()
        }
    }

    /// The same options with a fixed domain.
    pub fn with_domain(mut self, domain: Domain) -> Self {
        self.domain = Some(domain);
        self
    }

    /// The same options with the 2:1 balance on or off (see
    /// [`TreeOptions::balance`]).
    ///
    /// ```
    /// use ferrofmm_tree::{Octree, TreeOptions};
    /// let points: Vec<f64> = (0..300).map(|i| ((i * 37) % 101) as f64 / 101.0).collect();
    /// let tree = Octree::new(&points, None, &TreeOptions::adaptive(5).with_balance(false)).unwrap();
    /// assert!(!tree.has_lists());
    /// ```
    pub fn with_balance(mut self, balance: bool) -> Self {
        self.balance = balance;
        self
    }

    /// The same options with periodic axes (see [`TreeOptions::periodic`]):
    /// `[true; 3]` fully periodic, `[true, true, false]` a slab,
    /// `[true, false, false]` a rod. A periodic tree needs a given domain.
    ///
    /// ```
    /// use ferrofmm_tree::{Domain, Octree, TreeError, TreeOptions};
    /// let points: Vec<f64> = (0..900).map(|i| ((i * 37) % 101) as f64 / 101.0).collect();
    /// let opts = TreeOptions::adaptive(20).with_periodic([true; 3]);
    /// assert_eq!(Octree::new(&points, None, &opts).unwrap_err(), TreeError::PeriodicWithoutDomain);
    /// let cell = Domain::new([0.0; 3], 1.0).unwrap();
    /// let tree = Octree::new(&points, None, &opts.with_domain(cell)).unwrap();
    /// assert!(tree.is_periodic());
    /// let leaf = tree.leaves()[0];
    /// assert_eq!(tree.u_shifts(leaf).unwrap().len(), tree.u_list(leaf).len());
    /// ```
    pub fn with_periodic(mut self, axes: [bool; 3]) -> Self {
        self.periodic = axes;
        self
    }

    /// `true` if any axis is periodic.
    pub fn is_periodic(&self) -> bool {
        self.periodic.iter().any(|&p| p)
    }

    /// The same options with a maximum level.
    pub fn with_max_level(mut self, max_level: u32) -> Self {
        self.max_level = max_level;
        self
    }

    /// Checks the options.
    ///
    /// # Errors
    /// [`TreeError::ZeroLeafSize`], [`TreeError::LevelTooDeep`] (for
    /// `max_level` or `uniform_depth`), or [`TreeError::InvalidDomain`] for a
    /// given domain that [`Domain::new`] would reject;
    /// [`TreeError::PeriodicWithoutDomain`] for periodic axes without a
    /// given domain.
    pub fn validate(&self) -> Result<(), TreeError> {
        if self.leaf_size == 0 {
            return Err(TreeError::ZeroLeafSize);
        }
        for level in [Some(self.max_level), self.uniform_depth]
            .into_iter()
            .flatten()
        {
            if level > DEEPEST_LEVEL {
                return Err(TreeError::LevelTooDeep { level });
            }
        }
        if let Some(d) = self.domain {
            Domain::new(d.origin, d.width)?;
        } else if self.is_periodic() {
            return Err(TreeError::PeriodicWithoutDomain);
        }
        Ok(())
    }
}
