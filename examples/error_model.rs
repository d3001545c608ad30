//! The measurements behind the error model of `ferrofmm_fmm::tuning` and
//! the default SVD compression: relative L2 errors of the potential and of
//! the gradient for every order x M2L scheme x geometry x charge kind.
//!
//! ```text
//! cargo run --release --features sweeps --example error_model -- [N] [OPTIONS]
//! ```
//!
//! * `N`: points per geometry (default 20000).
//! * `kernel=laplace` (default) or `kernel=yukawa:K` (modified Helmholtz
//!   `e^{-K r} / (4 pi r)`; the geometries span about one unit).
//! * `geometries=cube,sphere,...` (default: all of `Geometry::ALL`),
//!   `charges=signed,positive` (default both), `orders=3,4,...` (default
//!   3..=12), `leaves=64` (leaf sizes), `precision=f64|f32`,
//!   `schemes=dense,svd,svd:1e-7,svd+0.6` (`svd` is the library's default
//!   tolerance, `svd:TAU` a given one, `svd+X` the tolerance
//!   `10^-(0.9 p + X)`; default `dense,svd`).
//!
//! One Markdown row per run: geometry, charges, order, leaf size, scheme,
//! SVD rank, potential and gradient errors on 997 evenly spaced targets
//! against direct summation in f64, and for `svd` rows the ratio to the
//! dense row of the same setting (`loss`). Operators are cached in
//! `target/error-model-cache`.

use std::time::Instant;

use ferrofmm::field::{SvdConfig, SvdM2l, default_svd_tolerance};
use ferrofmm::fmm::{Charges, Fmm, FmmBuilder, Geometry, relative_errors, sample_indices};
use ferrofmm::kernels::{EvalMode, Kernel, Laplace3d, ModifiedHelmholtz3d, Precision, Real};

const CACHE: &str = "target/error-model-cache";
const SAMPLE: usize = 997;

#[derive(Clone, Copy, Debug)]
enum Scheme {
    Dense,
    Svd(SvdTolerance),
}

/// The SVD tolerance of a run at order `p`.
#[derive(Clone, Copy, Debug)]
enum SvdTolerance {
    /// The library's default.
    Default,
    /// Given.
    Fixed(f64),
    /// `10^-(0.9 p + offset)`.
    Offset(f64),
}

impl SvdTolerance {
    fn at<T: Real>(self, p: usize) -> f64 {
        match self {
            SvdTolerance::Default => default_svd_tolerance(T::PRECISION, p),
            SvdTolerance::Fixed(tau) => tau,
            SvdTolerance::Offset(o) => 10f64.powf(-(0.9 * p as f64 + o)),
        }
    }
}

/// Values for every charge vector.
fn evaluate_all<T: Real, K: Kernel, S: ferrofmm::field::M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    charge_sets: &[(Charges, Vec<T>)],
) -> Vec<Vec<T>> {
    charge_sets
        .iter()
        .map(|(_, q)| fmm.evaluate(q).unwrap())
        .collect()
}

fn list<T: std::str::FromStr>(v: &str) -> Vec<T> {
    v.split(',').filter_map(|s| s.trim().parse().ok()).collect()
}

fn main() {
    let mut n = 20_000usize;
    let mut geometries = Geometry::ALL.to_vec();
    let mut kinds = Charges::ALL.to_vec();
    let mut orders: Vec<usize> = (3..=12).collect();
    let mut leaves = vec![64usize];
    let mut precision = Precision::F64;
    let mut schemes = vec![Scheme::Dense, Scheme::Svd(SvdTolerance::Default)];
    let mut yukawa: Option<f64> = None;
    for a in std::env::args().skip(1) {
        if let Some(v) = a.strip_prefix("kernel=") {
            yukawa = match v.strip_prefix("yukawa:").map(str::parse) {
                Some(Ok(k)) => Some(k),
                _ if v == "laplace" => None,
                _ => {
                    eprintln!("unknown kernel {v}");
                    std::process::exit(2);
                }
            };
        } else if let Some(v) = a.strip_prefix("geometries=") {
            geometries = v.split(',').filter_map(Geometry::from_name).collect();
        } else if let Some(v) = a.strip_prefix("charges=") {
            kinds = v.split(',').filter_map(Charges::from_name).collect();
        } else if let Some(v) = a.strip_prefix("orders=") {
            orders = list(v);
        } else if let Some(v) = a.strip_prefix("leaves=") {
            leaves = list(v);
        } else if let Some(v) = a.strip_prefix("precision=") {
            precision = if v == "f32" {
                Precision::F32
            } else {
                Precision::F64
            };
        } else if let Some(v) = a.strip_prefix("schemes=") {
            schemes = v
                .split(',')
                .filter_map(|s| match s {
                    "dense" => Some(Scheme::Dense),
                    "svd" => Some(Scheme::Svd(SvdTolerance::Default)),
                    _ => {
                        if let Some(o) = s.strip_prefix("svd+") {
                            o.parse().ok().map(|o| Scheme::Svd(SvdTolerance::Offset(o)))
                        } else {
                            let t = s.strip_prefix("svd:")?.parse().ok()?;
                            Some(Scheme::Svd(SvdTolerance::Fixed(t)))
                        }
                    }
                })
                .collect();
        } else if let Ok(v) = a.parse() {
            n = v;
        } else {
            eprintln!("unknown argument {a}");
            std::process::exit(2);
        }
    }
    println!(
        "N = {n}, {}, {}, potential + gradient, {SAMPLE} sampled targets\n",
        yukawa.map_or("laplace".to_string(), |k| format!("yukawa k = {k}")),
        precision.name()
    );
    println!(
        "| geometry | charges | p | leaf | scheme | rank | potential | gradient | loss pot | loss grad | s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for g in &geometries {
        let run = Run {
            geometry: *g,
            n,
            kinds: &kinds,
            orders: &orders,
            leaves: &leaves,
            schemes: &schemes,
        };
        match (precision, yukawa) {
            (Precision::F64, None) => run.measure::<f64, _>(Laplace3d),
            (Precision::F32, None) => run.measure::<f32, _>(Laplace3d),
            (Precision::F64, Some(k)) => run.measure::<f64, _>(yukawa_kernel(k)),
            (Precision::F32, Some(k)) => run.measure::<f32, _>(yukawa_kernel(k)),
        }
    }
}

fn yukawa_kernel(k: f64) -> ModifiedHelmholtz3d {
    ModifiedHelmholtz3d::new(k).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    })
}

/// One geometry's runs.
struct Run<'a> {
    geometry: Geometry,
    n: usize,
    kinds: &'a [Charges],
    orders: &'a [usize],
    leaves: &'a [usize],
    schemes: &'a [Scheme],
}

impl Run<'_> {
    fn measure<T: Real, K: Kernel + Clone>(&self, kernel: K) {
        let Run {
            geometry: g,
            n,
            kinds,
            orders,
            leaves,
            schemes,
        } = *self;
        let points: Vec<T> = g.points(n, 7);
        let charge_sets: Vec<(Charges, Vec<T>)> =
            kinds.iter().map(|&k| (k, k.generate(n, 11))).collect();
        let sample = sample_indices(n, SAMPLE);
        let mode = EvalMode::PotentialGradient;
        for &p in orders {
            for &leaf in leaves {
                let mut dense: Vec<Option<(f64, f64)>> = vec![None; charge_sets.len()];
                for &scheme in schemes {
                    let t = Instant::now();
                    let builder = FmmBuilder::new(&points)
                        .kernel(kernel.clone())
                        .order(p)
                        .leaf_size(leaf)
                        .mode(mode)
                        .cache_dir(CACHE);
                    let (results, rank, label) = match scheme {
                        Scheme::Dense => {
                            let Ok(fmm) = builder.build_dense().inspect_err(|e| eprintln!("{e}"))
                            else {
                                continue;
                            };
                            let r = evaluate_all(&fmm, &charge_sets);
                            (r, "-".to_string(), "dense".to_string())
                        }
                        Scheme::Svd(tolerance) => {
                            let tau = tolerance.at::<T>(p);
                            let config = SvdConfig {
                                rank: None,
                                tolerance: tau,
                            };
                            let built = builder.build_with::<SvdM2l<T>>(config);
                            let Ok(fmm) = built.inspect_err(|e| eprintln!("{e}")) else {
                                continue;
                            };
                            let r = evaluate_all(&fmm, &charge_sets);
                            let rank = fmm.m2l_scheme().rank().to_string();
                            (r, rank, format!("svd {tau:.0e}"))
                        }
                    };
                    let seconds = t.elapsed().as_secs_f64();
                    for (i, ((kind, q), values)) in charge_sets.iter().zip(&results).enumerate() {
                        let e =
                            relative_errors(&kernel, mode, &points, q, &points, values, &sample);
                        let grad = e.gradient.unwrap_or(f64::NAN);
                        let loss = match (scheme, dense[i]) {
                            (Scheme::Svd(_), Some((dp, dg))) => {
                                format!("{:.2} | {:.2}", e.potential / dp, grad / dg)
                            }
                            _ => "- | -".to_string(),
                        };
                        if let Scheme::Dense = scheme {
                            dense[i] = Some((e.potential, grad));
                        }
                        println!(
                            "| {} | {} | {p} | {leaf} | {label} | {rank} | {:.2e} | {grad:.2e} | {loss} | {seconds:.1} |",
                            g.name(),
                            kind.name(),
                            e.potential
                        );
                    }
                }
            }
        }
    }
}
