//! # ferrofmm-mpi
//!
//! The adaptive, 2:1-balanced octree of [`ferrofmm_tree`], built across the
//! ranks of an MPI job ([`mpi`], rsmpi) from points that start anywhere:
//! each rank passes whatever share it holds (possibly none) and ends with
//! one contiguous range of the Morton curve, its points, its boxes, the
//! coarse tree shared by all ranks, and the ghost boxes its interaction
//! lists reference. The union of the ranks' boxes is **exactly** the tree
//! [`ferrofmm_tree::Octree::new`] builds from all the points (same domain,
//! keys, leaves, point counts, lists): every step that has single-machine
//! maths calls the tree crate (sort, refinement, balance, lists).
//!
//! ## Steps ([`DistributedTree::build`])
//!
//! 1. **Validate and bound**: local checks, agreed on by all ranks
//!    ([`error`]); the bounding cube from an `all_reduce` of the extremes.
//! 2. **Sort** ([`sort`]): the tree crate's local Morton sort, then a
//!    sample sort with regular samples; points travel with their keys.
//! 3. **Partition** ([`partition`]): cuts at the ideal weight quantiles,
//!    moved to the nearest boundary of the leaf holding them, so that no box
//!    below the coarse tree is shared; points move to their range's rank.
//! 4. **Refine** locally below the coarsest boxes of the range
//!    ([`ferrofmm_tree::MortonCodes::refine_below`]); the boxes straddling
//!    cuts (the coarse tree) are known from the cuts alone.
//! 5. **Balance** ([`balance`]): rounds of exchanging internal boxes with
//!    the neighbouring ranks and the tree crate's balance, until no rank
//!    changes.
//! 6. **Ghosts** ([`ghosts`]): requests to the owners of the regions each
//!    box's lists can reach, answers, and the tree crate's lists on the
//!    result.
//!
//! Bad input on any rank is the same [`DistError`] on every rank.
//!
//! ## The distributed FMM ([`DistributedFmm`])
//!
//! On such a tree, [`DistributedFmm::build`] makes each rank's locally
//! essential tree and runs the single-machine passes of `ferrofmm-fmm` on
//! it ([`ferrofmm_fmm::TreeFmm`]), exchanging only ghost multipoles and
//! charges (point to point, with the ranks that need them) and the coarse
//! tree's sums (point to point too, through one root per coarse box); [`DistributedFmm::evaluate`] can be called for any number
//! of charge vectors and equals the single-machine FMM on the same tree
//! (see [`dfmm`]).
//!
//! ## Separate targets
//!
//! [`DistributedTree::build_with_targets`] takes each rank's sources and
//! its targets (either possibly empty on a rank, the targets anywhere):
//! the tree is [`ferrofmm_tree::Octree::new`] on all sources and all
//! targets (the domain covers both; a box is split while `max(#sources,
//! #targets) > leaf_size`; lists keep entries with sources in rows of
//! boxes with targets). The FMM on it takes the charges of each rank's
//! input sources and returns the values at its input targets, in its
//! input order.
//!
//! ```no_run
//! use ferrofmm_mpi::{DistOptions, DistributedTree};
//! let universe = mpi::initialize().unwrap();
//! let world = universe.world();
//! // This rank's share: any number of points, possibly none.
//! let points = vec![0.1, 0.2, 0.3, 0.9, 0.8, 0.7];
//! let tree = DistributedTree::build(&world, &points, &DistOptions::adaptive(32)).unwrap();
//! println!("{} points, {} leaves here", tree.points.len(), tree.leaves().count());
//! ```
#![warn(missing_docs)]

pub mod accuracy;
pub mod balance;
pub mod dfmm;
pub mod error;
mod exchange;
pub mod ghosts;
pub mod inputs;
pub mod partition;
pub mod solver;
pub mod sort;
pub mod stats;
pub mod stokes_layers;
mod tree;

pub use accuracy::{
    DistChoice, TUNING_SAMPLE, choose_parameters, sampled_errors, sampled_errors_at,
};
pub use dfmm::{
    DistFmmOptions, DistributedFmm, EVAL_PHASES, EvalStats, SetupStats, check_rank_memory,
};
pub use error::{DistError, InputProblem, agree_message, agree_options, agree_text};
pub use ghosts::{Ghost, GhostLayer, SeparateTargets};
pub use inputs::{CHECK_GEOMETRIES, Geometry};
pub use solver::{Attempt, DistPlan, DistRequest, DistSolution, DistSolver, VERIFY_SAMPLE};
pub use sort::LocalPoints;
pub use stats::{BuildStats, PHASES};
pub use stokes_layers::{DistStokesLayers, DistStokesSolution};
pub use tree::{DistOptions, DistTargets, DistributedTree};
