//! The root box: a cube larger than the points' bounding cube when that
//! makes the run cheaper.
//!
//! On the bounding cube of width `W`, a near-uniform set of `N` points has
//! leaves of about `N / 8^d` points at depth `d`: the leaf occupancies the
//! adaptive tree can reach step 8x at a time, whatever the leaf size. The
//! cost per point is about `a s + b / s` for leaves of `s` points (the
//! near field grows with `s`, the far field with the number of boxes), so
//! at an unlucky `N` the best reachable `s` sits up to `sqrt 8 = 2.8`
//! times away from the best one, and the run costs up to 1.5x what it
//! could (measured: 2.7 us a point at 1e5 against 4.5 us at 1e8 on the
//! same tolerance, docs/performance.md "Memory and large N").
//!
//! A root of width `c W` with the same lower corner puts the same points in
//! leaves of `N c^3 / 8^d`: with `c` in [`ROOT_SCALES`] (`c^3` = 1, 2, 4)
//! the reachable occupancies step 2x, and the best is within `sqrt 2` of
//! the optimum, where `a s + b / s` is within 6% of its minimum. The
//! boxes along the upper faces are only partly filled, and the choice
//! weighs that too: [`choose_root`] runs the chooser's simulation
//! ([`Tuner::choose_for`]) on each root and keeps the cheapest prediction,
//! or one with fewer boxes (less memory) predicted at most
//! [`ROOT_TIME_SLACK`] slower. A wider root whose boxes would not fit the
//! memory left beside the points ([`box_bytes`] against the builder's
//! [`MemoryLimit`](ferrofmm_field::MemoryLimit)) is not taken: more boxes
//! cost memory (about 30 bytes a point more at 1e8 for leaves half as
//! full), so the fastest run is the one that fits.
//! A larger root never changes the accuracy (the error model's tables do
//! not depend on where the points sit in their boxes), only the tree.
//!
//! The builder tries the larger roots from [`ROOT_SEARCH_MIN_POINTS`] points
//! on, and only for kernels without a length scale
//! (Laplace, Stokes): for a wavenumber `k` the operators and the error
//! depend on `k W`, which a larger root would raise. A periodic cell, a
//! domain given by the caller, far-separated clusters and a leaf size
//! given by the caller keep the bounding cube (the caller's leaf size
//! describes a tree on it).

use ferrofmm_kernels::Precision;
use ferrofmm_tree::Domain;

use super::chooser::{ChosenParameters, Tuner};
use super::occupancy::Occupancy;
use crate::FmmError;

/// Root widths weighed by [`choose_root`], as multiples of the points'
/// bounding cube: `2^(j/3)` for `j = 0, 1, 2`, so that leaf occupancies
/// step 2x instead of 8x.
pub const ROOT_SCALES: [f64; 3] = [1.0, 1.259_921_049_894_873_2, 1.587_401_051_968_199_4];

/// A chosen run and its root: `None` for the bounding cube of the points.
pub type RootChoice = (ChosenParameters, Option<Domain>);

/// The cheapest predicted parameters over the roots of [`ROOT_SCALES`]
/// (each the bounding cube of `sources` and `targets` widened from its
/// lower corner), or the fewest boxes among those within
/// [`ROOT_TIME_SLACK`] of it, with the root when it is not the bounding
/// cube.
/// [`ChosenParameters::root_scale`] says which was taken. The search of
/// each root is [`Tuner::choose_for`]'s; the pre-pass's Morton codes are
/// made once per root (about one sort of the points each).
///
/// A wider root is weighed only when its choice `fits` (the builder's
/// test: [`box_bytes`] within [`box_budget`]).
///
/// # Errors
/// As [`Tuner::choose_for`] on the bounding cube; a larger root that has
/// no admissible setting is skipped.
pub fn choose_root(
    tuner: &Tuner,
    eps: Option<f64>,
    sources: &[f64],
    targets: Option<&[f64]>,
    max_level: u32,
    fits: impl Fn(&ChosenParameters) -> bool,
) -> Result<RootChoice, FmmError> {
    choose_root_reporting(tuner, eps, sources, targets, max_level, fits, &|_, _| {})
}

/// [`choose_root`], calling `report(done, total)` with the roots weighed
/// so far of the [`ROOT_SCALES`] (`total`), from 0 to `total`.
///
/// # Errors
/// As [`choose_root`].
pub fn choose_root_reporting(
    tuner: &Tuner,
    eps: Option<f64>,
    sources: &[f64],
    targets: Option<&[f64]>,
    max_level: u32,
    fits: impl Fn(&ChosenParameters) -> bool,
    report: &dyn Fn(u64, u64),
) -> Result<RootChoice, FmmError> {
    let roots = ROOT_SCALES.len() as u64;
    report(0, roots);
    let tight = match targets {
        Some(t) => Domain::from_points(&[sources, t])?,
        None => Domain::from_points(&[sources])?,
    };
    let occupancy = Occupancy::new(sources, targets, Some(tight), max_level)?;
    let mut weighed: Vec<RootChoice> = vec![(tuner.choose_for(eps, &occupancy)?, None)];
    drop(occupancy);
    report(1, roots);
    for (k, &scale) in ROOT_SCALES.iter().enumerate().skip(1) {
        let Ok(domain) = Domain::new(tight.origin, tight.width * scale) else {
            continue;
        };
        let occupancy = Occupancy::new(sources, targets, Some(domain), max_level)?;
        if let Ok(mut chosen) = tuner.choose_for(eps, &occupancy)
            && fits(&chosen)
        {
            chosen.root_scale = scale;
            weighed.push((chosen, Some(domain)));
        }
        report(k as u64 + 1, roots);
    }
    report(roots, roots);
    Ok(fewest_boxes_near_cheapest(weighed))
}

/// Of the weighed roots, the one with the fewest boxes (so the least
/// memory for expansions, lists and tree) among those predicted within
/// [`ROOT_TIME_SLACK`] of the cheapest; on a tie, the smaller root.
fn fewest_boxes_near_cheapest(weighed: Vec<RootChoice>) -> RootChoice {
    let cheapest = weighed
        .iter()
        .map(|(c, _)| c.predicted_seconds)
        .fold(f64::INFINITY, f64::min);
    weighed
        .into_iter()
        .filter(|(c, _)| c.predicted_seconds <= (1.0 + ROOT_TIME_SLACK) * cheapest)
        .min_by_key(|(c, _)| c.estimated_work.n_boxes)
        .expect("the bounding cube is always weighed")
}

/// Bytes of the buffers that grow with the boxes of a tree of `work` with
/// expansions of `expansion_len` values
/// ([`expansion_len`](ferrofmm_field::expansion_len)):
/// - the multipole and local expansions (`2 expansion_len` values a box),
///   the tree's per-box arrays (about 200 bytes a box) and its U lists (8
///   bytes an entry);
/// - the M2L interactions made from the V lists (the tree's own V lists
///   are handed over to them): every built-in scheme reads them from their
///   sibling blocks (16 bytes a block of up to 63 pairs, about 58 in a
///   uniform level; about 20 bytes a box of slots and offsets), so 0.3
///   bytes a pair and 20 a box. The pair lists themselves (8 bytes a pair)
///   are released once the blocks are made: the FFT scheme reads only the
///   blocks, the SVD and dense schemes make one chunk's pairs at a time
///   ([`M2lInteractions::with_chunk`](ferrofmm_field::M2lInteractions::with_chunk)).
///
/// Within 15% of [`MemoryReport`](crate::MemoryReport)'s tree,
/// expansions and M2L interactions (the test `box_bytes_follow_the_built_tree`).
pub fn box_bytes(work: &super::WorkCounts, expansion_len: usize, precision: Precision) -> u64 {
    let n = expansion_len;
    let t = match precision {
        Precision::F32 => 4,
        Precision::F64 => 8,
    };
    let boxes = work.n_boxes as f64;
    let per_box = (2 * n * t + 200) as f64;
    let m2l = 0.3 * work.m2l_pairs + 20.0 * boxes;
    (boxes * per_box + 8.0 * work.u_entries + m2l) as u64
}

/// The bytes left for [`box_bytes`] under `limit` (`None`: no limit): the
/// limit less what the run needs whatever its tree
/// ([`MemoryReport::predict`](crate::MemoryReport::predict): the points,
/// the sort or the evaluation's densities and outputs), less the caller's
/// own densities (`values_per_source` f64 a source, held while the FMM
/// evaluates) and, for the FFT scheme, its spectra budget
/// ([`SPECTRA_BUDGET_BYTES`](ferrofmm_field::SPECTRA_BUDGET_BYTES)). At 1e8
/// points (order 8, FFT, a root 1.59x wide) the sum is 11.4 GiB against a
/// measured peak of 10.3: the sum counts both expansions and every output
/// at once, which the evaluation never holds together (it releases the
/// multipoles after M2P and the locals after L2P).
pub fn box_budget<T: ferrofmm_kernels::Real>(
    limit: Option<u64>,
    size: &crate::RunSize,
    fft: bool,
) -> Option<u64> {
    let densities = (size.n_sources as u64).saturating_mul(8 * size.values_per_source as u64);
    let spectra = if fft {
        ferrofmm_field::SPECTRA_BUDGET_BYTES as u64
    } else {
        0
    };
    limit.map(|l| {
        l.saturating_sub(crate::MemoryReport::predict::<T>(size))
            .saturating_sub(densities)
            .saturating_sub(spectra)
    })
}

/// Points (sources and separate targets) below which the front ends do
/// not weigh wider roots: each costs one more pre-pass (measured on the
/// uniform cube, 2 threads: 0.02 s at 1e5, 0.08 s at 1e6, 0.75 s at 1e7,
/// 10-14 s at 1e8), 5-15% of a run below a million points, where the
/// bounding cube was kept at 1e5 and 1e6 anyway; from 1e7 the wider root
/// saved 12-25% of the evaluation.
pub const ROOT_SEARCH_MIN_POINTS: usize = 2_000_000;

/// A root with fewer boxes is taken over the cheapest one when predicted
/// at most this fraction slower: near its best leaf occupancy the cost
/// per point is flat (`a s + b / s`), while the memory of expansions,
/// lists and tree grows with the boxes. Measured at 1e7 (uniform cube,
/// 1e-6, potential and gradient): leaves of 76 points are predicted 2%
/// faster than leaves of 152, with twice the boxes. The same slack lets
/// the scheme chooser take the FFT scheme, which holds less memory on a
/// large tree, over an SVD scheme predicted faster
/// ([`Tuner::choose_scheme_for`]).
pub const ROOT_TIME_SLACK: f64 = 0.05;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;
    use ferrofmm_field::n_surface_points;
    use ferrofmm_kernels::{EvalMode, Precision};
    use ferrofmm_tree::DEEPEST_LEVEL;

    use crate::tuning::{LaplaceModel, M2lCostShape, WorkCounts};
    use std::sync::Arc;

    fn tuner() -> Tuner {
        Tuner::from_model(
            Arc::new(LaplaceModel),
            Precision::F64,
            EvalMode::PotentialGradient,
            M2lCostShape::Fft,
        )
    }

    #[test]
    fn the_root_is_never_predicted_much_slower_than_the_bounding_cube() {
        for n in [20_000, 60_000, 150_000] {
            let points: Vec<f64> = Geometry::Cube.points(n, 3);
            let occ = Occupancy::new(&points, None, None, DEEPEST_LEVEL).unwrap();
            let tight = tuner().choose_for(Some(1e-6), &occ).unwrap();
            let (chosen, root) =
                choose_root(&tuner(), Some(1e-6), &points, None, DEEPEST_LEVEL, |_| true).unwrap();
            assert!(chosen.predicted_seconds <= (1.0 + ROOT_TIME_SLACK) * tight.predicted_seconds);
            assert_eq!(
                chosen.order, tight.order,
                "the accuracy does not depend on the root"
            );
            match root {
                None => assert_eq!(chosen.root_scale, 1.0),
                Some(d) => {
                    assert!(ROOT_SCALES[1..].contains(&chosen.root_scale));
                    assert_eq!(d.origin, occ.domain().origin);
                    assert!((d.width / occ.domain().width - chosen.root_scale).abs() < 1e-12);
                    for p in points.chunks_exact(3) {
                        assert!(d.contains([p[0], p[1], p[2]]));
                    }
                }
            }
        }
    }

    #[test]
    fn a_uniform_set_between_two_depths_gets_a_larger_root() {
        // 2.5e5 points: leaves of 61 or 488 on the bounding cube, both far
        // from the best occupancy; a root of 2^(1/3) or 2^(2/3) gives 122 or
        // 244.
        let points: Vec<f64> = Geometry::Cube.points(250_000, 5);
        let (chosen, root) =
            choose_root(&tuner(), Some(1e-6), &points, None, DEEPEST_LEVEL, |_| true).unwrap();
        assert!(root.is_some(), "kept the bounding cube: {chosen:?}");
        // Without room for the boxes of that choice, another is taken:
        // one that fits, or the bounding cube.
        let bytes = |c: &ChosenParameters| {
            box_bytes(&c.estimated_work, n_surface_points(c.order), Precision::F64)
        };
        let room = bytes(&chosen) - 1;
        let (other, other_root) =
            choose_root(&tuner(), Some(1e-6), &points, None, DEEPEST_LEVEL, |c| {
                bytes(c) <= room
            })
            .unwrap();
        assert_ne!(other, chosen);
        if other_root.is_some() {
            assert!(bytes(&other) <= room);
        } else {
            assert_eq!(other.root_scale, 1.0);
        }
    }

    #[test]
    fn box_bytes_follow_the_built_tree() {
        use crate::{FmmBuilder, MemoryReport};
        use ferrofmm_field::{FftConfig, FftM2l, SvdConfig, SvdM2l};
        let points: Vec<f64> = Geometry::Cube.points(40_000, 7);
        let charges = vec![1.0; 40_000];
        let builder = || FmmBuilder::new(&points).order(6).leaf_size(64);
        let check = |what: &str, work: crate::tuning::WorkCounts, m: MemoryReport| {
            let predicted = box_bytes(&work, n_surface_points(6), Precision::F64);
            let held = (m.expansions + m.tree + m.m2l_interactions) as f64;
            assert!(
                (predicted as f64 / held - 1.0).abs() < 0.15,
                "{what}: {predicted} against {held}"
            );
        };
        let fft = builder().build_with::<FftM2l<f64>>(FftConfig).unwrap();
        let svd = builder()
            .build_with::<SvdM2l<f64>>(SvdConfig::default())
            .unwrap();
        // Both schemes keep the sibling blocks, not the pair lists, before
        // and after an evaluation; the SVD scheme gives the same result as
        // with the lists held (its chunks are made exactly as they were).
        let deepest = |m: &[ferrofmm_field::M2lInteractions]| m[m.len() - 1].holds_pair_lists();
        assert!(!deepest(&fft.main().m2l_interactions));
        assert!(!deepest(&svd.main().m2l_interactions));
        fft.evaluate(&charges).unwrap();
        let streamed = svd.evaluate(&charges).unwrap();
        assert!(!deepest(&fft.main().m2l_interactions));
        assert!(!deepest(&svd.main().m2l_interactions));
        assert!(
            svd.memory().m2l_interactions * 10 < WorkCounts::of_fmm(&svd).m2l_pairs as usize * 8
        );
        let held = builder()
            .build_with::<SvdM2l<f64>>(SvdConfig::default())
            .unwrap();
        for inter in &held.main().m2l_interactions {
            inter.chunk_views().count();
        }
        assert!(deepest(&held.main().m2l_interactions));
        assert_eq!(held.evaluate(&charges).unwrap(), streamed);
        // The built tree's V lists are handed over to the M2L
        // interactions: `of_fmm` counts them there.
        assert_eq!(WorkCounts::of_tree(fft.tree()).m2l_pairs, 0.0);
        check("fft", WorkCounts::of_fmm(&fft), fft.memory());
        check("svd", WorkCounts::of_fmm(&svd), svd.memory());
    }
}
