//! Prints the chooser's best setting on each root of `ROOT_SCALES` for a
//! uniform cube of N points (potential + gradient, FFT, 1e-6):
//! `cargo run --release -p ferrofmm-fmm --example root_scan -- 1000000`.
use std::sync::Arc;

use ferrofmm_fmm::Geometry;
use ferrofmm_fmm::tuning::{LaplaceModel, M2lCostShape, Occupancy, ROOT_SCALES, Tuner};
use ferrofmm_kernels::{EvalMode, Precision};
use ferrofmm_tree::{DEEPEST_LEVEL, Domain};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1_000_000);
    let points: Vec<f64> = Geometry::Cube.points(n, 1);
    let tuner = Tuner::from_model(
        Arc::new(LaplaceModel),
        Precision::F64,
        EvalMode::PotentialGradient,
        M2lCostShape::Fft,
    );
    let tight = Domain::from_points(&[&points]).unwrap();
    for scale in ROOT_SCALES {
        let d = Domain::new(tight.origin, tight.width * scale).unwrap();
        let occ = Occupancy::new(&points, None, Some(d), DEEPEST_LEVEL).unwrap();
        for c in tuner.candidates(1e-6, &occ).unwrap() {
            println!(
                "scale {scale:.3} order {} leaf {:5} boxes {:8} p2p_pairs {:.3e} predicted {:.3} s (p2p {:.3} m2l {:.3} far {:.3} tree {:.3})",
                c.order,
                c.leaf_size,
                c.work.n_boxes,
                c.work.p2p_pairs as f64,
                c.predicted.total,
                c.predicted.p2p,
                c.predicted.m2l,
                c.predicted.far,
                c.predicted.tree
            );
        }
    }
}
