//! The `tree` subcommand: build, then print per-rank figures.

use clap::Args;
use ferrofmm_mpi::{DistOptions, DistributedTree, Geometry, PHASES};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Arguments of `tree`.
#[derive(Args)]
pub struct TreeArgs {
    /// Points file: whitespace-separated `x y z` per line, or raw
    /// little-endian f64 triples if the name ends in `.f64`. Rank `r` of
    /// `R` takes the points `r n / R .. (r + 1) n / R`.
    #[arg(long, conflicts_with = "generate")]
    points: Option<std::path::PathBuf>,
    /// Generate points instead: uniform, sphere, plummer, two-clusters
    /// (each rank generates `n / R` with its own seed).
    #[arg(long)]
    generate: Option<String>,
    /// Number of points to generate (all ranks together).
    #[arg(long, default_value_t = 1_000_000)]
    n: usize,
    /// Maximum points per leaf.
    #[arg(long, default_value_t = 64)]
    leaf_size: usize,
    /// Balance by `points` (default) or by `work`: build once, estimate
    /// each point's work from the interaction lists, build again balanced
    /// by it (both builds are reported).
    #[arg(long, default_value = "points")]
    weights: String,
    /// For `--weights work`: cost of one V, W or X entry in pair
    /// interactions.
    #[arg(long, default_value_t = 100.0)]
    far_cost: f64,
    /// Print one JSON line per rank instead of the table.
    #[arg(long)]
    json: bool,
}

fn read_points(path: &std::path::Path) -> Result<Vec<f64>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if path.extension().is_some_and(|e| e == "f64") {
        if bytes.len() % 8 != 0 {
            return Err(format!("{}: not a whole number of f64", path.display()));
        }
        return Ok(bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect());
    }
    let text = String::from_utf8(bytes).map_err(|e| e.to_string())?;
    text.split_whitespace()
        .map(|t| t.parse::<f64>().map_err(|e| format!("{t:?}: {e}")))
        .collect()
}

/// Runs `tree`; returns the exit status.
pub fn run(world: &SimpleCommunicator, a: &TreeArgs) -> i32 {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let points = match (&a.points, &a.generate) {
        (Some(path), _) => match read_points(path) {
            Ok(all) => {
                let n = all.len() / 3;
                let (s, e) = (me * n / size, (me + 1) * n / size);
                // A length that is not a multiple of 3 goes to the last rank.
                let end = if me + 1 == size { all.len() } else { 3 * e };
                all[3 * s..end].to_vec()
            }
            Err(e) => {
                eprintln!("rank {me}: {e}");
                vec![f64::NAN; 3]
            }
        },
        (None, Some(g)) => match Geometry::from_name(g) {
            Some(g) => {
                let n = (me + 1) * a.n / size - me * a.n / size;
                g.points::<f64>(n, 1000 + me as u64)
            }
            None => {
                eprintln!("unknown geometry {g}");
                return 2;
            }
        },
        (None, None) => {
            eprintln!("give --points FILE or --generate GEOMETRY");
            return 2;
        }
    };
    world.barrier();
    let t = std::time::Instant::now();
    let options = DistOptions::adaptive(a.leaf_size);
    let mut tree = match DistributedTree::build(world, &points, &options) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("rank {me}: {e}");
            return 1;
        }
    };
    if a.weights == "work" {
        let w = tree.work_weights(a.far_cost);
        let before: f64 = w.iter().sum();
        let coords = std::mem::take(&mut tree.points.coords);
        tree = match DistributedTree::build_weighted(world, &coords, Some(&w), &options) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("rank {me}: {e}");
                return 1;
            }
        };
        let after: f64 = tree.points.weights.iter().sum();
        let (mut all_b, mut all_a) = (vec![0.0f64; size], vec![0.0f64; size]);
        world.all_gather_into(&before, &mut all_b[..]);
        world.all_gather_into(&after, &mut all_a[..]);
        if me == 0 {
            let imb = |v: &[f64]| {
                v.iter().cloned().fold(0.0, f64::max) * size as f64 / v.iter().sum::<f64>()
            };
            println!(
                "work estimate: imbalance (max/mean) {:.4} balanced by points, {:.4} balanced by work",
                imb(&all_b),
                imb(&all_a)
            );
        }
    }
    world.barrier();
    let total = t.elapsed().as_secs_f64();
    let n = tree.points.len() as u64;
    let mut counts = vec![0u64; size];
    world.all_gather_into(&n, &mut counts[..]);
    let sum: u64 = counts.iter().sum();
    let imbalance = *counts.iter().max().unwrap() as f64 / (sum as f64 / size as f64);
    let s = &tree.stats;
    let leaves = tree.leaves().count();
    let line = if a.json {
        format!(
            "{{\"rank\":{me},\"ranks\":{size},\"n_total\":{sum},\"points\":{n},\"boxes\":{},\"leaves\":{leaves},\"coarse\":{},\"ghosts\":{},\"ghost_candidates\":{},\"partners\":{},\"balance_rounds\":{},\"imbalance\":{imbalance:.4},\"seconds\":{:?},\"bytes_sent\":{:?},\"total_seconds\":{total:.4}}}",
            tree.boxes.len(),
            tree.coarse.len(),
            tree.ghosts.ghosts.len(),
            tree.ghosts.received,
            tree.ghosts.partners.len(),
            s.balance_rounds,
            s.seconds.map(|x| (x * 1e4).round() / 1e4),
            s.bytes_sent
        )
    } else {
        let phases: Vec<String> = PHASES
            .iter()
            .zip(s.seconds.iter().zip(&s.bytes_sent))
            .map(|(p, (t, b))| format!("{p} {t:.3}s {b}B"))
            .collect();
        format!(
            "rank {me}/{size}: points {n} ({:.3} of mean), boxes {}, leaves {leaves}, coarse {}, ghosts {} (received {}, from {} ranks), balance rounds {}, bytes sent {}; {}",
            n as f64 / (sum as f64 / size as f64),
            tree.boxes.len(),
            tree.coarse.len(),
            tree.ghosts.ghosts.len(),
            tree.ghosts.received,
            tree.ghosts.partners.len(),
            s.balance_rounds,
            s.bytes_sent.iter().sum::<u64>(),
            phases.join(", ")
        )
    };
    // Print in rank order.
    for r in 0..size {
        if r == me {
            println!("{line}");
        }
        world.barrier();
    }
    if me == 0 && !a.json {
        println!(
            "total {sum} points on {size} ranks, imbalance (max/mean) {imbalance:.4}, build {total:.3}s"
        );
    }
    0
}
