//! [`Operators`]: check-to-equivalent pseudo-inverses (UC2E, DC2E) and the
//! parent/child translations (M2M, L2L) for every level of a tree.
//!
//! With `A_u = K(uc <- ue)` and `A_d = K(dc <- de)` the check matrices of a
//! box (check surface by rows, equivalent surface by columns):
//!
//! ```text
//! UC2E = A_u^+            DC2E = A_d^+                  (truncated SVD, rcond)
//! M2M_o = A_u(parent)^+ K(uc_parent <- ue_child_o)
//! L2L_o = A_d(child_o)^+ K(dc_child_o <- de_parent)
//! ```
//!
//! for the eight child octants `o`. The modules, each with its maths:
//!
//! * this one: the public [`Operators`] (which set serves a level, the
//!   apply methods) and [`OperatorDiagnostics`];
//! * `tables`: the per-level operator sets as stored and cached (the
//!   pseudo-inverse factors, the octant matrices, the cache layout and
//!   key);
//! * `build`: computing the sets in `f64` (per level or once for a
//!   homogeneous kernel) and rounding them to `T`;
//! * `symmetry`: the reflections of the surfaces and the symmetry tests
//!   that let `build` permute instead of recompute.
//!
//! Uses: `cache`, `levels`, `linalg`, `pinv`, `surface`, `threads`,
//! [`crate::gemm_scaled`] and [`OperatorParams`]; nothing of M2L.

mod build;
mod symmetry;
mod tables;

use ferrofmm_kernels::{Kernel, Real};

use crate::cache::{CachePayload, CacheStatus, load_or_compute};
use crate::levels::LevelMap;
use crate::pinv::PinvSummary;
use crate::{
    FieldError, OperatorParams, SurfaceKind, SurfaceRadii, Update, expansion_len, gemm_scaled,
    surface_points,
};
use build::compute;
use tables::{
    CheckToEquivalent, ChildTranslations, OperatorLayout, OperatorTables, PinvFactors, cache_key,
};

/// Center offset (in child half-widths) of child `octant` from its parent's
/// center: bit 0 set = `+x` half, bit 1 = `+y`, bit 2 = `+z`.
///
/// ```
/// assert_eq!(ferrofmm_field::octant_offset(0), [-1.0, -1.0, -1.0]);
/// assert_eq!(ferrofmm_field::octant_offset(5), [1.0, -1.0, 1.0]);
/// assert_eq!(ferrofmm_field::octant_offset(2), [-1.0, 1.0, -1.0]);
/// ```
pub fn octant_offset(octant: usize) -> [f64; 3] {
    assert!(octant < 8, "octant must be < 8, got {octant}");
    let s = |bit: usize| if octant >> bit & 1 == 1 { 1.0 } else { -1.0 };
    [s(0), s(1), s(2)]
}

/// The precomputed KIFMM operators other than M2L, for levels `0..=depth`
/// of a cubic domain of width `W` (a level-`l` box has half-width
/// `h_l = W / 2^(l+1)`).
///
/// With `n` points per surface and a box of center `c`, half-width `h`:
///
/// * **UC2E** (`uc2e`): upward check potential -> upward equivalent density,
///   `phi = A_u^+ u` with `A_u = K(uc <- ue)` (`A_u[j, i] = K(y_i, x_j)`,
///   `y` on the upward equivalent surface, `x` on the upward check surface).
/// * **DC2E** (`dc2e`): downward check potential -> downward equivalent
///   density, `psi += A_d^+ d` with `A_d = K(dc <- de)`.
/// * **M2M** (`m2m`): `phi_parent += A_u(parent)^+ K(uc_parent <- ue_child) phi_child`.
/// * **L2L** (`l2l`): `psi_child += A_d(child)^+ K(dc_child <- de_parent) psi_parent`.
///
/// The pseudo-inverses are truncated SVDs computed in `f64` and stored as
/// two factors (`V_r S_r^-1` and `U_r^T`, see `docs/stability.md`); M2M and
/// L2L are formed in `f64` and rounded to `T` once.
///
/// For a kernel homogeneous of degree `d` (`K(s x, s y) = s^d K(x, y)`)
/// everything is computed once at half-width 1 and rescaled: at half-width
/// `h` the pseudo-inverses scale by `h^-d`, M2M and L2L are scale
/// invariant. Other kernels get one operator set per level.
///
/// All apply methods are sequential (one matrix product each, `Par::Seq`)
/// and work on any number of boxes at once: expansions are column-major
/// `n x ncols` with each box's `n` values contiguous. Parallelise over
/// column blocks outside.
///
/// ```
/// use ferrofmm_field::{OperatorParams, Operators};
/// use ferrofmm_kernels::Laplace3d;
/// let ops = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(4), 1.0, 3).unwrap();
/// let n = ops.n_surface();
/// let check = vec![1.0; 2 * n]; // two boxes at level 3
/// let mut equiv = vec![0.0; 2 * n];
/// ops.uc2e(3, &check, &mut equiv);
/// let mut parent = vec![0.0; n];
/// ops.m2m(3, 0, &equiv[..n], &mut parent);
/// ```
pub struct Operators<T: Real> {
    order: usize,
    n: usize,
    radii: SurfaceRadii,
    rcond: f64,
    levels: LevelMap,
    child_levels: LevelMap,
    tables: OperatorTables<T>,
    cache_status: CacheStatus,
}

/// Health report of the pseudo-inverses, per operator set (one set for a
/// homogeneous kernel, one per level `0..=depth` otherwise).
#[derive(Clone, Debug, PartialEq)]
pub struct OperatorDiagnostics {
    /// UC2E summaries.
    pub uc2e: Vec<PinvSummary>,
    /// DC2E summaries.
    pub dc2e: Vec<PinvSummary>,
    /// Cutoff used.
    pub rcond: f64,
    /// Largest kept condition number over all pseudo-inverses.
    pub max_condition: f64,
    /// `eps_T * max_condition`: the relative size to which rounding errors
    /// of the working type in a check potential can grow in the equivalent
    /// density. Far above 1 means the equivalent densities are dominated by
    /// amplified noise (see `docs/stability.md`).
    pub rounding_amplification: f64,
    /// Human-readable warnings (empty when all is well).
    pub warnings: Vec<String>,
}

/// Summaries beyond which [`OperatorDiagnostics::warnings`] complains:
/// `eps_T * condition` above this threshold.
pub const AMPLIFICATION_WARNING: f64 = 1e3;

impl<T: Real> Operators<T> {
    /// Compute (or load from the cache) the operators of `kernel` for levels
    /// `0..=depth` of a domain of width `domain_width`.
    ///
    /// Errors: invalid parameters or geometry, a kernel returning non-finite
    /// values on the surfaces, SVD failure. Cache problems are not errors
    /// (see [`Operators::cache_status`]).
    pub fn new<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        domain_width: f64,
        depth: u32,
    ) -> Result<Self, FieldError> {
        Self::from_level(kernel, params, domain_width, depth, 0)
    }

    /// [`Operators::new`] for the levels `first_level..=depth` only: a
    /// kernel that needs one operator set per level (not homogeneous) gets
    /// no check-to-equivalent operators for the levels above
    /// `first_level` and no M2M / L2L between them (children at levels
    /// `first_level + 1..=depth` only). A tree whose far field (V, W and X
    /// lists) starts at level `l` needs nothing above it unless the root's
    /// expansions are used (coupling of far clusters): levels 0 and 1 have
    /// no V list, and each level's set costs an SVD of the check matrix.
    /// A homogeneous kernel has one set for every level and ignores
    /// `first_level` ([`Operators::first_level`] is then 0).
    ///
    /// ```
    /// use ferrofmm_field::{OperatorParams, Operators};
    /// use ferrofmm_kernels::ModifiedHelmholtz3d;
    /// let yukawa = ModifiedHelmholtz3d::new(2.0).unwrap();
    /// let params = OperatorParams::new(4);
    /// let ops = Operators::<f64>::from_level(&yukawa, &params, 1.0, 3, 2).unwrap();
    /// assert_eq!(ops.first_level(), 2);
    /// assert_eq!(ops.diagnostics().uc2e.len(), 2); // levels 2 and 3
    /// let n = ops.n_surface();
    /// let mut parent = vec![0.0; n];
    /// ops.m2m(3, 0, &vec![1.0; n], &mut parent); // children at level 3
    /// ```
    ///
    /// # Errors
    /// As [`Operators::new`].
    pub fn from_level<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        domain_width: f64,
        depth: u32,
        first_level: u32,
    ) -> Result<Self, FieldError> {
        params.validate()?;
        let homogeneity = kernel.homogeneity();
        let first = if homogeneity.is_some() {
            0
        } else {
            first_level
        };
        let levels = LevelMap::new(homogeneity, domain_width, depth, first)?;
        let child_levels = LevelMap::new(homogeneity, domain_width, depth, first + 1)?;
        let n = expansion_len(kernel, params.order);
        let rcond = params.rcond_for_kernel(kernel, T::PRECISION);
        let n_child_sets = if depth > first {
            child_levels.n_sets()
        } else {
            0
        };

        let key = cache_key::<K, T>(
            kernel,
            params,
            domain_width,
            depth,
            rcond,
            n_child_sets,
            first,
        );
        let accept = |l: &OperatorLayout| l.accept(n, levels.n_sets(), n_child_sets);
        let (tables, cache_status) = load_or_compute(
            params.cache_dir.as_deref(),
            params.cache_size_limit,
            &key,
            accept,
            || compute(kernel, params, rcond, &levels, n_child_sets),
        )?;
        Ok(Operators {
            order: params.order,
            n: tables.n,
            radii: params.radii,
            rcond,
            levels,
            child_levels,
            tables,
            cache_status,
        })
    }

    /// Shallowest level with operators (see [`Operators::from_level`]):
    /// the check-to-equivalent operators serve `first_level()..=depth()`,
    /// M2M and L2L children at `first_level() + 1..=depth()`. Always 0 for
    /// a homogeneous kernel.
    pub fn first_level(&self) -> u32 {
        match self.levels.homogeneity {
            Some(_) => 0,
            None => self.levels.first_level,
        }
    }

    /// Expansion order `p`.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Values in one expansion, `n = c (6 (p-1)^2 + 2)`: one per surface
    /// point and kernel [component](Kernel::components) (see
    /// [`expansion_len`](crate::expansion_len)); the points alone are
    /// [`n_surface_points`](crate::n_surface_points).
    pub fn n_surface(&self) -> usize {
        self.n
    }

    /// Surface radii (multiples of the box half-width).
    pub fn radii(&self) -> &SurfaceRadii {
        &self.radii
    }

    /// Pseudo-inverse cutoff used (relative to the largest singular value).
    pub fn rcond(&self) -> f64 {
        self.rcond
    }

    /// Deepest level the operators were built for.
    pub fn depth(&self) -> u32 {
        self.levels.depth
    }

    /// Half-width of a box at `level`, `W / 2^(level+1)`.
    pub fn half_width(&self, level: u32) -> f64 {
        self.levels.half_width(level)
    }

    /// Points of one of the four surfaces of the box at `level` with
    /// `center`: `center + r * h_level * unit_surface`. Convenience for
    /// P2M (sources -> upward check), M2P (upward equivalent -> targets),
    /// P2L (sources -> downward check) and L2P (downward equivalent ->
    /// targets).
    pub fn surface_points(&self, kind: SurfaceKind, level: u32, center: [f64; 3]) -> Vec<T> {
        surface_points(
            self.order,
            center,
            self.half_width(level),
            self.radii.radius(kind),
        )
    }

    /// What happened with the on-disk cache.
    pub fn cache_status(&self) -> &CacheStatus {
        &self.cache_status
    }

    /// Bytes held by the operator values.
    pub fn memory_bytes(&self) -> usize {
        let values: usize = self.tables.arrays().iter().map(|a| a.len()).sum();
        values * std::mem::size_of::<T>()
    }

    /// Ranks and conditioning of the pseudo-inverses, with warnings when the
    /// cutoff lets rounding errors of `T` dominate.
    pub fn diagnostics(&self) -> OperatorDiagnostics {
        let uc2e: Vec<_> = self.tables.sets.iter().map(|s| s.uc2e.summary).collect();
        let dc2e: Vec<_> = self.tables.sets.iter().map(|s| s.dc2e.summary).collect();
        let max_condition = uc2e
            .iter()
            .chain(&dc2e)
            .map(|s| s.condition())
            .fold(0.0, f64::max);
        let rounding_amplification = T::EPSILON.to_f64() * max_condition;
        let mut warnings = Vec::new();
        if rounding_amplification > AMPLIFICATION_WARNING {
            warnings.push(format!(
                "check-to-equivalent pseudo-inverse has condition {max_condition:.2e} (cutoff {:.1e}): \
                 {} rounding errors can be amplified {rounding_amplification:.1e}-fold into the \
                 equivalent densities; expect unreliable results at order {} — use the default cutoff \
                 ({:.0e}) or a lower order",
                self.rcond,
                T::PRECISION.name(),
                self.order,
                crate::default_pinv_rcond(T::PRECISION),
            ));
        }
        for (name, list) in [("UC2E", &uc2e), ("DC2E", &dc2e)] {
            if list.iter().any(|s| s.rank == 0) {
                warnings.push(format!(
                    "{name} pseudo-inverse has rank 0 (kernel vanishes on the surfaces?)"
                ));
            }
        }
        OperatorDiagnostics {
            uc2e,
            dc2e,
            rcond: self.rcond,
            max_condition,
            rounding_amplification,
            warnings,
        }
    }

    fn ncols(&self, len: usize, what: &str) -> usize {
        assert_eq!(
            len % self.n,
            0,
            "{what}: length {len} is not a multiple of n = {}",
            self.n
        );
        len / self.n
    }

    /// `equiv = UC2E(level) check`: upward check potentials to upward
    /// equivalent densities for `ncols = check.len() / n` boxes
    /// (column-major `n x ncols`). **Overwrites** `equiv`.
    ///
    /// # Panics
    /// On length mismatch; for a non-homogeneous kernel when `level > depth`.
    pub fn uc2e(&self, level: u32, check: &[T], equiv: &mut [T]) {
        let out = ("uc2e", "equiv", Update::Overwrite);
        self.check_to_equivalent(level, |s| &s.uc2e, check, equiv, out);
    }

    /// `local += DC2E(level) check`: downward check potentials to downward
    /// equivalent densities (column-major `n x ncols`). **Accumulates**.
    ///
    /// # Panics
    /// On length mismatch; for a non-homogeneous kernel when `level > depth`.
    pub fn dc2e(&self, level: u32, check: &[T], local: &mut [T]) {
        let out = ("dc2e", "local", Update::Accumulate);
        self.check_to_equivalent(level, |s| &s.dc2e, check, local, out);
    }

    /// `output [+]= s A^+ check` with the pseudo-inverse `pick` chooses
    /// from the set serving `level` and its factor `s = (h / h_set)^-d`;
    /// `what` names the operator, its output and the update in panics.
    fn check_to_equivalent(
        &self,
        level: u32,
        pick: impl Fn(&CheckToEquivalent<T>) -> &PinvFactors<T>,
        check: &[T],
        output: &mut [T],
        (what, output_name, update): (&str, &str, Update),
    ) {
        let ncols = self.ncols(check.len(), what);
        assert_eq!(
            output.len(),
            check.len(),
            "{what}: {output_name} and check lengths differ"
        );
        let (set, scale) = self.levels.lookup(level, -1.0);
        pick(&self.tables.sets[set]).apply(scale, ncols, check, output, update);
    }

    /// The parent/child translations for children at `child_level`.
    fn children(&self, child_level: u32, octant: usize) -> &ChildTranslations<T> {
        assert!(octant < 8, "octant must be < 8, got {octant}");
        assert!(child_level >= 1, "child level must be at least 1");
        assert!(
            !self.tables.children.is_empty(),
            "operators were built without M2M/L2L (depth 0, or no level below the first)"
        );
        let (set, _) = self.child_levels.lookup(child_level, 0.0);
        &self.tables.children[set]
    }

    /// `parent += M2M(child_level, octant) child`: child upward equivalent
    /// densities to the parent's (column-major `n x ncols`, accumulates).
    /// `octant`: bit 0 = child in the `+x` half, bit 1 = `+y`, bit 2 = `+z`.
    ///
    /// # Panics
    /// On length mismatch, `octant >= 8`, `child_level == 0`, depth 0, or
    /// (non-homogeneous kernel) `child_level > depth`.
    pub fn m2m(&self, child_level: u32, octant: usize, child: &[T], parent: &mut [T]) {
        let op = &self.children(child_level, octant).m2m[octant];
        self.translate(op, child, parent, "m2m");
    }

    /// `child += L2L(child_level, octant) parent`: parent downward
    /// equivalent densities to the child's (accumulates).
    ///
    /// # Panics
    /// As [`Operators::m2m`].
    pub fn l2l(&self, child_level: u32, octant: usize, parent: &[T], child: &mut [T]) {
        let op = &self.children(child_level, octant).l2l[octant];
        self.translate(op, parent, child, "l2l");
    }

    /// `output += op input` with the `n x n` translation `op`, for
    /// `input.len() / n` columns.
    fn translate(&self, op: &[T], input: &[T], output: &mut [T], what: &str) {
        let ncols = self.ncols(input.len(), what);
        assert_eq!(
            input.len(),
            output.len(),
            "{what}: parent and child lengths differ"
        );
        gemm_scaled(
            self.n,
            ncols,
            self.n,
            1.0,
            op,
            input,
            output,
            Update::Accumulate,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_kernels::Laplace3d;

    /// M2M and L2L come from the per-octant arrays: octant `o`'s M2M of a
    /// constant density differs from octant `7 - o`'s by the mirror
    /// symmetry only, so their sums agree.
    #[test]
    fn octant_matrices_are_the_ones_applied() {
        let ops = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(4), 1.0, 2).unwrap();
        let n = ops.n_surface();
        let child = vec![1.0; n];
        let sum = |o: usize| {
            let mut parent = vec![0.0; n];
            ops.m2m(2, o, &child, &mut parent);
            parent.iter().sum::<f64>()
        };
        for o in 0..8 {
            let (a, b) = (sum(o), sum(7 - o));
            assert!((a - b).abs() <= 1e-10 * a.abs(), "{o}: {a} vs {b}");
            let direct = &ops.children(2, o).m2m[o];
            assert_eq!(direct.len(), n * n);
        }
    }
}
