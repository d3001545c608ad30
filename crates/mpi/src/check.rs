//! The `check` and `bad` subcommands: the distributed tree against the
//! single-machine tree of the same points, and bad input on one rank.

use std::collections::BTreeSet;

use clap::Args;
use ferrofmm_mpi::{
    CHECK_GEOMETRIES, DistError, DistOptions, DistributedTree, Geometry, InputProblem,
};
use ferrofmm_tree::{MortonKey, Octree, TreeOptions};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Arguments of `check`.
#[derive(Args)]
pub struct CheckArgs {
    /// Geometries (comma-separated) or `all`.
    #[arg(long, default_value = "all")]
    geometry: String,
    /// Layouts of the points over the ranks (comma-separated) or `all`:
    /// even, first-empty, all-on-last, skewed, strided, duplicates,
    /// weighted (even, balanced by uneven per-point weights).
    #[arg(long, default_value = "all")]
    layout: String,
    /// Number of points (all ranks together).
    #[arg(long, default_value_t = 20_000)]
    n: usize,
    /// Leaf sizes (comma-separated).
    #[arg(long, default_value = "1,16,150")]
    leaf_size: String,
    /// Seed of the points.
    #[arg(long, default_value_t = 7)]
    seed: u64,
}

const LAYOUTS: [&str; 7] = [
    "even",
    "first-empty",
    "all-on-last",
    "skewed",
    "strided",
    "duplicates",
    "weighted",
];

/// The original indices of the points each rank holds under `layout`.
pub(crate) fn shares(layout: &str, n: usize, size: usize) -> Vec<Vec<usize>> {
    let contiguous = |w: &dyn Fn(usize) -> f64| -> Vec<Vec<usize>> {
        let total: f64 = (0..size).map(w).sum();
        let mut start = 0;
        let mut acc = 0.0;
        (0..size)
            .map(|r| {
                acc += w(r);
                let end = if r + 1 == size {
                    n
                } else {
                    (acc / total * n as f64) as usize
                };
                let s = (start..end).collect();
                start = end;
                s
            })
            .collect()
    };
    match layout {
        "first-empty" if size > 1 => contiguous(&|r| if r == 0 { 0.0 } else { 1.0 }),
        "all-on-last" => contiguous(&|r| if r + 1 == size { 1.0 } else { 0.0 }),
        "skewed" => contiguous(&|r| ((r + 1) * (r + 1)) as f64),
        "strided" => (0..size).map(|r| (r..n).step_by(size).collect()).collect(),
        _ => contiguous(&|_| 1.0),
    }
}

pub(crate) fn list(spec: &str, all: &[&str]) -> Vec<String> {
    if spec == "all" {
        all.iter().map(|s| s.to_string()).collect()
    } else {
        spec.split(',').map(str::to_string).collect()
    }
}

/// Compares one distributed build with the single-machine tree; returns
/// the failures seen on this rank.
fn compare(
    tree: &DistributedTree,
    single: &Octree,
    points: &[f64],
    order: &[usize],
    me: usize,
) -> Vec<String> {
    let mut bad = Vec::new();
    let (lo, hi) = (tree.cuts[me], tree.cuts[me + 1]);
    if tree.domain != *single.domain() {
        bad.push(format!("domain {:?} != {:?}", tree.domain, single.domain()));
    }
    // Points: in range, sorted, and the originals.
    let p = &tree.points;
    for i in 0..p.len() {
        let c = p.codes[i];
        if c < lo || c >= hi || (i > 0 && (p.codes[i - 1], p.ids[i - 1]) >= (c, p.ids[i])) {
            bad.push(format!("point {i}: code {c} out of range or order"));
            break;
        }
        let orig = order[p.ids[i] as usize];
        if p.coords[3 * i..3 * i + 3] != points[3 * orig..3 * orig + 3]
            || MortonKey::from_point(
                [points[3 * orig], points[3 * orig + 1], points[3 * orig + 2]],
                &tree.domain,
                ferrofmm_tree::DEEPEST_LEVEL,
            )
            .morton()
                != c
        {
            bad.push(format!("point {i} (id {}) is not the original", p.ids[i]));
            break;
        }
    }
    // Boxes: same keys, leaves and counts.
    for &(key, leaf, count) in &tree.boxes {
        match single.index_of(key) {
            None => bad.push(format!("box {key} not in the single-machine tree")),
            Some(b) => {
                if single.is_leaf(b) != leaf || single.source_range(b).len() != count {
                    bad.push(format!(
                        "box {key}: leaf {leaf} count {count}, single {} {}",
                        single.is_leaf(b),
                        single.source_range(b).len()
                    ));
                }
            }
        }
        if bad.len() > 5 {
            return bad;
        }
    }
    for &key in &tree.coarse {
        if single.index_of(key).is_none_or(|b| single.is_leaf(b)) {
            bad.push(format!(
                "coarse box {key} missing or a leaf in the single tree"
            ));
        }
    }
    // Lists of every own box, and the ghosts they need.
    let inside = |k: MortonKey| {
        let r = k.morton_range();
        lo <= r.start && r.end <= hi
    };
    let g = &tree.ghosts;
    let skel = |k: MortonKey| {
        g.skeleton
            .binary_search_by_key(&(k.level(), k), |s| (s.level(), *s))
    };
    let mut needed: BTreeSet<MortonKey> = BTreeSet::new();
    let single_lists = single.interaction_lists();
    for &(key, _, _) in &tree.boxes {
        let b = single.index_of(key).unwrap_or(0);
        let Ok(s) = skel(key) else {
            bad.push(format!("box {key} missing from the skeleton"));
            continue;
        };
        for (name, a, d) in [
            ("U", &single_lists.u, &g.lists.u),
            ("V", &single_lists.v, &g.lists.v),
            ("W", &single_lists.w, &g.lists.w),
            ("X", &single_lists.x, &g.lists.x),
        ] {
            let want: BTreeSet<MortonKey> = a.get(b).iter().map(|&i| single.key(i)).collect();
            let got: BTreeSet<MortonKey> = d.get(s).iter().map(|&i| g.skeleton[i]).collect();
            if want != got {
                let extra: Vec<String> = got.difference(&want).map(|k| format!("{k}")).collect();
                let missing: Vec<String> = want.difference(&got).map(|k| format!("{k}")).collect();
                bad.push(format!(
                    "{name} list of {key}: {} entries, single {} (extra {extra:?}, missing {missing:?})",
                    got.len(),
                    want.len()
                ));
            }
            needed.extend(want.into_iter().filter(|&k| !inside(k)));
        }
        if bad.len() > 5 {
            return bad;
        }
    }
    let ghosts: BTreeSet<MortonKey> = g.ghosts.iter().map(|x| x.key).collect();
    if ghosts != needed {
        bad.push(format!(
            "ghosts: {} boxes, the single tree's lists need {} ({} missing, {} extra)",
            ghosts.len(),
            needed.len(),
            needed.difference(&ghosts).count(),
            ghosts.difference(&needed).count()
        ));
    }
    for gh in &g.ghosts {
        if let Some(b) = single.index_of(gh.key)
            && !tree.coarse.contains(&gh.key)
            && single.is_leaf(b) != gh.leaf
        {
            bad.push(format!("ghost {} leaf flag {}", gh.key, gh.leaf));
            break;
        }
    }
    bad
}

/// Runs `check`; returns the exit status (0: every comparison passed).
pub fn run(world: &SimpleCommunicator, a: &CheckArgs) -> i32 {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let geoms: Vec<String> = list(&a.geometry, &CHECK_GEOMETRIES.map(Geometry::name));
    let layouts = list(&a.layout, &LAYOUTS);
    let mut failures = 0u32;
    for gname in &geoms {
        let Some(geom) = Geometry::from_name(gname) else {
            eprintln!("unknown geometry {gname}");
            return 2;
        };
        for layout in &layouts {
            let mut points = geom.points::<f64>(a.n, a.seed);
            if layout == "duplicates" {
                // Every point four times (whole leaves of one cell).
                let base = points[..3 * (a.n / 4).max(1).min(a.n)].to_vec();
                points = base.repeat(4);
            }
            let n = points.len() / 3;
            let share = shares(layout, n, size);
            let order: Vec<usize> = share.concat();
            let mine: Vec<f64> = share[me]
                .iter()
                .flat_map(|&i| points[3 * i..3 * i + 3].to_vec())
                .collect();
            for leaf in a
                .leaf_size
                .split(',')
                .filter_map(|s| s.parse::<usize>().ok())
            {
                let single = Octree::new(&points, None, &TreeOptions::adaptive(leaf))
                    .expect("valid test points");
                let weights: Option<Vec<f64>> = (layout == "weighted")
                    .then(|| share[me].iter().map(|&i| 1.0 + (i % 7) as f64).collect());
                let built = DistributedTree::build_weighted(
                    world,
                    &mine,
                    weights.as_deref(),
                    &DistOptions::adaptive(leaf),
                );
                let local_bad = match built {
                    Ok(tree) => {
                        let mut bad = compare(&tree, &single, &points, &order, me);
                        // Every point on exactly one rank, every box once.
                        let sums = [
                            tree.points.len() as u64,
                            tree.boxes.len() as u64,
                            tree.leaves().count() as u64,
                        ];
                        let mut tot = [0u64; 3];
                        world.all_reduce_into(&sums[..], &mut tot[..], SystemOperation::sum());
                        let want = [
                            n as u64,
                            (single.n_boxes() - tree.coarse.len()) as u64,
                            single.leaves().len() as u64,
                        ];
                        if tot != want {
                            bad.push(format!(
                                "totals (points, boxes, leaves) {tot:?}, want {want:?}"
                            ));
                        }
                        let ids: BTreeSet<u64> = tree.points.ids.iter().copied().collect();
                        if ids.len() != tree.points.len() {
                            bad.push("a point twice on one rank".into());
                        }
                        if me == 0 {
                            let mut counts = vec![0u64; size];
                            world.all_gather_into(&(tree.points.len() as u64), &mut counts[..]);
                            let imb = *counts.iter().max().unwrap() as f64 * size as f64 / n as f64;
                            println!(
                                "{gname} {layout} n={n} leaf={leaf} R={size}: boxes {}, imbalance {imb:.3}, balance rounds {}, ghosts on rank 0 {}",
                                single.n_boxes(),
                                tree.stats.balance_rounds,
                                tree.ghosts.ghosts.len()
                            );
                        } else {
                            let mut counts = vec![0u64; size];
                            world.all_gather_into(&(tree.points.len() as u64), &mut counts[..]);
                        }
                        bad
                    }
                    Err(e) => vec![format!("build failed: {e}")],
                };
                for b in &local_bad {
                    println!("FAIL rank {me} {gname} {layout} leaf={leaf}: {b}");
                }
                failures += local_bad.len() as u32;
            }
        }
    }
    let mut all = 0u32;
    world.all_reduce_into(&failures, &mut all, SystemOperation::sum());
    if me == 0 {
        println!(
            "{}",
            if all == 0 {
                "CHECK PASSED"
            } else {
                "CHECK FAILED"
            }
        );
    }
    i32::from(all != 0)
}

/// Arguments of `bad`.
#[derive(Args)]
pub struct BadArgs {
    /// nan, length, empty (no points anywhere), leaf0 (zero leaf size on
    /// the last rank), options (a different leaf size on the last rank),
    /// infinite, weights (one weight too few on the last rank).
    #[arg(long)]
    case: String,
}

/// Runs `bad`: the last rank gets bad input; returns 0 if every rank got
/// the expected error and all agree.
pub fn run_bad(world: &SimpleCommunicator, a: &BadArgs) -> i32 {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let last = me + 1 == size;
    let mut points = Geometry::Cube.points::<f64>(1000, 3 + me as u64);
    let mut leaf = 16;
    // Every case but `empty` is the last rank's input, reported by all.
    let last_rank = |problem| DistError::BadInput {
        rank: size as i32 - 1,
        problem,
    };
    let expected = match a.case.as_str() {
        "nan" | "infinite" => {
            if last {
                let (i, x) = match a.case.as_str() {
                    "nan" => (7, f64::NAN),
                    _ => (5, f64::INFINITY),
                };
                points[i] = x;
            }
            last_rank(InputProblem::NonFinite)
        }
        "length" => {
            if last {
                points.pop();
            }
            last_rank(InputProblem::BadLength)
        }
        "empty" => {
            points.clear();
            DistError::NoPoints
        }
        "leaf0" => {
            if last {
                leaf = 0;
            }
            last_rank(InputProblem::ZeroLeafSize)
        }
        "options" => {
            if last && size > 1 {
                leaf = 17;
            }
            if size > 1 {
                last_rank(InputProblem::MismatchedOptions)
            } else {
                println!("ERROR AGREED (nothing to mismatch on one rank)");
                return 0;
            }
        }
        "weights" => last_rank(InputProblem::BadWeights),
        other => {
            eprintln!("unknown case {other}");
            return 2;
        }
    };
    let weights = (a.case == "weights").then(|| vec![1.0; points.len() / 3 - usize::from(last)]);
    let ok = match DistributedTree::build_weighted(
        world,
        &points,
        weights.as_deref(),
        &DistOptions::adaptive(leaf),
    ) {
        Ok(_) => {
            println!("rank {me}: no error");
            false
        }
        Err(e) => {
            println!("rank {me}: {e}");
            e == expected
        }
    };
    let mut all = 0u8;
    world.all_reduce_into(&u8::from(!ok), &mut all, SystemOperation::max());
    if me == 0 {
        println!(
            "{}",
            if all == 0 {
                "ERROR AGREED"
            } else {
                "ERROR NOT AGREED"
            }
        );
    }
    i32::from(all != 0)
}
