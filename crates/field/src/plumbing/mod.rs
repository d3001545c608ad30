//! Plumbing for those who implement [`M2lScheme`](crate::M2lScheme) outside
//! this crate: the pieces the built-in schemes are made of, public and
//! documented, in the spirit of rayon's `iter::plumbing`. A user of the
//! FMM never needs this module.
//!
//! # What a scheme does
//!
//! [`M2lScheme::apply`](crate::M2lScheme::apply) adds, for every V-list
//! pair `(t, s, v)` of one level,
//!
//! ```text
//! check[:, t] += K_v(h) multipoles[:, s],    K_v(h)[j, i] = K(y_i + 2 h v, x_j),
//! ```
//!
//! where `y_i` are the upward equivalent points and `x_j` the downward
//! check points of a box of half-width `h` centred at the origin
//! ([`m2l_matrix`] assembles `K_v(h)` in `f64`). For a kernel homogeneous
//! of degree `d`, `K_v(h) = (h / h_ref)^d K_v(h_ref)`, so one operator set
//! serves every level; otherwise each level `2..=depth` has its own set.
//! [`LevelMap`] says which set serves a level and with which factor.
//!
//! A scheme builds its operators in
//! [`M2lScheme::precompute_for`](crate::M2lScheme::precompute_for) (only
//! the transfer vectors a tree uses); [`M2lScheme::precompute`](
//! crate::M2lScheme::precompute), every vector at every level, is provided.
//!
//! # The building blocks
//!
//! * [`M2lInteractions`](crate::M2lInteractions) holds a level's pairs cut
//!   into chunks of target columns ([`ChunkView`]), each grouped by transfer
//!   vector ([`GroupView`]): every group is one product `K_v * block`.
//! * [`for_each_chunk`] runs a closure per chunk in parallel, giving it the
//!   chunk's own columns of `check` (disjoint `&mut` slices, no locks);
//!   [`for_each_chunk_with_progress`] also reports each chunk done, for
//!   [`M2lScheme::apply_with_progress`](crate::M2lScheme::apply_with_progress).
//! * [`gather`] copies a group's source columns into a contiguous block,
//!   [`crate::gemm_scaled`] multiplies, [`scatter_add`] adds the result to
//!   the group's target columns; [`for_each_vector_group`] is that loop
//!   over a chunk's groups, with the product supplied by the scheme.
//! * [`check_lengths`] asserts the slice lengths `apply` promises.
//! * [`SiblingBlocks`] (from
//!   [`M2lInteractions::sibling_blocks`](crate::M2lInteractions::sibling_blocks))
//!   regroups a level's pairs by parent: `8 x 8` blocks of children at 26
//!   parent offsets, for schemes that treat siblings together (the FFT
//!   scheme); the maths is on [`SiblingBlocks`].
//! * [`crate::planned_sets`] and [`crate::M2lUsage`] say which transfer
//!   vectors a tree uses, for
//!   [`M2lScheme::precompute_for`](crate::M2lScheme::precompute_for).
//! * [`conformance::check_scheme`] compares a scheme with per-vector dense
//!   products on two full levels; run it in your scheme's tests.
//!
//! A dense scheme is then, per chunk: `for_each_vector_group(&chunk,
//! multipoles, n, out, n, |v, src, dst| gemm_scaled(n, len, n, scale,
//! K[v], src, dst, Update::Overwrite))` (see
//! `examples/custom_m2l.rs` in the repository for a complete scheme
//! written outside this crate, run through the FMM).
//!
//! # What stays sealed
//!
//! The operator cache (file format, checksums, [`crate::CacheStatus`]
//! values) is not part of the plumbing: its layout is versioned with the
//! built-in schemes' stores, and a scheme from outside would need its own
//! format version anyway. An outside scheme keeps its own files (or none)
//! and reports [`crate::CacheStatus::Disabled`], the trait's default.

pub mod conformance;

pub use crate::interactions::{ChunkView, GroupView};
pub use crate::levels::{FIRST_M2L_LEVEL, LevelMap, REFERENCE_HALF_WIDTH, half_width};
pub use crate::m2l::{
    check_lengths, for_each_chunk, for_each_chunk_with_progress, for_each_vector_group, gather,
    m2l_matrix, scatter_add,
};
pub use crate::pinv::truncated_solve;
pub use crate::siblings::{
    LoosePair, N_PARENT_OFFSETS, SiblingBlock, SiblingBlocks, block_vector, full_mask, octant_bits,
    parent_offset,
};
