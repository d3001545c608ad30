//! # ferrofmm-tree
//!
//! Morton keys, linear adaptive 2:1-balanced octrees and the interaction
//! lists of the adaptive fast multipole method, as plain data in flat arrays.
//! It depends on nothing else of ferrofmm: use it alone for space-filling
//! curves, spatial sorting or neighbour queries.
//!
//! * [`MortonKey`] ([`morton`]): a box as one `u64` — interleaved anchor
//!   bits and the level; sorting keys gives a depth-first traversal. The
//!   deepest level is [`DEEPEST_LEVEL`] = 19.
//! * [`Domain`] ([`domain`]): the cube `[origin, origin + width)^3` holding
//!   sources and targets, computed or given.
//! * [`Octree`] ([`octree`]): points sorted along the Morton curve, boxes
//!   numbered by (level, Morton code), refined until each leaf holds at most
//!   `leaf_size` points ([`TreeOptions`], [`options`]) or uniformly, then
//!   2:1 balanced ([`balance`]). Only boxes holding points exist.
//! * Interaction lists U, V, W, X ([`lists`]) in CSR form, each pruned to
//!   boxes that actually exchange something; their rules over a box's
//!   neighbourhood (offsets, which children of a neighbour are V-list
//!   candidates or touch the box) in [`list_rules`], for code that counts
//!   the lists without building them.
//! * Periodic trees ([`TreeOptions::periodic`]): the given domain is a cell
//!   repeating along some axes; balance, colleagues and lists wrap around
//!   it, each list entry carrying the image shift of its source box
//!   ([`Octree::u_shifts`] and the like; see [`lists`]).
//! * [`MortonCodes`] and [`TreeShape`] ([`shape`]): the boxes and point
//!   counts of the adaptive, balanced tree for any leaf size, from sorted
//!   Morton codes alone, with the builder's own refinement and balance
//!   (what a parameter chooser needs, at a fraction of a build).
//! * [`separated_clusters`] ([`clusters`]): far-apart groups of points (a
//!   distant outlier, two clouds far apart) that are better served by one
//!   tree each than by one tree whose levels are spent on empty space.
//!
//! ```
//! use ferrofmm_tree::{Octree, TreeOptions};
//!
//! // A 10 x 10 x 10 grid of points, at most 8 per leaf.
//! let pts: Vec<f64> = (0..1000)
//!     .flat_map(|i| [(i % 10) as f64, ((i / 10) % 10) as f64, (i / 100) as f64])
//!     .collect();
//! let tree = Octree::new(&pts, None, &TreeOptions::adaptive(8)).unwrap();
//! for &leaf in tree.leaves() {
//!     assert!(tree.source_range(leaf).len() <= 8);
//!     assert!(tree.v_list(leaf).len() <= 189);
//! }
//! // Sorted position k holds caller point perm[k].
//! let perm = tree.source_permutation();
//! assert_eq!(&tree.sorted_sources()[..3], &pts[3 * perm[0]..3 * perm[0] + 3]);
//! ```
#![warn(missing_docs)]

pub mod balance;
mod bounds;
mod build;
pub mod clusters;
pub mod csr;
pub mod domain;
pub mod error;
pub mod list_rules;
pub mod lists;
pub mod morton;
mod neighbours;
pub mod octree;
pub mod options;
pub mod shape;

pub use clusters::{Cluster, DEFAULT_SEPARATION, separated_clusters};
pub use csr::Csr;
pub use domain::Domain;
pub use error::{PointSet, TreeError};
pub use lists::InteractionLists;
pub use morton::{DEEPEST_LEVEL, FINEST_GRID, MortonKey};
pub use octree::{Octree, TreeBuildStep};
pub use options::TreeOptions;
pub use shape::{MortonCodes, ShapeBox, TreeShape};
