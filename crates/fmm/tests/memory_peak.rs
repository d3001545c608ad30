//! The heap an FMM run holds at its peak against the bytes it accounts for
//! ([`Fmm::memory`]): a copy of the points or the outputs that creeps back
//! (each is 24-32 bytes a point) shows up here.
//!
//! A binary of its own: a counting global allocator measures the heap
//! (current and peak bytes) of everything the run allocates.

use std::alloc::{GlobalAlloc, Layout, System};
use std::mem::size_of;
use std::sync::atomic::{AtomicUsize, Ordering};

use ferrofmm_fmm::{FmmBuilder, Geometry, MemoryReport, RunSize, charges};
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, SourceKind};

/// The system allocator, counting live bytes and their high-water mark.
///
/// Page-aligned blocks are not counted: they are the dense linear
/// algebra's per-thread packing buffers (twice the L3 cache per thread
/// that ever multiplies matrices, allocated once and mostly never
/// touched), not the run's data; nothing in ferrofmm asks for that
/// alignment.
struct Counting;

fn counted(layout: &Layout) -> bool {
    layout.align() < 4096
}

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded unchanged to `System`, which upholds the
// `GlobalAlloc` contract; the counters only observe the sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc` is passed on unchanged.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() && counted(&layout) {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `alloc` above with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        if counted(&layout) {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract for `realloc` is passed on unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() && counted(&layout) {
            if new_size >= layout.size() {
                let grow = new_size - layout.size();
                let live = LIVE.fetch_add(grow, Ordering::Relaxed) + grow;
                PEAK.fetch_max(live, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Start a measurement: the peak from now on, above what is live now.
fn reset_peak() -> usize {
    let live = LIVE.load(Ordering::Relaxed);
    PEAK.store(live, Ordering::Relaxed);
    live
}

const MIB: f64 = 1024.0 * 1024.0;

/// A run of `n` uniform points with zero-mean charges, potential and
/// gradient, f64, built by `build` on two threads (so that the per-thread
/// scratch is the same everywhere): the heap's peak over building and
/// evaluating is the accounted buffers plus 4 MiB (per-thread scratch and
/// small buffers: half of what one more copy of the densities, the
/// smallest per-point buffer, would add at a million points), and the
/// accounted points are one sorted copy and one permutation.
fn holds_what_it_accounts_for<S: ferrofmm_field::M2lScheme<f64>>(
    n: usize,
    build: impl FnOnce(&[f64]) -> ferrofmm_fmm::Fmm<f64, Laplace3d, S> + Send,
) {
    let points: Vec<f64> = Geometry::Cube.points(n, 3);
    let q: Vec<f64> = charges(n, 3);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let base = reset_peak();
    let fmm = pool.install(|| build(&points));
    let build_peak = PEAK.load(Ordering::Relaxed) - base;
    let held = LIVE.load(Ordering::Relaxed) - base;
    reset_peak();
    let values = pool.install(|| fmm.evaluate(&q).unwrap());
    let eval_peak = PEAK.load(Ordering::Relaxed) - base;
    let memory = pool.install(|| fmm.memory());
    let w = Laplace3d.values_per_target(EvalMode::PotentialGradient);
    assert_eq!(values.len(), w * n);

    eprintln!(
        "build peak {:.1} MiB, evaluation peak {:.1} MiB, accounted {:.1} MiB, held {:.1} MiB",
        build_peak as f64 / MIB,
        eval_peak as f64 / MIB,
        memory.total as f64 / MIB,
        held as f64 / MIB
    );
    // One copy of the points (f64, tree order) and one permutation.
    assert_eq!(memory.points, n * (3 * 8 + 8));
    // What the built FMM holds is what it accounts for, less the
    // evaluation's buffers (made per evaluation).
    let built = memory.total - memory.evaluation_scratch;
    let slack = 4.0 * MIB;
    assert!(
        (held as f64) < built as f64 + slack,
        "held after the build {:.1} MiB, accounted {:.1} MiB",
        held as f64 / MIB,
        built as f64 / MIB
    );
    // The peak of an evaluation: everything accounted, the outputs once.
    assert!(
        (eval_peak as f64) < memory.total as f64 + slack,
        "evaluation peak {:.1} MiB, accounted {:.1} MiB",
        eval_peak as f64 / MIB,
        memory.total as f64 / MIB
    );
    // Less what is never alive at once: the outputs are made when the
    // leaf passes begin, after the multipoles (but those M2P reads) are
    // released, so the peak is either the downward pass's (without the
    // outputs) or the leaf passes' (without the multipoles). Checked
    // where both are well above the slack.
    let outputs = w * n * size_of::<f64>();
    let apart = outputs.min(memory.expansions / 2);
    if apart as f64 > 2.0 * slack {
        assert!(
            (eval_peak as f64) < (memory.total - apart) as f64 + slack,
            "evaluation peak {:.1} MiB, accounted {:.1} MiB less {:.1} MiB never held together",
            eval_peak as f64 / MIB,
            memory.total as f64 / MIB,
            apart as f64 / MIB
        );
    }
    // The build's peak: besides what it keeps, the sort's Morton codes
    // (16 bytes a point), the operators' precomputation (at orders 4-5
    // up to 8 MiB: the SVD's 316 dense M2L matrices), the tree's V lists
    // until the M2L interactions that replace them are made (8 bytes an
    // entry) and, beside them, one level's grouped pair lists until its
    // sibling blocks are made and the lists released (8 bytes a pair, at
    // most as many as the V lists); one more copy of the points (24 bytes
    // a point, 23 MiB at a million) would not fit.
    let v_lists = 8.0 * fmm.summary().list_entries[1] as f64;
    assert!(
        (build_peak as f64) < built as f64 + 16.0 * n as f64 + 2.0 * v_lists + 12.0 * MIB,
        "build peak {:.1} MiB, accounted {:.1} MiB",
        build_peak as f64 / MIB,
        built as f64 / MIB
    );
    // The prediction from the point counts is a lower bound of the peak.
    let predicted = MemoryReport::predict::<f64>(&RunSize {
        n_sources: n,
        n_targets: None,
        values_per_source: Laplace3d.values_per_source(SourceKind::Charge),
        values_per_target: w,
        n_vectors: 1,
    });
    assert!((predicted as usize) < eval_peak.max(build_peak));
}

/// One million points, SVD M2L (no scratch of its own): one copy of the
/// outputs more (they are put in the caller's order in place) would be
/// 30 MiB over. Then FFT M2L, whose source spectra (a level's, within the
/// budget) are accounted too. One test: the counters are the process's.
#[test]
fn runs_hold_what_they_account_for() {
    holds_what_it_accounts_for(1_000_000, |points| {
        FmmBuilder::new(points)
            .mode(EvalMode::PotentialGradient)
            .order(4)
            .leaf_size(256)
            .cache(ferrofmm_field::CacheSetting::Off)
            .build_svd()
            .unwrap()
    });
    // Many small leaves, SVD M2L (whose scratch is small and exactly
    // accounted): the multipoles (29 MiB) and the outputs (12 MiB) are
    // both far above the slack, so holding them together would fail.
    holds_what_it_accounts_for(400_000, |points| {
        FmmBuilder::new(points)
            .mode(EvalMode::PotentialGradient)
            .order(5)
            .leaf_size(32)
            .cache(ferrofmm_field::CacheSetting::Off)
            .build_svd()
            .unwrap()
    });
    holds_what_it_accounts_for(300_000, |points| {
        FmmBuilder::new(points)
            .mode(EvalMode::PotentialGradient)
            .order(5)
            .leaf_size(128)
            .cache(ferrofmm_field::CacheSetting::Off)
            .build_with::<ferrofmm_field::FftM2l<f64>>(ferrofmm_field::FftConfig)
            .unwrap()
    });
}
