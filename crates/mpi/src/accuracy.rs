//! A requested accuracy over MPI: the parameters chosen from a sample of
//! the points ([`choose_parameters`]), and the accuracy achieved measured
//! against direct summation over all ranks ([`sampled_errors`]).
//!
//! # Choosing from a sample
//!
//! The single-machine chooser ([`ferrofmm_fmm::tuning::Tuner`]) reads the
//! sorted Morton codes of all points. Across ranks that would mean
//! gathering `8 N` bytes on one rank; instead rank 0 gathers a systematic
//! sample of at most [`TUNING_SAMPLE`] points (every `s`-th point of each
//! rank, `s = ceil(N / TUNING_SAMPLE)`) and runs the chooser on it, then
//! broadcasts its choice, so every rank builds with the same parameters
//! (the chooser's search is time-bounded, so it is run once, not on every
//! rank). What this gives:
//!
//! * **the order and the SVD tolerance** come from the error model, which
//!   depends on the tolerance, the kernel, the float type and the finest
//!   boxes' rounding ratio, not on `N`: the same as on one machine (the
//!   sample's tree is shallower, so the rounding floor is taken a level or
//!   two early; it matters only near the float type's limit, and
//!   [`sampled_errors`] checks the result);
//! * **the leaf size** balances the near field (`s^2` pairs per leaf)
//!   against the far field (a fixed cost per box), a balance within each
//!   leaf's neighbourhood that holds at any `N` for the same density
//!   profile; a sample of the points has that profile. For `N <=
//!   TUNING_SAMPLE` the sample is every point and the choice is the single
//!   machine's;
//! * **the cost model** is calibrated where the operator cache folder
//!   holds a calibration of rank 0's processor at the ranks' thread count
//!   (`ferrofmm calibrate --threads T`, run on one node with the threads
//!   of one rank): the balance of near and far field is a rank's own, so a
//!   rank's calibration is the one that applies.
//!
//! # Checking
//!
//! [`sampled_errors`] compares the FMM's values at `k` points sampled
//! evenly over the global input order with direct summation over all
//! points in `f64`: the sample's coordinates and values are summed into
//! every rank (`all_reduce`), each rank adds its own points' field at the
//! sample, and a second `all_reduce` completes it: `k (3 + w)` values and
//! `k w` values per rank, and `N k / R` kernel evaluations on each.

use ferrofmm_field::M2lCostShape;
use ferrofmm_fmm::SchemeChoice;
use ferrofmm_fmm::tuning::{ChosenParameters, MachineCalibration, Occupancy, Tuner, default_model};
use ferrofmm_kernels::{EvalMode, Kernel, Precision, SourceKind, direct_sum_sources};
use ferrofmm_tree::DEEPEST_LEVEL;
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::traits::*;

use crate::error::{DistError, agree_message};

/// Most points rank 0 gathers for [`choose_parameters`] (`24` bytes each).
pub const TUNING_SAMPLE: usize = 200_000;

/// Parameters for a requested accuracy, the same on every rank.
#[derive(Clone, Debug, PartialEq)]
pub struct DistChoice {
    /// Expansion order.
    pub order: usize,
    /// Largest number of points in a leaf.
    pub leaf_size: usize,
    /// Relative singular-value cut of the SVD scheme (unused by others).
    pub svd_tolerance: f64,
    /// The error the model predicts (the larger of potential and gradient
    /// when gradients are evaluated).
    pub predicted_error: f64,
    /// The M2L scheme's cost shape the choice was made for.
    pub shape: M2lCostShape,
    /// Points in the sample the choice was made on.
    pub sample: usize,
    /// The chooser's full answer (rank 0 only; `None` elsewhere).
    pub chosen: Option<ChosenParameters>,
    /// Whether rank 0 weighed the costs with a calibration of this machine
    /// ([`MachineCalibration`], from `ferrofmm calibrate`); the same on
    /// every rank.
    pub calibrated: bool,
}

/// Chooses order, leaf size and SVD tolerance for the relative L2 error
/// `eps` of `kernel` in float type `precision`, or the leaf size (and
/// scheme) for a fixed `order` (a collective; see the [module docs](self)). `shape`: the M2L scheme to choose for, or `None`
/// to choose between the SVD and FFT schemes by predicted time (FFT where
/// [`SchemeChoice::auto_is_fft`], as on one machine); `svd_cached`:
/// whether the SVD scheme's operators come from a cache (its precomputation
/// is then not counted); `calibration`: the cost model's calibration for
/// this processor and a rank's threads (used on rank 0, where the chooser
/// runs; `None`: the built-in costs).
///
/// # Errors
/// The same [`DistError`] on every rank: a tolerance out of range for the
/// float type or beyond what the points allow, no points, or bad points.
#[allow(clippy::too_many_arguments)]
pub fn choose_parameters<C: Communicator, K: Kernel>(
    comm: &C,
    points: &[f64],
    kernel: &K,
    eps: Option<f64>,
    order: Option<usize>,
    precision: Precision,
    mode: EvalMode,
    shape: Option<M2lCostShape>,
    svd_cached: bool,
    calibration: Option<&MachineCalibration>,
) -> Result<DistChoice, DistError> {
    // The single-machine chooser on the gathered sample (rank 0).
    let choose_on = |sample: &[f64]| -> Result<(M2lCostShape, ChosenParameters), String> {
        if let Some(eps) = eps {
            ferrofmm_fmm::tuning::validate_tolerance(eps, precision).map_err(|e| e.to_string())?;
        }
        let occupancy =
            Occupancy::new(sample, None, None, DEEPEST_LEVEL).map_err(|e| e.to_string())?;
        let width = occupancy_width(sample);
        let shape = match shape {
            None if SchemeChoice::auto_is_fft(kernel) => Some(M2lCostShape::Fft),
            s => s,
        };
        let mut tuner = Tuner::from_model(
            default_model(kernel, width),
            precision,
            mode,
            shape.unwrap_or(M2lCostShape::Compressed),
        )
        .with_calibration(calibration.cloned());
        if let Some(p) = order {
            tuner = tuner.with_order(p);
        }
        match shape {
            Some(s) => tuner.choose_for(eps, &occupancy).map(|c| (s, c)),
            None => tuner.choose_scheme_for(eps, &occupancy, svd_cached),
        }
        .map_err(|e| e.to_string())
    };
    let n_local = (points.len() / 3) as u64;
    let mut n_total = 0u64;
    comm.all_reduce_into(&n_local, &mut n_total, SystemOperation::sum());
    let stride = n_total.div_ceil(TUNING_SAMPLE as u64).max(1) as usize;
    let mine: Vec<f64> = points
        .chunks_exact(3)
        .step_by(stride)
        .flatten()
        .copied()
        .collect();
    let size = comm.size() as usize;
    let count = mine.len() as i32;
    let mut counts = vec![0i32; size];
    comm.all_gather_into(&count, &mut counts[..]);
    let root = comm.process_at_rank(0);
    let chosen = if comm.rank() == 0 {
        let sizes: Vec<usize> = counts.iter().map(|&c| c as usize).collect();
        let (c, displs) = crate::exchange::layout(&sizes);
        let mut sample = vec![0.0f64; sizes.iter().sum()];
        let mut part = PartitionMut::new(&mut sample[..], c, displs);
        root.gather_varcount_into_root(&mine[..], &mut part);
        Some(choose_on(&sample))
    } else {
        root.gather_varcount_into(&mine[..]);
        None
    };
    let local = match chosen {
        Some(Err(e)) => Err(e),
        _ => Ok(chosen.and_then(Result::ok)),
    };
    let chosen = agree_message(comm, local)?;
    let sample = counts.iter().map(|&c| c as usize).sum::<usize>() / 3;
    let mut wire = [0.0f64; 6];
    if let Some((s, c)) = &chosen {
        wire = [
            c.order as f64,
            c.leaf_size as f64,
            c.svd_tolerance,
            c.predicted_error,
            if *s == M2lCostShape::Fft { 1.0 } else { 0.0 },
            if calibration.is_some() { 1.0 } else { 0.0 },
        ];
    }
    root.broadcast_into(&mut wire[..]);
    Ok(DistChoice {
        order: wire[0] as usize,
        leaf_size: wire[1] as usize,
        svd_tolerance: wire[2],
        predicted_error: wire[3],
        shape: if wire[4] == 1.0 {
            M2lCostShape::Fft
        } else {
            shape.unwrap_or(M2lCostShape::Compressed)
        },
        sample,
        chosen: chosen.map(|(_, c)| c),
        calibrated: wire[5] == 1.0,
    })
}

/// Width of the bounding cube of `points` (the wavenumber models use
/// `k` times it).
fn occupancy_width(points: &[f64]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points.chunks_exact(3) {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max)
}

/// Relative L2 errors `[potential, gradient]` of `values` (this rank's
/// points, `kernel.values_per_target(mode)` each, the first
/// [`Kernel::components`] of them the potential) at `k` points sampled
/// evenly over the global order of the points (rank by rank), against
/// direct summation in `f64` over all points with `densities` (`kind`,
/// [`Kernel::values_per_source`] each). A collective; the gradient error is
/// 0 when `mode` has no gradient. See the [module docs](self).
#[allow(clippy::too_many_arguments)]
pub fn sampled_errors<C: Communicator, K: Kernel>(
    comm: &C,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    points: &[f64],
    densities: &[f64],
    values: &[f64],
    k: usize,
) -> [f64; 2] {
    sampled_errors_at(
        comm, kernel, kind, mode, points, densities, points, values, k,
    )
}

/// The `k` targets (at most all of them) spread over the global input
/// order (`j * total / k` for `j < k`) and their values (`w` per target),
/// from their owners to every rank: `3 k` coordinates then `w k` values
/// (`None` when no rank has a target or `k == 0`). A collective.
pub fn gather_sample<C: Communicator>(
    comm: &C,
    targets: &[f64],
    values: &[f64],
    w: usize,
    k: usize,
) -> Option<Vec<f64>> {
    let n_local = (targets.len() / 3) as u64;
    let mut counts = vec![0u64; comm.size() as usize];
    comm.all_gather_into(&n_local, &mut counts[..]);
    let first: u64 = counts[..comm.rank() as usize].iter().sum();
    let total: u64 = counts.iter().sum();
    let k = k.min(usize::try_from(total).unwrap_or(usize::MAX));
    if k == 0 {
        return None;
    }
    let mut mine = vec![0.0; (3 + w) * k];
    for j in 0..k {
        let id = j as u64 * total / k as u64;
        if id >= first && id < first + n_local {
            let i = (id - first) as usize;
            mine[3 * j..3 * j + 3].copy_from_slice(&targets[3 * i..3 * i + 3]);
            mine[3 * k + w * j..3 * k + w * (j + 1)].copy_from_slice(&values[w * i..w * (i + 1)]);
        }
    }
    let mut shared = vec![0.0; mine.len()];
    comm.all_reduce_into(&mine[..], &mut shared[..], SystemOperation::sum());
    Some(shared)
}

/// [`sampled_errors`] with separate targets: `values` are this rank's
/// results at its `targets` (input order), the `k` samples are spread over
/// the global order of the targets, and the direct sum runs over every
/// rank's `sources` with `densities` (a target on a source skips it, as in
/// the FMM). A collective.
#[allow(clippy::too_many_arguments)]
pub fn sampled_errors_at<C: Communicator, K: Kernel>(
    comm: &C,
    kernel: &K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &[f64],
    densities: &[f64],
    targets: &[f64],
    values: &[f64],
    k: usize,
) -> [f64; 2] {
    let w = kernel.values_per_target(mode);
    let c = kernel.components();
    let Some(shared) = gather_sample(comm, targets, values, w, k) else {
        return [0.0, 0.0];
    };
    let k = shared.len() / (3 + w);
    let (sample, fmm) = shared.split_at(3 * k);
    let mut direct = vec![0.0; w * k];
    direct_sum_sources(kernel, kind, mode, sources, densities, sample, &mut direct);
    let mut sum = vec![0.0; w * k];
    comm.all_reduce_into(&direct[..], &mut sum[..], SystemOperation::sum());
    let mut s = [0.0f64; 4];
    for (f, d) in fmm.chunks_exact(w).zip(sum.chunks_exact(w)) {
        for j in 0..w {
            let g = usize::from(j >= c);
            s[2 * g] += (f[j] - d[j]) * (f[j] - d[j]);
            s[2 * g + 1] += d[j] * d[j];
        }
    }
    let rel = |num: f64, den: f64| if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    [rel(s[0], s[1]), rel(s[2], s[3])]
}
