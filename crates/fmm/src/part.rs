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
//! How clusters interact is in [`crate::coupling`].

use ferrofmm_field::{M2lInteractions, M2lScheme, Operators};
use ferrofmm_kernels::Real;
use ferrofmm_tree::Octree;

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
    /// ([`coordinate_origin`](crate::fmm::coordinate_origin)): all
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
}

impl<T: Real, S: M2lScheme<T>> TreePart<T, S> {
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
        let key = self.tree.key(b);
        let domain = self.tree.domain();
        let c: [f64; 3] = {
            let a = key.center(domain);
            std::array::from_fn(|i| a[i] - self.centre[i])
        };
        let r = key.half_width(domain) * radius;
        out.clear();
        out.extend(
            unit.chunks_exact(3)
                .flat_map(|u| [c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2]])
                .map(T::from_f64),
        );
    }
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

    /// The caller's index of each stored target, in stored order.
    pub(crate) fn stored_target_ids(&self) -> Vec<usize> {
        match &self.body {
            Body::Tree(t) if !t.has_targets => Vec::new(),
            Body::Tree(t) => t
                .tree
                .target_permutation()
                .iter()
                .map(|&k| self.target_id(k))
                .collect(),
            Body::Points(_) => (0..self.n_targets).map(|k| self.target_id(k)).collect(),
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
