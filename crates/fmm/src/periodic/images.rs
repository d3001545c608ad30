//! Lattice sums of any kernel whose sum converges absolutely (a user's
//! kernel, damped Helmholtz waves, dispersion-like `r^-6` terms):
//! [`LatticeSum::Images`](super::LatticeSum::Images). The periodisation
//! operator is built from super-cells of `3^j` cells, with the kernel's own
//! values and no lattice identity; the reference a run is checked against
//! is the image sum itself, shell by shell.
//!
//! # The periodisation operator by super-cells
//!
//! `P u` is the potential on the cell's downward check surface of the far
//! images (`|n|_inf >= 2`, along the periodic axes `A`) of the root's
//! upward equivalent density `u`. Let `S_j` be the super-cell of `3^j`
//! cells along each periodic axis, centred on the cell (half-width `h_j =
//! 3^j L / 2`): it holds the images `|n|_inf <= (3^j - 1) / 2`. The far
//! images split into rings: ring `j` is the copies of `S_j` at the offsets
//! `o 3^j L` with `2 <= |o|_inf <= 4` (702 copies in bulk, 72 in a slab, 6
//! in a rod), the images `(3^{j+1} + 1) / 2 <= |n|_inf <= (3^{j+2} - 1) /
//! 2`. Each copy is at least one `S_j` apart from `S_j`, the separation of
//! an M2L pair, so with
//!
//! ```text
//! M_0 = I,   M_j = pinv(K(uc_j <- ue_j)) sum_t K(uc_j <- ue_{j-1} + t 3^{j-1} L) M_{j-1}
//! ```
//!
//! (`t` over the `3^|A|` children: `M_j u` is the equivalent density of
//! `S_j`, an M2M from its children) the ring's potential on the cell's
//! check points `y_c` is
//!
//! ```text
//! P_0 = sum_o K(y_c <- ue_0 + o L)                                  (exact)
//! P_j = K(y_c <- de_j) pinv(K(dc_j <- de_j)) sum_o K(dc_j <- ue_j + o 3^j L) M_j
//! ```
//!
//! (an M2L to `S_j`'s downward check surface, then `S_j`'s local density
//! evaluated at the cell's check points, which lie inside `S_j`), and `P =
//! sum_j P_j`. For a kernel homogeneous of degree `d` each ring is
//! `q = 3^(|A| + d)` times the last (`3^|A|` times the copies, each `3^d`
//! times as strong), so the sum converges when `d < -|A|` (`r^-4` and
//! faster in bulk); a screened kernel's rings fall faster than any power.
//! Rings are added until the last one, and the geometric tail
//! `|P_j| q / (1 - q)` that it predicts, are below [`OPERATOR_TOLERANCE`]
//! of `|P|` (largest entries); a sum whose rings do not shrink by
//! `DIVERGING_RATIO` or more (`r^-3` and slower in bulk, Laplace or
//! undamped Helmholtz among them) is refused. Each ring costs `702 + 27`
//! kernel matrices of the surface size and two pseudo-inverses.
//!
//! A kernel that is not homogeneous needs every ring's operators, so a
//! ring is first priced by probes: its image count times the largest
//! kernel entry at its nearest distance, the same geometry scaled at each
//! level, so that two levels' probes stand in the ratio of the kernel's
//! decay. A ring predicted below a hundredth of the tolerance (from the
//! last ring's size and that ratio) ends the sum without being built: a
//! screened or strongly damped kernel stops after one or two rings. An
//! oscillating kernel ([`Kernel::wavenumber`] `k > 0`) whose next ring
//! still matters and whose super-cell is more than
//! [`crate::MAX_WAVENUMBER_WIDTH`] radians across is refused: the
//! expansions cannot resolve it, and the sum would be wrong, not slow.
//!
//! # The image sum
//!
//! The reference ([`ImageSum`]) adds the images shell by shell, `|n|_inf
//! = m` for `m = 0, 1, ...`, each target's sum leaving out only the
//! source it coincides with (the kernel's `K(x, x) = 0`: its own images
//! are included). A shell's largest value `S_m` fits a power `S_m ~ m^-b`
//! against the last, and the sum stops when the tail that power predicts,
//! `S_m m / (b - 1)`, is below the tolerance of the total (for the
//! potentials and the gradients each). A kernel that decays slowly needs
//! many shells for a tight tolerance: the reference refuses above a budget
//! of kernel evaluations, with the reason, rather than run for hours.

use faer::Mat;
use ferrofmm_field::{SurfaceRadii, surface_points};
use ferrofmm_kernels::{EvalMode, Kernel};
use rayon::prelude::*;

use super::Periodic;
use crate::FmmError;

/// Largest entry of the last ring, with its predicted tail, relative to
/// `P`'s largest entry, at which [`periodisation_operator`] stops: far below
/// what any order reaches.
pub(crate) const OPERATOR_TOLERANCE: f64 = 1e-15;

/// Most super-cell levels tried: `3^40 L` is beyond any decay that
/// converges at all.
const MAX_LEVELS: usize = 40;

/// Rings that shrink by less than this factor (from the third on) mean a
/// sum that does not converge, or too slowly to sum (`r^-3` in bulk).
const DIVERGING_RATIO: f64 = 0.9;

/// A ring predicted below this share of [`OPERATOR_TOLERANCE`] (of `P`'s
/// largest entry) is not built.
const NEGLIGIBLE_RING: f64 = 1e-2;

/// Kernel evaluations an [`ImageSum`] may spend on one call.
const IMAGE_SUM_BUDGET: f64 = 4e10;

/// The images `n` (integer lattice vectors, zero along the open axes of
/// `mask`) with `lo <= |n|_inf <= hi`.
///
/// ```text
/// bulk: (2 hi + 1)^3 - (2 lo - 1)^3 of them (lo >= 1)
/// ```
pub(crate) fn lattice_images(mask: [bool; 3], lo: i64, hi: i64) -> Vec<[i64; 3]> {
    let range = |a: usize| if mask[a] { -hi..=hi } else { 0..=0 };
    let mut out = Vec::new();
    for i in range(0) {
        for j in range(1) {
            for k in range(2) {
                let norm = i.abs().max(j.abs()).max(k.abs());
                if norm >= lo && norm <= hi {
                    out.push([i, j, k]);
                }
            }
        }
    }
    out
}

/// `sum_s K(targets <- sources + s)` over the `shifts`, row-major `c nt x
/// c ns` (rows: target point and component), in parallel over the shifts.
fn sum_images<K: Kernel>(
    kernel: &K,
    targets: &[f64],
    sources: &[f64],
    shifts: &[[f64; 3]],
) -> Result<Mat<f64>, FmmError> {
    let c = kernel.components();
    let (nt, ns) = (c * targets.len() / 3, c * sources.len() / 3);
    let len = nt * ns;
    let sum = shifts
        .par_iter()
        .fold(
            || {
                (
                    vec![0.0f64; len],
                    vec![0.0f64; len],
                    vec![0.0f64; sources.len()],
                )
            },
            |(mut acc, mut one, mut moved), s| {
                for (m, p) in moved.chunks_exact_mut(3).zip(sources.chunks_exact(3)) {
                    for a in 0..3 {
                        m[a] = p[a] + s[a];
                    }
                }
                kernel.assemble::<f64>(&moved, targets, &mut one);
                acc.iter_mut().zip(&one).for_each(|(a, b)| *a += b);
                (acc, one, moved)
            },
        )
        .map(|(acc, _, _)| acc)
        .reduce(
            || vec![0.0f64; len],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    if sum.iter().any(|v| !v.is_finite()) {
        return Err(FmmError::InvalidParameter(format!(
            "the kernel {} gave a value that is not finite between a periodic cell's \
             surfaces and its images",
            kernel.name()
        )));
    }
    Ok(Mat::from_fn(nt, ns, |i, j| sum[i * ns + j]))
}

/// `pinv(a) b` with the truncated pseudo-inverse (cutoff `rcond`).
fn solve(a: &Mat<f64>, b: &Mat<f64>, rcond: f64) -> Result<Mat<f64>, FmmError> {
    let (m, n, k) = (a.nrows(), a.ncols(), b.ncols());
    let a_rows: Vec<f64> = (0..m * n).map(|e| a[(e / n, e % n)]).collect();
    let b_rows: Vec<f64> = (0..m * k).map(|e| b[(e / k, e % k)]).collect();
    let x = ferrofmm_field::plumbing::truncated_solve(&a_rows, m, n, &b_rows, k, rcond)?;
    Ok(Mat::from_fn(n, k, |i, j| x[i * k + j]))
}

/// Largest absolute entry.
fn max_abs(m: &Mat<f64>) -> f64 {
    let mut out = 0.0f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            out = out.max(m[(i, j)].abs());
        }
    }
    out
}

/// The lattice vectors `n` scaled to offsets `n * scale * L` (per axis).
fn offsets(images: &[[i64; 3]], lengths: [f64; 3], scale: f64) -> Vec<[f64; 3]> {
    images
        .iter()
        .map(|n| std::array::from_fn(|a| n[a] as f64 * scale * lengths[a]))
        .collect()
}

/// The periodisation operator `P` of `kernel` for `cell` at `order` (see
/// the [module docs](self)), row-major `c n x c n` (rows: the root's
/// downward check points, columns: its upward equivalent points, both
/// relative to the cell's centre), with the surfaces `radii` and the
/// pseudo-inverse cutoff `rcond`.
///
/// # Errors
/// [`FmmError::InvalidParameter`] when the rings do not shrink (a lattice
/// sum that does not converge absolutely) or a kernel value is not finite.
pub(crate) fn periodisation_operator<K: Kernel>(
    kernel: &K,
    cell: &Periodic,
    order: usize,
    radii: SurfaceRadii,
    rcond: f64,
) -> Result<Vec<f64>, FmmError> {
    let rings = Rings::new(kernel, cell, order, radii, rcond);
    // Ring 0, exactly.
    let mut p = sum_images(
        kernel,
        &rings.check,
        &rings.surface(0, radii.upward_equivalent),
        &offsets(&rings.ring, rings.lengths, 1.0),
    )?;
    let mut sizes = Convergence::new(max_abs(&p));
    match kernel.homogeneity() {
        Some(_) => {
            // Every level's M2M, M2L-to-local and L2L are level 1's (the
            // kernel scales out of each): ring j adds E L2L^(j-1) T M2M^j.
            let m2m = rings.m2m(1)?;
            let t = rings.m2l_local(1)?;
            let l2l = solve(
                &rings.matrix(1, radii.downward_check, 1, radii.downward_equivalent)?,
                &rings.matrix(1, radii.downward_check, 2, radii.downward_equivalent)?,
                rcond,
            )?;
            let mut m = m2m.clone();
            let mut down = rings.local_at_check(1)?;
            for j in 1..=MAX_LEVELS {
                let level = &down * (&t * &m);
                p += &level;
                if sizes.done(j, max_abs(&level), max_abs(&p), &rings)? {
                    break;
                }
                m = &m2m * &m;
                down = &down * &l2l;
            }
        }
        None => {
            let n = p.ncols();
            let mut m = Mat::<f64>::identity(n, n);
            let mut probe = rings.probe(0);
            for j in 1..=MAX_LEVELS {
                // A ring the kernel's decay makes negligible is not built:
                // its size predicted from the last one's by the probes.
                let next = rings.probe(j);
                let predicted = if probe > 0.0 {
                    sizes.last * next / probe
                } else {
                    0.0
                };
                probe = next;
                if predicted <= NEGLIGIBLE_RING * OPERATOR_TOLERANCE * max_abs(&p) {
                    break;
                }
                rings.check_resolved(j, predicted / max_abs(&p))?;
                m = &rings.m2m(j)? * &m;
                let local = &rings.m2l_local(j)? * &m;
                let level = rings.local_at_check(j)? * local;
                p += &level;
                if sizes.done(j, max_abs(&level), max_abs(&p), &rings)? {
                    break;
                }
            }
        }
    }
    let n = p.ncols();
    Ok((0..n * n).map(|e| p[(e / n, e % n)]).collect())
}

/// The geometry of the super-cells of one cell and order.
struct Rings<'k, K: Kernel> {
    kernel: &'k K,
    name: String,
    axes: super::PeriodicAxes,
    order: usize,
    radii: SurfaceRadii,
    rcond: f64,
    lengths: [f64; 3],
    half: f64,
    /// The cell's downward check points.
    check: Vec<f64>,
    /// Ring offsets `2 <= |o|_inf <= 4` and children `|t|_inf <= 1`.
    ring: Vec<[i64; 3]>,
    children: Vec<[i64; 3]>,
}

impl<'k, K: Kernel> Rings<'k, K> {
    fn new(kernel: &'k K, cell: &Periodic, order: usize, radii: SurfaceRadii, rcond: f64) -> Self {
        let mask = cell.axes().mask();
        let half = 0.5 * cell.width();
        Rings {
            kernel,
            name: kernel.name(),
            axes: cell.axes(),
            order,
            radii,
            rcond,
            lengths: cell.lengths(),
            half,
            check: surface_points::<f64>(order, [0.0; 3], half, radii.downward_check),
            ring: lattice_images(mask, 2, 4),
            children: lattice_images(mask, 0, 1),
        }
    }

    /// The surface of radius `r` (half-widths) of `S_j`.
    fn surface(&self, j: usize, r: f64) -> Vec<f64> {
        let h = 3f64.powi(j as i32) * self.half;
        surface_points::<f64>(self.order, [0.0; 3], h, r)
    }

    /// `K(surface r_t of S_jt <- surface r_s of S_js)`, both centred.
    fn matrix(&self, jt: usize, rt: f64, js: usize, rs: f64) -> Result<Mat<f64>, FmmError> {
        sum_images(
            self.kernel,
            &self.surface(jt, rt),
            &self.surface(js, rs),
            &[[0.0; 3]],
        )
    }

    /// How strongly ring `j` acts at most: its number of images times the
    /// largest kernel entry at its nearest distance,
    /// `(2 - r_ue / 2) 3^j L - (r_dc / 2) L` (the ring's equivalent points
    /// to the cell's check points, `1.475 3^j L - 0.525 L` with the
    /// default radii; the same geometry scaled at every level, so that the
    /// ratio of two levels' probes follows the kernel's decay), probed
    /// along the 26 lattice directions at 1, 1.1 and 1.25 times that
    /// distance (an oscillating kernel does not vanish at all three).
    fn probe(&self, j: usize) -> f64 {
        let scale = 3f64.powi(j as i32);
        let width = 2.0 * self.half;
        let distance = (2.0 - 0.5 * self.radii.upward_equivalent) * scale * width
            - 0.5 * self.radii.downward_check * width;
        let images = self.ring.len() as f64 * (self.children.len() as f64).powi(j as i32);
        let c = self.kernel.components();
        let mut block = vec![0.0f64; c * c];
        let mut largest = 0.0f64;
        for dir in lattice_images([true; 3], 1, 1) {
            let norm = ((dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]) as f64).sqrt();
            for stretch in [1.0, 1.1, 1.25] {
                let r = stretch * distance / norm;
                let at = dir.map(|d| d as f64 * r);
                self.kernel.assemble::<f64>(&[0.0; 3], &at, &mut block);
                largest = block.iter().fold(largest, |m, v| m.max(v.abs()));
            }
        }
        images * largest
    }

    /// Refuse ring `j` of relative size `share` when its super-cell is too
    /// many wavelengths wide for the expansion (`Re k 3^j L` above
    /// [`crate::MAX_WAVENUMBER_WIDTH`]): weakly damped waves.
    fn check_resolved(&self, j: usize, share: f64) -> Result<(), FmmError> {
        let width = 3f64.powi(j as i32) * 2.0 * self.half;
        let kw = self.kernel.wavenumber() * width;
        if kw > crate::MAX_WAVENUMBER_WIDTH {
            return Err(FmmError::InvalidParameter(format!(
                "the lattice sum of {} needs super-cells {:.0} cells wide (their images still \
                 add {share:.1e} of the total), {kw:.0} radians across, beyond the expansions' \
                 reach (k W <= {}): the waves are damped too weakly for a periodic sum here; \
                 a larger imaginary part of the wavenumber, or a smaller cell, makes it",
                self.name,
                3f64.powi(j as i32),
                crate::MAX_WAVENUMBER_WIDTH
            )));
        }
        Ok(())
    }

    /// `K(the cell's check points <- S_j's downward equivalent points)`:
    /// `S_j`'s local density evaluated where `P` is wanted.
    fn local_at_check(&self, j: usize) -> Result<Mat<f64>, FmmError> {
        sum_images(
            self.kernel,
            &self.check,
            &self.surface(j, self.radii.downward_equivalent),
            &[[0.0; 3]],
        )
    }

    /// `S_{j-1}`'s equivalent density to `S_j`'s (M2M from the children).
    fn m2m(&self, j: usize) -> Result<Mat<f64>, FmmError> {
        let r = self.radii;
        let up = sum_images(
            self.kernel,
            &self.surface(j, r.upward_check),
            &self.surface(j - 1, r.upward_equivalent),
            &offsets(&self.children, self.lengths, 3f64.powi(j as i32 - 1)),
        )?;
        solve(
            &self.matrix(j, r.upward_check, j, r.upward_equivalent)?,
            &up,
            self.rcond,
        )
    }

    /// `S_j`'s equivalent density to `S_j`'s local density of ring `j`.
    fn m2l_local(&self, j: usize) -> Result<Mat<f64>, FmmError> {
        let r = self.radii;
        let m2l = sum_images(
            self.kernel,
            &self.surface(j, r.downward_check),
            &self.surface(j, r.upward_equivalent),
            &offsets(&self.ring, self.lengths, 3f64.powi(j as i32)),
        )?;
        solve(
            &self.matrix(j, r.downward_check, j, r.downward_equivalent)?,
            &m2l,
            self.rcond,
        )
    }
}

/// When to stop adding rings, and when to refuse.
struct Convergence {
    last: f64,
    slow: usize,
}

impl Convergence {
    fn new(first: f64) -> Self {
        Convergence {
            last: first,
            slow: 0,
        }
    }

    /// Whether ring `j` of largest entry `size` (the total's: `total`)
    /// ends the sum; an error when the rings do not shrink.
    fn done<K: Kernel>(
        &mut self,
        j: usize,
        size: f64,
        total: f64,
        rings: &Rings<'_, K>,
    ) -> Result<bool, FmmError> {
        let q = if self.last > 0.0 {
            size / self.last
        } else {
            0.0
        };
        self.last = size;
        if size == 0.0 || (q < 1.0 && size * (1.0 + q / (1.0 - q)) <= OPERATOR_TOLERANCE * total) {
            return Ok(true);
        }
        if j >= 2 && q >= DIVERGING_RATIO {
            self.slow += 1;
        }
        if self.slow >= 2 || j == MAX_LEVELS {
            let periodic = rings.axes.mask().iter().filter(|&&b| b).count();
            return Err(FmmError::InvalidParameter(format!(
                "the lattice sum of {} does not converge absolutely in a {} (a ring of \
                 super-cells {:.0} cells wide adds {q:.2} times the last): periodic boundaries \
                 sum kernels that decay faster than r^-{periodic} there (a screened or damped \
                 kernel, a dispersion term), and Laplace, Yukawa and Stokes by their own \
                 lattice sums",
                rings.name,
                rings.axes.kind(),
                3f64.powi(j as i32 + 1),
            )));
        }
        Ok(false)
    }
}

/// The lattice sum of a kernel whose sum converges absolutely, image shell
/// by image shell (see the [module docs](self)): the reference of a
/// periodic run of [`LatticeSum::Images`](super::LatticeSum::Images).
pub(crate) struct ImageSum<K: Kernel> {
    kernel: K,
    cell: Periodic,
    sources: Vec<f64>,
    densities: Vec<f64>,
    tolerance: f64,
}

impl<K: Kernel> ImageSum<K> {
    /// The sum of `kernel` over the images of the `sources` (wrapped into
    /// `cell` here) with `densities` (charges, `c` per source), to
    /// `tolerance` relative to the largest value.
    pub(crate) fn new(
        kernel: &K,
        cell: &Periodic,
        sources: &[f64],
        densities: &[f64],
        tolerance: f64,
    ) -> Self {
        ImageSum {
            kernel: kernel.clone(),
            cell: *cell,
            sources: cell.wrap_all(sources),
            densities: densities.to_vec(),
            tolerance,
        }
    }

    /// The values at the sources `sample` (each leaving out only itself).
    pub(crate) fn at_sources(
        &self,
        sample: &[usize],
        mode: EvalMode,
    ) -> Result<Vec<f64>, FmmError> {
        let at: Vec<f64> = sample
            .iter()
            .flat_map(|&i| [0, 1, 2].map(|a| self.sources[3 * i + a]))
            .collect();
        self.sum_at(&at, mode)
    }

    /// The values at the points `at`.
    pub(crate) fn at_points(&self, at: &[f64], mode: EvalMode) -> Result<Vec<f64>, FmmError> {
        self.sum_at(&self.cell.wrap_all(at), mode)
    }

    fn sum_at(&self, at: &[f64], mode: EvalMode) -> Result<Vec<f64>, FmmError> {
        let c = self.kernel.components();
        let w = self.kernel.values_per_target(mode);
        let n_at = at.len() / 3;
        let pairs = (self.sources.len() / 3 * n_at).max(1) as f64;
        let mask = self.cell.axes().mask();
        let lengths = self.cell.lengths();
        let mut total = vec![0.0f64; w * n_at];
        let mut last = [0.0f64; 2];
        let mut spent = 0.0;
        for m in 0i64.. {
            let shell = offsets(&lattice_images(mask, m, m), lengths, 1.0);
            spent += pairs * shell.len() as f64;
            if spent > IMAGE_SUM_BUDGET {
                return Err(FmmError::InvalidParameter(format!(
                    "the image sum of {} did not reach {:.1e} within {} shells ({:.1e} kernel \
                     evaluations): its lattice sum converges too slowly for a reference by \
                     images; compare at fewer targets or a looser tolerance",
                    self.kernel.name(),
                    self.tolerance,
                    m,
                    IMAGE_SUM_BUDGET
                )));
            }
            let added = self.shell(&shell, at, mode, w);
            // Largest value of the shell and of the total, for the
            // potentials (group 0) and the derivatives (group 1).
            let group = |v: &[f64]| {
                let mut g = [0.0f64; 2];
                for (i, x) in v.iter().enumerate() {
                    let k = usize::from(i % w >= c);
                    g[k] = g[k].max(x.abs());
                }
                g
            };
            total.iter_mut().zip(&added).for_each(|(t, a)| *t += a);
            let (size, sum) = (group(&added), group(&total));
            let done = m >= 3
                && (0..2).all(|k| {
                    if size[k] == 0.0 {
                        return true;
                    }
                    if last[k] <= size[k] {
                        return false;
                    }
                    let mf = m as f64;
                    let b = (last[k] / size[k]).ln() / (mf / (mf - 1.0)).ln();
                    b > 1.0 && size[k] * mf / (b - 1.0) <= self.tolerance * sum[k]
                });
            last = size;
            if done {
                break;
            }
        }
        Ok(total)
    }

    /// One shell's values at `at`, in parallel over its images: the
    /// targets move by `-s` instead of the sources by `s`.
    fn shell(&self, shifts: &[[f64; 3]], at: &[f64], mode: EvalMode, w: usize) -> Vec<f64> {
        let len = w * at.len() / 3;
        shifts
            .par_iter()
            .fold(
                || (vec![0.0f64; len], vec![0.0f64; at.len()]),
                |(mut acc, mut moved), s| {
                    for (m, p) in moved.chunks_exact_mut(3).zip(at.chunks_exact(3)) {
                        for a in 0..3 {
                            m[a] = p[a] - s[a];
                        }
                    }
                    self.kernel
                        .evaluate(mode, &self.sources, &self.densities, &moved, &mut acc);
                    (acc, moved)
                },
            )
            .map(|(acc, _)| acc)
            .reduce(
                || vec![0.0f64; len],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_shells_count_as_cubes() {
        assert_eq!(lattice_images([true; 3], 2, 4).len(), 9 * 9 * 9 - 27);
        assert_eq!(lattice_images([true, true, false], 2, 4).len(), 81 - 9);
        assert_eq!(lattice_images([true, false, false], 2, 4).len(), 6);
        assert_eq!(lattice_images([true; 3], 0, 0), vec![[0, 0, 0]]);
        assert_eq!(lattice_images([true; 3], 3, 3).len(), 7 * 7 * 7 - 5 * 5 * 5);
    }
}
