//! Computing the operator sets in `f64` and rounding them to `T` once.
//!
//! Per set (half-width `h`): `A_u = K(uc <- ue)`, `A_d = K(dc <- de)` on
//! the surfaces of a box at the origin and their truncated pseudo-inverses
//! (`crate::pinv`). Per child set, for the eight octants `o` (child center
//! `h_c offset(o)`):
//!
//! ```text
//! M2M_o = s_p A_u(parent)^+ K(uc_parent <- ue_child_o)
//! L2L_o = s_c A_d(child)^+ K(dc_child_o <- de_parent)
//! ```
//!
//! with `s_p = 1` and `s_c = (1/2)^-d` for a kernel homogeneous of degree
//! `d` (everything at parent half-width 1; [`ChildGeometry`]), `1` and the
//! sets of both levels otherwise. Where the kernel matrices show the
//! symmetries of `super::symmetry`, DC2E comes from the SVD of UC2E
//! (`A_d = D A_u^T D`) and octant `o`'s M2M / L2L are octant 0's with rows
//! and columns permuted: one product per set instead of eight.

use faer::{Mat, MatRef, Par};
use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;

use super::octant_offset;
use super::symmetry::{is_permuted, permute, reflection, transpose_signs};
use super::tables::{CheckToEquivalent, ChildTranslations, OperatorTables, PinvFactors};
use crate::levels::LevelMap;
use crate::linalg::{col_major, kernel_matrix, product, round_to};
use crate::pinv::{PinvF64, pinv, pinv_pair};
use crate::{FieldError, OperatorParams, expansion_len, surface_points};

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
pub(super) fn compute<K: Kernel, T: Real>(
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

/// `factor * vs * (ut * k)` in `f64`, column-major.
fn apply_pinv_f64(p: &PinvF64, factor: f64, k: MatRef<'_, f64>) -> Vec<f64> {
    let vs = MatRef::from_column_major_slice(&p.vs, p.summary.n, p.rank);
    let ut = MatRef::from_column_major_slice(&p.ut, p.rank, k.nrows());
    let tmp = product(ut, k, 1.0, Par::Seq);
    col_major(product(vs, tmp.as_ref(), factor, Par::Seq).as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d};

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
        let check_matrix = |equivalent: f64, check: f64| {
            kernel_matrix(&helmholtz, &at(equivalent), &at(check), "").unwrap()
        };
        let a_u = check_matrix(r.upward_equivalent, r.upward_check);
        let a_d = check_matrix(r.downward_equivalent, r.downward_check);
        let d = transpose_signs(a_u.as_ref(), a_d.as_ref()).expect("a symmetric kernel");
        assert_eq!(d[..4], [1.0, -1.0, 1.0, -1.0]);
        let fast: OperatorTables<f64> = compute(&helmholtz, &params, 1e-13, &levels, 3).unwrap();
        let n = fast.n;
        let sigma = reflection(params.order, 7, 2);
        let m2m0: Vec<f64> = fast.children[1].m2m[0].clone();
        assert_eq!(permute(&m2m0, n, &sigma), fast.children[1].m2m[7]);
    }
}
