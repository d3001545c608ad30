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

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{EvalMode, Kernel, Real};
use rayon::prelude::*;

use crate::Fmm;
use crate::batch::{gather_apply_scatter, par_columns};
use crate::timings::EvalTimings;

/// One full evaluation for one charge vector (already validated).
pub(crate) fn evaluate<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    charges: &[T],
) -> (Vec<T>, EvalTimings) {
    let t0 = Instant::now();
    let mut timings = EvalTimings::default();
    let tree = &fmm.tree;
    let n = fmm.operators.n_surface();
    let n_boxes = tree.n_boxes();
    let q: Vec<T> = tree
        .source_permutation()
        .iter()
        .map(|&i| charges[i])
        .collect();

    let mut multipoles = vec![T::ZERO; n * n_boxes];
    let t = Instant::now();
    p2m(fmm, &q, &mut multipoles);
    timings.p2m = t.elapsed();
    let t = Instant::now();
    m2m(fmm, &mut multipoles);
    timings.m2m = t.elapsed();

    let mut locals = vec![T::ZERO; n * n_boxes];
    downward(fmm, &q, &multipoles, &mut locals, &mut timings);

    let w = fmm.mode.values_per_target();
    let mut sorted = vec![T::ZERO; w * fmm.n_targets];
    leaf_passes(fmm, &q, &multipoles, &locals, &mut sorted, &mut timings);

    let mut out = vec![T::ZERO; w * fmm.n_targets];
    for (k, &i) in tree.target_permutation().iter().enumerate() {
        out[w * i..w * (i + 1)].copy_from_slice(&sorted[w * k..w * (k + 1)]);
    }
    timings.total = t0.elapsed();
    (out, timings)
}

fn source_slices<'a, T: Real>(
    fmm: &'a Fmm<T, impl Kernel, impl M2lScheme<T>>,
    q: &'a [T],
    r: Range<usize>,
) -> (&'a [T], &'a [T]) {
    (&fmm.sources[3 * r.start..3 * r.end], &q[r])
}

/// Leaves' sources to their upward check surfaces, then check-to-equivalent per level.
fn p2m<T: Real, K: Kernel, S: M2lScheme<T>>(fmm: &Fmm<T, K, S>, q: &[T], multipoles: &mut [T]) {
    let tree = &fmm.tree;
    let ops = &fmm.operators;
    let n = ops.n_surface();
    let radius = ops.radii().upward_check;
    let mut check = vec![T::ZERO; multipoles.len()];
    check
        .par_chunks_mut(n)
        .enumerate()
        .for_each_init(Vec::new, |surface, (b, col)| {
            let r = tree.source_range(b);
            if !tree.is_leaf(b) || r.is_empty() {
                return;
            }
            fmm.surface_of(b, radius, surface);
            let (x, qb) = source_slices(fmm, q, r);
            fmm.kernel
                .evaluate(EvalMode::Potential, x, qb, surface, col);
        });
    for level in 0..=tree.depth() {
        let r = tree.level_range(level);
        par_columns(
            n,
            &check[n * r.start..n * r.end],
            &mut multipoles[n * r.start..n * r.end],
            |c, u| ops.uc2e(level, c, u),
        );
    }
}

/// Children to parents, deepest level first.
fn m2m<T: Real, K: Kernel, S: M2lScheme<T>>(fmm: &Fmm<T, K, S>, multipoles: &mut [T]) {
    let tree = &fmm.tree;
    let ops = &fmm.operators;
    let n = ops.n_surface();
    for level in (1..=tree.depth()).rev() {
        let r = tree.level_range(level);
        let (parents, children) = multipoles.split_at_mut(n * r.start);
        for (octant, pairs) in octant_pairs(fmm, r.clone()).iter().enumerate() {
            // Source columns are relative to the level start, destinations global.
            gather_apply_scatter(n, pairs, children, parents, |c, p| {
                ops.m2m(level, octant, c, p)
            });
        }
    }
}

/// `(child column relative to the level start, parent box)` grouped by octant.
fn octant_pairs<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    level: Range<usize>,
) -> [Vec<(usize, usize)>; 8] {
    let tree = &fmm.tree;
    let mut groups: [Vec<(usize, usize)>; 8] = Default::default();
    for c in level.clone() {
        if let Some(p) = tree.parent(c) {
            groups[tree.key(c).octant()].push((c - level.start, p));
        }
    }
    groups
}

/// M2L, P2L and L2L level by level, top down.
fn downward<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    q: &[T],
    multipoles: &[T],
    locals: &mut [T],
    timings: &mut EvalTimings,
) {
    let tree = &fmm.tree;
    let ops = &fmm.operators;
    let n = ops.n_surface();
    let radius = ops.radii().downward_check;
    for level in 1..=tree.depth() {
        let r = tree.level_range(level);
        if r.is_empty() {
            continue;
        }
        let mut check = vec![T::ZERO; n * r.len()];

        let t = Instant::now();
        let interactions = &fmm.m2l_interactions[level as usize];
        if !interactions.is_empty() {
            fmm.m2l.apply(
                level,
                interactions,
                &multipoles[n * r.start..n * r.end],
                &mut check,
            );
        }
        timings.m2l += t.elapsed();

        let t = Instant::now();
        check
            .par_chunks_mut(n)
            .enumerate()
            .for_each_init(Vec::new, |surface, (j, col)| {
                let b = r.start + j;
                let xs = tree.x_list(b);
                if xs.is_empty() {
                    return;
                }
                fmm.surface_of(b, radius, surface);
                for &a in xs {
                    let (x, qa) = source_slices(fmm, q, tree.source_range(a));
                    fmm.kernel
                        .evaluate(EvalMode::Potential, x, qa, surface, col);
                }
            });
        timings.p2l += t.elapsed();

        let t = Instant::now();
        let (parents, level_locals) = locals.split_at_mut(n * r.start);
        let level_locals = &mut level_locals[..n * r.len()];
        par_columns(n, &check, level_locals, |c, d| ops.dc2e(level, c, d));
        if level >= 2 {
            for (octant, pairs) in octant_pairs(fmm, r.clone()).iter().enumerate() {
                let pairs: Vec<(usize, usize)> = pairs.iter().map(|&(c, p)| (p, c)).collect();
                gather_apply_scatter(n, &pairs, parents, level_locals, |p, c| {
                    ops.l2l(level, octant, p, c)
                });
            }
        }
        timings.l2l += t.elapsed();
    }
}

/// L2P, M2P and P2P, each parallel over the target leaves.
fn leaf_passes<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    q: &[T],
    multipoles: &[T],
    locals: &[T],
    sorted: &mut [T],
    timings: &mut EvalTimings,
) {
    let tree = &fmm.tree;
    let ops = &fmm.operators;
    let n = ops.n_surface();
    let w = fmm.mode.values_per_target();
    let mode = fmm.mode;
    let mut slices = leaf_output_slices(fmm, w, sorted);
    let targets_of = |b: usize| {
        let r = tree.target_range(b);
        &fmm.target_points()[3 * r.start..3 * r.end]
    };

    let t = Instant::now();
    let down_equiv = ops.radii().downward_equivalent;
    slices
        .par_iter_mut()
        .for_each_init(Vec::new, |surface, (b, out)| {
            fmm.surface_of(*b, down_equiv, surface);
            let d = &locals[n * *b..n * (*b + 1)];
            fmm.kernel.evaluate(mode, surface, d, targets_of(*b), out);
        });
    timings.l2p = t.elapsed();

    let t = Instant::now();
    let up_equiv = ops.radii().upward_equivalent;
    slices
        .par_iter_mut()
        .for_each_init(Vec::new, |surface, (b, out)| {
            for &a in tree.w_list(*b) {
                fmm.surface_of(a, up_equiv, surface);
                let u = &multipoles[n * a..n * (a + 1)];
                fmm.kernel.evaluate(mode, surface, u, targets_of(*b), out);
            }
        });
    timings.m2p = t.elapsed();

    let t = Instant::now();
    slices.par_iter_mut().for_each(|(b, out)| {
        let y = targets_of(*b);
        for &a in tree.u_list(*b) {
            let (x, qa) = source_slices(fmm, q, tree.source_range(a));
            fmm.kernel.evaluate(mode, x, qa, y, out);
        }
    });
    timings.p2p = t.elapsed();
}

/// Disjoint output slices, one per leaf that holds targets.
fn leaf_output_slices<'a, T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    w: usize,
    sorted: &'a mut [T],
) -> Vec<(usize, &'a mut [T])> {
    let tree = &fmm.tree;
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
