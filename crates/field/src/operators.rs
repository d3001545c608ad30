//! [`Operators`]: check-to-equivalent pseudo-inverses (UC2E, DC2E) and the
//! parent/child translations (M2M, L2L) for every level of a tree.

use faer::{Accum, Mat, MatRef, Par};
use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;

use crate::cache::{
    CacheKey, CachePayload, CacheStatus, StoreLayout, ValueReader, load_or_compute,
};
use crate::levels::LevelMap;
use crate::linalg::{col_major, kernel_matrix, round_to};
use crate::pinv::{PinvF64, PinvSummary, pinv, pinv_pair};
use crate::{
    FieldError, OperatorParams, SurfaceKind, SurfaceRadii, Update, expansion_len, gemm_scaled,
    surface_points,
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

/// A truncated pseudo-inverse `A^+ = (V_r S_r^-1) U_r^T` in the working
/// type, kept as its two factors and applied as two products (never
/// formed: see `docs/stability.md`).
struct PinvFactors<T> {
    /// `V_r S_r^-1`, column-major `n x r`.
    vs: Vec<T>,
    /// `U_r^T`, column-major `r x n`.
    ut: Vec<T>,
    /// What the truncation kept (`n`, the rank `r`, singular values).
    summary: PinvSummary,
}

impl<T: Real> PinvFactors<T> {
    fn from_f64(p: &PinvF64) -> Self {
        PinvFactors {
            vs: round_to(&p.vs),
            ut: round_to(&p.ut),
            summary: p.summary,
        }
    }

    /// `out = [out +] scale A^+ input` for `ncols` column-major columns.
    fn apply(&self, scale: f64, ncols: usize, input: &[T], out: &mut [T], update: Update) {
        let (n, r) = (self.summary.n, self.summary.rank);
        let mut tmp = vec![T::ZERO; r * ncols];
        gemm_scaled(
            r,
            ncols,
            n,
            1.0,
            &self.ut,
            input,
            &mut tmp,
            Update::Overwrite,
        );
        gemm_scaled(n, ncols, r, scale, &self.vs, &tmp, out, update);
    }
}

/// The check-to-equivalent pseudo-inverses of one operator set (one level,
/// or every level of a homogeneous kernel).
struct CheckToEquivalent<T> {
    /// UC2E: upward check potential -> upward equivalent density.
    uc2e: PinvFactors<T>,
    /// DC2E: downward check potential -> downward equivalent density.
    dc2e: PinvFactors<T>,
}

/// The parent/child translations of one child-level set: one column-major
/// `n x n` matrix per octant of the child.
struct ChildTranslations<T> {
    /// M2M: child upward equivalent density -> parent's.
    m2m: [Vec<T>; 8],
    /// L2L: parent downward equivalent density -> child's.
    l2l: [Vec<T>; 8],
}

/// Everything [`Operators`] precomputes; what the operator cache stores.
struct OperatorTables<T> {
    n: usize,
    sets: Vec<CheckToEquivalent<T>>,
    children: Vec<ChildTranslations<T>>,
}

/// The pseudo-inverse summaries of one set, as cached.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct SetSummaries {
    uc2e: PinvSummary,
    dc2e: PinvSummary,
}

/// What a cached [`OperatorTables`] holds, in order: per set the factors
/// `V_r S_r^-1` and `U_r^T` of UC2E then of DC2E (their ranks in the
/// summaries), then per child set the eight M2M and the eight L2L
/// matrices (`n x n`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct OperatorLayout {
    /// Surface points `n`.
    n: usize,
    /// Per set, what its two pseudo-inverses kept.
    sets: Vec<SetSummaries>,
    /// Child-level sets (M2M and L2L).
    child_sets: usize,
}

impl StoreLayout for OperatorLayout {
    fn n_values(&self) -> Result<usize, String> {
        let n = self.n;
        let mut total = 16 * n * n * self.child_sets;
        for s in &self.sets {
            for p in [s.uc2e, s.dc2e] {
                if p.n != n || p.rank > n {
                    return Err(format!(
                        "pseudo-inverse of rank {} on {} points for n = {n}",
                        p.rank, p.n
                    ));
                }
                total += 2 * n * p.rank;
            }
        }
        Ok(total)
    }
}

impl<T: Real> CachePayload<T> for OperatorTables<T> {
    type Layout = OperatorLayout;

    fn layout(&self) -> OperatorLayout {
        OperatorLayout {
            n: self.n,
            sets: self
                .sets
                .iter()
                .map(|s| SetSummaries {
                    uc2e: s.uc2e.summary,
                    dc2e: s.dc2e.summary,
                })
                .collect(),
            child_sets: self.children.len(),
        }
    }

    fn arrays(&self) -> Vec<&[T]> {
        let pinvs = self
            .sets
            .iter()
            .flat_map(|s| [&s.uc2e.vs, &s.uc2e.ut, &s.dc2e.vs, &s.dc2e.ut].map(Vec::as_slice));
        let children = self
            .children
            .iter()
            .flat_map(|c| c.m2m.iter().chain(&c.l2l).map(Vec::as_slice));
        pinvs.chain(children).collect()
    }

    fn from_values(layout: OperatorLayout, values: Vec<T>) -> Result<Self, String> {
        let n = layout.n;
        let mut reader = ValueReader::new(values);
        let mut factors = |summary: PinvSummary| -> Result<PinvFactors<T>, String> {
            Ok(PinvFactors {
                vs: reader.take(n * summary.rank)?,
                ut: reader.take(summary.rank * n)?,
                summary,
            })
        };
        let sets = layout
            .sets
            .iter()
            .map(|s| {
                Ok(CheckToEquivalent {
                    uc2e: factors(s.uc2e)?,
                    dc2e: factors(s.dc2e)?,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let mut octants = || -> Result<[Vec<T>; 8], String> {
            let mats: Vec<Vec<T>> = (0..8)
                .map(|_| reader.take(n * n))
                .collect::<Result<_, _>>()?;
            Ok(mats.try_into().expect("eight octants"))
        };
        let children = (0..layout.child_sets)
            .map(|_| {
                Ok(ChildTranslations {
                    m2m: octants()?,
                    l2l: octants()?,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        reader.finish()?;
        Ok(OperatorTables { n, sets, children })
    }
}

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

        let mut key =
            CacheKey::new::<K, T>("operators", kernel, params.order, params.radii.to_array())
                .for_domain(domain_width, depth);
        key.rcond = Some(rcond);
        key.flags = vec![n_child_sets as u64];
        if first > 0 {
            // Files of the full set keep their key.
            key.flags.push(u64::from(first));
        }
        let accept = |l: &OperatorLayout| {
            if l.n == n && l.sets.len() == levels.n_sets() && l.child_sets == n_child_sets {
                Ok(())
            } else {
                Err("layout disagrees with the parameters".to_string())
            }
        };
        let (tables, cache_status) =
            load_or_compute(params.cache_dir.as_deref(), &key, accept, || {
                compute(kernel, params, rcond, &levels, n_child_sets)
            })?;
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
        let ncols = self.ncols(check.len(), "uc2e");
        assert_eq!(
            equiv.len(),
            check.len(),
            "uc2e: equiv and check lengths differ"
        );
        let (set, scale) = self.levels.lookup(level, -1.0);
        self.tables.sets[set]
            .uc2e
            .apply(scale, ncols, check, equiv, Update::Overwrite);
    }

    /// `local += DC2E(level) check`: downward check potentials to downward
    /// equivalent densities (column-major `n x ncols`). **Accumulates**.
    ///
    /// # Panics
    /// On length mismatch; for a non-homogeneous kernel when `level > depth`.
    pub fn dc2e(&self, level: u32, check: &[T], local: &mut [T]) {
        let ncols = self.ncols(check.len(), "dc2e");
        assert_eq!(
            local.len(),
            check.len(),
            "dc2e: local and check lengths differ"
        );
        let (set, scale) = self.levels.lookup(level, -1.0);
        self.tables.sets[set]
            .dc2e
            .apply(scale, ncols, check, local, Update::Accumulate);
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

/// Where the translations of one child-level set come from: the parent's
/// and the child's operator set, half-width and pseudo-inverse scale.
struct ChildGeometry {
    parent_set: usize,
    parent_half_width: f64,
    /// Factor on the parent's UC2E (M2M).
    parent_scale: f64,
    child_set: usize,
    child_half_width: f64,
    /// Factor on the child's DC2E (L2L).
    child_scale: f64,
}

impl ChildGeometry {
    /// Child set `c` (children at level `c + 1`): a homogeneous kernel of
    /// degree `d` computes everything at parent half-width 1 (the child's
    /// DC2E, computed at half-width 1, scales by `(1/2)^-d`); any other
    /// kernel uses the sets of both levels.
    fn of(levels: &LevelMap, c: usize) -> Self {
        match levels.homogeneity {
            Some(d) => ChildGeometry {
                parent_set: 0,
                parent_half_width: 1.0,
                parent_scale: 1.0,
                child_set: 0,
                child_half_width: 0.5,
                child_scale: 0.5f64.powf(-d),
            },
            None => {
                let hc = levels.half_width(levels.first_level + c as u32 + 1);
                ChildGeometry {
                    parent_set: c,
                    parent_half_width: 2.0 * hc,
                    parent_scale: 1.0,
                    child_set: c + 1,
                    child_half_width: hc,
                    child_scale: 1.0,
                }
            }
        }
    }
}

/// Compute all operator sets in `f64` and round to `T`, using the kernel's
/// symmetries where they hold ([`Symmetry::Use`]).
fn compute<K: Kernel, T: Real>(
    kernel: &K,
    params: &OperatorParams,
    rcond: f64,
    levels: &LevelMap,
    n_child_sets: usize,
) -> Result<OperatorTables<T>, FieldError> {
    compute_with(kernel, params, rcond, levels, n_child_sets, Symmetry::Use)
}

/// Whether [`compute_with`] may use the symmetries of the kernel matrices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Symmetry {
    /// Where the matrices show them (checked entry by entry): DC2E from the
    /// SVD of UC2E, and the M2M / L2L of octants `1..8` permuted from
    /// octant 0's.
    Use,
    /// Every SVD and product computed directly (the reference for tests).
    #[cfg_attr(not(test), allow(dead_code))]
    Ignore,
}

/// Relative agreement (to the largest entry) at which two kernel matrices
/// count as equal up to a symmetry: far below any truncation, far above the
/// rounding of surface points that are mirror images of each other.
const SYMMETRY_TOLERANCE: f64 = 1e-12;

/// The check-to-equivalent pseudo-inverses of one set at half-width `h`,
/// and for each reflection mask `1..8` whether both check matrices are
/// invariant under the reflection of the surfaces.
fn check_to_equivalent<K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    rcond: f64,
    h: f64,
    reflections: &[Vec<usize>],
    symmetry: Symmetry,
) -> Result<(PinvF64, PinvF64, [bool; 8]), FieldError> {
    let (p, r, origin) = (params.order, params.radii, [0.0; 3]);
    let ue: Vec<f64> = surface_points(p, origin, h, r.upward_equivalent);
    let uc: Vec<f64> = surface_points(p, origin, h, r.upward_check);
    let de: Vec<f64> = surface_points(p, origin, h, r.downward_equivalent);
    let dc: Vec<f64> = surface_points(p, origin, h, r.downward_check);
    let a_u = kernel_matrix(kernel, &ue, &uc, "the upward check matrix")?;
    let a_d = kernel_matrix(kernel, &de, &dc, "the downward check matrix")?;
    let mut invariant = [false; 8];
    if symmetry == Symmetry::Use {
        for (mask, sigma) in reflections.iter().enumerate().skip(1) {
            invariant[mask] = is_permuted(a_u.as_ref(), a_u.as_ref(), sigma)
                && is_permuted(a_d.as_ref(), a_d.as_ref(), sigma);
        }
    }
    let signs = match symmetry {
        Symmetry::Use => transpose_signs(a_u.as_ref(), a_d.as_ref()),
        Symmetry::Ignore => None,
    };
    let (pu, pd) = match signs {
        Some(d) => pinv_pair(a_u.as_ref(), &d, rcond, "UC2E")?,
        None => (
            pinv(a_u.as_ref(), rcond, "UC2E")?,
            pinv(a_d.as_ref(), rcond, "DC2E")?,
        ),
    };
    Ok((pu, pd, invariant))
}

/// Compute all operator sets in `f64` and round to `T`.
///
/// The sets are independent: with at least as many sets as threads they
/// run in parallel (each factorisation sequential), otherwise one after
/// another with faer's own parallelism.
fn compute_with<K: Kernel, T: Real>(
    kernel: &K,
    params: &OperatorParams,
    rcond: f64,
    levels: &LevelMap,
    n_child_sets: usize,
    symmetry: Symmetry,
) -> Result<OperatorTables<T>, FieldError> {
    let p = params.order;
    let n = expansion_len(kernel, p);
    let c = kernel.components();
    let r = params.radii;
    let origin = [0.0; 3];
    // Per reflection mask, the permutation of the (component-expanded)
    // surface indices; mask 0 is the identity.
    let reflections: Vec<Vec<usize>> = (0..8).map(|mask| reflection(p, mask, c)).collect();
    // Check-to-equivalent pseudo-inverses, one pair per set.
    let one_set = |s: usize| {
        check_to_equivalent(
            kernel,
            params,
            rcond,
            levels.set_half_width(s),
            &reflections,
            symmetry,
        )
    };
    let n_sets = levels.n_sets();
    let pinvs: Vec<(PinvF64, PinvF64, [bool; 8])> =
        if n_sets >= 2 && n_sets >= crate::threads::effective_threads() {
            (0..n_sets)
                .into_par_iter()
                .map(one_set)
                .collect::<Result<_, _>>()?
        } else {
            (0..n_sets).map(one_set).collect::<Result<_, _>>()?
        };
    // Child operators: M2M_o = UC2E(parent) K(uc_parent <- ue_child),
    // L2L_o = DC2E(child) K(dc_child <- de_parent). A reflection that maps
    // octant 0 to octant o maps the surfaces onto themselves; where the
    // kernel matrices are invariant under it (a radial kernel), so is the
    // (unique) truncated pseudo-inverse, and M2M_o is M2M_0 with rows and
    // columns permuted: one product per set instead of eight.
    let children = (0..n_child_sets)
        .into_par_iter()
        .map(|cs| -> Result<ChildTranslations<T>, FieldError> {
            let g = ChildGeometry::of(levels, cs);
            let (pu, _, parent_invariant) = &pinvs[g.parent_set];
            let (_, pd, child_invariant) = &pinvs[g.child_set];
            let (hp, hc) = (g.parent_half_width, g.child_half_width);
            let matrix = |octant: usize, m2m: bool| -> Result<Mat<f64>, FieldError> {
                let off = octant_offset(octant);
                let cc = [hc * off[0], hc * off[1], hc * off[2]];
                if m2m {
                    let ue_c: Vec<f64> = surface_points(p, cc, hc, r.upward_equivalent);
                    let uc_p: Vec<f64> = surface_points(p, origin, hp, r.upward_check);
                    kernel_matrix(kernel, &ue_c, &uc_p, "M2M")
                } else {
                    let de_p: Vec<f64> = surface_points(p, origin, hp, r.downward_equivalent);
                    let dc_c: Vec<f64> = surface_points(p, cc, hc, r.downward_check);
                    kernel_matrix(kernel, &de_p, &dc_c, "L2L")
                }
            };
            let apply = |k: MatRef<'_, f64>, m2m: bool| {
                if m2m {
                    apply_pinv_f64(pu, g.parent_scale, k)
                } else {
                    apply_pinv_f64(pd, g.child_scale, k)
                }
            };
            let octants = |m2m: bool| -> Result<[Vec<T>; 8], FieldError> {
                let invariant = if m2m {
                    parent_invariant
                } else {
                    child_invariant
                };
                let k0 = matrix(0, m2m)?;
                let op0 = apply(k0.as_ref(), m2m);
                let mut mats: Vec<Vec<T>> = (1..8)
                    .into_par_iter()
                    .map(|o| -> Result<Vec<T>, FieldError> {
                        let ko = matrix(o, m2m)?;
                        let sigma = &reflections[o];
                        let op = if invariant[o] && is_permuted(k0.as_ref(), ko.as_ref(), sigma) {
                            permute(&op0, n, sigma)
                        } else {
                            apply(ko.as_ref(), m2m)
                        };
                        Ok(round_to(&op))
                    })
                    .collect::<Result<_, _>>()?;
                mats.insert(0, round_to(&op0));
                Ok(mats.try_into().expect("eight octants"))
            };
            let (m2m, l2l) = rayon::join(|| octants(true), || octants(false));
            Ok(ChildTranslations {
                m2m: m2m?,
                l2l: l2l?,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let sets = pinvs
        .iter()
        .map(|(u, d, _)| CheckToEquivalent {
            uc2e: PinvFactors::from_f64(u),
            dc2e: PinvFactors::from_f64(d),
        })
        .collect();
    Ok(OperatorTables { n, sets, children })
}

/// Per index of a surface expanded to `c` components per point (point
/// major, as [`Kernel::assemble`] writes them), the index of its mirror
/// image under the reflection of the axes set in `mask` (bit 0: x).
fn reflection(order: usize, mask: usize, c: usize) -> Vec<usize> {
    let unit = crate::surface::unit_surface(order);
    let last = (order - 1) as i64;
    let grid = |u: &[f64; 3]| u.map(|x| ((x + 1.0) * 0.5 * last as f64).round() as i64);
    let index: std::collections::HashMap<[i64; 3], usize> =
        unit.iter().enumerate().map(|(i, u)| (grid(u), i)).collect();
    let mut out = Vec::with_capacity(c * unit.len());
    for u in &unit {
        let mut k = grid(u);
        for (d, k) in k.iter_mut().enumerate() {
            if mask >> d & 1 == 1 {
                *k = last - *k;
            }
        }
        let j = index[&k];
        out.extend((0..c).map(|a| c * j + a));
    }
    out
}

/// Largest absolute entry.
fn max_abs(a: MatRef<'_, f64>) -> f64 {
    let mut m: f64 = 0.0;
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            m = m.max(a[(i, j)].abs());
        }
    }
    m
}

/// Whether `b[sigma(j), sigma(i)] = a[j, i]` for every entry (square
/// matrices, to [`SYMMETRY_TOLERANCE`] of the largest entry of `a`).
fn is_permuted(a: MatRef<'_, f64>, b: MatRef<'_, f64>, sigma: &[usize]) -> bool {
    let n = a.nrows();
    if a.shape() != (n, n) || b.shape() != (n, n) || sigma.len() != n {
        return false;
    }
    let scale = max_abs(a);
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    let tol = SYMMETRY_TOLERANCE * scale;
    (0..n).all(|i| (0..n).all(|j| (b[(sigma[j], sigma[i])] - a[(j, i)]).abs() <= tol))
}

/// `out[sigma(j), sigma(i)] = a[j, i]` for a column-major `n x n` matrix.
fn permute(a: &[f64], n: usize, sigma: &[usize]) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            out[sigma[i] * n + sigma[j]] = a[i * n + j];
        }
    }
    out
}

/// The signs `d` with `b = D a^T D` (`D = diag(d)`, `d_0 = 1`) when `b` is
/// of that form to [`SYMMETRY_TOLERANCE`]; `None` otherwise (including
/// when a sign cannot be read off the first row and column).
fn transpose_signs(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let n = a.nrows();
    if n == 0 || a.shape() != (n, n) || b.shape() != (n, n) {
        return None;
    }
    let scale = max_abs(a);
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let tol = SYMMETRY_TOLERANCE * scale;
    let mut d = vec![1.0; n];
    for (i, di) in d.iter_mut().enumerate().skip(1) {
        let (x, y) = (b[(0, i)], a[(i, 0)]);
        if x.abs() <= tol || y.abs() <= tol {
            return None;
        }
        *di = if (x > 0.0) == (y > 0.0) { 1.0 } else { -1.0 };
    }
    let ok = (0..n).all(|i| (0..n).all(|j| (b[(j, i)] - d[j] * d[i] * a[(i, j)]).abs() <= tol));
    ok.then_some(d)
}

/// `factor * vs * (ut * k)` in `f64`, column-major.
fn apply_pinv_f64(p: &PinvF64, factor: f64, k: MatRef<'_, f64>) -> Vec<f64> {
    let n_out = p.summary.n;
    let vs = MatRef::from_column_major_slice(&p.vs, n_out, p.rank);
    let ut = MatRef::from_column_major_slice(&p.ut, p.rank, k.nrows());
    let mut tmp = Mat::<f64>::zeros(p.rank, k.ncols());
    faer::linalg::matmul::matmul(tmp.as_mut(), Accum::Replace, ut, k, 1.0, Par::Seq);
    let mut out = Mat::<f64>::zeros(n_out, k.ncols());
    faer::linalg::matmul::matmul(
        out.as_mut(),
        Accum::Replace,
        vs,
        tmp.as_ref(),
        factor,
        Par::Seq,
    );
    col_major(out.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d};

    /// The cached form holds every factor and matrix once, in layout
    /// order, and reads back to the same tables; a layout that contradicts
    /// itself or its payload is refused.
    #[test]
    fn tables_round_trip_through_their_layout() {
        let yukawa = ModifiedHelmholtz3d::new(2.0).unwrap();
        let params = OperatorParams::new(3);
        let levels = LevelMap::new(yukawa.homogeneity(), 1.0, 3, 0).unwrap();
        let tables: OperatorTables<f64> =
            compute(&yukawa, &params, 1e-12, &levels, 3).expect("operators");
        let layout = tables.layout();
        assert_eq!(layout.sets.len(), 4);
        assert_eq!(layout.child_sets, 3);
        let values: Vec<f64> = tables.arrays().concat();
        assert_eq!(layout.n_values(), Ok(values.len()));
        let back = OperatorTables::from_values(layout.clone(), values.clone()).unwrap();
        assert_eq!(back.arrays(), tables.arrays());
        assert_eq!(back.layout(), layout);
        // One value short or long, or a rank above n: refused.
        assert!(OperatorTables::<f64>::from_values(layout.clone(), values[1..].to_vec()).is_err());
        let mut longer = values.clone();
        longer.push(0.0);
        assert!(OperatorTables::<f64>::from_values(layout.clone(), longer).is_err());
        let mut bad = layout;
        bad.sets[1].dc2e.rank = bad.n + 1;
        assert!(bad.n_values().is_err());
    }

    /// `A^+` formed from its factors, column-major `n x n`.
    fn formed(f: &PinvFactors<f64>) -> Vec<f64> {
        let (n, r) = (f.summary.n, f.summary.rank);
        let vs = MatRef::from_column_major_slice(&f.vs, n, r);
        let ut = MatRef::from_column_major_slice(&f.ut, r, n);
        col_major((vs * ut).as_ref())
    }

    fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        diff / scale
    }

    /// DC2E from the SVD of UC2E and the octants' M2M / L2L permuted from
    /// octant 0's equal what the direct SVDs and products give, for real
    /// (Yukawa), complex (Helmholtz, real form) and homogeneous (Laplace)
    /// kernels; and the symmetries are found (the matrices are permuted
    /// copies, not recomputed).
    #[test]
    fn symmetric_shortcuts_equal_the_direct_computation() {
        use ferrofmm_kernels::Helmholtz3d;
        let params = OperatorParams::new(5);
        let check = |name: &str, tables: (OperatorTables<f64>, OperatorTables<f64>)| {
            let (fast, direct) = tables;
            assert_eq!(fast.sets.len(), direct.sets.len());
            for (s, (a, b)) in fast.sets.iter().zip(&direct.sets).enumerate() {
                assert_eq!(a.uc2e.summary, b.uc2e.summary, "{name} set {s}");
                assert_eq!(a.dc2e.summary.rank, b.dc2e.summary.rank, "{name} set {s}");
                for (x, y) in [(&a.uc2e, &b.uc2e), (&a.dc2e, &b.dc2e)] {
                    let d = relative_difference(&formed(y), &formed(x));
                    assert!(
                        d < 1e-8,
                        "{name} set {s}: pseudo-inverses differ by {d:.1e}"
                    );
                }
            }
            for (cs, (a, b)) in fast.children.iter().zip(&direct.children).enumerate() {
                for o in 0..8 {
                    for (x, y) in [(&a.m2m[o], &b.m2m[o]), (&a.l2l[o], &b.l2l[o])] {
                        let d = relative_difference(y, x);
                        assert!(d < 1e-8, "{name} child set {cs} octant {o}: {d:.1e}");
                    }
                }
            }
        };
        let both = |kernel: &dyn Fn(Symmetry) -> OperatorTables<f64>| {
            (kernel(Symmetry::Use), kernel(Symmetry::Ignore))
        };
        let yukawa = ModifiedHelmholtz3d::new(3.0).unwrap();
        let levels = LevelMap::new(None, 1.0, 3, 0).unwrap();
        check(
            "yukawa",
            both(&|s| compute_with(&yukawa, &params, 1e-13, &levels, 3, s).unwrap()),
        );
        let helmholtz = Helmholtz3d::new(5.0).unwrap();
        check(
            "helmholtz",
            both(&|s| compute_with(&helmholtz, &params, 1e-13, &levels, 3, s).unwrap()),
        );
        let one = LevelMap::new(Some(-1.0), 1.0, 3, 0).unwrap();
        check(
            "laplace",
            both(&|s| compute_with(&Laplace3d, &params, 1e-13, &one, 1, s).unwrap()),
        );
        // The shortcuts are taken: the downward check matrix is the upward
        // one transposed up to signs (conjugation of the real form), and
        // octant 7 is octant 0 permuted exactly.
        let h = levels.half_width(2);
        let r = params.radii;
        let at = |radius: f64| surface_points::<f64>(params.order, [0.0; 3], h, radius);
        let a_u = kernel_matrix(
            &helmholtz,
            &at(r.upward_equivalent),
            &at(r.upward_check),
            "",
        )
        .unwrap();
        let a_d = kernel_matrix(
            &helmholtz,
            &at(r.downward_equivalent),
            &at(r.downward_check),
            "",
        )
        .unwrap();
        let d = transpose_signs(a_u.as_ref(), a_d.as_ref()).expect("a symmetric kernel");
        assert_eq!(d[..4], [1.0, -1.0, 1.0, -1.0]);
        let fast: OperatorTables<f64> = compute(&helmholtz, &params, 1e-13, &levels, 3).unwrap();
        let n = fast.n;
        let sigma = reflection(params.order, 7, 2);
        let m2m0: Vec<f64> = fast.children[1].m2m[0].clone();
        assert_eq!(permute(&m2m0, n, &sigma), fast.children[1].m2m[7]);
    }

    /// Surfaces map onto themselves under every reflection, components
    /// kept together.
    #[test]
    fn reflections_are_permutations() {
        for (order, c) in [(2, 1), (5, 2), (6, 3)] {
            let n = c * crate::n_surface_points(order);
            for mask in 0..8 {
                let sigma = reflection(order, mask, c);
                let mut seen = vec![false; n];
                for (i, &j) in sigma.iter().enumerate() {
                    assert_eq!(i % c, j % c);
                    seen[j] = true;
                }
                assert!(seen.iter().all(|&s| s));
                let twice: Vec<usize> = sigma.iter().map(|&j| sigma[j]).collect();
                assert_eq!(
                    twice,
                    (0..n).collect::<Vec<_>>(),
                    "a reflection is an involution"
                );
            }
        }
    }

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
