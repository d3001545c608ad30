//! [`Operators`]: check-to-equivalent pseudo-inverses (UC2E, DC2E) and the
//! parent/child translations (M2M, L2L) for every level of a tree.

use std::ops::Range;

use faer::{Accum, Mat, MatRef, Par};
use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;

use crate::cache::{CacheKey, CachePayload, CacheStatus, load_or_compute};
use crate::levels::LevelMap;
use crate::linalg::{col_major, kernel_matrix, round_to};
use crate::pinv::{PinvF64, PinvSummary, pinv};
use crate::{
    FieldError, OperatorParams, SurfaceKind, SurfaceRadii, gemm_scaled, n_surface_points,
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
    store: OperatorStore<T>,
    layout: Layout,
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

#[derive(Clone, Debug)]
struct SetInfo {
    uc2e: PinvSummary,
    dc2e: PinvSummary,
}

/// The cached part: layout metadata and one flat value array.
struct OperatorStore<T> {
    n: usize,
    sets: Vec<SetInfo>,
    n_child_sets: usize,
    data: Vec<T>,
}

#[derive(Clone, Debug)]
struct SetRanges {
    uc_vs: Range<usize>,
    uc_ut: Range<usize>,
    dc_vs: Range<usize>,
    dc_ut: Range<usize>,
}

#[derive(Clone, Debug)]
struct Layout {
    sets: Vec<SetRanges>,
    /// First value of child set `c`; M2M octant `o` at `+ o n^2`, L2L at
    /// `+ (8 + o) n^2`.
    child_base: Vec<usize>,
    total: usize,
}

fn layout(n: usize, sets: &[SetInfo], n_child_sets: usize) -> Layout {
    let mut off = 0;
    let mut take = |len: usize| {
        let r = off..off + len;
        off += len;
        r
    };
    let set_ranges = sets
        .iter()
        .map(|s| SetRanges {
            uc_vs: take(n * s.uc2e.rank),
            uc_ut: take(s.uc2e.rank * n),
            dc_vs: take(n * s.dc2e.rank),
            dc_ut: take(s.dc2e.rank * n),
        })
        .collect();
    let child_base = (0..n_child_sets).map(|_| take(16 * n * n).start).collect();
    Layout {
        sets: set_ranges,
        child_base,
        total: off,
    }
}

fn summary_to_meta(s: &PinvSummary, out: &mut Vec<u64>) {
    out.extend([
        s.n as u64,
        s.rank as u64,
        s.sigma_max.to_bits(),
        s.sigma_min_kept.to_bits(),
        s.sigma_min.to_bits(),
    ]);
}

fn summary_from_meta(m: &[u64]) -> PinvSummary {
    PinvSummary {
        n: m[0] as usize,
        rank: m[1] as usize,
        sigma_max: f64::from_bits(m[2]),
        sigma_min_kept: f64::from_bits(m[3]),
        sigma_min: f64::from_bits(m[4]),
    }
}

impl<T: Real> CachePayload<T> for OperatorStore<T> {
    fn meta(&self) -> Vec<u64> {
        let mut m = vec![
            self.n as u64,
            self.sets.len() as u64,
            self.n_child_sets as u64,
        ];
        for s in &self.sets {
            summary_to_meta(&s.uc2e, &mut m);
            summary_to_meta(&s.dc2e, &mut m);
        }
        m
    }

    fn data(&self) -> &[T] {
        &self.data
    }

    fn from_parts(meta: Vec<u64>, data: Vec<T>) -> Result<Self, String> {
        if meta.len() < 3 {
            return Err("short metadata".into());
        }
        let (n, n_sets, n_child_sets) = (meta[0] as usize, meta[1] as usize, meta[2] as usize);
        if meta.len() != 3 + 10 * n_sets {
            return Err("metadata length".into());
        }
        let sets: Vec<SetInfo> = (0..n_sets)
            .map(|s| SetInfo {
                uc2e: summary_from_meta(&meta[3 + 10 * s..]),
                dc2e: summary_from_meta(&meta[8 + 10 * s..]),
            })
            .collect();
        if sets
            .iter()
            .any(|s| s.uc2e.rank > n || s.dc2e.rank > n || s.uc2e.n != n || s.dc2e.n != n)
        {
            return Err("rank exceeds surface size".into());
        }
        if layout(n, &sets, n_child_sets).total != data.len() {
            return Err("payload length disagrees with layout".into());
        }
        Ok(OperatorStore {
            n,
            sets,
            n_child_sets,
            data,
        })
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
        params.validate()?;
        let homogeneity = kernel.homogeneity();
        let levels = LevelMap::new(homogeneity, domain_width, depth, 0)?;
        let child_levels = LevelMap::new(homogeneity, domain_width, depth, 1)?;
        let n = n_surface_points(params.order);
        let rcond = params.rcond_for(T::PRECISION);
        let n_child_sets = if depth >= 1 { child_levels.n_sets() } else { 0 };

        let mut key =
            CacheKey::new::<K, T>("operators", kernel, params.order, params.radii.to_array());
        key.rcond = Some(rcond);
        key.flags = vec![n_child_sets as u64];
        if homogeneity.is_none() {
            key.geometry = Some((domain_width, depth));
        }
        let accept = |s: &OperatorStore<T>| {
            if s.n == n && s.sets.len() == levels.n_sets() && s.n_child_sets == n_child_sets {
                Ok(())
            } else {
                Err("layout disagrees with the parameters".to_string())
            }
        };
        let (store, cache_status) = load_or_compute::<T, OperatorStore<T>>(
            params.cache_dir.as_deref(),
            &key,
            accept,
            || compute(kernel, params, rcond, &levels, n_child_sets),
        )?;
        let layout = layout(n, &store.sets, n_child_sets);
        Ok(Operators {
            order: params.order,
            n: store.n,
            radii: params.radii,
            rcond,
            levels,
            child_levels,
            store,
            layout,
            cache_status,
        })
    }

    /// Expansion order `p`.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Points per surface, `n = 6 (p-1)^2 + 2`: the length of one expansion.
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
        self.store.data.len() * std::mem::size_of::<T>()
    }

    /// Ranks and conditioning of the pseudo-inverses, with warnings when the
    /// cutoff lets rounding errors of `T` dominate.
    pub fn diagnostics(&self) -> OperatorDiagnostics {
        let uc2e: Vec<_> = self.store.sets.iter().map(|s| s.uc2e).collect();
        let dc2e: Vec<_> = self.store.sets.iter().map(|s| s.dc2e).collect();
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
        let r = &self.layout.sets[set];
        self.apply_pinv(
            &r.uc_vs,
            &r.uc_ut,
            self.store.sets[set].uc2e.rank,
            scale,
            ncols,
            check,
            equiv,
            false,
        );
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
        let r = &self.layout.sets[set];
        self.apply_pinv(
            &r.dc_vs,
            &r.dc_ut,
            self.store.sets[set].dc2e.rank,
            scale,
            ncols,
            check,
            local,
            true,
        );
    }

    #[allow(clippy::too_many_arguments)]
    fn apply_pinv(
        &self,
        vs: &Range<usize>,
        ut: &Range<usize>,
        rank: usize,
        scale: f64,
        ncols: usize,
        input: &[T],
        out: &mut [T],
        accumulate: bool,
    ) {
        let n = self.n;
        let mut tmp = vec![T::ZERO; rank * ncols];
        gemm_scaled(
            rank,
            ncols,
            n,
            1.0,
            &self.store.data[ut.clone()],
            input,
            &mut tmp,
            false,
        );
        gemm_scaled(
            n,
            ncols,
            rank,
            scale,
            &self.store.data[vs.clone()],
            &tmp,
            out,
            accumulate,
        );
    }

    fn child_op(&self, child_level: u32, octant: usize, l2l: bool) -> &[T] {
        assert!(octant < 8, "octant must be < 8, got {octant}");
        assert!(child_level >= 1, "child level must be at least 1");
        assert!(
            !self.layout.child_base.is_empty(),
            "operators were built with depth 0: no M2M/L2L"
        );
        let (set, _) = self.child_levels.lookup(child_level, 0.0);
        let nn = self.n * self.n;
        let start = self.layout.child_base[set] + (octant + if l2l { 8 } else { 0 }) * nn;
        &self.store.data[start..start + nn]
    }

    /// `parent += M2M(child_level, octant) child`: child upward equivalent
    /// densities to the parent's (column-major `n x ncols`, accumulates).
    /// `octant`: bit 0 = child in the `+x` half, bit 1 = `+y`, bit 2 = `+z`.
    ///
    /// # Panics
    /// On length mismatch, `octant >= 8`, `child_level == 0`, depth 0, or
    /// (non-homogeneous kernel) `child_level > depth`.
    pub fn m2m(&self, child_level: u32, octant: usize, child: &[T], parent: &mut [T]) {
        let ncols = self.ncols(child.len(), "m2m");
        assert_eq!(
            parent.len(),
            child.len(),
            "m2m: parent and child lengths differ"
        );
        let op = self.child_op(child_level, octant, false);
        gemm_scaled(self.n, ncols, self.n, 1.0, op, child, parent, true);
    }

    /// `child += L2L(child_level, octant) parent`: parent downward
    /// equivalent densities to the child's (accumulates).
    ///
    /// # Panics
    /// As [`Operators::m2m`].
    pub fn l2l(&self, child_level: u32, octant: usize, parent: &[T], child: &mut [T]) {
        let ncols = self.ncols(parent.len(), "l2l");
        assert_eq!(
            parent.len(),
            child.len(),
            "l2l: parent and child lengths differ"
        );
        let op = self.child_op(child_level, octant, true);
        gemm_scaled(self.n, ncols, self.n, 1.0, op, parent, child, true);
    }
}

/// Compute all operator sets in `f64` and round to `T`.
fn compute<K: Kernel, T: Real>(
    kernel: &K,
    params: &OperatorParams,
    rcond: f64,
    levels: &LevelMap,
    n_child_sets: usize,
) -> Result<OperatorStore<T>, FieldError> {
    let p = params.order;
    let n = n_surface_points(p);
    let r = params.radii;
    let origin = [0.0; 3];
    // Check-to-equivalent pseudo-inverses, one pair per set.
    let mut pinvs: Vec<(PinvF64, PinvF64)> = Vec::with_capacity(levels.n_sets());
    for s in 0..levels.n_sets() {
        let h = levels.set_half_width(s);
        let ue: Vec<f64> = surface_points(p, origin, h, r.upward_equivalent);
        let uc: Vec<f64> = surface_points(p, origin, h, r.upward_check);
        let de: Vec<f64> = surface_points(p, origin, h, r.downward_equivalent);
        let dc: Vec<f64> = surface_points(p, origin, h, r.downward_check);
        let a_u = kernel_matrix(kernel, &ue, &uc, "the upward check matrix")?;
        let a_d = kernel_matrix(kernel, &de, &dc, "the downward check matrix")?;
        let pu = pinv(a_u.as_ref(), rcond, "UC2E")?;
        let pd = pinv(a_d.as_ref(), rcond, "DC2E")?;
        pinvs.push((pu, pd));
    }
    let sets: Vec<SetInfo> = pinvs
        .iter()
        .map(|(u, d)| SetInfo {
            uc2e: u.summary,
            dc2e: d.summary,
        })
        .collect();
    let lay = layout(n, &sets, n_child_sets);
    let mut data = vec![T::ZERO; lay.total];
    for (s, (pu, pd)) in pinvs.iter().enumerate() {
        let rr = &lay.sets[s];
        data[rr.uc_vs.clone()].copy_from_slice(&round_to::<T>(&pu.vs));
        data[rr.uc_ut.clone()].copy_from_slice(&round_to::<T>(&pu.ut));
        data[rr.dc_vs.clone()].copy_from_slice(&round_to::<T>(&pd.vs));
        data[rr.dc_ut.clone()].copy_from_slice(&round_to::<T>(&pd.ut));
    }
    // Child operators.
    for c in 0..n_child_sets {
        // (parent set, parent factor, parent h, child set, child factor, child h)
        let (sp, fp, hp, sc, fc, hc) = match levels.homogeneity {
            Some(d) => (0, 1.0, 1.0, 0, 0.5f64.powf(-d), 0.5),
            None => {
                let hc = levels.half_width(c as u32 + 1);
                (c, 1.0, 2.0 * hc, c + 1, 1.0, hc)
            }
        };
        let (pu, _) = &pinvs[sp];
        let (_, pd) = &pinvs[sc];
        let ops: Vec<Result<Vec<f64>, FieldError>> = (0..16usize)
            .into_par_iter()
            .map(|job| {
                let octant = job % 8;
                let off = octant_offset(octant);
                let cc = [hc * off[0], hc * off[1], hc * off[2]];
                if job < 8 {
                    let ue_c: Vec<f64> = surface_points(p, cc, hc, r.upward_equivalent);
                    let uc_p: Vec<f64> = surface_points(p, [0.0; 3], hp, r.upward_check);
                    let k = kernel_matrix(kernel, &ue_c, &uc_p, "M2M")?;
                    Ok(apply_pinv_f64(pu, fp, k.as_ref()))
                } else {
                    let de_p: Vec<f64> = surface_points(p, [0.0; 3], hp, r.downward_equivalent);
                    let dc_c: Vec<f64> = surface_points(p, cc, hc, r.downward_check);
                    let k = kernel_matrix(kernel, &de_p, &dc_c, "L2L")?;
                    Ok(apply_pinv_f64(pd, fc, k.as_ref()))
                }
            })
            .collect();
        let base = lay.child_base[c];
        for (job, op) in ops.into_iter().enumerate() {
            let op = op?;
            data[base + job * n * n..base + (job + 1) * n * n].copy_from_slice(&round_to::<T>(&op));
        }
    }
    Ok(OperatorStore {
        n,
        sets,
        n_child_sets,
        data,
    })
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
