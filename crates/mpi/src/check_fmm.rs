//! The `fmm-check` subcommand: the distributed FMM against the
//! single-machine FMM on the same tree and operators, for several
//! geometries, kernels, M2L schemes and layouts of the points over the
//! ranks; two charge vectors on one build; bad charges on one rank.

use clap::Args;
use ferrofmm_field::{DenseM2l, FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::FmmBuilder;
use ferrofmm_kernels::{
    EvalMode, Helmholtz3d, Kernel, Laplace3d, ModifiedHelmholtz3d, SourceKind, Stokes3d,
};
use ferrofmm_mpi::{
    CHECK_GEOMETRIES, DistError, DistFmmOptions, DistOptions, DistributedFmm, DistributedTree,
    Geometry, InputProblem,
};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::check::{list, shares};

/// Arguments of `fmm-check`.
#[derive(Args)]
pub struct FmmCheckArgs {
    /// Geometries (comma-separated) or `all`.
    #[arg(long, default_value = "all")]
    geometry: String,
    /// Kernel and scheme pairs (comma-separated) or `all`: laplace-svd,
    /// laplace-dense, laplace-fft, helmholtz-svd, helmholtz-fft (modified
    /// Helmholtz, k = 3), oscillatory-svd, oscillatory-fft (Helmholtz
    /// exp(ikr)/(4 pi r), k = 4: complex charges), stokes-svd, stokes-fft
    /// (forces), dipoles-svd (Laplace, charges and dipoles).
    #[arg(long, default_value = "all")]
    method: String,
    /// Layouts of the input points over the ranks (see `check`).
    #[arg(long, default_value = "even,first-empty")]
    layout: String,
    /// Number of points (all ranks together).
    #[arg(long, default_value_t = 3000)]
    n: usize,
    /// Leaf size (small, so that the coarse tree has V lists of its own).
    #[arg(long, default_value_t = 10)]
    leaf_size: usize,
    /// Expansion order.
    #[arg(long, default_value_t = 4)]
    order: usize,
    /// Largest relative L2 difference allowed (potential and gradient).
    #[arg(long, default_value_t = 1e-12)]
    tolerance: f64,
    /// Seed of the points and charges.
    #[arg(long, default_value_t = 11)]
    seed: u64,
    /// Operator cache folder for both FMMs of each case. Without it the
    /// distributed FMM computes its operators on every rank and the
    /// single-machine one uses the default cache (FERROFMM_CACHE, ...).
    /// The cases of one kind, scheme and order share their operators, so
    /// a folder computes them once per run instead of twice per case.
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<std::path::PathBuf>,
}

const METHODS: [&str; 10] = [
    "laplace-svd",
    "laplace-dense",
    "laplace-fft",
    "helmholtz-svd",
    "helmholtz-fft",
    "oscillatory-svd",
    "oscillatory-fft",
    "stokes-svd",
    "stokes-fft",
    "dipoles-svd",
];

/// Zero-mean densities, uniform in `[-0.5, 0.5)` (`ferrofmm_fmm::charges`),
/// `nq` per point.
fn charges(n: usize, nq: usize, seed: u64) -> Vec<f64> {
    ferrofmm_fmm::charges(nq * n, seed)
}

/// The densities of the points `ids`, `nq` each.
fn pick(q: &[f64], ids: &[usize], nq: usize) -> Vec<f64> {
    ids.iter()
        .flat_map(|&i| q[nq * i..nq * (i + 1)].iter().copied())
        .collect()
}

/// Relative L2 differences (potential, gradient) over all ranks, of
/// `got[i]` (`w` values per point, the first `c` the potential) against
/// `want[ids[i]]`.
fn differences(
    world: &SimpleCommunicator,
    got: &[f64],
    want: &[f64],
    ids: &[usize],
    w: usize,
    c: usize,
) -> [f64; 2] {
    let mut s = [0.0f64; 4];
    for (i, &id) in ids.iter().enumerate() {
        for j in 0..w {
            let (g, x) = (got[w * i + j], want[w * id + j]);
            let k = usize::from(j >= c);
            s[2 * k] += (g - x) * (g - x);
            s[2 * k + 1] += x * x;
        }
    }
    let mut all = [0.0f64; 4];
    world.all_reduce_into(&s[..], &mut all[..], SystemOperation::sum());
    [
        (all[0] / all[1].max(f64::MIN_POSITIVE)).sqrt(),
        (all[2] / all[3].max(f64::MIN_POSITIVE)).sqrt(),
    ]
}

/// One case: returns the worst difference over the evaluations, or why
/// it failed.
fn case<K: Kernel + Clone, S: M2lScheme<f64>>(
    world: &SimpleCommunicator,
    all: &[f64],
    layout: &str,
    a: &FmmCheckArgs,
    kernel: K,
    sources: SourceKind,
) -> Result<f64, String> {
    let config = S::Config::default();
    let n = all.len() / 3;
    let all_shares = shares(layout, n, world.size() as usize);
    let share = &all_shares[world.rank() as usize];
    let mine: Vec<f64> = share
        .iter()
        .flat_map(|&i| all[3 * i..3 * i + 3].to_vec())
        .collect();
    let dtree = DistributedTree::build(world, &mine, &DistOptions::adaptive(a.leaf_size))
        .map_err(|e| e.to_string())?;
    let options = DistFmmOptions {
        sources,
        cache_dir: a.cache_dir.clone(),
        ..DistFmmOptions::new(a.order, EvalMode::PotentialGradient)
    };
    let c = kernel.components();
    let nq = kernel.values_per_source(sources);
    let w = kernel.values_per_target(EvalMode::PotentialGradient);
    let dfmm = DistributedFmm::<f64, K, S>::build(world, &dtree, kernel.clone(), &config, &options)
        .map_err(|e| e.to_string())?;
    let mut single = FmmBuilder::new(all);
    if let Some(dir) = &a.cache_dir {
        single = single.cache_dir(dir.clone());
    }
    let single = single
        .kernel(kernel)
        .domain(dtree.domain)
        .leaf_size(a.leaf_size)
        .order(a.order)
        .mode(EvalMode::PotentialGradient)
        .source_kind(sources)
        .build_with::<S>(config)
        .map_err(|e| e.to_string())?;
    if single.n_clusters() != 1 {
        return Err("the single-machine FMM split the points".into());
    }
    let mut worst = 0.0f64;
    // Two charge vectors on one build, in input order; then one in tree order.
    for (k, seed) in [a.seed + 100, a.seed + 200].into_iter().enumerate() {
        let q = charges(n, nq, seed);
        let want = single.evaluate(&q).map_err(|e| e.to_string())?;
        let (got, _) = dfmm
            .evaluate(world, &pick(&q, share, nq))
            .map_err(|e| e.to_string())?;
        let d = differences(world, &got, &want, share, w, c);
        worst = worst.max(d[0]).max(d[1]);
        if k == 1 {
            // Tree order: global ids index the concatenation of the shares.
            let order: Vec<usize> = all_shares.concat();
            let ids: Vec<usize> = dtree
                .points
                .ids
                .iter()
                .map(|&id| order[id as usize])
                .collect();
            let (got, _) = dfmm
                .evaluate_sorted(world, &pick(&q, &ids, nq))
                .map_err(|e| e.to_string())?;
            let d = differences(world, &got, &want, &ids, w, c);
            worst = worst.max(d[0]).max(d[1]);
        }
    }
    Ok(worst)
}

/// One kernel-and-scheme pair of [`METHODS`].
fn run_method(
    world: &SimpleCommunicator,
    all: &[f64],
    layout: &str,
    a: &FmmCheckArgs,
    method: &str,
) -> Result<f64, String> {
    let yukawa = ModifiedHelmholtz3d::new(3.0).map_err(|e| e.to_string())?;
    let oscillatory = Helmholtz3d::new(4.0).map_err(|e| e.to_string())?;
    let stokes = Stokes3d::default();
    let charge = SourceKind::Charge;
    match method {
        "laplace-svd" => case::<_, SvdM2l<f64>>(world, all, layout, a, Laplace3d, charge),
        "laplace-dense" => case::<_, DenseM2l<f64>>(world, all, layout, a, Laplace3d, charge),
        "laplace-fft" => case::<_, FftM2l<f64>>(world, all, layout, a, Laplace3d, charge),
        "helmholtz-svd" => case::<_, SvdM2l<f64>>(world, all, layout, a, yukawa, charge),
        "helmholtz-fft" => case::<_, FftM2l<f64>>(world, all, layout, a, yukawa, charge),
        "oscillatory-svd" => case::<_, SvdM2l<f64>>(world, all, layout, a, oscillatory, charge),
        "oscillatory-fft" => case::<_, FftM2l<f64>>(world, all, layout, a, oscillatory, charge),
        "stokes-svd" => case::<_, SvdM2l<f64>>(world, all, layout, a, stokes, charge),
        "stokes-fft" => case::<_, FftM2l<f64>>(world, all, layout, a, stokes, charge),
        "dipoles-svd" => {
            case::<_, SvdM2l<f64>>(world, all, layout, a, Laplace3d, SourceKind::ChargeDipole)
        }
        other => Err(format!("unknown method {other}")),
    }
}

/// Runs every case; prints `FMM CHECK PASSED` (rank 0) when all agree.
pub fn run(world: &SimpleCommunicator, a: &FmmCheckArgs) -> i32 {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let geoms = list(&a.geometry, &CHECK_GEOMETRIES.map(Geometry::name));
    let methods = list(&a.method, &METHODS);
    let layouts = list(&a.layout, &["even", "first-empty"]);
    let mut failures = 0;
    for g in &geoms {
        let Some(geom) = Geometry::from_name(g) else {
            eprintln!("unknown geometry {g}");
            return 2;
        };
        let all = geom.points::<f64>(a.n, a.seed);
        for layout in &layouts {
            for m in &methods {
                let r = run_method(world, &all, layout, a, m);
                let ok = matches!(r, Ok(d) if d <= a.tolerance);
                failures += usize::from(!ok);
                if me == 0 {
                    println!(
                        "{} {g} {layout} {m} n={} R={size}: {r:?}",
                        if ok { "ok  " } else { "FAIL" },
                        a.n
                    );
                }
            }
        }
    }
    // Bad charges on the last rank: the same error everywhere.
    {
        let all = Geometry::Cube.points::<f64>(a.n, a.seed);
        let share = &shares("even", a.n, size)[me];
        let mine: Vec<f64> = share
            .iter()
            .flat_map(|&i| all[3 * i..3 * i + 3].to_vec())
            .collect();
        let bad = DistributedTree::build(world, &mine, &DistOptions::adaptive(a.leaf_size))
            .map_err(|e| e.to_string())
            .and_then(|t| {
                let f = DistributedFmm::<f64, _, SvdM2l<f64>>::build(
                    world,
                    &t,
                    Laplace3d,
                    &Default::default(),
                    &DistFmmOptions::new(a.order, EvalMode::Potential),
                )
                .map_err(|e| e.to_string())?;
                let mut q = vec![0.1; share.len()];
                if me + 1 == size {
                    q.push(1.0);
                }
                Ok(f.evaluate(world, &q).err())
            });
        let want = DistError::BadInput {
            rank: size as i32 - 1,
            problem: InputProblem::BadCharges,
        };
        let ok = matches!(&bad, Ok(Some(e)) if *e == want);
        let mut all_ok = 0u32;
        world.all_reduce_into(&u32::from(!ok), &mut all_ok, SystemOperation::sum());
        if all_ok != 0 {
            failures += 1;
            eprintln!("rank {me}: bad charges gave {bad:?}");
        }
    }
    if me == 0 {
        if failures == 0 {
            println!("FMM CHECK PASSED");
        } else {
            println!("FMM CHECK FAILED ({failures} cases)");
        }
    }
    i32::from(failures != 0)
}
