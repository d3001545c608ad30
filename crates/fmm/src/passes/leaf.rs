//! The leaf passes, one at a time so that a caller can release each
//! buffer once read: M2P (the multipoles of W-list boxes), L2P (the
//! locals), then P2P (the charges).
//!
//! * M2P: `phi(y) += K(y, x_equiv_A) u_A` for `A` in `W(B)`.
//! * L2P: `phi(y) += K(y, x_equiv_B) d_B` at the targets of leaf `B`.
//! * P2P: `phi(y) += K(y, x) q` for the sources of `A` in `U(B)`.
//!
//! Each pass runs in parallel over the target leaves, writing its own
//! disjoint slice of the outputs (in tree order).

use std::time::Instant;

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{Kernel, Real, SourceKind};
use ferrofmm_tree::Octree;
use rayon::prelude::*;

use super::{Ctx, source_slices};
use crate::part::{TreePart, image_points, shift_at};
use crate::progress::{self, Work};
use crate::timings::EvalTimings;

/// L2P, M2P and P2P, each parallel over the target leaves (M2P first, so
/// that a caller may release the multipoles before L2P, and the locals
/// before P2P, as [`super::evaluate`] does).
#[allow(clippy::too_many_arguments)]
pub(crate) fn leaf_passes<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    q: &[T],
    multipoles: &[T],
    locals: &[T],
    sorted: &mut [T],
    timings: &mut EvalTimings,
    work: &Work<'_>,
) {
    let w = cx.kernel.values_per_target(cx.mode);
    let mut slices = leaf_output_slices(&part.tree, w, sorted);
    let n = part.operators.n_surface();
    m2p_pass(
        cx,
        part,
        |a| &multipoles[n * a..n * (a + 1)],
        &mut slices,
        timings,
    );
    l2p_pass(cx, part, locals, &mut slices, timings);
    leaf_progress(part, &slices, work);
    p2p_pass(cx, part, q, &mut slices, timings, work);
}

/// Output slices of the target leaves ([`leaf_output_slices`]).
pub(super) type LeafSlices<'a, T> = Vec<(usize, &'a mut [T])>;

/// The targets of box `b` (interleaved, in `T`).
fn targets_of<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>, b: usize) -> &[T] {
    let r = part.tree.target_range(b);
    &part.target_points()[3 * r.start..3 * r.end]
}

/// L2P: `phi(y) += K(y, x_equiv_B) d_B` at the targets of every leaf `B`.
pub(super) fn l2p_pass<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    locals: &[T],
    slices: &mut LeafSlices<'_, T>,
    timings: &mut EvalTimings,
) {
    let n = part.operators.n_surface();
    let t = Instant::now();
    let down_equiv = part.operators.radii().downward_equivalent;
    slices
        .par_iter_mut()
        .for_each_init(Vec::new, |surface, (b, out)| {
            part.surface_of(cx.unit_surface, *b, down_equiv, surface);
            let d = &locals[n * *b..n * (*b + 1)];
            let y = targets_of(part, *b);
            cx.kernel
                .evaluate_sources(SourceKind::Charge, cx.mode, surface, d, y, out);
        });
    timings.l2p += t.elapsed();
}

/// M2P: `phi(y) += K(y, x_equiv_A) u_A` for `A` in `W(B)` (nothing for a
/// part without sources).
pub(super) fn m2p_pass<'m, T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    multipole_of: impl Fn(usize) -> &'m [T] + Sync,
    slices: &mut LeafSlices<'_, T>,
    timings: &mut EvalTimings,
) {
    if !part.has_sources {
        return;
    }
    let tree = &part.tree;
    let t = Instant::now();
    let up_equiv = part.operators.radii().upward_equivalent;
    slices
        .par_iter_mut()
        .for_each_init(Vec::new, |surface, (b, out)| {
            let shifts = tree.w_shifts(*b);
            for (k, &a) in tree.w_list(*b).iter().enumerate() {
                part.image_surface_of(cx.unit_surface, a, shift_at(shifts, k), up_equiv, surface);
                let u = multipole_of(a);
                let y = targets_of(part, *b);
                cx.kernel
                    .evaluate_sources(SourceKind::Charge, cx.mode, surface, u, y, out);
            }
        });
    timings.m2p += t.elapsed();
}

/// The multipoles M2P reads: those of the boxes in some W list, in box
/// order, so that the level-sized multipole buffer can be released before
/// the outputs are made. Few in a near-uniform tree (W lists appear only
/// where leaf levels differ); at most every box's.
pub(super) struct WMultipoles<T> {
    /// Position of each box's multipole in `values` (`u32::MAX`: none).
    index: Vec<u32>,
    values: Vec<T>,
    n: usize,
}

impl<T: Real> WMultipoles<T> {
    pub(super) fn gather<S: M2lScheme<T>>(part: &TreePart<T, S>, multipoles: &[T]) -> Self {
        let tree = &part.tree;
        let n = part.operators.n_surface();
        let mut index = vec![u32::MAX; tree.n_boxes()];
        if part.has_sources {
            for &b in tree.leaves() {
                for &a in tree.w_list(b) {
                    index[a] = 0;
                }
            }
        }
        let mut values = Vec::new();
        let mut count = 0u32;
        for (a, slot) in index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = count;
                count += 1;
                values.extend_from_slice(&multipoles[n * a..n * (a + 1)]);
            }
        }
        WMultipoles { index, values, n }
    }

    /// The multipole of box `a` (which must be in a W list).
    pub(super) fn of(&self, a: usize) -> &[T] {
        let k = self.index[a] as usize;
        &self.values[self.n * k..self.n * (k + 1)]
    }
}

/// The progress units of L2P and M2P, reported together once both ran.
pub(super) fn leaf_progress<T: Real, S: M2lScheme<T>>(
    part: &TreePart<T, S>,
    slices: &LeafSlices<'_, T>,
    work: &Work<'_>,
) {
    if !part.has_sources {
        return;
    }
    let n = part.operators.n_surface();
    work.add_with(|| {
        slices
            .iter()
            .map(|(b, _)| progress::l2p_m2p_units(part, n, *b))
            .sum()
    });
}

/// P2P: `phi(y) += K(y, x) q` for the sources of `A` in `U(B)` (nothing
/// for a part without sources).
pub(super) fn p2p_pass<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    q: &[T],
    slices: &mut LeafSlices<'_, T>,
    timings: &mut EvalTimings,
    work: &Work<'_>,
) {
    if !part.has_sources {
        return;
    }
    let tree = &part.tree;
    let w = cx.kernel.values_per_target(cx.mode);
    let t = Instant::now();
    // Few leaves for the threads (a shallow tree, a direct sum: one leaf
    // holding every point) are split into blocks of targets, so that
    // every thread has work; a target's sum is the same either way.
    let split = slices.len() < 4 * rayon::current_num_threads();
    let blocks: Vec<(usize, usize, &mut [T])> = slices
        .iter_mut()
        .flat_map(|(b, out)| {
            let rows = if split {
                P2P_SPLIT_TARGETS
            } else {
                out.len() / w.max(1)
            };
            out.chunks_mut(w * rows.max(1))
                .enumerate()
                .map(move |(k, chunk)| (*b, k * rows.max(1), chunk))
        })
        .collect();
    let width = tree.domain().width;
    blocks
        .into_par_iter()
        .for_each_init(Vec::new, |image, (b, first, out)| {
            let y = targets_of(part, b);
            let y = &y[3 * first..3 * first + 3 * (out.len() / w)];
            let shifts = tree.u_shifts(b);
            for (k, &a) in tree.u_list(b).iter().enumerate() {
                let (x, qa) = source_slices(cx, part, q, tree.source_range(a));
                let x = image_points(x, shift_at(shifts, k), width, image);
                cx.kernel.evaluate_sources(cx.kind, cx.mode, x, qa, y, out);
            }
            work.add_with(|| progress::p2p_units(part, b, out.len() / w.max(1)));
        });
    timings.p2p += t.elapsed();
}

/// Targets per P2P task when a tree has too few leaves to keep the
/// threads busy (as [`ferrofmm_kernels::DIRECT_SUM_BLOCK`]).
const P2P_SPLIT_TARGETS: usize = ferrofmm_kernels::DIRECT_SUM_BLOCK;

/// Disjoint output slices, one per leaf that holds targets.
pub(super) fn leaf_output_slices<'a, T: Real>(
    tree: &Octree,
    w: usize,
    sorted: &'a mut [T],
) -> LeafSlices<'a, T> {
    let mut leaves: Vec<usize> = tree
        .leaves()
        .iter()
        .copied()
        .filter(|&b| !tree.target_range(b).is_empty())
        .collect();
    leaves.sort_unstable_by_key(|&b| tree.target_range(b).start);
    let mut slices = Vec::with_capacity(leaves.len());
    let mut rest = sorted;
    let mut pos = 0;
    for b in leaves {
        let r = tree.target_range(b);
        let tail = std::mem::take(&mut rest)
            .split_at_mut(w * (r.start - pos))
            .1;
        let (mine, tail) = tail.split_at_mut(w * r.len());
        rest = tail;
        pos = r.end;
        slices.push((b, mine));
    }
    slices
}
