//! Periodic Laplace (or Yukawa, or Stokes) runs against a converged Ewald
//! reference (issue 32): the figures behind docs/periodic.md, and the
//! files a peer (OpenMM) is run on.
//!
//! `cargo run --release --features sweeps --example periodic_bench -- N L DIR [k=K | stokes | sediment] [verify] [EPS...]`
//!
//! `k=K` runs the Yukawa kernel `e^{-K r} / (4 pi r)` against the screened
//! Ewald sum; `stokes` the Stokeslet (viscosity 1) with forces uniform in
//! `[-0.5, 0.5)^3` less their mean (zero sum), `sediment` with the force
//! `(0, 0, -1)` on every point (a sedimenting suspension), both against
//! Hasimoto's sum ([`ferrofmm_kernels::StokesEwaldSum`]; the written
//! `charges.f64` are then the forces, `reference.f64` the velocity and its
//! gradient, 12 values an ion); `verify` runs the library's verification
//! after each evaluation (raising the order when the choice fell short),
//! as the front ends do.
//!
//! Writes to `DIR`: `points.f64` (N x 3), `charges.f64` (N, +-1, neutral),
//! `sample.f64` (the indices of the sampled ions), `reference.f64` (at
//! each sampled ion `phi, dphi/dx, dphi/dy, dphi/dz` of the Ewald sum to
//! `1e-14`, kernel `1 / (4 pi r)`), all raw little-endian `f64`; then
//! prints one JSON line per tolerance: the chosen order and leaf size,
//! setup and evaluation seconds, the potential and gradient errors at the
//! sample (relative L2) and the energy `1/2 sum q phi`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use ferrofmm_fmm::{FmmBuilder, Geometry, Periodic, random_sample};
use ferrofmm_kernels::{
    EvalMode, EwaldOptions, EwaldSum, Kernel, Laplace3d, ModifiedHelmholtz3d, PeriodicCell,
    Stokes3d, StokesEwaldSum,
};

/// Ions whose reference values are computed.
const SAMPLE: usize = 1000;

fn write(path: PathBuf, values: &[f64]) {
    let mut f = std::fs::File::create(&path).expect("create output");
    for v in values {
        f.write_all(&v.to_le_bytes()).expect("write output");
    }
}

fn rel(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    (d / n).sqrt()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: periodic_bench N L DIR [EPS...]");
        std::process::exit(2);
    }
    let n: usize = args[1].parse().expect("N");
    let side: f64 = args[2].parse().expect("L");
    let dir = PathBuf::from(&args[3]);
    let mut rest: &[String] = &args[4..];
    let mut kappa = 0.0;
    let mut verify = false;
    // `Some(true)`: equal forces (sedimenting); `Some(false)`: zero sum.
    let mut stokes: Option<bool> = None;
    loop {
        match rest.first().map(String::as_str) {
            Some(a) if a.starts_with("k=") => kappa = a[2..].parse().expect("k=K"),
            Some("stokes") => stokes = Some(false),
            Some("sediment") => stokes = Some(true),
            Some("verify") => verify = true,
            _ => break,
        }
        rest = &rest[1..];
    }
    // `EPS` asks for a tolerance, `pORDER` for an order (the leaf size
    // chosen for it): the f64 floor is beyond the tolerances.
    let settings: Vec<(Option<f64>, Option<usize>)> = rest
        .iter()
        .map(|a| match a.strip_prefix('p') {
            Some(order) => (None, Some(order.parse().expect("pORDER"))),
            None => (Some(a.parse().expect("EPS")), None),
        })
        .collect();
    std::fs::create_dir_all(&dir).expect("output folder");

    let points: Vec<f64> = Geometry::Cube
        .points::<f64>(n, 1)
        .iter()
        .map(|x| x * side)
        .collect();
    let charges: Vec<f64> = match stokes {
        None => (0..n)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect(),
        Some(true) => (0..n).flat_map(|_| [0.0, 0.0, -1.0]).collect(),
        Some(false) => {
            let mut f = ferrofmm_fmm::Charges::Signed.generate::<f64>(3 * n, 2);
            for c in 0..3 {
                let mean = f.iter().skip(c).step_by(3).sum::<f64>() / n as f64;
                f.iter_mut().skip(c).step_by(3).for_each(|x| *x -= mean);
            }
            f
        }
    };
    let sample = random_sample(n, SAMPLE);
    write(dir.join("points.f64"), &points);
    write(dir.join("charges.f64"), &charges);
    write(
        dir.join("sample.f64"),
        &sample.iter().map(|&i| i as f64).collect::<Vec<_>>(),
    );

    let t = Instant::now();
    let cell = PeriodicCell::new([0.0; 3], [side; 3]).expect("cell");
    let options = EwaldOptions::new(1e-14)
        .expected_targets(sample.len())
        .screening(kappa);
    let reference = match stokes {
        None => EwaldSum::with_options(cell, &points, &charges, options)
            .expect("ewald")
            .at_sources(&sample, EvalMode::PotentialGradient),
        Some(_) => {
            let options = EwaldOptions::new(1e-14).expected_targets(sample.len());
            StokesEwaldSum::with_options(cell, &points, &charges, 1.0, options)
                .expect("ewald")
                .at_sources(&sample, EvalMode::PotentialGradient)
        }
    }
    .expect("reference");
    let reference_s = t.elapsed().as_secs_f64();
    write(dir.join("reference.f64"), &reference);
    println!(
        "{{\"code\": \"ewald reference\", \"n\": {n}, \"box\": {side}, \"k\": {kappa}, \"sample\": {}, \"seconds\": {reference_s:.3}}}",
        sample.len()
    );
    let run = Run {
        points: &points,
        charges: &charges,
        sample: &sample,
        reference: &reference,
        side,
        verify,
    };
    if stokes.is_some() {
        run.settings(Stokes3d::default(), &settings);
    } else if kappa > 0.0 {
        run.settings(ModifiedHelmholtz3d::new(kappa).expect("k"), &settings);
    } else {
        run.settings(Laplace3d, &settings);
    }
}

/// The runs of one kernel.
struct Run<'a> {
    points: &'a [f64],
    charges: &'a [f64],
    sample: &'a [usize],
    reference: &'a [f64],
    side: f64,
    verify: bool,
}

impl Run<'_> {
    fn settings<K: Kernel>(&self, kernel: K, settings: &[(Option<f64>, Option<usize>)]) {
        let Run {
            points,
            charges,
            sample,
            reference,
            side,
            verify,
        } = *self;
        let c = kernel.components();
        let w = 4 * c;
        let n = charges.len() / c;

        let pick = |v: &[f64], grad: bool| -> Vec<f64> {
            v.chunks_exact(w)
                .flat_map(|v| {
                    if grad {
                        v[c..].to_vec()
                    } else {
                        v[..c].to_vec()
                    }
                })
                .collect()
        };
        for &(eps, order) in settings {
            let t = Instant::now();
            let mut builder = FmmBuilder::new(points)
                .kernel(kernel.clone())
                .periodic(Periodic::cube(side))
                .mode(EvalMode::PotentialGradient);
            if let Some(eps) = eps {
                builder = builder.tolerance(eps);
            }
            if let Some(order) = order {
                builder = builder.order(order);
            }
            let mut fmm = builder
                .verify(verify)
                .default_cache()
                .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
                .expect("build");
            let setup_s = t.elapsed().as_secs_f64();
            let mut best = f64::INFINITY;
            let mut values = Vec::new();
            let mut check_s = 0.0;
            for _ in 0..2 {
                let t = Instant::now();
                values = if verify && eps.is_some() {
                    let out = fmm.evaluate_verified(charges).expect("evaluate");
                    check_s = out.verification.map_or(0.0, |v| v.check_s());
                    out.values
                } else {
                    fmm.evaluate(charges).expect("evaluate")
                };
                best = best.min(t.elapsed().as_secs_f64() - check_s);
            }
            let at: Vec<f64> = sample
                .iter()
                .flat_map(|&i| values[w * i..w * (i + 1)].to_vec())
                .collect();
            // The energy of charges; none for forces.
            let energy = fmm.energy(charges, &values).unwrap_or(f64::NAN);
            let eps = eps.map_or("null".to_string(), |e| format!("{e:e}"));
            println!(
                "{{\"code\": \"ferrofmm\", \"n\": {n}, \"eps\": {eps}, \"order\": {}, \"leaf\": {}, \"setup_s\": {setup_s:.3}, \"eval_s\": {best:.3}, \"check_s\": {check_s:.3}, \"pot_err\": {:.3e}, \"grad_err\": {:.3e}, \"energy\": {energy:.15e}}}",
                fmm.order(),
                fmm.leaf_size(),
                rel(&pick(&at, false), &pick(reference, false)),
                rel(&pick(&at, true), &pick(reference, true)),
            );
        }
    }
}
