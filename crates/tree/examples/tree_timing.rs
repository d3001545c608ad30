//! Times tree construction (sort + refine + balance + lists) on uniform
//! points in a cube and on a sphere surface, on clustered points and on
//! coincident points. Then, for each set, the share of the build's time
//! done at the end of each step (what `TreeBuildStep::done_share` models).
//!
//! `cargo run --release -p ferrofmm-tree --example tree_timing [n] [leaf_size]`

use std::time::Instant;

use std::sync::Mutex;

use ferrofmm_tree::{Octree, TreeBuildStep, TreeOptions};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn cube(n: usize, rng: &mut StdRng) -> Vec<f64> {
    (0..3 * n).map(|_| rng.random::<f64>()).collect()
}

fn sphere(n: usize, rng: &mut StdRng) -> Vec<f64> {
    let mut out = Vec::with_capacity(3 * n);
    while out.len() < 3 * n {
        let p: [f64; 3] = std::array::from_fn(|_| 2.0 * rng.random::<f64>() - 1.0);
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if r > 1e-3 && r <= 1.0 {
            out.extend(p.map(|x| x / r));
        }
    }
    out
}

/// 20 clusters of relative size 1e-1 .. 1e-5 (log-uniform), plus 1%
/// uniform background: a deep, very non-uniform tree.
fn clusters(n: usize, rng: &mut StdRng) -> Vec<f64> {
    let specs: Vec<([f64; 3], f64)> = (0..20)
        .map(|_| {
            let c = [
                rng.random::<f64>(),
                rng.random::<f64>(),
                rng.random::<f64>(),
            ];
            (c, 10f64.powf(-rng.random_range(1.0..5.0)))
        })
        .collect();
    let mut out = Vec::with_capacity(3 * n);
    for i in 0..n {
        if i % 100 == 0 {
            out.extend((0..3).map(|_| rng.random::<f64>()));
        } else {
            let (c, s) = specs[rng.random_range(0..specs.len())];
            out.extend(c.map(|x| x + s * (rng.random::<f64>() - 0.5)));
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(1_000_000, |s| s.parse().expect("n"));
    let leaf_size: usize = args.get(2).map_or(150, |s| s.parse().expect("leaf size"));
    let mut rng = StdRng::seed_from_u64(42);
    let opts = TreeOptions::adaptive(leaf_size);
    let sets = [
        ("uniform_cube", cube(n, &mut rng)),
        ("sphere_surface", sphere(n, &mut rng)),
        ("clusters", clusters(n, &mut rng)),
        ("coincident", [0.5, 0.25, 0.125].repeat(n)),
    ];
    for (name, pts) in sets {
        let mut best = f64::INFINITY;
        let mut tree = None;
        for _ in 0..5 {
            let t = Instant::now();
            let built = Octree::new(&pts, None, &opts).expect("tree");
            best = best.min(t.elapsed().as_secs_f64());
            tree = Some(built);
        }
        let tree = tree.expect("built");
        let t = Instant::now();
        let ends = Mutex::new(Vec::new());
        Octree::new_reporting(&pts, None, &opts, &|s| {
            ends.lock().unwrap().push((s, t.elapsed().as_secs_f64()))
        })
        .expect("tree");
        let ends = ends.into_inner().unwrap();
        let total = ends.last().map_or(1.0, |e| e.1);
        let shares: Vec<String> = ends
            .iter()
            .map(|(s, e)| format!("{s:?} {:.2} (model {:.2})", e / total, s.done_share()))
            .collect();
        println!("{name:>15} step shares: {}", shares.join(", "));
        assert_eq!(ends.len(), TreeBuildStep::ALL.len());
        let l = tree.interaction_lists();
        println!(
            "{name:>15} n={n} leaf={leaf_size}: {:.1} ms (best of 5) | depth {} boxes {} leaves {} | max U {} V {} W {} X {} | entries U {} V {} W {} X {}",
            best * 1e3,
            tree.depth(),
            tree.n_boxes(),
            tree.leaves().len(),
            l.u.max_row_len(),
            l.v.max_row_len(),
            l.w.max_row_len(),
            l.x.max_row_len(),
            l.u.n_entries(),
            l.v.n_entries(),
            l.w.n_entries(),
            l.x.n_entries(),
        );
    }
}
