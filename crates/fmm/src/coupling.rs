//! Interactions between far-separated clusters ([`crate::part`]).
//!
//! Clusters `A` and `B` are apart along some axis by at least
//! `4 max(w_A, w_B)` (`w` the largest extent over the three axes; box
//! centres at least five widths apart, against two for a V-list pair of
//! one tree), so each lies far outside the other's far-field surfaces. `A` acts on `B` through whichever is smaller
//! on each side:
//!
//! * **source side** — `A`'s sources with their charges, or, when `A` has a
//!   tree and more sources than `n` (surface points per box), its root's
//!   upward equivalent surface `x_equiv` with the root multipole `u_A`
//!   (valid outside `A`'s upward check surface);
//! * **target side** — `B`'s targets directly, or, when `B` has a tree and
//!   more targets than `n`, its root's downward check surface, whose
//!   potentials join the root's local expansion
//!   (`d_root = DC2E_0 c_root`, carried to the leaves by L2L and L2P).
//!
//! So the four cases are P2P, M2P, P2L and a root-to-root M2L, each a plain
//! kernel sum `out(y) += sum_x K(x, y) w(x)` over at most
//! `min(n_A, n) x min(n_B, n)` pairs per cluster pair: linear in the number
//! of points for a fixed number of clusters. Coordinates are taken relative
//! to `B`'s origin, differences formed in `f64`; since the clusters are far
//! apart, rounding them to `T` costs nothing in relative accuracy.

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{EvalMode, Kernel, Real, SourceKind};
use rayon::prelude::*;

use crate::Fmm;
use crate::part::{Body, Part};

/// Where one cluster's sources act from: points (relative to `centre`) with
/// weights (charges or dipoles of `kind`, or equivalent densities, which
/// are charges).
pub(crate) struct SourceSide<'a, T> {
    points: SidePoints<'a, T>,
    weights: &'a [T],
    kind: SourceKind,
}

/// Where one cluster receives: its targets (with `mode`) or its root's
/// downward check surface (potential only).
pub(crate) enum TargetSide<'a, T> {
    /// Stored targets relative to the part's `centre`, values into the
    /// part's stored-order output.
    Points { points: &'a [T], centre: [f64; 3] },
    /// The root's downward check surface, absolute `f64` coordinates.
    RootCheck { surface: Vec<f64>, centre: [f64; 3] },
}

enum SidePoints<'a, T> {
    /// Stored coordinates relative to `centre`.
    Stored { points: &'a [T], centre: [f64; 3] },
    /// Absolute coordinates (a root surface).
    Absolute(Vec<f64>),
}

impl<T: Real> SourceSide<'_, T> {
    /// The points in the frame of `origin`, rounded to `T`.
    fn points_from(&self, origin: [f64; 3]) -> Vec<T> {
        match &self.points {
            SidePoints::Stored { points, centre } => {
                let shift: [f64; 3] = std::array::from_fn(|c| centre[c] - origin[c]);
                points
                    .chunks_exact(3)
                    .flat_map(|p| {
                        std::array::from_fn::<T, 3, _>(|c| T::from_f64(p[c].to_f64() + shift[c]))
                    })
                    .collect()
            }
            SidePoints::Absolute(p) => relative(p, origin),
        }
    }
}

/// `p - origin` per point, rounded to `T`.
fn relative<T: Real>(p: &[f64], origin: [f64; 3]) -> Vec<T> {
    p.chunks_exact(3)
        .flat_map(|x| std::array::from_fn::<T, 3, _>(|c| T::from_f64(x[c] - origin[c])))
        .collect()
}

/// A root surface of `radius` half-widths, absolute coordinates.
fn root_surface<T: Real, S: M2lScheme<T>>(
    fmm: &Fmm<T, impl Kernel, S>,
    tree: &ferrofmm_tree::Octree,
    radius: f64,
) -> Vec<f64> {
    let d = tree.domain();
    let c = d.center();
    let r = 0.5 * d.width * radius;
    fmm.unit_surface
        .chunks_exact(3)
        .flat_map(|u| [c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2]])
        .collect()
}

/// The source side of `part`, given its charges in stored order and, for
/// a tree, its multipoles; `None` when it has no sources.
pub(crate) fn source_side<'a, T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    part: &'a Part<T, S>,
    charges: &'a [T],
    multipoles: &'a [T],
) -> Option<SourceSide<'a, T>> {
    if part.n_sources == 0 {
        return None;
    }
    let n = fmm.unit_surface.len() / 3;
    Some(match &part.body {
        Body::Tree(t) if part.n_sources > n => SourceSide {
            points: SidePoints::Absolute(root_surface(
                fmm,
                &t.tree,
                t.operators.radii().upward_equivalent,
            )),
            weights: &multipoles[..fmm.expansion_len()],
            kind: SourceKind::Charge,
        },
        Body::Tree(t) => SourceSide {
            points: SidePoints::Stored {
                points: &t.sources,
                centre: t.centre,
            },
            weights: charges,
            kind: fmm.source_kind,
        },
        Body::Points(p) => SourceSide {
            points: SidePoints::Stored {
                points: &p.sources,
                centre: p.centre,
            },
            weights: charges,
            kind: fmm.source_kind,
        },
    })
}

/// The target side of `part`; `None` when it has no targets.
pub(crate) fn target_side<'a, T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    part: &'a Part<T, S>,
) -> Option<TargetSide<'a, T>> {
    if part.n_targets == 0 {
        return None;
    }
    let n = fmm.unit_surface.len() / 3;
    Some(match &part.body {
        Body::Tree(t) if part.n_targets > n => TargetSide::RootCheck {
            surface: root_surface(fmm, &t.tree, t.operators.radii().downward_check),
            centre: t.centre,
        },
        Body::Tree(t) => TargetSide::Points {
            points: t.target_points(),
            centre: t.centre,
        },
        Body::Points(p) => TargetSide::Points {
            points: p.target_points(),
            centre: p.centre,
        },
    })
}

/// Adds every other cluster's field to `target`: into `out` (the part's
/// stored-order values, `mode`) or into `root_check` (potentials on the
/// root's downward check surface).
pub(crate) fn add_far_clusters<T: Real, K: Kernel>(
    kernel: &K,
    mode: EvalMode,
    target: &TargetSide<'_, T>,
    sources: &[&SourceSide<'_, T>],
    out: &mut [T],
    root_check: &mut [T],
) {
    match target {
        TargetSide::Points { points, centre } => {
            for s in sources {
                let x = s.points_from(*centre);
                sum_parallel(kernel, s.kind, mode, &x, s.weights, points, out);
            }
        }
        TargetSide::RootCheck { surface, centre } => {
            let y: Vec<T> = relative(surface, *centre);
            for s in sources {
                let x = s.points_from(*centre);
                sum_parallel(
                    kernel,
                    s.kind,
                    EvalMode::Potential,
                    &x,
                    s.weights,
                    &y,
                    root_check,
                );
            }
        }
    }
}

/// Pairs below which one kernel call runs on one thread.
const SERIAL_PAIRS: usize = 1 << 16;
/// Targets (or sources) per parallel task.
const CHUNK: usize = 64;

/// `out(y) += sum_x K(x, y) w(x)`, parallel over targets when there are
/// many, else over sources (partial sums added at the end).
#[allow(clippy::too_many_arguments)]
fn sum_parallel<T: Real, K: Kernel>(
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    x: &[T],
    w: &[T],
    y: &[T],
    out: &mut [T],
) {
    let (nx, ny) = (x.len() / 3, y.len() / 3);
    let v = kernel.values_per_target(mode);
    let nq = kernel.values_per_source(kind);
    if nx * ny <= SERIAL_PAIRS {
        kernel.evaluate_sources(kind, mode, x, w, y, out);
    } else if ny >= 4 * CHUNK {
        y.par_chunks(3 * CHUNK)
            .zip(out.par_chunks_mut(v * CHUNK))
            .for_each(|(yc, oc)| kernel.evaluate_sources(kind, mode, x, w, yc, oc));
    } else {
        let step = (nx / rayon::current_num_threads().max(1) / 4).max(4 * CHUNK);
        let partial = x
            .par_chunks(3 * step)
            .zip(w.par_chunks(nq * step))
            .fold(
                || vec![T::ZERO; out.len()],
                |mut acc, (xc, wc)| {
                    kernel.evaluate_sources(kind, mode, xc, wc, y, &mut acc);
                    acc
                },
            )
            .reduce(
                || vec![T::ZERO; out.len()],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(a, b)| *a += *b);
                    a
                },
            );
        out.iter_mut().zip(&partial).for_each(|(o, p)| *o += *p);
    }
}
