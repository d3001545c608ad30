//! The distributed FMM with separate targets, under `mpirun` with 1 to 4
//! ranks (`--oversubscribe`: CI machines have 2 cores).
//!
//! This file is its own MPI program (`harness = false`): run by `cargo
//! test`, it launches itself under `mpirun` for each rank count, with
//! `FERROFMM_TARGETS_WORKER` set; each worker rank then builds
//! `DistributedTree::build_with_targets` and `DistributedFmm` on its share
//! of the sources and of the targets and compares with the single-machine
//! `Fmm` with the same sources, targets, domain, order, leaf size and
//! scheme:
//!
//! * the tree: every rank's boxes plus the coarse tree are the boxes of
//!   `Octree::new(sources, Some(targets))`, with the same U, V, W and X
//!   rows (as key sets) for every box of the rank;
//! * the values at every target, in each rank's input order of targets
//!   (and once in tree order), to 1e-12 relative (L2 over all targets);
//! * layouts: sources and targets spread evenly, all sources on the first
//!   rank (the others have none), all targets on the last rank, both (the
//!   middle ranks have neither), targets outside the sources' cube,
//!   targets in a tight cluster;
//! * Laplace (SVD M2L) and Stokes (FFT M2L; forces, a vector kernel);
//! * bad targets on the last rank (a NaN, a bad length) and no target at
//!   all: the same error on every rank.

use std::process::Command;

use ferrofmm_field::{FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::FmmBuilder;
use ferrofmm_kernels::{EvalMode, Kernel, Laplace3d, SourceKind, Stokes3d};
use ferrofmm_mpi::{
    DistError, DistFmmOptions, DistOptions, DistributedFmm, DistributedTree, Geometry, InputProblem,
};
use ferrofmm_tree::{MortonKey, Octree, TreeOptions};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

const WORKER: &str = "FERROFMM_TARGETS_WORKER";
const PASSED: &str = "TARGETS CHECK PASSED";
const ORDER: usize = 4;
const LEAF: usize = 12;
const TOLERANCE: f64 = 1e-12;

fn main() {
    if std::env::var_os(WORKER).is_some() {
        std::process::exit(worker());
    }
    let exe = std::env::current_exe().expect("the test's own path");
    let mpirun = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let mut failed = Vec::new();
    for ranks in 1..=4 {
        let out = Command::new("timeout")
            .arg("300")
            .arg(&mpirun)
            .arg("--oversubscribe")
            .arg("-n")
            .arg(ranks.to_string())
            .arg(&exe)
            .env(WORKER, "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .env("RAYON_NUM_THREADS", "1")
            .env("FERROFMM_CACHE", "off")
            .output()
            .unwrap_or_else(|e| panic!("cannot run `timeout {mpirun}` (install openmpi-bin): {e}"));
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        println!("--- {ranks} rank(s)\n{text}");
        if !(out.status.success() && text.contains(PASSED)) {
            failed.push(ranks);
        }
    }
    if !failed.is_empty() {
        eprintln!("separate targets: failed on {failed:?} rank(s)");
        std::process::exit(1);
    }
    println!("test distributed_fmm_with_separate_targets ... ok");
}

/// One MPI rank: every case; prints [`PASSED`] on rank 0 when all pass.
fn worker() -> i32 {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let me = world.rank();
    let cube = |n, seed| Geometry::Cube.points::<f64>(n, seed);
    let moved = |p: Vec<f64>, scale: f64, shift: [f64; 3]| -> Vec<f64> {
        p.chunks_exact(3)
            .flat_map(|x| [0, 1, 2].map(|a| scale * x[a] + shift[a]))
            .collect()
    };
    let sources = cube(2000, 1);
    let cases: Vec<(&str, Vec<f64>, &str, &str)> = vec![
        ("even", cube(1500, 2), "even", "even"),
        ("no sources off rank 0", cube(1500, 3), "first", "even"),
        (
            "no targets off the last rank",
            cube(1500, 4),
            "even",
            "last",
        ),
        ("neither on the middle ranks", cube(800, 7), "first", "last"),
        (
            "targets outside the sources' cube",
            moved(cube(1200, 5), 0.6, [1.3, -0.2, 0.5]),
            "strided",
            "even",
        ),
        (
            "clustered targets",
            moved(Geometry::Plummer.points::<f64>(1500, 6), 0.3, [0.5; 3]),
            "even",
            "strided",
        ),
    ];
    let mut failures = 0;
    for (name, targets, src_layout, tgt_layout) in &cases {
        let methods: &[&str] = if *name == "even" || name.starts_with("clustered") {
            &["laplace-svd", "stokes-fft"]
        } else {
            &["laplace-svd"]
        };
        for method in methods {
            let r = case(&world, &sources, targets, src_layout, tgt_layout, method);
            let ok = matches!(r, Ok(d) if d <= TOLERANCE);
            failures += usize::from(!ok);
            if me == 0 {
                let status = if ok { "ok  " } else { "FAIL" };
                println!("{status} {name} ({src_layout}/{tgt_layout}) {method}: {r:?}");
            }
        }
    }
    failures += bad_targets(&world, &sources);
    if me == 0 && failures == 0 {
        println!("{PASSED}");
    }
    i32::from(failures != 0)
}

/// The indices of `n` items this rank holds: `even` (contiguous blocks),
/// `first` / `last` (all on one rank), `strided` (round robin).
fn share(layout: &str, n: usize, size: usize, rank: usize) -> Vec<usize> {
    match layout {
        "first" => (0..n).filter(|_| rank == 0).collect(),
        "last" => (0..n).filter(|_| rank + 1 == size).collect(),
        "strided" => (rank..n).step_by(size).collect(),
        _ => (n * rank / size..n * (rank + 1) / size).collect(),
    }
}

/// The items `ids` of `v`, `k` values each.
fn pick(v: &[f64], ids: &[usize], k: usize) -> Vec<f64> {
    ids.iter()
        .flat_map(|&i| v[k * i..k * (i + 1)].iter().copied())
        .collect()
}

/// One kernel and scheme: the worst relative difference, or why it failed.
fn case(
    world: &SimpleCommunicator,
    sources: &[f64],
    targets: &[f64],
    src_layout: &str,
    tgt_layout: &str,
    method: &str,
) -> Result<f64, String> {
    match method {
        "laplace-svd" => {
            compare::<_, SvdM2l<f64>>(world, sources, targets, src_layout, tgt_layout, Laplace3d)
        }
        "stokes-fft" => compare::<_, FftM2l<f64>>(
            world,
            sources,
            targets,
            src_layout,
            tgt_layout,
            Stokes3d::default(),
        ),
        other => Err(format!("unknown method {other}")),
    }
}

fn compare<K: Kernel + Clone, S: M2lScheme<f64>>(
    world: &SimpleCommunicator,
    sources: &[f64],
    targets: &[f64],
    src_layout: &str,
    tgt_layout: &str,
    kernel: K,
) -> Result<f64, String> {
    let (size, rank) = (world.size() as usize, world.rank() as usize);
    let (ns, nt) = (sources.len() / 3, targets.len() / 3);
    let my_src = share(src_layout, ns, size, rank);
    let my_tgt = share(tgt_layout, nt, size, rank);
    let dtree = DistributedTree::build_with_targets(
        world,
        &pick(sources, &my_src, 3),
        &pick(targets, &my_tgt, 3),
        &DistOptions::adaptive(LEAF),
    )
    .map_err(|e| e.to_string())?;
    check_tree(world, &dtree, sources, targets)?;

    let mode = EvalMode::PotentialGradient;
    let options = DistFmmOptions::new(ORDER, mode);
    let config = S::Config::default();
    let dfmm = DistributedFmm::<f64, K, S>::build(world, &dtree, kernel.clone(), &config, &options)
        .map_err(|e| e.to_string())?;
    let single = FmmBuilder::new(sources)
        .targets(targets)
        .kernel(kernel.clone())
        .domain(dtree.domain)
        .leaf_size(LEAF)
        .order(ORDER)
        .mode(mode)
        .build_with::<S>(config)
        .map_err(|e| e.to_string())?;
    if single.n_clusters() != 1 {
        return Err("the single-machine FMM split the points".into());
    }
    let nq = kernel.values_per_source(SourceKind::Charge);
    let w = kernel.values_per_target(mode);
    let q = ferrofmm_fmm::charges::<f64>(nq * ns, 17);
    let want = single.evaluate(&q).map_err(|e| e.to_string())?;
    let (got, _) = dfmm
        .evaluate(world, &pick(&q, &my_src, nq))
        .map_err(|e| e.to_string())?;
    if got.len() != w * my_tgt.len() || dfmm.n_input_targets() != my_tgt.len() {
        return Err(format!("{} values for {} targets", got.len(), my_tgt.len()));
    }
    let mut worst = difference(world, &got, &pick(&want, &my_tgt, w));

    // Tree order: charges of `dtree.points`, values at `dtree.targets`.
    let src_order = global_order(src_layout, ns, size);
    let tgt_order = global_order(tgt_layout, nt, size);
    let tree_targets = &dtree
        .targets
        .as_ref()
        .ok_or("no targets in the tree")?
        .points;
    let q_sorted: Vec<f64> = dtree
        .points
        .ids
        .iter()
        .flat_map(|&id| {
            let i = src_order[id as usize];
            q[nq * i..nq * (i + 1)].to_vec()
        })
        .collect();
    let (got, _) = dfmm
        .evaluate_sorted(world, &q_sorted)
        .map_err(|e| e.to_string())?;
    let ids: Vec<usize> = tree_targets
        .ids
        .iter()
        .map(|&id| tgt_order[id as usize])
        .collect();
    if dfmm.n_targets() != ids.len() {
        return Err("n_targets differs from the tree's targets".into());
    }
    worst = worst.max(difference(world, &got, &pick(&want, &ids, w)));
    Ok(worst)
}

/// Global id -> index in the whole set: ids number the concatenation of
/// the ranks' shares.
fn global_order(layout: &str, n: usize, size: usize) -> Vec<usize> {
    (0..size).flat_map(|r| share(layout, n, size, r)).collect()
}

/// Relative L2 difference over all ranks.
fn difference(world: &SimpleCommunicator, got: &[f64], want: &[f64]) -> f64 {
    let mut s = [0.0f64; 2];
    for (g, x) in got.iter().zip(want) {
        s[0] += (g - x) * (g - x);
        s[1] += x * x;
    }
    if got.len() != want.len() {
        s[0] = f64::INFINITY;
    }
    let mut all = [0.0f64; 2];
    world.all_reduce_into(&s[..], &mut all[..], SystemOperation::sum());
    (all[0] / all[1].max(f64::MIN_POSITIVE)).sqrt()
}

/// The rank's boxes (and the coarse tree) are those of the single-machine
/// tree with targets, with the same lists.
fn check_tree(
    world: &SimpleCommunicator,
    dtree: &DistributedTree,
    sources: &[f64],
    targets: &[f64],
) -> Result<(), String> {
    let options = TreeOptions {
        domain: Some(dtree.domain),
        ..TreeOptions::adaptive(LEAF)
    };
    let tree = Octree::new(sources, Some(targets), &options).map_err(|e| e.to_string())?;
    let mut problems = Vec::new();
    for &(key, leaf, count) in &dtree.boxes {
        match tree.index_of(key) {
            Some(b) if tree.is_leaf(b) == leaf && tree.source_range(b).len() == count => {}
            _ => problems.push(format!("box {key} differs")),
        }
    }
    let g = &dtree.ghosts;
    let keys = |rows: &[usize], of: &dyn Fn(usize) -> MortonKey| {
        let mut k: Vec<MortonKey> = rows.iter().map(|&a| of(a)).collect();
        k.sort_unstable();
        k
    };
    for (s, &key) in g.skeleton.iter().enumerate() {
        let Some(b) = tree.index_of(key) else {
            continue;
        };
        if dtree.boxes.binary_search_by_key(&key, |x| x.0).is_err() {
            continue;
        }
        let whole = tree.interaction_lists();
        for (name, all, mine) in [
            ("U", &whole.u, &g.lists.u),
            ("V", &whole.v, &g.lists.v),
            ("W", &whole.w, &g.lists.w),
            ("X", &whole.x, &g.lists.x),
        ] {
            let want = keys(all.get(b), &|a| tree.key(a));
            let got = keys(mine.get(s), &|a| g.skeleton[a]);
            if want != got {
                let (g, w) = (got.len(), want.len());
                problems.push(format!(
                    "{name} row of {key} differs ({g} entries, {w} on one machine)"
                ));
            }
        }
    }
    let mine = dtree.boxes.len() as u64;
    let mut total = 0u64;
    world.all_reduce_into(&mine, &mut total, SystemOperation::sum());
    if total + dtree.coarse.len() as u64 != tree.n_boxes() as u64 {
        problems.push(format!(
            "{total} boxes + {} coarse != {}",
            dtree.coarse.len(),
            tree.n_boxes()
        ));
    }
    match problems.first() {
        None => Ok(()),
        Some(p) => Err(format!("rank {}: {p}", world.rank())),
    }
}

/// Bad targets on the last rank, and no target anywhere: the same error on
/// every rank. Returns the number of failures.
fn bad_targets(world: &SimpleCommunicator, sources: &[f64]) -> usize {
    let (size, rank) = (world.size() as usize, world.rank() as usize);
    let last = rank + 1 == size;
    let mine = pick(sources, &share("even", sources.len() / 3, size, rank), 3);
    let good = vec![0.5, 0.5, 0.5, 0.1, 0.9, 0.3];
    let bad_input = |problem| DistError::BadInput {
        rank: size as i32 - 1,
        problem,
    };
    let cases: Vec<(&str, Vec<f64>, DistError)> = vec![
        (
            "NaN target",
            if last {
                vec![0.5, f64::NAN, 0.5]
            } else {
                good.clone()
            },
            bad_input(InputProblem::NonFiniteTarget),
        ),
        (
            "target length",
            if last { vec![0.5, 0.5] } else { good.clone() },
            bad_input(InputProblem::BadTargetLength),
        ),
        ("no targets", Vec::new(), DistError::NoTargets),
    ];
    let mut failures = 0;
    for (name, targets, want) in cases {
        let got = DistributedTree::build_with_targets(
            world,
            &mine,
            &targets,
            &DistOptions::adaptive(LEAF),
        )
        .err();
        let ok = got.as_ref() == Some(&want);
        let mut bad = 0u32;
        world.all_reduce_into(&u32::from(!ok), &mut bad, SystemOperation::sum());
        failures += usize::from(bad != 0);
        if !ok {
            eprintln!("rank {rank}: {name}: {got:?}, expected {want:?}");
        }
        if rank == 0 {
            println!("{} {name}", if bad == 0 { "ok  " } else { "FAIL" });
        }
    }
    failures
}
