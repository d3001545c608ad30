//! The per-level operator sets as [`Operators`](super::Operators) holds
//! and caches them ([`OperatorTables`]).
//!
//! A truncated pseudo-inverse `A^+ = (V_r S_r^-1) U_r^T` is kept as its
//! two factors ([`PinvFactors`], `n x r` and `r x n`) and applied as two
//! products, never formed (`docs/stability.md`): `out = s (V_r S_r^-1)
//! (U_r^T input)`. Each operator set holds the UC2E and DC2E factors of
//! one level (or of every level, for a homogeneous kernel); each child set
//! the eight `n x n` M2M and the eight L2L matrices of its octants.
//!
//! The cache payload is, in order: per set `V_r S_r^-1`, `U_r^T` of UC2E
//! then of DC2E, then per child set the eight M2M and the eight L2L
//! matrices ([`OperatorLayout`]); the key ([`cache_key`]) names the kernel,
//! order, radii, domain, depth, cutoff and the number of child sets.

use ferrofmm_kernels::{Kernel, Real};

use crate::cache::{CacheKey, CachePayload, StoreLayout, ValueReader};
use crate::linalg::round_to;
use crate::pinv::{PinvF64, PinvSummary};
use crate::{OperatorParams, Update, gemm_scaled};

/// A truncated pseudo-inverse `A^+ = (V_r S_r^-1) U_r^T` in the working
/// type, kept as its two factors and applied as two products (never
/// formed: see `docs/stability.md`).
pub(super) struct PinvFactors<T> {
    /// `V_r S_r^-1`, column-major `n x r`.
    pub(super) vs: Vec<T>,
    /// `U_r^T`, column-major `r x n`.
    pub(super) ut: Vec<T>,
    /// What the truncation kept (`n`, the rank `r`, singular values).
    pub(super) summary: PinvSummary,
}

impl<T: Real> PinvFactors<T> {
    pub(super) fn from_f64(p: &PinvF64) -> Self {
        PinvFactors {
            vs: round_to(&p.vs),
            ut: round_to(&p.ut),
            summary: p.summary,
        }
    }

    /// `out = [out +] scale A^+ input` for `ncols` column-major columns.
    pub(super) fn apply(
        &self,
        scale: f64,
        ncols: usize,
        input: &[T],
        out: &mut [T],
        update: Update,
    ) {
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
pub(super) struct CheckToEquivalent<T> {
    /// UC2E: upward check potential -> upward equivalent density.
    pub(super) uc2e: PinvFactors<T>,
    /// DC2E: downward check potential -> downward equivalent density.
    pub(super) dc2e: PinvFactors<T>,
}

/// The parent/child translations of one child-level set: one column-major
/// `n x n` matrix per octant of the child.
pub(super) struct ChildTranslations<T> {
    /// M2M: child upward equivalent density -> parent's.
    pub(super) m2m: [Vec<T>; 8],
    /// L2L: parent downward equivalent density -> child's.
    pub(super) l2l: [Vec<T>; 8],
}

/// Everything [`Operators`](super::Operators) precomputes; what the operator cache stores.
pub(super) struct OperatorTables<T> {
    /// Values per expansion.
    pub(super) n: usize,
    /// Check-to-equivalent operators, one per set.
    pub(super) sets: Vec<CheckToEquivalent<T>>,
    /// Parent/child translations, one per child set.
    pub(super) children: Vec<ChildTranslations<T>>,
}

/// The pseudo-inverse summaries of one set, as cached.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct SetSummaries {
    uc2e: PinvSummary,
    dc2e: PinvSummary,
}

/// What a cached [`OperatorTables`] holds, in order: per set the factors
/// `V_r S_r^-1` and `U_r^T` of UC2E then of DC2E (their ranks in the
/// summaries), then per child set the eight M2M and the eight L2L
/// matrices (`n x n`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct OperatorLayout {
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

impl OperatorLayout {
    /// `Ok` when a cached layout is the one wanted: `n` values per
    /// expansion, `sets` operator sets and `child_sets` child sets.
    pub(super) fn accept(&self, n: usize, sets: usize, child_sets: usize) -> Result<(), String> {
        if self.n == n && self.sets.len() == sets && self.child_sets == child_sets {
            Ok(())
        } else {
            Err("layout disagrees with the parameters".to_string())
        }
    }
}

/// The cache key of the operators of `kernel` in `T`: kernel, order, radii,
/// domain width and depth, the cutoff `rcond`, the number of child sets
/// and (when not 0) the first level.
pub(super) fn cache_key<K: Kernel, T: Real>(
    kernel: &K,
    params: &OperatorParams,
    domain_width: f64,
    depth: u32,
    rcond: f64,
    n_child_sets: usize,
    first: u32,
) -> CacheKey {
    let mut key = CacheKey::new::<K, T>("operators", kernel, params.order, params.radii.to_array())
        .for_domain(domain_width, depth);
    key.rcond = Some(rcond);
    key.flags = vec![n_child_sets as u64];
    if first > 0 {
        // Files of the full set keep their key.
        key.flags.push(u64::from(first));
    }
    key
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::levels::LevelMap;
    use ferrofmm_kernels::ModifiedHelmholtz3d;

    /// The cached form holds every factor and matrix once, in layout
    /// order, and reads back to the same tables; a layout that contradicts
    /// itself or its payload is refused.
    #[test]
    fn tables_round_trip_through_their_layout() {
        let yukawa = ModifiedHelmholtz3d::new(2.0).unwrap();
        let params = OperatorParams::new(3);
        let levels = LevelMap::new(yukawa.homogeneity(), 1.0, 3, 0).unwrap();
        let tables: OperatorTables<f64> =
            super::super::build::compute(&yukawa, &params, 1e-12, &levels, 3).expect("operators");
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
}
