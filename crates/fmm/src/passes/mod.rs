//! The FMM passes: upward (P2M, M2M), downward (M2L, P2L, L2L) and leaf
//! evaluation (L2P, M2P, P2P).
//!
//! With `n` equivalent points per box, box `b` owns columns
//! `multipoles[n b .. n (b + 1)]` (upward equivalent densities) and
//! `locals[n b .. n (b + 1)]` (downward equivalent densities). Boxes are
//! sorted by level, so each level is one column-major `n x n_level` matrix
//! and level operators run as matrix-matrix products.
//!
//! * P2M: `u = UC2E_l (K(y_check, x) q)` for every leaf holding sources.
//! * M2M: `u_parent += M2M_{l, octant} u_child`, bottom up.
//! * M2L: `c_B += K(y_check_B, x_equiv_A) u_A` for `A` in `V(B)` (by the scheme).
//! * P2L: `c_B += K(y_check_B, x) q` for the sources of `A` in `X(B)`.
//! * L2L: `d_B += DC2E_l c_B + L2L_{l, octant} d_parent`, top down.
//! * L2P: `phi(y) += K(y, x_equiv_B) d_B` at the targets of leaf `B`.
//! * M2P: `phi(y) += K(y, x_equiv_A) u_A` for `A` in `W(B)`.
//! * P2P: `phi(y) += K(y, x) q` for the sources of `A` in `U(B)`.

use std::ops::Range;
use std::time::Instant;

use ferrofmm_field::{M2lProgress, M2lScheme};
use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use rayon::prelude::*;

use crate::batch::{gather_apply_scatter, par_columns_in_place};
use crate::part::{Body, TreePart, image_points, shift_at};
use crate::progress::{self, Work};
use crate::timings::EvalTimings;
use crate::{Fmm, coupling};

mod leaf;
pub(crate) use leaf::leaf_passes;
use leaf::{WMultipoles, l2p_pass, leaf_output_slices, leaf_progress, m2p_pass, p2p_pass};

/// What every pass reads besides the tree part: the kernel, what is
/// evaluated, and the unit-cube surface grid (interleaved, `f64`).
pub(crate) struct Ctx<'a, K> {
    pub(crate) kernel: &'a K,
    pub(crate) mode: EvalMode,
    /// What each source carries: `kind.values_per_source()` densities per
    /// source in the charge vectors the passes read.
    pub(crate) kind: SourceKind,
    pub(crate) unit_surface: &'a [f64],
}

/// One full evaluation for one charge vector (already validated): every
/// cluster's upward pass, the clusters' coupling ([`crate::coupling`]), then
/// every cluster's downward and leaf passes.
pub(crate) fn evaluate<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    charges: &[T],
) -> (Vec<T>, EvalTimings) {
    let t0 = Instant::now();
    let mut timings = EvalTimings::default();
    let n = fmm.expansion_len();
    let work = Work::new(fmm.progress.as_ref(), || total_units(fmm));
    let w = fmm.kernel.values_per_target(fmm.mode);

    let cx = fmm.ctx();
    let nq = fmm.kernel.values_per_source(fmm.source_kind);
    let local_q: Vec<Vec<T>> = fmm
        .parts
        .iter()
        .map(|p| p.local_charges(charges, nq))
        .collect();
    let mut multipoles: Vec<Vec<T>> = fmm
        .parts
        .iter()
        .zip(&local_q)
        .map(|(part, q)| match part.tree_part() {
            Some(tp) if tp.has_sources => upward(&cx, tp, q, &mut timings, &work),
            _ => Vec::new(),
        })
        .collect();

    // Values in each part's stored order, and its root's check potentials.
    // One part (no coupling writes into them) gets its outputs only when
    // its leaf passes begin: they are not held beside both expansions.
    let stored_values = |p: &crate::part::Part<T, S>| {
        let stored = match p.tree_part() {
            Some(tp) if !tp.has_targets => 0,
            _ => p.n_targets,
        };
        w * stored
    };
    let mut values: Vec<Vec<T>> = fmm
        .parts
        .iter()
        .map(|p| match fmm.parts.len() {
            1 => Vec::new(),
            _ => vec![T::ZERO; stored_values(p)],
        })
        .collect();
    let mut root_checks: Vec<Vec<T>> = fmm.parts.iter().map(|_| Vec::new()).collect();
    // A periodic cell: the far images act on the root ([`crate::periodic`]).
    let mut periodic_constant = [0.0; 3];
    if let (Some(far), Some(tp)) = (&fmm.periodic, fmm.parts[0].tree_part()) {
        let t = Instant::now();
        let centre = cell_centre(far, tp);
        let (check, constant) = far.root_check(&multipoles[0], &tp.sources, centre, &local_q[0]);
        root_checks[0] = check;
        periodic_constant = constant;
        timings.coupling = t.elapsed();
    }
    if fmm.parts.len() > 1 {
        let t = Instant::now();
        couple(fmm, &local_q, &multipoles, &mut values, &mut root_checks);
        timings.coupling = t.elapsed();
    }

    for (k, part) in fmm.parts.iter().enumerate() {
        match &part.body {
            Body::Tree(tp) if tp.has_targets => {
                let mut locals = vec![T::ZERO; n * tp.tree.n_boxes()];
                let root = (!root_checks[k].is_empty()).then_some(&root_checks[k][..]);
                downward(
                    &cx,
                    tp,
                    &local_q[k],
                    &multipoles[k],
                    root,
                    &mut locals,
                    &mut timings,
                    &work,
                    |_, _, _| {},
                );
                // The leaf passes one at a time, each buffer released once
                // read, so that the outputs are never held beside both
                // expansions: the multipoles M2P reads (those of W-list
                // boxes) are gathered and the rest released before the
                // outputs are made; then M2P, L2P and, the locals released,
                // P2P.
                let w_multipoles = WMultipoles::gather(tp, &multipoles[k]);
                multipoles[k] = Vec::new();
                if values[k].is_empty() {
                    values[k] = vec![T::ZERO; stored_values(part)];
                }
                let mut slices = leaf_output_slices(&tp.tree, w, &mut values[k]);
                m2p_pass(&cx, tp, |a| w_multipoles.of(a), &mut slices, &mut timings);
                drop(w_multipoles);
                l2p_pass(&cx, tp, &locals, &mut slices, &mut timings);
                drop(locals);
                leaf_progress(tp, &slices, &work);
                p2p_pass(&cx, tp, &local_q[k], &mut slices, &mut timings, &work);
            }
            // A part without targets stores no values.
            Body::Tree(_) => {}
            Body::Points(pp) => {
                if values[k].is_empty() {
                    values[k] = vec![T::ZERO; stored_values(part)];
                }
                let t = Instant::now();
                if part.n_sources > 0 && part.n_targets > 0 {
                    fmm.kernel.evaluate_sources(
                        fmm.source_kind,
                        fmm.mode,
                        &pp.sources,
                        &local_q[k],
                        pp.target_points(),
                        &mut values[k],
                    );
                }
                timings.p2p += t.elapsed();
                work.add((part.n_sources * part.n_targets) as u64);
            }
        }
    }
    work.finish();

    if let (Some(far), Some(tp)) = (&fmm.periodic, fmm.parts[0].tree_part()) {
        let centre = cell_centre(far, tp);
        far.add_terms(
            periodic_constant,
            w,
            &tp.sources,
            &local_q[0],
            tp.target_points(),
            centre,
            &mut values[0],
        );
    }

    // The values in the caller's order: one part holding every target is
    // put in order in place (no second copy of the outputs); several are
    // gathered into a new vector.
    drop((local_q, multipoles, root_checks));
    let out = match &fmm.parts[..] {
        [part] if part.n_stored_targets() == fmm.n_targets => {
            let mut v = values.pop().expect("one part, one vector");
            permute_in_place(&mut v, w, |k| part.stored_target_id(k));
            v
        }
        _ => {
            let mut out = vec![T::ZERO; w * fmm.n_targets];
            for (part, v) in fmm.parts.iter().zip(&values) {
                for k in 0..part.n_stored_targets() {
                    let i = part.stored_target_id(k);
                    out[w * i..w * (i + 1)].copy_from_slice(&v[w * k..w * (k + 1)]);
                }
            }
            out
        }
    };
    timings.total = t0.elapsed();
    (out, timings)
}

/// Move block `k` of `values` (`w` values each) to block `dest(k)`, for a
/// permutation `dest`, in place: each cycle of the permutation is followed
/// once, carrying one block, with one bit a block to mark those moved.
pub(crate) fn permute_in_place<T: Copy>(values: &mut [T], w: usize, dest: impl Fn(usize) -> usize) {
    if w == 0 {
        return;
    }
    let m = values.len() / w;
    let mut moved = vec![0u64; m.div_ceil(64)];
    let mut carry: Vec<T> = Vec::with_capacity(w);
    for start in 0..m {
        if moved[start / 64] >> (start % 64) & 1 == 1 {
            continue;
        }
        carry.clear();
        carry.extend_from_slice(&values[w * start..w * (start + 1)]);
        let mut j = start;
        loop {
            moved[j / 64] |= 1 << (j % 64);
            let d = dest(j);
            if d == start {
                values[w * start..w * (start + 1)].copy_from_slice(&carry);
                break;
            }
            carry.swap_with_slice(&mut values[w * d..w * (d + 1)]);
            j = d;
        }
    }
}

/// The work units of one evaluation ([`crate::progress`]).
fn total_units<T: Real, K: Kernel, S: M2lScheme<T>>(fmm: &Fmm<T, K, S>) -> u64 {
    fmm.parts
        .iter()
        .map(|part| match &part.body {
            Body::Tree(tp) => {
                let up = if tp.has_sources {
                    progress::upward_units(tp)
                } else {
                    0
                };
                let down = if tp.has_targets {
                    progress::downward_units(tp) + progress::leaf_units(tp)
                } else {
                    0
                };
                up + down
            }
            Body::Points(_) => (part.n_sources * part.n_targets) as u64,
        })
        .sum()
}

/// The centre of a periodic cell in the coordinates of its tree part.
fn cell_centre<T: Real, S>(far: &crate::periodic::FarImages, tp: &TreePart<T, S>) -> [f64; 3] {
    let c = far.cell.centre();
    std::array::from_fn(|a| c[a] - tp.centre[a])
}

/// P2M and M2M of one tree part: its multipoles.
pub(crate) fn upward<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    q: &[T],
    timings: &mut EvalTimings,
    work: &Work<'_>,
) -> Vec<T> {
    let n = part.operators.n_surface();
    let mut multipoles = vec![T::ZERO; n * part.tree.n_boxes()];
    let t = Instant::now();
    p2m(cx, part, q, &mut multipoles);
    timings.p2m += t.elapsed();
    let t = Instant::now();
    m2m(part, &mut multipoles);
    timings.m2m += t.elapsed();
    work.add_with(|| progress::upward_units(part));
    multipoles
}

/// Every cluster's field on every other ([`crate::coupling`]), in
/// parallel over the receiving clusters.
fn couple<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    local_q: &[Vec<T>],
    multipoles: &[Vec<T>],
    values: &mut [Vec<T>],
    root_checks: &mut [Vec<T>],
) {
    let n = fmm.expansion_len();
    let sources: Vec<Option<coupling::SourceSide<'_, T>>> = fmm
        .parts
        .iter()
        .zip(local_q.iter().zip(multipoles))
        .map(|(p, (q, m))| coupling::source_side(fmm, p, q, m))
        .collect();
    fmm.parts
        .par_iter()
        .zip(values.par_iter_mut().zip(root_checks.par_iter_mut()))
        .enumerate()
        .for_each(|(k, (part, (out, root_check)))| {
            let Some(target) = coupling::target_side(fmm, part) else {
                return;
            };
            if matches!(target, coupling::TargetSide::RootCheck { .. }) {
                *root_check = vec![T::ZERO; n];
            }
            let others: Vec<&coupling::SourceSide<'_, T>> = sources
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .filter_map(|(_, s)| s.as_ref())
                .collect();
            coupling::add_far_clusters(&fmm.kernel, fmm.mode, &target, &others, out, root_check);
        });
}

/// The coordinates and densities of the sources `r` (tree order).
pub(super) fn source_slices<'a, T: Real, S: M2lScheme<T>, K: Kernel>(
    cx: &Ctx<'_, K>,
    part: &'a TreePart<T, S>,
    q: &'a [T],
    r: Range<usize>,
) -> (&'a [T], &'a [T]) {
    let nq = cx.kernel.values_per_source(cx.kind);
    (
        &part.sources[3 * r.start..3 * r.end],
        &q[nq * r.start..nq * r.end],
    )
}

/// Leaves' sources to their upward check surfaces, then check-to-equivalent
/// per level. The check potentials are gathered in the multipoles' own
/// columns (still zero: M2M comes after) and turned into multipoles there,
/// so no buffer of every box's check potentials is held beside them.
fn p2m<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    q: &[T],
    multipoles: &mut [T],
) {
    let tree = &part.tree;
    let ops = &part.operators;
    let n = ops.n_surface();
    let radius = ops.radii().upward_check;
    let has_check =
        |b: usize| tree.is_leaf(b) && !tree.source_range(b).is_empty() && part.is_active(b);
    multipoles
        .par_chunks_mut(n)
        .enumerate()
        .for_each_init(Vec::new, |surface, (b, col)| {
            if !has_check(b) {
                return;
            }
            part.surface_of(cx.unit_surface, b, radius, surface);
            let (x, qb) = source_slices(cx, part, q, tree.source_range(b));
            cx.kernel
                .evaluate_sources(cx.kind, EvalMode::Potential, x, qb, surface, col);
        });
    // Levels above the operators' first hold no multipole anyone reads
    // (`Operators::from_level`): their leaves' check potentials are cleared.
    let first = ops.first_level().min(tree.depth() + 1);
    multipoles[..n * tree.level_range(first).start].fill(T::ZERO);
    for level in first..=tree.depth() {
        let r = tree.level_range(level);
        // Only leaves with sources (and, in a part, active ones) have a
        // check potential; every other column is zero and stays so.
        let keep = |j: usize| has_check(r.start + j);
        let keep: Option<&(dyn Fn(usize) -> bool + Sync)> = part.active.is_some().then_some(&keep);
        par_columns_in_place(n, &mut multipoles[n * r.start..n * r.end], keep, |c, u| {
            ops.uc2e(level, c, u)
        });
    }
}

/// Children to parents, deepest level first.
fn m2m<T: Real, S: M2lScheme<T>>(part: &TreePart<T, S>, multipoles: &mut [T]) {
    let tree = &part.tree;
    let ops = &part.operators;
    let n = ops.n_surface();
    for level in (ops.first_level() + 1..=tree.depth()).rev() {
        let r = tree.level_range(level);
        let (parents, children) = multipoles.split_at_mut(n * r.start);
        for (octant, pairs) in octant_pairs(part, r.clone()).iter().enumerate() {
            // Source columns are relative to the level start, destinations global.
            gather_apply_scatter(n, pairs, children, parents, |c, p| {
                ops.m2m(level, octant, c, p)
            });
        }
    }
}

/// `(child column relative to the level start, parent box)` grouped by
/// octant, for the [active](TreePart::active) children.
fn octant_pairs<T: Real, S: M2lScheme<T>>(
    part: &TreePart<T, S>,
    level: Range<usize>,
) -> [Vec<(usize, usize)>; 8] {
    let tree = &part.tree;
    let mut groups: [Vec<(usize, usize)>; 8] = Default::default();
    for c in level.clone() {
        if !part.is_active(c) {
            continue;
        }
        if let Some(p) = tree.parent(c) {
            groups[tree.key(c).octant()].push((c - level.start, p));
        }
    }
    groups
}

/// M2L, P2L and L2L level by level, top down. With `root_check` (the
/// far clusters' potentials on the root's downward check surface) the
/// root gets a local expansion too, and L2L starts at level 1.
#[allow(clippy::too_many_arguments)]
pub(crate) fn downward<T: Real, K: Kernel, S: M2lScheme<T>>(
    cx: &Ctx<'_, K>,
    part: &TreePart<T, S>,
    q: &[T],
    multipoles: &[T],
    root_check: Option<&[T]>,
    locals: &mut [T],
    timings: &mut EvalTimings,
    work: &Work<'_>,
    mut on_checks: impl FnMut(u32, Range<usize>, &mut [T]),
) {
    let tree = &part.tree;
    let ops = &part.operators;
    let n = ops.n_surface();
    let radius = ops.radii().downward_check;
    if let Some(check) = root_check {
        let t = Instant::now();
        ops.dc2e(0, check, &mut locals[..n]);
        timings.l2l += t.elapsed();
    }
    let from_root = root_check.is_some();
    // Above the operators' first level there is no V or X list and (without
    // a root check) no local expansion: nothing to compute.
    for level in ops.first_level().max(1)..=tree.depth() {
        let r = tree.level_range(level);
        if r.is_empty() {
            continue;
        }
        // The level's check potentials are gathered in its local
        // expansions' own columns (still zero: L2L into them comes after)
        // and turned into local expansions there, so no level-sized buffer
        // is held beside them.
        let (parents, level_locals) = locals.split_at_mut(n * r.start);
        let check = &mut level_locals[..n * r.len()];

        let t = Instant::now();
        let interactions = &part.m2l_interactions[level as usize];
        // The M2L's units are counted as the scheme reports its pieces;
        // the rest of the level's when it ends.
        let mut m2l_counted = 0;
        if part.has_sources && !interactions.is_empty() {
            let multipoles = &multipoles[n * r.start..n * r.end];
            if work.active() {
                m2l_counted = progress::m2l_units(part, level);
                let share = work.share(m2l_counted);
                let report = |done, total| share.advance(done, total);
                part.m2l.apply_with_progress(
                    level,
                    interactions,
                    multipoles,
                    check,
                    M2lProgress::new(&report),
                );
                share.finish();
            } else {
                part.m2l.apply(level, interactions, multipoles, check);
            }
        }
        timings.m2l += t.elapsed();

        let t = Instant::now();
        let width = tree.domain().width;
        check.par_chunks_mut(n).enumerate().for_each_init(
            || (Vec::new(), Vec::new()),
            |(surface, image), (j, col)| {
                let b = r.start + j;
                let xs = tree.x_list(b);
                if xs.is_empty() || !part.has_sources {
                    return;
                }
                let shifts = tree.x_shifts(b);
                part.surface_of(cx.unit_surface, b, radius, surface);
                for (k, &a) in xs.iter().enumerate() {
                    let (x, qa) = source_slices(cx, part, q, tree.source_range(a));
                    let x = image_points(x, shift_at(shifts, k), width, image);
                    cx.kernel
                        .evaluate_sources(cx.kind, EvalMode::Potential, x, qa, surface, col);
                }
            },
        );
        timings.p2l += t.elapsed();
        on_checks(level, r.clone(), check);

        let t = Instant::now();
        let level_locals = check;
        let active = |j: usize| part.is_active(r.start + j);
        let keep: Option<&(dyn Fn(usize) -> bool + Sync)> =
            part.active.is_some().then_some(&active);
        par_columns_in_place(n, level_locals, keep, |c, d| ops.dc2e(level, c, d));
        if (level >= 2 || from_root) && level > ops.first_level() {
            for (octant, pairs) in octant_pairs(part, r.clone()).iter().enumerate() {
                let pairs: Vec<(usize, usize)> = pairs.iter().map(|&(c, p)| (p, c)).collect();
                gather_apply_scatter(n, &pairs, parents, level_locals, |p, c| {
                    ops.l2l(level, octant, p, c)
                });
            }
        }
        timings.l2l += t.elapsed();
        work.add_with(|| progress::level_units(part, level) - m2l_counted);
    }
}

#[cfg(test)]
mod tests {
    use super::permute_in_place;

    /// In place equals the plain gather, for permutations with long and
    /// short cycles, fixed points, and several values a block.
    #[test]
    fn permuting_in_place_matches_a_copy() {
        let mut state = 7u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for (m, w) in [(0, 4), (1, 1), (2, 3), (65, 1), (1000, 4), (777, 10)] {
            // A random permutation (Fisher-Yates), and the identity.
            let mut dest: Vec<usize> = (0..m).collect();
            for i in (1..m).rev() {
                dest.swap(i, (next() % (i as u64 + 1)) as usize);
            }
            for dest in [dest, (0..m).collect()] {
                let values: Vec<f64> = (0..m * w).map(|x| x as f64).collect();
                let mut want = vec![0.0; m * w];
                for k in 0..m {
                    want[w * dest[k]..w * (dest[k] + 1)]
                        .copy_from_slice(&values[w * k..w * (k + 1)]);
                }
                let mut got = values.clone();
                permute_in_place(&mut got, w, |k| dest[k]);
                assert_eq!(got, want, "m {m}, w {w}");
            }
        }
    }
}
