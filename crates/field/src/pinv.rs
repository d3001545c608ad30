//! Truncated-SVD pseudo-inverse in two factors (check -> equivalent).
//!
//! For the check matrix `A = K(check <- equivalent) = U S V^T` (computed in
//! `f64`) we keep the singular values `sigma_i > rcond * sigma_0` and store
//! `pinv(A) = (V_r S_r^-1) (U_r^T)` as the two factors `V_r S_r^-1`
//! (`n x r`) and `U_r^T` (`r x n`). Applying them one after the other —
//! first the orthogonal projection `U_r^T c`, then the scaling and
//! synthesis — is backward stable (Malhotra–Biros, PVFMM), whereas the
//! explicit product `V S^-1 U^T` rounded to the working type mixes entries
//! of size `1 / sigma_r` and loses the cancellation the factors preserve.

use faer::MatRef;

use crate::FieldError;
use crate::linalg::{SvdF64, col_major, svd};

/// A pseudo-inverse `A^+ = vs * ut` in `f64`, truncated at a relative cutoff.
pub(crate) struct PinvF64 {
    /// `V_r S_r^-1`, column-major `ncols(A) x rank`.
    pub vs: Vec<f64>,
    /// `U_r^T`, column-major `rank x nrows(A)`.
    pub ut: Vec<f64>,
    pub rank: usize,
    pub summary: PinvSummary,
}

/// What the truncated pseudo-inverse of one check matrix kept.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PinvSummary {
    /// Number of singular values (the surface size `n`).
    pub n: usize,
    /// Number of singular values kept, `sigma_i > rcond * sigma_0`.
    pub rank: usize,
    /// Largest singular value `sigma_0`.
    pub sigma_max: f64,
    /// Smallest kept singular value `sigma_{rank-1}`.
    pub sigma_min_kept: f64,
    /// Smallest singular value as computed in `f64` (values near
    /// `1e-16 sigma_0` are rounding noise, not the true value).
    pub sigma_min: f64,
}

impl PinvSummary {
    /// Condition number of the kept part, `sigma_0 / sigma_{rank-1}`: the
    /// largest amplification the pseudo-inverse applies to a perturbation of
    /// the check potential.
    pub fn condition(&self) -> f64 {
        if self.rank == 0 {
            0.0
        } else {
            self.sigma_max / self.sigma_min_kept
        }
    }
}

/// Truncated pseudo-inverse of `a` (`m x n`): keeps `sigma_i > rcond *
/// sigma_0` (and `sigma_i > 0`).
pub(crate) fn pinv(a: MatRef<'_, f64>, rcond: f64, what: &str) -> Result<PinvF64, FieldError> {
    let SvdF64 { u, s, v } = svd(a, what)?;
    Ok(from_svd(u.as_ref(), &s, v.as_ref(), rcond, None))
}

/// The least-squares solution `X = A^+ B` with the truncated pseudo-inverse
/// of `A` (keeping `sigma_i > rcond sigma_0`), applied in its two factors
/// (`U_r^T B`, then `V_r S_r^-1`), as every check-to-equivalent solve here
/// is. `a` is row-major `m x n`, `b` row-major `m x k`; the result is
/// row-major `n x k`. For those who translate equivalent densities outside
/// the built-in operators (the periodic FMM's super-cells).
///
/// ```
/// use ferrofmm_field::plumbing::truncated_solve;
/// // A diagonal 2 x 2 system and a singular value below the cutoff.
/// let x = truncated_solve(&[2.0, 0.0, 0.0, 4.0], 2, 2, &[1.0, 1.0], 1, 1e-13).unwrap();
/// assert!((x[0] - 0.5).abs() < 1e-15 && (x[1] - 0.25).abs() < 1e-15);
/// let x = truncated_solve(&[2.0, 0.0, 0.0, 1e-20], 2, 2, &[1.0, 1.0], 1, 1e-13).unwrap();
/// assert_eq!(x[1], 0.0);
/// ```
///
/// # Errors
/// [`FieldError::InvalidParams`] for slices of the wrong lengths;
/// [`FieldError::SvdFailed`] when the SVD does not converge.
pub fn truncated_solve(
    a: &[f64],
    m: usize,
    n: usize,
    b: &[f64],
    k: usize,
    rcond: f64,
) -> Result<Vec<f64>, FieldError> {
    if a.len() != m * n || b.len() != m * k {
        return Err(FieldError::InvalidParams(format!(
            "truncated_solve: A has {} entries for {m} x {n}, B {} for {m} x {k}",
            a.len(),
            b.len()
        )));
    }
    let a = faer::Mat::from_fn(m, n, |i, j| a[i * n + j]);
    let p = pinv(a.as_ref(), rcond, "truncated solve")?;
    let b = faer::Mat::from_fn(m, k, |i, j| b[i * k + j]);
    let vs = MatRef::from_column_major_slice(&p.vs, n, p.rank);
    let ut = MatRef::from_column_major_slice(&p.ut, p.rank, m);
    let x = vs * (ut * b);
    Ok((0..n * k).map(|e| x[(e / k, e % k)]).collect())
}

/// The truncated pseudo-inverses of `a` and of `b = D a^T D` (`a` square,
/// `D = diag(signs)`), from one SVD: with `a = U S V^T`, `b = (D V) S (D
/// U)^T`, so `b^+ = (D U_r S_r^-1) (V_r^T D)`. The downward check matrix of
/// a symmetric kernel is such a `b` of the upward one (the surfaces swap
/// radii; a complex kernel in real form needs `D = diag(1, -1, ...)`, the
/// conjugation), and the SVD is nearly all of the cost.
pub(crate) fn pinv_pair(
    a: MatRef<'_, f64>,
    signs: &[f64],
    rcond: f64,
    what: &str,
) -> Result<(PinvF64, PinvF64), FieldError> {
    let SvdF64 { u, s, v } = svd(a, what)?;
    let pa = from_svd(u.as_ref(), &s, v.as_ref(), rcond, None);
    let pb = from_svd(v.as_ref(), &s, u.as_ref(), rcond, Some(signs));
    Ok((pa, pb))
}

/// `(V_r S_r^-1, U_r^T)` of `A = U S V^T`, with the rows of `U` and `V`
/// scaled by `signs` when given (the pseudo-inverse of `D A D`).
fn from_svd(
    u: MatRef<'_, f64>,
    s: &[f64],
    v: MatRef<'_, f64>,
    rcond: f64,
    signs: Option<&[f64]>,
) -> PinvF64 {
    let sigma0 = s.first().copied().unwrap_or(0.0);
    let rank = s
        .iter()
        .take_while(|&&x| x > rcond * sigma0 && x > 0.0)
        .count();
    let (m, n) = (u.nrows(), v.nrows());
    let sign = |i: usize| signs.map_or(1.0, |d| d[i]);
    let vs_mat = faer::Mat::from_fn(n, rank, |i, j| sign(i) * v[(i, j)] / s[j]);
    let ut_mat = faer::Mat::from_fn(rank, m, |i, j| sign(j) * u[(j, i)]);
    PinvF64 {
        vs: col_major(vs_mat.as_ref()),
        ut: col_major(ut_mat.as_ref()),
        rank,
        summary: PinvSummary {
            n: s.len(),
            rank,
            sigma_max: sigma0,
            sigma_min_kept: if rank > 0 { s[rank - 1] } else { 0.0 },
            sigma_min: s.last().copied().unwrap_or(0.0),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn inverts_well_conditioned_and_truncates() {
        let n = 12;
        let a = Mat::<f64>::from_fn(n, n, |i, j| {
            if i == j {
                2.0 + i as f64
            } else {
                0.1 / (1.0 + i as f64 + j as f64)
            }
        });
        let p = pinv(a.as_ref(), 1e-15, "test").unwrap();
        assert_eq!(p.rank, n);
        let vs = MatRef::from_column_major_slice(&p.vs, n, p.rank);
        let ut = MatRef::from_column_major_slice(&p.ut, p.rank, n);
        let prod = vs * (ut * &a);
        let err = (&prod - Mat::<f64>::identity(n, n)).norm_max();
        assert!(err < 1e-13, "{err}");
        // A graded matrix loses the values below the cutoff.
        let g = Mat::<f64>::from_fn(
            n,
            n,
            |i, j| if i == j { 10f64.powi(-(i as i32)) } else { 0.0 },
        );
        let p = pinv(g.as_ref(), 1e-6, "graded").unwrap();
        assert_eq!(p.rank, 6);
        assert!((p.summary.condition() - 1e5).abs() < 1e-6);
        assert_eq!(pinv(g.as_ref(), 0.0, "graded").unwrap().rank, n);
    }
}
