//! Times periodic trees against a free-space tree of the same points in
//! the same cell: full build (sort + refine + balance + lists) and the
//! build without balance and lists, whose difference is the cost of the
//! balance and the lists.
//!
//! `cargo run --release -p ferrofmm-tree --example periodic_timing [n] [leaf_size] [reps]`

use std::time::Instant;

use ferrofmm_tree::{Domain, Octree, TreeOptions};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn best_of(reps: usize, pts: &[f64], opts: &TreeOptions) -> (f64, Octree) {
    let mut best = f64::INFINITY;
    let mut tree = None;
    for _ in 0..reps {
        let t = Instant::now();
        let built = Octree::new(pts, None, opts).expect("tree");
        best = best.min(t.elapsed().as_secs_f64());
        tree = Some(built);
    }
    (best, tree.expect("built"))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(1_000_000, |s| s.parse().expect("n"));
    let leaf_size: usize = args.get(2).map_or(400, |s| s.parse().expect("leaf size"));
    let reps: usize = args.get(3).map_or(9, |s| s.parse().expect("repetitions"));
    let mut rng = StdRng::seed_from_u64(42);
    let pts: Vec<f64> = (0..3 * n).map(|_| rng.random::<f64>()).collect();
    let cell = Domain::new([0.0; 3], 1.0).expect("cell");
    let base = TreeOptions::adaptive(leaf_size).with_domain(cell);
    for (name, axes) in [
        ("free", [false; 3]),
        ("xyz", [true; 3]),
        ("slab xy", [true, true, false]),
        ("rod x", [true, false, false]),
    ] {
        let opts = base.clone().with_periodic(axes);
        let bare_opts = opts.clone().with_balance(false);
        let (mut full, mut bare) = (f64::INFINITY, f64::INFINITY);
        let mut tree = None;
        // Alternate the two builds so that machine noise hits both alike.
        for _ in 0..reps {
            let (t, built) = best_of(1, &pts, &opts);
            full = full.min(t);
            tree = Some(built);
            bare = bare.min(best_of(1, &pts, &bare_opts).0);
        }
        let tree = tree.expect("built");
        let l = tree.interaction_lists();
        println!(
            "{name:>8} n={n} leaf={leaf_size}: build {:.1} ms, without balance+lists {:.1} ms, \
             balance+lists {:.1} ms | depth {} boxes {} leaves {} | entries U {} V {} W {} X {}",
            full * 1e3,
            bare * 1e3,
            (full - bare) * 1e3,
            tree.depth(),
            tree.n_boxes(),
            tree.leaves().len(),
            l.u.n_entries(),
            l.v.n_entries(),
            l.w.n_entries(),
            l.x.n_entries(),
        );
    }
}
