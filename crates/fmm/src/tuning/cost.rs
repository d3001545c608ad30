//! The cost model: predicted seconds from work counts, and its least-
//! squares fit.

use ferrofmm_field::{M2lCostShape, fft_frequencies, n_surface_points};
use ferrofmm_kernels::EvalMode;

use super::work::WorkCounts;
use crate::EvalTimings;

/// Seconds per unit of work, one coefficient per kind of work, fitted on a
/// 2-core Intel Xeon (Sapphire Rapids, AVX-512) with 2 rayon threads
/// (`docs/tolerance.md`, "Fitted on this machine"). Only the ratios matter to the
/// choice, so another machine of the same kind chooses the same. When an
/// operator gets faster or the machine changes, re-fit with
/// [`CostModel::fit`] (the example `cost_check` of this crate prints a new
/// set to paste into [`CostModel::default`]).
///
/// With `n` points per surface and M2L rank `k`, the predicted time of the
/// tree and one evaluation is
///
/// ```text
/// P2P    p2p_pair p2p_pairs + p2p_entry u_entries
/// far    surface_point n (N_s + N_t) + far_point n far_points
///        + dense n^2 boxes + box_surface n boxes
/// M2L    m2l_flop k^2 v_pairs + m2l_pair k v_pairs + m2l_box n k m2l_boxes
///          (SVD, `M2lCostShape::Compressed`; dense: `k = n`)
///        fft_pair F v_pairs + fft_box F log2(F) m2l_boxes
///          (FFT, `M2lCostShape::Fft`; `F` = `fft_frequencies(p)`)
/// tree   tree_point (N_s + N_t) + tree_box boxes + tree_pair v_pairs
/// ```
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CostModel {
    /// Per P2P source-target pair.
    pub p2p_pair: f64,
    /// Per U-list entry (one leaf-to-leaf block).
    pub p2p_entry: f64,
    /// Per point-surface kernel evaluation of P2M and L2P (`n` per point).
    pub surface_point: f64,
    /// Per point-surface kernel evaluation of M2P and P2L (`n` per far
    /// point).
    pub far_point: f64,
    /// Per `n^2` per box (check-to-equivalent, M2M and L2L products).
    pub dense: f64,
    /// Per `n` per box (surfaces, gathers, scatters).
    pub box_surface: f64,
    /// Per `k^2` per V-list pair (the compressed M2L products).
    pub m2l_flop: f64,
    /// Per `k` per V-list pair (gathering and scattering compressed
    /// expansions).
    pub m2l_pair: f64,
    /// Per `n k` per box on levels `>= 2` (compressing multipoles,
    /// expanding check potentials).
    pub m2l_box: f64,
    /// FFT M2L: per frequency per V-list pair (the pointwise products).
    pub fft_pair: f64,
    /// FFT M2L: per `F log2 F` per box on levels `>= 2` (one forward and
    /// one inverse transform).
    pub fft_box: f64,
    /// Tree: per point (Morton codes, sort, permutations).
    pub tree_point: f64,
    /// Tree: per box (refinement, balance).
    pub tree_box: f64,
    /// Tree: per V-list pair (interaction lists).
    pub tree_pair: f64,
}

impl Default for CostModel {
    /// The model fitted on the Intel machine (`docs/tolerance.md`).
    fn default() -> Self {
        CostModel {
            // Fitted (`CostModel::fit`, group by group, non-negative least
            // squares of the relative error) to 134 runs of `cost_check`:
            // Laplace potentials, zero-mean charges, N = 1e5 and 1e6, cube,
            // sphere and Plummer, orders 3-10 at leaves 32-768, FFT and SVD
            // each, and two deep uniform trees (2e6 points, leaf 32, FFT,
            // orders 6 and 8) (docs/tolerance.md, "Fitted on this machine").
            p2p_pair: 2.96e-10,
            p2p_entry: 7.84e-8,
            surface_point: 3.02e-10,
            far_point: 3.03e-10,
            dense: 1.15e-10,
            box_surface: 2.58e-8,
            m2l_flop: 5.68e-12,
            m2l_pair: 1.08e-9,
            m2l_box: 3.16e-10,
            fft_pair: 1.15e-10,
            fft_box: 3.84e-9,
            tree_point: 3.51e-8,
            tree_box: 2.18e-6,
            tree_pair: 2.38e-8,
        }
    }
}

/// Cost of a target-side kernel evaluation with the gradient relative to
/// the potential alone: the measured P2P rates on one core, 4.88e9
/// (potential) against 3.05e9 (potential and gradient) interactions per
/// second (AVX-512, `cargo bench --bench p2p`).
pub const GRADIENT_COST_FACTOR: f64 = 1.6;

/// As [`GRADIENT_COST_FACTOR`] with Hessians too (ten outputs per target,
/// the composed loop of `ferrofmm_kernels::lanes::RadialLaneKernel`):
/// measured on AVX2 (f64, one core, `cargo bench --bench p2p -- sources`)
/// the Hessian costs 1.86x the gradient (414e6 against 770e6 interactions
/// per second; potential 864e6), so 1.86 x 1.6 on the AVX-512 figures the
/// other factors come from.
pub const HESSIAN_COST_FACTOR: f64 = 3.0;

impl CostModel {
    /// The model for evaluation mode `mode`. The coefficients are fitted on
    /// potentials; with gradients, target-side kernel work (P2P, L2P, M2P)
    /// costs [`GRADIENT_COST_FACTOR`] more. Surface work counts P2M and L2P
    /// (and P2L and M2P) together, so it takes half of the extra.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::CostModel;
    /// use ferrofmm_kernels::EvalMode;
    /// let pot = CostModel::default();
    /// let grad = CostModel::default().for_mode(EvalMode::PotentialGradient);
    /// assert!(grad.p2p_pair > pot.p2p_pair);
    /// assert_eq!(CostModel::default().for_mode(EvalMode::Potential), pot);
    /// ```
    pub fn for_mode(self, mode: EvalMode) -> Self {
        let factor = match mode {
            EvalMode::Potential => return self,
            EvalMode::PotentialGradient => GRADIENT_COST_FACTOR,
            EvalMode::PotentialGradientHessian => HESSIAN_COST_FACTOR,
        };
        let half = 0.5 * (1.0 + factor);
        self.kernel_work_scaled(factor, half)
    }

    /// The model with the P2P pairs `pair` times and the point-surface
    /// work (surface and far points) `points` times as costly.
    fn kernel_work_scaled(self, pair: f64, points: f64) -> Self {
        CostModel {
            p2p_pair: self.p2p_pair * pair,
            surface_point: self.surface_point * points,
            far_point: self.far_point * points,
            ..self
        }
    }
}

impl CostModel {
    /// The model of a kernel whose pairwise evaluation costs `factor` times
    /// the one this model was fitted on: every kernel evaluation (P2P
    /// pairs and point-surface work) scales, the operator products do not.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::CostModel;
    /// let m = CostModel::default().scaled_kernel(4.0);
    /// assert_eq!(m.p2p_pair, 4.0 * CostModel::default().p2p_pair);
    /// assert_eq!(m.m2l_flop, CostModel::default().m2l_flop);
    /// ```
    pub fn scaled_kernel(self, factor: f64) -> Self {
        self.kernel_work_scaled(factor, factor)
    }
}

impl CostModel {
    /// The model of a kernel with `c` [components](ferrofmm_kernels::Kernel::components):
    /// expansions hold `c n` values, so the operator products per box and
    /// the compressed M2L (whose ranks grow about `c`-fold) cost `c^2`
    /// times as much, the gathers `c` times; the FFT scheme's pointwise
    /// products (`c^2` spectra per pair) `c^2` times, its transforms (`c`
    /// per box each way) `c` times; the kernel evaluations are
    /// [`CostModel::scaled_kernel`]'s to scale.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::CostModel;
    /// let (one, m) = (CostModel::default(), CostModel::default().with_components(3));
    /// assert_eq!(m.m2l_flop, 9.0 * one.m2l_flop);
    /// assert_eq!(m.fft_pair, 9.0 * one.fft_pair);
    /// assert_eq!(m.fft_box, 3.0 * one.fft_box);
    /// assert_eq!(m.p2p_pair, one.p2p_pair);
    /// ```
    pub fn with_components(self, c: usize) -> Self {
        let c = c as f64;
        CostModel {
            dense: self.dense * (c * c),
            box_surface: self.box_surface * c,
            m2l_flop: self.m2l_flop * (c * c),
            m2l_pair: self.m2l_pair * c,
            m2l_box: self.m2l_box * (c * c),
            fft_pair: self.fft_pair * (c * c),
            fft_box: self.fft_box * c,
            ..self
        }
    }
}

impl CostModel {
    /// The model of a complex kernel ([`Kernel::is_complex`](ferrofmm_kernels::Kernel::is_complex)):
    /// [`CostModel::with_components`]`(2)`, except that the FFT scheme
    /// convolves one complex spectrum of `N^3` (about `2 F`) frequencies per
    /// box instead of four real ones: its pointwise products cost twice the
    /// scalar kernel's, not four times (its transforms twice, as before).
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::CostModel;
    /// let (one, z) = (CostModel::default(), CostModel::default().with_complex_components());
    /// assert_eq!(z.fft_pair, 2.0 * one.fft_pair);
    /// assert_eq!(z.fft_box, 2.0 * one.fft_box);
    /// assert_eq!(z.m2l_flop, 4.0 * one.m2l_flop);
    /// ```
    pub fn with_complex_components(self) -> Self {
        CostModel {
            fft_pair: self.fft_pair * 2.0,
            ..self.with_components(2)
        }
    }
}

/// Predicted seconds, by kind of work.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CostPrediction {
    /// P2P.
    pub p2p: f64,
    /// P2M, L2P, M2P, P2L kernel evaluations, check-to-equivalent, M2M, L2L.
    pub far: f64,
    /// M2L.
    pub m2l: f64,
    /// Building the tree.
    pub tree: f64,
    /// All of the above.
    pub total: f64,
}

/// One measured run, for [`CostModel::fit`].
#[derive(Clone, Copy, Debug)]
pub struct CostSample {
    /// Work of the run's tree ([`WorkCounts::of_tree`]).
    pub work: WorkCounts,
    /// Expansion order.
    pub order: usize,
    /// M2L rank (`n` for the dense scheme; ignored for FFT).
    pub rank: usize,
    /// How the run's M2L scheme scales.
    pub shape: M2lCostShape,
    /// Measured evaluation.
    pub eval: EvalTimings,
    /// Measured tree construction, seconds.
    pub tree_seconds: f64,
}

/// Units of work of each group, in the order of the coefficients.
pub(super) struct Features {
    pub(super) p2p: [f64; 2],
    pub(super) far: [f64; 4],
    pub(super) m2l: [f64; 3],
    pub(super) fft: [f64; 2],
    pub(super) tree: [f64; 3],
}

/// The features of a run whose M2L scales as `shape`.
pub(super) fn features_for(
    shape: M2lCostShape,
    w: &WorkCounts,
    order: usize,
    rank: usize,
) -> Features {
    let n = n_surface_points(order) as f64;
    let k = match shape {
        M2lCostShape::Dense => n,
        _ => rank as f64,
    };
    let fft = shape == M2lCostShape::Fft;
    let f = fft_frequencies(order) as f64;
    let points = (w.n_sources + w.n_targets) as f64;
    let boxes = w.n_boxes as f64;
    Features {
        p2p: [w.p2p_pairs, w.u_entries],
        far: [n * points, n * w.far_points, n * n * boxes, n * boxes],
        m2l: if fft {
            [0.0; 3]
        } else {
            [
                k * k * w.m2l_pairs,
                k * w.m2l_pairs,
                n * k * w.m2l_boxes as f64,
            ]
        },
        fft: if fft {
            [f * w.m2l_pairs, f * f.log2() * w.m2l_boxes as f64]
        } else {
            [0.0; 2]
        },
        tree: [points, boxes, w.m2l_pairs],
    }
}

pub(super) fn dot(c: &[f64], x: &[f64]) -> f64 {
    c.iter().zip(x).map(|(a, b)| a * b).sum()
}

impl CostModel {
    pub(super) fn groups(&self) -> ([f64; 2], [f64; 4], [f64; 3], [f64; 3]) {
        (
            [self.p2p_pair, self.p2p_entry],
            [
                self.surface_point,
                self.far_point,
                self.dense,
                self.box_surface,
            ],
            [self.m2l_flop, self.m2l_pair, self.m2l_box],
            [self.tree_point, self.tree_box, self.tree_pair],
        )
    }

    /// Predicted time of building the tree and one evaluation with the SVD
    /// M2L at rank `rank`.
    pub fn predict(&self, work: &WorkCounts, order: usize, rank: usize) -> CostPrediction {
        self.predict_for(M2lCostShape::Compressed, work, order, rank)
    }

    /// Predicted time of building the tree and one evaluation with an M2L
    /// scheme that scales as `shape` (`rank` is used by
    /// [`M2lCostShape::Compressed`] only).
    pub fn predict_for(
        &self,
        shape: M2lCostShape,
        work: &WorkCounts,
        order: usize,
        rank: usize,
    ) -> CostPrediction {
        let f = features_for(shape, work, order, rank);
        let (p2p, far, m2l, tree) = self.groups();
        let p = CostPrediction {
            p2p: dot(&p2p, &f.p2p),
            far: dot(&far, &f.far),
            m2l: dot(&m2l, &f.m2l) + dot(&[self.fft_pair, self.fft_box], &f.fft),
            tree: dot(&tree, &f.tree),
            total: 0.0,
        };
        CostPrediction {
            total: p.p2p + p.far + p.m2l + p.tree,
            ..p
        }
    }

    /// Fit the coefficients to measured runs: non-negative least squares
    /// of the relative error, group by group (P2P; P2M + L2P + M2P + P2L +
    /// M2M + L2L; M2L; the tree). A group without data keeps the default.
    pub fn fit(samples: &[CostSample]) -> CostModel {
        let mut m = CostModel::default();
        let fs: Vec<Features> = samples
            .iter()
            .map(|s| features_for(s.shape, &s.work, s.order, s.rank))
            .collect();
        let secs = |d: std::time::Duration| d.as_secs_f64();
        let rows = |x: &dyn Fn(&Features) -> Vec<f64>, y: &dyn Fn(&CostSample) -> f64| {
            fs.iter()
                .zip(samples)
                .map(|(f, s)| (x(f), y(s)))
                .collect::<Vec<_>>()
        };
        if let Some(c) = fit_nonnegative(&rows(&|f| f.p2p.to_vec(), &|s| secs(s.eval.p2p))) {
            [m.p2p_pair, m.p2p_entry] = [c[0], c[1]];
        }
        let far = rows(&|f| f.far.to_vec(), &|s| {
            let e = &s.eval;
            secs(e.p2m) + secs(e.l2p) + secs(e.m2p) + secs(e.p2l) + secs(e.m2m) + secs(e.l2l)
        });
        if let Some(c) = fit_nonnegative(&far) {
            [m.surface_point, m.far_point, m.dense, m.box_surface] = [c[0], c[1], c[2], c[3]];
        }
        // M2L: the SVD (and dense) runs and the FFT runs apart.
        let m2l_rows = |fft: bool| {
            fs.iter()
                .zip(samples)
                .filter(|(_, s)| (s.shape == M2lCostShape::Fft) == fft)
                .map(|(f, s)| {
                    let x = if fft { f.fft.to_vec() } else { f.m2l.to_vec() };
                    (x, secs(s.eval.m2l))
                })
                .collect::<Vec<_>>()
        };
        if let Some(c) = fit_nonnegative(&m2l_rows(false)) {
            [m.m2l_flop, m.m2l_pair, m.m2l_box] = [c[0], c[1], c[2]];
        }
        if let Some(c) = fit_nonnegative(&m2l_rows(true)) {
            [m.fft_pair, m.fft_box] = [c[0], c[1]];
        }
        if let Some(c) = fit_nonnegative(&rows(&|f| f.tree.to_vec(), &|s| s.tree_seconds)) {
            [m.tree_point, m.tree_box, m.tree_pair] = [c[0], c[1], c[2]];
        }
        m
    }
}

/// Non-negative least squares of the relative residual: minimise
/// `sum_i ((c . x_i - y_i) / y_i)^2` over `c >= 0` (features whose
/// coefficient would be negative are dropped one at a time). `None` when
/// no row has a positive finite `y`.
pub(super) fn fit_nonnegative(rows: &[(Vec<f64>, f64)]) -> Option<Vec<f64>> {
    let rows: Vec<(Vec<f64>, f64)> = rows
        .iter()
        .filter(|(_, y)| *y > 0.0 && y.is_finite())
        .map(|(x, y)| (x.iter().map(|v| v / y).collect(), 1.0))
        .collect();
    let dim = rows.first()?.0.len();
    let mut active: Vec<bool> = vec![true; dim];
    loop {
        let idx: Vec<usize> = (0..dim).filter(|&i| active[i]).collect();
        let c = least_squares(&rows, &idx)?;
        let mut full = vec![0.0; dim];
        for (&i, &v) in idx.iter().zip(&c) {
            full[i] = v;
        }
        match idx
            .iter()
            .zip(&c)
            .filter(|(_, v)| **v < 0.0)
            .min_by(|a, b| a.1.total_cmp(b.1))
        {
            Some((&i, _)) => active[i] = false,
            None => return Some(full),
        }
    }
}

/// Least squares on the columns `idx` (scaled to unit norm) through faer's
/// thin SVD: `c = V diag(1 / s) U^T y` over the singular values above
/// `1e-10 s_0`, so a column that depends on the others takes no weight
/// instead of blowing up. `None` when the SVD fails.
pub(super) fn least_squares(rows: &[(Vec<f64>, f64)], idx: &[usize]) -> Option<Vec<f64>> {
    let d = idx.len();
    let scale: Vec<f64> = idx
        .iter()
        .map(|&i| {
            let s = rows.iter().map(|(x, _)| x[i] * x[i]).sum::<f64>().sqrt();
            if s > 0.0 { s } else { 1.0 }
        })
        .collect();
    let x = faer::Mat::<f64>::from_fn(rows.len(), d, |r, c| rows[r].0[idx[c]] / scale[c]);
    let svd = x.thin_svd().ok()?;
    let (u, sv, v) = (svd.U(), svd.S(), svd.V());
    let s0 = if sv.dim() > 0 { sv[0] } else { 0.0 };
    let mut c = vec![0.0; d];
    for k in 0..sv.dim() {
        let sk = sv[k];
        if sk.is_nan() || sk <= 1e-10 * s0 {
            continue;
        }
        let uty: f64 = (0..rows.len()).map(|r| u[(r, k)] * rows[r].1).sum();
        for (j, cj) in c.iter_mut().enumerate() {
            *cj += v[(j, k)] * uty / sk;
        }
    }
    Some(c.iter().zip(&scale).map(|(c, s)| c / s).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;
    use crate::tuning::{Occupancy, estimated_svd_rank};
    use ferrofmm_tree::DEEPEST_LEVEL;

    #[test]
    fn fit_recovers_known_coefficients() {
        let truth = CostModel {
            p2p_pair: 1e-9,
            p2p_entry: 3e-8,
            surface_point: 2e-9,
            far_point: 1.5e-9,
            dense: 3e-11,
            box_surface: 4e-8,
            m2l_flop: 5e-11,
            m2l_pair: 6e-10,
            m2l_box: 7e-11,
            tree_point: 1e-7,
            tree_box: 2e-6,
            tree_pair: 5e-8,
            fft_pair: 2e-10,
            fft_box: 3e-9,
        };
        let mut samples = Vec::new();
        for (g, n) in [(Geometry::Cube, 6000), (Geometry::Plummer, 9000)] {
            let pts: Vec<f64> = g.points(n, 1);
            let occ = Occupancy::new(&pts, None, None, DEEPEST_LEVEL).unwrap();
            for (p, leaf, tau) in [
                (3, 16, 1e-3),
                (4, 64, 1e-5),
                (6, 32, 1e-6),
                (8, 256, 1e-8),
                (5, 128, 1e-4),
                (7, 24, 1e-7),
                (9, 48, 1e-9),
            ] {
                let w = occ.work(leaf);
                let k = estimated_svd_rank(p, tau);
                for shape in [M2lCostShape::Compressed, M2lCostShape::Fft] {
                    let f = features_for(shape, &w, p, k);
                    let (gp, gf, gm, gt) = truth.groups();
                    let d = std::time::Duration::from_secs_f64;
                    let far = dot(&gf, &f.far);
                    let m2l = dot(&gm, &f.m2l) + dot(&[truth.fft_pair, truth.fft_box], &f.fft);
                    let eval = EvalTimings {
                        p2p: d(dot(&gp, &f.p2p)),
                        p2m: d(0.3 * far),
                        l2p: d(0.3 * far),
                        m2m: d(0.1 * far),
                        l2l: d(0.3 * far),
                        m2l: d(m2l),
                        ..Default::default()
                    };
                    samples.push(CostSample {
                        work: w,
                        order: p,
                        rank: k,
                        shape,
                        eval,
                        tree_seconds: dot(&gt, &f.tree),
                    });
                }
            }
        }
        let fit = CostModel::fit(&samples);
        let (a, b) = (fit.groups(), truth.groups());
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(u, v)| (u / v - 1.0).abs() < 1e-4);
        assert!(close(&a.0, &b.0), "{fit:?}");
        assert!(close(&a.1, &b.1), "{fit:?}");
        assert!(close(&a.2, &b.2), "{fit:?}");
        assert!(close(&a.3, &b.3), "{fit:?}");
        assert!(
            close(
                &[fit.fft_pair, fit.fft_box],
                &[truth.fft_pair, truth.fft_box]
            ),
            "{fit:?}"
        );
        // Predictions of the fitted model reproduce the samples.
        for s in &samples {
            let t = fit.predict_for(s.shape, &s.work, s.order, s.rank);
            let measured =
                s.eval.p2p + s.eval.p2m + s.eval.l2p + s.eval.m2m + s.eval.l2l + s.eval.m2l;
            let measured = measured.as_secs_f64() + s.tree_seconds;
            assert!((t.total / measured - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn non_negative_fit_drops_harmful_features() {
        // y = 2 x0 exactly; x1 anti-correlated noise would get a negative
        // coefficient in plain least squares.
        let rows: Vec<(Vec<f64>, f64)> = (1..20)
            .map(|i| {
                let x0 = i as f64;
                let x1 = if i % 2 == 0 { 1.0 } else { 0.5 };
                (vec![x0, x1], 2.0 * x0 - 0.01 * x1)
            })
            .collect();
        let c = fit_nonnegative(&rows).unwrap();
        assert!(c[1] == 0.0 && (c[0] / 2.0 - 1.0).abs() < 0.01, "{c:?}");
    }
}
