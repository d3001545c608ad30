//! The cutting step of the clustering: a set is cut along the axis where
//! the largest gaps between its groups of points hold.
//!
//! Along axis `a`, two consecutive groups `A`, `B` with gap `g` are cut
//! apart when
//!
//! ```text
//! g >= ratio * max(d(A), d(B)),    d(G) = max(e_a(G), w(G) / (2 ratio), E_a / n)
//! ```
//!
//! (the [module documentation](super) says why). The groups start as the
//! runs of occupied cells of a histogram of [`CELLS`] cells along `a`; a
//! stack scan merges the top group with the one below while their cut
//! fails, which leaves the unique largest set of cuts that hold
//! ([`cut_cells`]). [`split_once`] keeps the axis whose best cut has the
//! largest score `g / max(w(A), w(B))`.

use rayon::prelude::*;

use crate::bounds::{Bounds, bounds};

/// Cells of the histogram along an axis.
const CELLS: usize = 256;

/// The pieces of `set` cut at every cut that holds on the best axis, or
/// `None` when no axis has one (see the [module documentation](self)).
pub(super) fn split_once(
    set: &[usize],
    point: &(impl Fn(usize) -> [f64; 3] + Sync),
    ratio: f64,
) -> Option<Vec<Vec<usize>>> {
    if set.len() < 2 {
        return None;
    }
    let Bounds { lo, hi } = bounds(set, point);
    let mut best: Option<(f64, usize, Vec<usize>)> = None;
    for axis in 0..3 {
        let extent = hi[axis] - lo[axis];
        if !(extent > 0.0 && extent.is_finite()) {
            continue;
        }
        let cell = |p: [f64; 3]| -> usize {
            let c = ((p[axis] - lo[axis]) / extent * CELLS as f64) as usize;
            c.min(CELLS - 1)
        };
        let cells = set
            .par_iter()
            .with_min_len(1 << 14)
            .fold(
                || vec![Bounds::EMPTY; CELLS],
                |mut cells, &i| {
                    let p = point(i);
                    cells[cell(p)].add(p);
                    cells
                },
            )
            .reduce(
                || vec![Bounds::EMPTY; CELLS],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        x.merge(y);
                    }
                    a
                },
            );
        let spacing = extent / set.len() as f64;
        if let Some((score, piece_of_cell)) = cut_cells(&cells, axis, ratio, spacing)
            && best.as_ref().is_none_or(|(s, _, _)| score > *s)
        {
            best = Some((score, axis, piece_of_cell));
        }
    }
    let (_, axis, piece_of_cell) = best?;
    let extent = hi[axis] - lo[axis];
    let n_pieces = piece_of_cell.iter().max().map_or(0, |&m| m + 1);
    let mut pieces = vec![Vec::new(); n_pieces];
    for &i in set {
        let c = ((point(i)[axis] - lo[axis]) / extent * CELLS as f64) as usize;
        pieces[piece_of_cell[c.min(CELLS - 1)]].push(i);
    }
    Some(pieces)
}

/// The largest set of cuts that hold between the runs of occupied `cells`
/// along `axis`: the piece of each cell and the best cut's score
/// `g / max(w(A), w(B))`, or `None` when no cut holds. `spacing` is the
/// piece's mean point spacing along `axis` (its extent over its count).
fn cut_cells(cells: &[Bounds], axis: usize, ratio: f64, spacing: f64) -> Option<(f64, Vec<usize>)> {
    // A group's size along the cut, at least `1 / (2 ratio)` of its width
    // and the mean spacing.
    let size = |g: &Bounds| -> f64 {
        (g.hi[axis] - g.lo[axis])
            .max(g.width() / (2.0 * ratio))
            .max(spacing)
    };
    let holds = |a: &Bounds, b: &Bounds| -> bool {
        let gap = b.lo[axis] - a.hi[axis];
        gap > 0.0 && gap >= ratio * size(a).max(size(b))
    };
    // Runs of occupied cells, each with its first cell.
    let mut runs: Vec<(usize, Bounds)> = Vec::new();
    let mut previous_empty = true;
    for (c, g) in cells.iter().enumerate() {
        if g.is_empty() {
            previous_empty = true;
            continue;
        }
        match runs.last_mut() {
            Some((_, run)) if !previous_empty => run.merge(g),
            _ => runs.push((c, *g)),
        }
        previous_empty = false;
    }
    // Stack scan: merge while the cut below the top fails.
    let mut stack: Vec<(usize, Bounds)> = Vec::with_capacity(runs.len());
    for run in runs {
        stack.push(run);
        while stack.len() >= 2 {
            let (top, below) = (stack[stack.len() - 1].1, stack[stack.len() - 2].1);
            if holds(&below, &top) {
                break;
            }
            let (_, top) = stack.pop().expect("two entries");
            stack.last_mut().expect("one entry").1.merge(&top);
        }
    }
    if stack.len() < 2 {
        return None;
    }
    let score = stack
        .windows(2)
        .map(|w| {
            let gap = w[1].1.lo[axis] - w[0].1.hi[axis];
            let wider = w[0].1.width().max(w[1].1.width());
            if wider > 0.0 {
                gap / wider
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max);
    let mut piece_of_cell = vec![0; cells.len()];
    for (piece, w) in stack.iter().enumerate() {
        let end = stack.get(piece + 1).map_or(cells.len(), |next| next.0);
        piece_of_cell[w.0..end].fill(piece);
    }
    Some((score, piece_of_cell))
}
