//! The `tree` subcommand: build, then print per-rank figures.

use clap::Args;
use ferrofmm_io::Contents;
use ferrofmm_mpi::{DistOptions, DistributedTree, Geometry, PHASES, agree_options, agree_text};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Arguments of `tree`.
#[derive(Args)]
pub struct TreeArgs {
    /// Points file, as `ferrofmm eval` reads it: .csv (x,y,z per line,
    /// commas or spaces, optional header, `#` comments), .npy (N x 3,
    /// float64 or float32) or raw .f64 (little-endian float64, x, y, z
    /// per point). Rank `r` of `R` takes the points
    /// `r n / R .. (r + 1) n / R` (of a C-order .npy or a .f64 file it
    /// reads only those).
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
    #[arg(long, default_value = "points", value_parser = ["points", "work"])]
    weights: String,
    /// For `--weights work`: cost of one V, W or X entry in pair
    /// interactions.
    #[arg(long, default_value_t = 100.0)]
    far_cost: f64,
    /// Print one JSON line per rank instead of the table.
    #[arg(long)]
    json: bool,
}

/// Every option of `tree`, as (name, value) pairs: the same on every rank
/// ([`agree_options`]).
fn shared_options(a: &TreeArgs) -> Vec<(&'static str, String)> {
    vec![
        (
            "--points",
            a.points
                .as_ref()
                .map_or_else(|| "(not given)".into(), |p| p.display().to_string()),
        ),
        (
            "--generate",
            a.generate.clone().unwrap_or_else(|| "(not given)".into()),
        ),
        ("--n", a.n.to_string()),
        ("--leaf-size", a.leaf_size.to_string()),
        ("--weights", a.weights.clone()),
        ("--far-cost", a.far_cost.to_string()),
        ("--json", a.json.to_string()),
    ]
}

/// This rank's points of `path`, the outcome agreed by every rank.
fn read_points(world: &SimpleCommunicator, path: &std::path::Path) -> Result<Vec<f64>, String> {
    let (me, size) = (world.rank() as usize, world.size() as usize);
    let reader = agree_text(world, crate::eval_io::reader(world))?;
    let local = crate::eval_io::read_slice(&reader, path, Contents::Points, me, size);
    agree_text(world, local).map(|(points, _, _)| points)
}

/// Runs `tree`; returns the exit status.
pub fn run(world: &SimpleCommunicator, a: &TreeArgs) -> i32 {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    // Errors are the same on every rank (agreed): rank 0 prints them.
    let fail = |e: String| {
        if me == 0 {
            eprintln!("error: {e}");
        }
        1
    };
    if let Err(e) = agree_options(world, &shared_options(a)) {
        return fail(e);
    }
    let points = match (&a.points, &a.generate) {
        (Some(path), _) => match read_points(world, path) {
            Ok(points) => points,
            Err(e) => return fail(e),
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
        Err(e) => return fail(e.to_string()),
    };
    if a.weights == "work" {
        let w = tree.work_weights(a.far_cost);
        let before: f64 = w.iter().sum();
        let coords = std::mem::take(&mut tree.points.coords);
        tree = match DistributedTree::build_weighted(world, &coords, Some(&w), &options) {
            Ok(t) => t,
            Err(e) => return fail(e.to_string()),
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
    let (boxes, coarse, ghosts) = (
        tree.boxes.len(),
        tree.coarse.len(),
        tree.ghosts.ghosts.len(),
    );
    let (received, partners, rounds) = (
        tree.ghosts.received,
        tree.ghosts.partners.len(),
        s.balance_rounds,
    );
    let line = if a.json {
        format!(
            "{{\"rank\":{me},\"ranks\":{size},\"n_total\":{sum},\"points\":{n},\"boxes\":{boxes},\"leaves\":{leaves},\"coarse\":{coarse},\"ghosts\":{ghosts},\"ghost_candidates\":{received},\"partners\":{partners},\"balance_rounds\":{rounds},\"imbalance\":{imbalance:.4},\"seconds\":{:?},\"bytes_sent\":{:?},\"total_seconds\":{total:.4}}}",
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
            "rank {me}/{size}: points {n} ({:.3} of mean), boxes {boxes}, leaves {leaves}, coarse {coarse}, ghosts {ghosts} (received {received}, from {partners} ranks), balance rounds {rounds}, bytes sent {}; {}",
            n as f64 / (sum as f64 / size as f64),
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
