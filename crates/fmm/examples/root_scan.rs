//! Prints the chooser's candidates on each root of `ROOT_SCALES` for a
//! uniform cube of N points (potential + gradient, 1e-6, the FFT scheme or
//! `svd`), then the root `choose_root` takes under a memory limit (GiB,
//! optional, `-` for none):
//! `cargo run --release -p ferrofmm-fmm --example root_scan -- 100000000 12 svd`.
use std::sync::Arc;

use ferrofmm_field::n_surface_points;
use ferrofmm_fmm::tuning::{
    LaplaceModel, M2lCostShape, Occupancy, ROOT_SCALES, Tuner, box_budget, box_bytes, choose_root,
};
use ferrofmm_fmm::{Geometry, RunSize};
use ferrofmm_kernels::{EvalMode, Precision};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = args
        .first()
        .and_then(|a| a.parse().ok())
        .unwrap_or(1_000_000);
    let limit: Option<u64> = args
        .get(1)
        .and_then(|a| a.parse::<f64>().ok())
        .map(|g| (g * (1u64 << 30) as f64) as u64);
    let shape = match args.get(2).map(String::as_str) {
        Some("svd") => M2lCostShape::Compressed,
        _ => M2lCostShape::Fft,
    };
    let points: Vec<f64> = Geometry::Cube.points(n, 1);
    let tuner = Tuner::from_model(
        Arc::new(LaplaceModel),
        Precision::F64,
        EvalMode::PotentialGradient,
        shape,
    );
    let tight = Domain::from_points(&[&points]).unwrap();
    for scale in ROOT_SCALES {
        let d = Domain::new(tight.origin, tight.width * scale).unwrap();
        let occ = Occupancy::new(&points, None, Some(d), DEEPEST_LEVEL).unwrap();
        for c in tuner.candidates(1e-6, &occ).unwrap() {
            println!(
                "scale {scale:.3} order {} leaf {:5} boxes {:8} p2p_pairs {:.3e} box bytes {:.2} GiB predicted {:.3} s (p2p {:.3} m2l {:.3} far {:.3} tree {:.3})",
                c.order,
                c.leaf_size,
                c.work.n_boxes,
                c.work.p2p_pairs,
                box_bytes(&c.work, n_surface_points(c.order), Precision::F64) as f64
                    / (1u64 << 30) as f64,
                c.predicted.total,
                c.predicted.p2p,
                c.predicted.m2l,
                c.predicted.far,
                c.predicted.tree
            );
        }
    }
    let size = RunSize {
        n_sources: n,
        n_targets: None,
        values_per_source: 1,
        values_per_target: 4,
        n_vectors: 1,
    };
    let budget = box_budget::<f64>(limit, &size, shape == M2lCostShape::Fft);
    let fits = |c: &ferrofmm_fmm::tuning::ChosenParameters| {
        budget.is_none_or(|room| {
            let bytes = box_bytes(&c.estimated_work, n_surface_points(c.order), Precision::F64);
            bytes <= room
        })
    };
    let (c, root) = choose_root(&tuner, Some(1e-6), &points, None, DEEPEST_LEVEL, fits).unwrap();
    println!(
        "limit {:?} GiB, budget for boxes {:?} GiB: root {:.3}x ({}), order {}, leaf {}, {} boxes, predicted {:.3} s",
        limit.map(|l| l as f64 / (1u64 << 30) as f64),
        budget.map(|b| b as f64 / (1u64 << 30) as f64),
        c.root_scale,
        if root.is_some() {
            "wider"
        } else {
            "bounding cube"
        },
        c.order,
        c.leaf_size,
        c.estimated_work.n_boxes,
        c.predicted_seconds
    );
}
