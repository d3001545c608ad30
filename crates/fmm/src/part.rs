//! The clusters of a problem: one tree each, or bare points.
//!
//! The driver splits sources and targets into clusters that are far apart
//! ([`ferrofmm_tree::clusters`]: cut along an axis where the gap is
//! [`DEFAULT_SEPARATION`](ferrofmm_tree::DEFAULT_SEPARATION) times the
//! groups' size along it, and every two clusters apart in 3D by at least
//! four times the wider one's width). A set without such gaps is one
//! cluster, and everything is as with a single octree. Otherwise each cluster is a [`Part`]:
//!
//! * the largest cluster (part 0), and every cluster with more than
//!   `leaf_size` sources or targets, gets an octree of its own with its own
//!   domain and coordinate origin ([`TreePart`]), so a distant point neither
//!   spends the tree's levels nor the coordinates' digits;
//! * a smaller cluster keeps its points only ([`PointsPart`]); its own pairs
//!   are summed directly (at most `leaf_size^2` of them).
//!
//! How clusters interact is in [`crate::coupling`]. This module also
//! builds the parts ([`clusters_of`], [`build_tree_part`], [`points_part`]).

use std::borrow::Cow;
use std::time::Instant;

use crate::SetupStep;
use crate::setup_progress::TREE_UNITS;

use ferrofmm_field::{FieldError, M2lInteractions, M2lScheme, OperatorParams, Operators};
use ferrofmm_kernels::{Kernel, Real};
use ferrofmm_tree::{Cluster, DEFAULT_SEPARATION, Domain, Octree, TreeOptions, separated_clusters};

use crate::FmmError;
use crate::builder::FmmBuilder;
use crate::coordinates::{coordinate_origin, permute_points, relative_points};
use crate::precompute::{OperatorNeeds, build_operators, level_interactions};
use crate::timings::SetupTimings;
use crate::validate::check_domain_width;

/// The state of a cluster with a tree: what a single-tree FMM keeps.
pub(crate) struct TreePart<T: Real, S> {
    pub(crate) tree: Octree,
    pub(crate) operators: Operators<T>,
    pub(crate) m2l: S,
    /// V-list interactions per level (index = level).
    pub(crate) m2l_interactions: Vec<M2lInteractions>,
    /// Sources in Morton (leaf) order, interleaved, relative to `centre`.
    pub(crate) sources: Vec<T>,
    /// Targets in Morton (leaf) order, interleaved, relative to `centre`;
    /// `None` when the tree's targets are its sources (not stored twice).
    pub(crate) targets: Option<Vec<T>>,
    /// Near the centre of the tree's domain
    /// ([`coordinate_origin`]): all
    /// coordinates the passes see (points and surfaces) are relative to
    /// it, so that far from the origin (say at 1e8 + [0, 1)^3, or
    /// 1e4 + [0, 1)^3 in f32) they keep the digits that resolve the
    /// problem instead of those of the offset.
    pub(crate) centre: [f64; 3],
    /// `false` for a cluster of targets only: the tree was built on the
    /// targets, which also stand in as its sources (with no charge), and the
    /// passes that carry sources are skipped.
    pub(crate) has_sources: bool,
    /// `false` for a cluster of sources only: the tree was built on the
    /// sources, and only the upward pass runs.
    pub(crate) has_targets: bool,
    /// The boxes whose expansions this process needs
    /// ([`crate::TreeFmm::with_active_boxes`]): `None` (every box) on one
    /// machine. Elsewhere P2M, UC2E and M2M skip the other boxes (their
    /// multipoles stay zero) and DC2E and L2L skip them (their locals stay
    /// zero); M2L and P2L still compute every box's check potential.
    pub(crate) active: Option<Vec<bool>>,
    /// The transfer vectors and levels the operators were built for (kept
    /// for a rebuild at another order: the tree's V lists may be gone).
    pub(crate) needs: OperatorNeeds,
}

impl<T: Real, S: M2lScheme<T>> TreePart<T, S> {
    /// V-list pairs of every level: the tree hands its V lists over to the
    /// M2L interactions, so they are counted there.
    pub(crate) fn m2l_pairs(&self) -> usize {
        self.m2l_interactions.iter().map(M2lInteractions::len).sum()
    }

    /// The part of `tree` with its operators and M2L scheme: each level's
    /// V-list pairs grouped for M2L, and the points (`f64`, interleaved;
    /// `targets` `None` when they are the sources) relative to the tree's
    /// [`coordinate_origin`], in the tree's sorted order: `permute` when
    /// they are in the caller's order (put through the tree's
    /// permutations), not when they already are in the tree's order.
    pub(crate) fn assemble(
        tree: Octree,
        (operators, m2l): (Operators<T>, S),
        sources: &[f64],
        targets: Option<&[f64]>,
        permute: bool,
        (has_sources, has_targets): (bool, bool),
        needs: OperatorNeeds,
    ) -> Result<Self, FmmError> {
        // A scheme that reads only the sibling blocks (FFT) or one chunk's
        // pairs at a time (SVD, dense) gets the levels without their pair
        // lists, released level by level as they are made
        // (`M2lInteractions::release_pairs`: 8 bytes a V pair).
        let compact = !m2l.reads_pair_lists();
        let m2l_interactions = (0..=tree.depth())
            .map(|level| {
                let mut inter = level_interactions(&tree, level)?;
                if compact {
                    inter.release_pairs();
                }
                Ok::<_, FieldError>(inter)
            })
            .collect::<Result<_, _>>()?;
        let mut tree = tree;
        let centre = coordinate_origin(tree.domain());
        // Points in the caller's order come sorted from the tree, whose
        // copy is taken over (not held twice); points already in the
        // tree's order (a caller's tree) are copied.
        let (sources, targets) = match permute {
            true => {
                // The tree was built on these points: it has a target set
                // of its own exactly when `targets` is given.
                let (s, t) = tree.take_sorted_points();
                debug_assert_eq!(t.is_some(), targets.is_some());
                (
                    relative_points(s, centre),
                    t.map(|t| relative_points(t, centre)),
                )
            }
            false => (
                permute_points(sources, None, centre),
                targets.map(|t| permute_points(t, None, centre)),
            ),
        };
        Ok(TreePart {
            tree,
            operators,
            m2l,
            m2l_interactions,
            sources,
            targets,
            centre,
            has_sources,
            has_targets,
            active: None,
            needs,
        })
    }
    /// Whether box `b` is [active](TreePart::active).
    pub(crate) fn is_active(&self, b: usize) -> bool {
        self.active.as_ref().is_none_or(|a| a[b])
    }

    /// Target coordinates in the tree's order (relative to `centre`): the
    /// sources' when the tree has one point set.
    pub(crate) fn target_points(&self) -> &[T] {
        self.targets.as_deref().unwrap_or(&self.sources)
    }

    /// Check or equivalent surface of box `b` scaled by `radius` (a multiple
    /// of the half-width), from the unit-cube surface grid `unit`, written
    /// into `out` (interleaved, relative to `centre` like the points).
    pub(crate) fn surface_of(&self, unit: &[f64], b: usize, radius: f64, out: &mut Vec<T>) {
        self.image_surface_of(unit, b, [0; 3], radius, out);
    }

    /// [`TreePart::surface_of`] for the image of box `b` at the periodic
    /// shift `shift` (in cells; see [`ferrofmm_tree::TreeOptions::periodic`]).
    pub(crate) fn image_surface_of(
        &self,
        unit: &[f64],
        b: usize,
        shift: [i8; 3],
        radius: f64,
        out: &mut Vec<T>,
    ) {
        let key = self.tree.key(b);
        let domain = self.tree.domain();
        let c: [f64; 3] = {
            let a = key.center(domain);
            std::array::from_fn(|i| a[i] - self.centre[i])
        };
        let r = key.half_width(domain) * radius;
        let c: [f64; 3] = std::array::from_fn(|a| c[a] + f64::from(shift[a]) * domain.width);
        out.clear();
        out.extend(
            unit.chunks_exact(3)
                .flat_map(|u| [c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2]])
                .map(T::from_f64),
        );
    }
}

/// The points `x` (interleaved) of a box seen at the periodic image
/// `shift` of a cell of side `width`: `x` itself for no shift, else a
/// translated copy in `buffer`.
pub(crate) fn image_points<'a, T: Real>(
    x: &'a [T],
    shift: [i8; 3],
    width: f64,
    buffer: &'a mut Vec<T>,
) -> &'a [T] {
    if shift == [0; 3] {
        return x;
    }
    let offset: [f64; 3] = std::array::from_fn(|a| f64::from(shift[a]) * width);
    buffer.clear();
    buffer.extend(
        x.chunks_exact(3).flat_map(|p| {
            std::array::from_fn::<T, 3, _>(|a| T::from_f64(p[a].to_f64() + offset[a]))
        }),
    );
    buffer
}

/// The shift of entry `k` of a list row whose shifts are `shifts` (`None`:
/// a tree without periodicity, every shift zero).
#[inline]
pub(crate) fn shift_at(shifts: Option<&[[i8; 3]]>, k: usize) -> [i8; 3] {
    shifts.map_or([0; 3], |s| s[k])
}

/// A small cluster: its points, in the order of its index lists, relative
/// to `centre`.
pub(crate) struct PointsPart<T> {
    pub(crate) sources: Vec<T>,
    /// `None` when the targets are the sources.
    pub(crate) targets: Option<Vec<T>>,
    pub(crate) centre: [f64; 3],
}

impl<T: Real> PointsPart<T> {
    /// Target coordinates (the sources' when they are the same set).
    pub(crate) fn target_points(&self) -> &[T] {
        self.targets.as_deref().unwrap_or(&self.sources)
    }
}

/// What a part holds.
pub(crate) enum Body<T: Real, S> {
    Tree(Box<TreePart<T, S>>),
    Points(PointsPart<T>),
}

/// One cluster: its body and which of the caller's points it holds.
pub(crate) struct Part<T: Real, S> {
    pub(crate) body: Body<T, S>,
    /// The caller's index of each of the part's sources (in the part's own
    /// numbering, before any tree sort); `None`: all sources, in order.
    pub(crate) source_ids: Option<Vec<usize>>,
    /// As `source_ids`, for the targets.
    pub(crate) target_ids: Option<Vec<usize>>,
    pub(crate) n_sources: usize,
    pub(crate) n_targets: usize,
}

impl<T: Real, S: M2lScheme<T>> Part<T, S> {
    /// The caller's index of the part's `k`-th source.
    pub(crate) fn source_id(&self, k: usize) -> usize {
        self.source_ids.as_ref().map_or(k, |ids| ids[k])
    }

    /// The caller's index of the part's `k`-th target.
    pub(crate) fn target_id(&self, k: usize) -> usize {
        self.target_ids.as_ref().map_or(k, |ids| ids[k])
    }

    /// The tree, for a part that has one.
    pub(crate) fn tree_part(&self) -> Option<&TreePart<T, S>> {
        match &self.body {
            Body::Tree(t) => Some(t),
            Body::Points(_) => None,
        }
    }

    /// Densities (`nq` per source: charges, dipoles) of the part's
    /// sources in the order its body stores them (tree order for a tree),
    /// from the caller's.
    pub(crate) fn local_charges(&self, charges: &[T], nq: usize) -> Vec<T> {
        let take = |k: usize| {
            let i = self.source_id(k);
            &charges[nq * i..nq * (i + 1)]
        };
        match &self.body {
            Body::Tree(t) if !t.has_sources => Vec::new(),
            Body::Tree(t) => t
                .tree
                .source_permutation()
                .iter()
                .flat_map(|&k| take(k))
                .copied()
                .collect(),
            Body::Points(_) => (0..self.n_sources).flat_map(take).copied().collect(),
        }
    }

    /// The number of targets the part stores values for (none for a tree
    /// part without targets).
    pub(crate) fn n_stored_targets(&self) -> usize {
        match &self.body {
            Body::Tree(t) if !t.has_targets => 0,
            _ => self.n_targets,
        }
    }

    /// The caller's index of stored target `k` (`k <`
    /// [`n_stored_targets`](Self::n_stored_targets)).
    pub(crate) fn stored_target_id(&self, k: usize) -> usize {
        match &self.body {
            Body::Tree(t) => self.target_id(t.tree.target_permutation()[k]),
            Body::Points(_) => self.target_id(k),
        }
    }

    /// Sources and targets of the part in absolute `f64` coordinates,
    /// written at their caller indices into `sources` and `targets` (an
    /// empty `targets` when the targets are the sources: not written).
    pub(crate) fn write_original_points(&self, sources: &mut [f64], targets: &mut [f64]) {
        let put = |out: &mut [f64], points: &[T], centre: [f64; 3], id: &dyn Fn(usize) -> usize| {
            if out.is_empty() {
                return;
            }
            for (k, p) in points.chunks_exact(3).enumerate() {
                let i = id(k);
                for c in 0..3 {
                    out[3 * i + c] = p[c].to_f64() + centre[c];
                }
            }
        };
        match &self.body {
            Body::Tree(t) => {
                let sp = t.tree.source_permutation();
                let tp = t.tree.target_permutation();
                if t.has_sources {
                    put(sources, &t.sources, t.centre, &|k| self.source_id(sp[k]));
                }
                if t.has_targets {
                    put(targets, t.target_points(), t.centre, &|k| {
                        self.target_id(tp[k])
                    });
                }
            }
            Body::Points(p) => {
                put(sources, &p.sources, p.centre, &|k| self.source_id(k));
                put(targets, p.target_points(), p.centre, &|k| self.target_id(k));
            }
        }
    }
}

/// The far-separated clusters of the problem, largest first (by
/// `max(#sources, #targets)`; ties keep the order of
/// [`separated_clusters`]). One cluster (with empty index lists, meaning
/// everything) when `fixed_domain` is set or there are no far groups.
pub(crate) fn clusters_of(
    sources: &[f64],
    targets: Option<&[f64]>,
    fixed_domain: bool,
) -> Vec<Cluster> {
    if fixed_domain {
        return vec![Cluster::default()];
    }
    let mut clusters = separated_clusters(sources, targets, DEFAULT_SEPARATION);
    if clusters.len() <= 1 {
        return vec![Cluster::default()];
    }
    let main = (0..clusters.len())
        .max_by_key(|&k| (clusters[k].size(), std::cmp::Reverse(k)))
        .unwrap_or(0);
    clusters[..=main].rotate_right(1);
    clusters
}

/// The points of `points` at `ids`, interleaved.
pub(crate) fn gather<T: Copy>(points: &[T], ids: &[usize]) -> Vec<T> {
    ids.iter()
        .flat_map(|&i| [points[3 * i], points[3 * i + 1], points[3 * i + 2]])
        .collect()
}

/// The caller's points and the cluster a part is built from (`ids: None`:
/// everything, in the caller's order).
pub(crate) struct PartInput<'a> {
    pub(crate) src64: &'a [f64],
    pub(crate) tgt64: Option<&'a [f64]>,
    pub(crate) ids: Option<&'a Cluster>,
}

impl PartInput<'_> {
    /// The part's sources and targets (`None`: the targets are the sources,
    /// or the part has no targets of its own set).
    fn points<'b, U: Copy>(
        &self,
        src: &'b [U],
        tgt: Option<&'b [U]>,
    ) -> (Cow<'b, [U]>, Option<Cow<'b, [U]>>) {
        match self.ids {
            None => (Cow::Borrowed(src), tgt.map(Cow::Borrowed)),
            Some(c) => (
                Cow::Owned(gather(src, &c.sources)),
                tgt.map(|t| Cow::Owned(gather(t, &c.targets))),
            ),
        }
    }
}

/// A cluster with a tree: the tree on its points, the operators for it, the
/// points in tree order relative to the tree's coordinate origin.
pub(crate) fn build_tree_part<T: Real, K: Kernel, S: M2lScheme<T>>(
    b: &FmmBuilder<'_, T, K>,
    params: &OperatorParams,
    config: &S::Config,
    input: &PartInput<'_>,
    setup: &mut SetupTimings,
) -> Result<TreePart<T, S>, FmmError> {
    let t0 = Instant::now();
    let (src64, tgt64) = input.points(input.src64, input.tgt64);
    let has_sources = !src64.is_empty();
    let has_targets = tgt64.as_ref().is_none_or(|t| !t.is_empty());
    // A one-sided cluster builds its tree on the side it has.
    let (tree_src64, tree_tgt64) = match (has_sources, has_targets) {
        (true, true) => (&src64, tgt64.as_ref()),
        (true, false) => (&src64, None),
        _ => (tgt64.as_ref().expect("targets"), None),
    };
    let options = TreeOptions {
        leaf_size: b.leaf_size,
        max_level: b.max_level,
        domain: b.domain,
        uniform_depth: None,
        balance: true,
        periodic: b.periodic.map_or([false; 3], |cell| cell.axes().mask()),
    };
    let reporter = &b.setup_progress;
    reporter.report(SetupStep::Tree, 0, TREE_UNITS);
    let tree = Octree::new_reporting(tree_src64, tree_tgt64.map(|t| &t[..]), &options, &|s| {
        reporter.tree_step(s)
    })?;
    setup.tree += t0.elapsed();
    check_domain_width(tree.domain().width, T::PRECISION, tree.depth())?;
    let mut timings = SetupTimings::default();
    // The root's local expansion is needed when other clusters or the
    // far images of a periodic cell act on it.
    let coupled = input.ids.is_some() || b.periodic.is_some();
    // Finding the used transfer vectors counts as operator setup.
    let t = Instant::now();
    let needs = OperatorNeeds::of(&tree, coupled);
    setup.operators += t.elapsed();
    reporter.report(SetupStep::Operators, 0, 1);
    let (operators, m2l) = build_operators(&b.kernel, params, config, &tree, &needs, &mut timings)?;
    reporter.finish(SetupStep::Operators);
    setup.operators += timings.operators;
    setup.m2l_precompute += timings.m2l_precompute;

    let t = Instant::now();
    reporter.report(SetupStep::Layout, 0, 1);
    let mut part = TreePart::assemble(
        tree,
        (operators, m2l),
        tree_src64,
        tree_tgt64.map(|t| &t[..]),
        true,
        (has_sources, has_targets),
        needs,
    )?;
    // The M2L interactions hold the V entries from here on: the tree's
    // own V lists would be a second copy (8 bytes an entry).
    drop(part.tree.take_v_lists());
    setup.layout += t.elapsed();
    reporter.report(SetupStep::Layout, 1, 1);
    Ok(part)
}

/// A small cluster: its points relative to the origin of its bounding cube.
pub(crate) fn points_part<T: Real>(input: &PartInput<'_>) -> PointsPart<T> {
    let (src64, tgt64) = input.points(input.src64, input.tgt64);
    let sets: Vec<&[f64]> = [Some(&src64[..]), tgt64.as_deref()]
        .into_iter()
        .flatten()
        .collect();
    let centre = Domain::from_points(&sets).map_or([0.0; 3], |d| coordinate_origin(&d));
    let targets = tgt64.map(|t| permute_points(&t, None, centre));
    PointsPart {
        sources: permute_points(&src64, None, centre),
        targets,
        centre,
    }
}
