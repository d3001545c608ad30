//! Build, evaluate, check and (optionally) save one FMM run.
//!
//! This is the one place where the command line's float type and M2L
//! scheme become type parameters: [`run`] matches on them once and calls
//! [`run_typed`], which is generic over `T: Real` and `S: M2lScheme<T>`.

use std::path::Path;
use std::time::Instant;

use ferrofmm_field::{CacheSetting, DenseM2l, FftM2l, M2lScheme, SvdM2l};
use ferrofmm_fmm::tuning::choose_precision;
use ferrofmm_fmm::{
    BuildScheme, EvalTimings, Fmm, FmmBuilder, effective_tolerance,
    relative_errors_sources_with_progress, sample_indices,
};
use ferrofmm_fmm::{MemoryLimit, MemoryReport, PrecomputeMonitor, Verification};
use ferrofmm_kernels::{EvalMode, Kernel, KernelVisitor, Precision, Real, SourceKind};

use super::{KernelArg, PrecisionArg, SchemeArg};
use crate::error::{CliError, Result};
use crate::memory::peak_rss_bytes;
use crate::progress::with_stage;
use crate::report::{
    ErrorFigures, EvalSeconds, MemoryFigures, OperatorSeconds, RunReport, SetupSeconds,
    TreeFigures, cache_report,
};
use ferrofmm_io::{self as io, Values};

mod input;
mod layers;

pub use input::{Input, Settings, densities};

use input::points_of;

/// Run the FMM described by `input` and `settings`; write the values to
/// `output` when given (format by extension).
pub fn run(input: Input, settings: &Settings, output: Option<&Path>) -> Result<RunReport> {
    use PrecisionArg::{Auto, F64};
    let mode = settings.mode();
    // The one default rule of every front end: no order and no tolerance
    // means the default tolerance.
    let settings = &Settings {
        tolerance: effective_tolerance(
            settings.tolerance,
            settings.order,
            settings.precision.float_type(),
        ),
        default_tolerance: settings.tolerance.is_none() && settings.order.is_none(),
        ..settings.clone()
    };
    check_generated_memory(&input, settings, mode)?;
    let mut input = input;
    // The points, made once, for the automatic choices (only with a
    // tolerance and an `auto` setting that needs them).
    let needs_points = (settings.tolerance.is_some() && settings.precision == Auto)
        || settings
            .scheme
            .needs_points(settings.kernel, settings.tolerance, settings.order);
    // A periodic run's tree is built on the points wrapped into its cell:
    // the choices see those.
    // Built-in points are made once, here, and kept for the run.
    if let (
        true,
        Input::Generated {
            geometry,
            n,
            seed,
            points: points @ None,
            ..
        },
    ) = (needs_points, &mut input)
    {
        *points = Some(geometry.points(*n, *seed));
    }
    let points = needs_points.then(|| {
        let (s, t) = points_of(&input);
        match &settings.periodic {
            Some(cell) => (
                std::borrow::Cow::Owned(cell.wrap_all(&s)),
                t.map(|t| std::borrow::Cow::Owned(cell.wrap_all(t))),
            ),
            None => (s, t.map(std::borrow::Cow::Borrowed)),
        }
    });
    let precision = match (settings.precision, settings.tolerance, &points) {
        (Auto, Some(eps), Some((s, t))) => auto_precision(s, t.as_deref(), eps, mode)?,
        (Auto, _, _) => F64,
        (p, _, _) => p,
    };
    let scheme = settings.scheme.resolve(
        settings.kernel,
        settings.tolerance,
        settings.order,
        points.as_ref().map(|(s, t)| (s.as_ref(), t.as_deref())),
        mode,
        precision.float_type(),
        // The SVD precomputation counts as free only with a folder the
        // user named (the default folder may be cold).
        matches!(settings.cache, CacheSetting::Dir(_)),
        ferrofmm_fmm::tuning::MachineCalibration::from_cache(&settings.cache).as_ref(),
    )?;
    drop(points);
    let settings = &Settings {
        precision,
        scheme,
        ..settings.clone()
    };
    settings.kernel.visit(WithKernel {
        input,
        settings,
        output,
    })
}

/// Built-in points are refused before they are made when they and the
/// FMM's per-point buffers cannot fit ([`MemoryReport::predict`], in the
/// smaller float type a `--precision auto` could pick, plus the charges
/// the command holds; the points, which in f64 it holds only until the FMM
/// is built, are left out of this lower bound). The builder checks the
/// same for points from files, once they are read.
fn check_generated_memory(input: &Input, settings: &Settings, mode: EvalMode) -> Result<()> {
    let Input::Generated { n, .. } = input else {
        return Ok(());
    };
    let c = settings.kernel.components();
    let size = ferrofmm_fmm::RunSize {
        n_sources: *n,
        n_targets: None,
        values_per_source: c,
        values_per_target: c * mode.values_per_target(),
        n_vectors: 1,
    };
    let (library, t) = match settings.precision {
        PrecisionArg::F64 => (MemoryReport::predict::<f64>(&size), 8),
        _ => (MemoryReport::predict::<f32>(&size), 4),
    };
    let charges = (*n as u64).saturating_mul(c as u64 * t);
    let limit = if settings.force {
        MemoryLimit::Unlimited
    } else {
        MemoryLimit::Auto
    };
    ferrofmm_fmm::check_memory(
        library.saturating_add(charges),
        limit,
        &format!("a demo of {n} points"),
    )?;
    Ok(())
}

/// The rest of [`run`] for the kernel `--kernel` names.
struct WithKernel<'a> {
    input: Input,
    settings: &'a Settings,
    output: Option<&'a Path>,
}

impl KernelVisitor for WithKernel<'_> {
    type Output = Result<RunReport>;

    fn visit<K: Kernel>(self, kernel: K) -> Result<RunReport> {
        run_kernel(kernel, self.input, self.settings, self.output)
    }
}

/// [`run`] with the kernel chosen: the one match on float type and scheme.
fn run_kernel<K: Kernel>(
    kernel: K,
    input: Input,
    settings: &Settings,
    output: Option<&Path>,
) -> Result<RunReport> {
    use PrecisionArg::{Auto, F32, F64};
    use SchemeArg::{Dense, Fft, Svd};
    match (settings.precision, settings.scheme) {
        (F64, Svd) => run_chosen::<f64, SvdM2l<f64>, K>(kernel, input, settings, output),
        (F64, Dense) => run_chosen::<f64, DenseM2l<f64>, K>(kernel, input, settings, output),
        (F32, Svd) => run_chosen::<f32, SvdM2l<f32>, K>(kernel, input, settings, output),
        (F32, Dense) => run_chosen::<f32, DenseM2l<f32>, K>(kernel, input, settings, output),
        (F64, Fft) => run_chosen::<f64, FftM2l<f64>, K>(kernel, input, settings, output),
        (F32, Fft) => run_chosen::<f32, FftM2l<f32>, K>(kernel, input, settings, output),
        (Auto, _) | (_, SchemeArg::Auto) => {
            unreachable!("auto precision and scheme are resolved above")
        }
    }
}

/// [`run_typed`], or a Stokes run with stresslets or the pressure
/// ([`layers::run`]).
fn run_chosen<T: Real, S: BuildScheme<T>, K: Kernel>(
    kernel: K,
    input: Input,
    settings: &Settings,
    output: Option<&Path>,
) -> Result<RunReport>
where
    S::Config: Default,
{
    if layers::wanted(&input, settings) {
        layers::run::<T, S>(input, settings, output)
    } else {
        run_typed::<T, S, K>(kernel, input, settings, output)
    }
}

/// f32 where it still reaches `eps` on these points, else f64.
fn auto_precision(
    sources: &[f64],
    targets: Option<&[f64]>,
    eps: f64,
    mode: EvalMode,
) -> Result<PrecisionArg> {
    Ok(match choose_precision(eps, mode, sources, targets)? {
        Precision::F32 => PrecisionArg::F32,
        Precision::F64 => PrecisionArg::F64,
    })
}

/// Column names of the output for a run of `mode` with `kernel`:
/// `potential`, then `grad_x, grad_y, grad_z`, then `hess_xx, hess_yy,
/// hess_zz, hess_xy, hess_xz, hess_yz`; for a kernel with components each
/// quantity once per component, suffixed (`potential_re, potential_im,
/// grad_x_re, ...` for Helmholtz; `potential_x, potential_y, potential_z,
/// grad_x_x, grad_x_y, ...` for Stokes, where `grad_x_y` is `d u_y / d x`).
pub fn output_names(mode: EvalMode, kernel: KernelArg) -> Vec<String> {
    io::column_names(mode.values_per_target(), kernel.component_names())
}

/// The values as the float type they are.
fn as_values<T: Real>(values: &[T]) -> Values<'_> {
    match (T::as_f64_slice(values), T::as_f32_slice(values)) {
        (Some(v), _) => Values::F64(v),
        (None, Some(v)) => Values::F32(v),
        (None, None) => unreachable!("Real is implemented for f32 and f64 only"),
    }
}

/// A tolerance checked after evaluating and missed (even at the raised
/// orders) fails the command before anything is written: exit status 1,
/// never a result less accurate than asked with status 0.
fn require_met(
    verification: Option<&Verification>,
    precision: Precision,
    why: String,
) -> Result<()> {
    match verification.filter(|v| !v.met) {
        None => Ok(()),
        Some(v) => Err(CliError::ToleranceNotMet {
            tolerance: v.tolerance,
            measured: v.measured().worst(),
            attempts: v.attempts.len(),
            order: v.last().order,
            precision: precision.name(),
            why,
        }),
    }
}

/// Why a periodic Stokes run with a net force reaches less than zero-sum
/// forces: its velocities are a small difference of large terms (the
/// images' mean flow against the back pressure), which costs about
/// `sqrt(N) |mean f| / rms(f)` in relative accuracy (docs/periodic.md).
/// A sentence for [`CliError::ToleranceNotMet`] when that factor exceeds
/// 3; empty otherwise.
fn net_force_reason<T: Real, K: Kernel>(kernel: &K, periodic: bool, forces: &[T]) -> String {
    let stokes = matches!(
        ferrofmm_fmm::periodic::lattice_sum(kernel),
        Some(ferrofmm_fmm::periodic::LatticeSum::Stokes { .. })
    );
    let n = forces.len() / 3;
    if !(periodic && stokes) || n == 0 {
        return String::new();
    }
    let mean: [f64; 3] = std::array::from_fn(|c| {
        forces
            .iter()
            .skip(c)
            .step_by(3)
            .map(|f| f.to_f64())
            .sum::<f64>()
            / n as f64
    });
    let rms = (forces.iter().map(|f| f.to_f64().powi(2)).sum::<f64>() / n as f64).sqrt();
    let mean = (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]).sqrt();
    let factor = (n as f64).sqrt() * mean / rms.max(f64::MIN_POSITIVE);
    if factor <= 3.0 {
        return String::new();
    }
    format!(
        "; these forces have a net force, which makes a periodic Stokes run's velocities a small \
         difference of large terms, about {factor:.0}x less accurate than zero-sum forces at the \
         same order (docs/periodic.md)"
    )
}

/// [`run`] for float type `T`, M2L scheme `S` and kernel `K`.
pub fn run_typed<T: Real, S: BuildScheme<T>, K: Kernel>(
    kernel: K,
    input: Input,
    settings: &Settings,
    output: Option<&Path>,
) -> Result<RunReport>
where
    S::Config: Default,
{
    let start = Instant::now();
    let mode = settings.mode();
    // Points stay in f64 whatever T is: the FMM rounds them only relative
    // to its tree's origin (`FmmBuilder::from_f64`), and `--check` compares
    // with the direct sums at the caller's own coordinates. Densities are
    // converted once (consumed, so that only one copy is held).
    let convert = |v: Vec<f64>| v.into_iter().map(T::from_f64).collect::<Vec<T>>();
    let (geometry, charge_kind) = match &input {
        Input::Generated {
            geometry, charges, ..
        } => (
            Some(geometry.name().to_string()),
            Some(charges.name().to_string()),
        ),
        Input::Given { .. } => (None, None),
    };
    let (sources, targets, kind, q): (Vec<f64>, Option<Vec<f64>>, SourceKind, Vec<T>) = match input
    {
        Input::Generated {
            geometry,
            charges,
            n,
            seed,
            points,
        } => with_stage(
            format!("generating {n} points ({})", geometry.name()),
            || {
                let mut q: Vec<f64> = charges.generate(n * settings.kernel.components(), seed);
                if settings.periodic.is_some()
                    && ferrofmm_fmm::periodic::lattice_screening(&kernel) == Some(0.0)
                {
                    // A periodic Laplace cell must be neutral.
                    let mean = q.iter().sum::<f64>() / q.len().max(1) as f64;
                    q.iter_mut().for_each(|x| *x -= mean);
                }
                (
                    points.unwrap_or_else(|| geometry.points(n, seed)),
                    None,
                    SourceKind::Charge,
                    convert(q),
                )
            },
        ),
        Input::Given {
            sources,
            targets,
            charges,
            dipoles,
            stresslets: _,
        } => {
            let (kind, d) = densities(charges, dipoles, settings.kernel.components());
            ferrofmm_fmm::check_representable::<T>(&d)?;
            (sources, targets, kind, convert(d))
        }
    };

    let mut fmm = {
        let stage = crate::progress::stage("setup");
        let monitor = PrecomputeMonitor::new().with_cancel_flag(crate::interrupt::flag());
        let _precomputing = crate::interrupt::precomputing();
        let builder = configured(
            kernel.clone(),
            kind,
            mode,
            &sources,
            targets.as_deref(),
            settings,
        )
        .monitor(monitor)
        .setup_progress(stage.setup_progress());
        S::build(builder)
    }?;

    // One copy of the points: in f64 and free space the FMM's own gives
    // them back exactly for the check (`Fmm::points_f64`), so the caller's
    // is dropped before evaluating (24 bytes a point). In f32, or wrapped
    // into a periodic cell, the caller's own coordinates are kept.
    let separate_targets = targets.is_some();
    let held = (T::PRECISION == Precision::F32 || settings.periodic.is_some())
        .then_some((sources, targets));
    let inputs_bytes = (std::mem::size_of_val(&q[..])
        + held.as_ref().map_or(0, |(s, t)| {
            std::mem::size_of_val(&s[..]) + t.as_ref().map_or(0, |t| std::mem::size_of_val(&t[..]))
        })) as u64;

    let repeats = settings.repeats.max(1);
    let mut totals = Vec::with_capacity(repeats);
    let mut best: Option<EvalTimings> = None;
    let mut values = Vec::new();
    let mut verification = None;
    for r in 0..repeats {
        let label = if repeats > 1 {
            format!("evaluation {}/{repeats}", r + 1)
        } else {
            "evaluation".to_string()
        };
        drop(std::mem::take(&mut values)); // never hold two results at once
        let verified = r == 0 && settings.tolerance.is_some() && settings.verify;
        let label = if verified {
            format!("{label} (verified)")
        } else {
            label
        };
        // The passes report their progress to the stage's bar.
        let stage = crate::progress::stage(label.clone());
        fmm.set_progress(Some(stage.eval_progress(label)));
        let result = if verified {
            // The first evaluation checks the tolerance (and may raise the
            // order); later repeats time the final setting.
            fmm.evaluate_verified(&q).map(|out| {
                verification = out.verification;
                (out.values, out.timings)
            })
        } else {
            fmm.evaluate_timed(&q)
        };
        fmm.set_progress(None);
        drop(stage);
        let (v, timings) = result?;
        totals.push(timings.total.as_secs_f64());
        if best.is_none_or(|b| timings.total < b.total) {
            best = Some(timings);
        }
        values = v;
    }
    require_met(
        verification.as_ref(),
        T::PRECISION,
        net_force_reason(&kernel, settings.periodic.is_some(), &q),
    )?;
    let best = best.unwrap_or_default();
    totals.sort_by(f64::total_cmp);
    let median = if repeats % 2 == 1 {
        totals[repeats / 2]
    } else {
        0.5 * (totals[repeats / 2 - 1] + totals[repeats / 2])
    };

    let (errors, direct_check_s) = if settings.check > 0 {
        let t0 = Instant::now();
        let (sources, targets) = held.unwrap_or_else(|| fmm.points_f64());
        let tgt = targets.as_deref().unwrap_or(&sources);
        let sample = sample_indices(fmm.n_targets(), settings.check);
        let e = match &settings.periodic {
            Some(cell) => with_stage(
                format!("lattice sums on {} sampled targets", sample.len()),
                || {
                    ferrofmm_fmm::relative_errors_periodic(
                        &kernel,
                        cell,
                        mode,
                        &sources,
                        &q,
                        targets.as_deref(),
                        &values,
                        &sample,
                    )
                },
            )?,
            None => {
                // A bar with the time left: at 1e8 sources a check of 1000
                // targets is 1e11 pairs.
                let what = format!("direct summation on {} sampled targets", sample.len());
                let stage = crate::progress::stage(what.clone());
                let progress = stage.eval_progress(what);
                relative_errors_sources_with_progress(
                    &kernel, kind, mode, &sources, &q, tgt, &values, &sample, &progress,
                )
            }
        };
        let figures = ErrorFigures {
            n_sampled: e.n_sampled,
            potential: e.potential,
            gradient: e.gradient,
            hessian: e.hessian,
            pressure: None,
            pressure_gradient: None,
        };
        (Some(figures), Some(t0.elapsed().as_secs_f64()))
    } else {
        (None, None)
    };

    if let Some(path) = output {
        with_stage(format!("writing {}", path.display()), || {
            let names = output_names(mode, settings.kernel);
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let write = if settings.complex_output {
                io::write_complex
            } else {
                io::write
            };
            match &settings.out_sources {
                Some((at_sources, n)) => {
                    let split = n * names.len();
                    write(at_sources, as_values(&values[..split]), &names)?;
                    write(path, as_values(&values[split..]), &names)
                }
                None => write(path, as_values(&values), &names),
            }
        })?;
    }

    // The energy of charges at the sources themselves (a scalar kernel).
    let energy = fmm.energy(&q, &values).ok();
    Ok(report(
        &fmm,
        settings,
        &kernel,
        Outcome {
            start,
            geometry,
            charges: charge_kind,
            verification,
            repeats,
            best,
            median,
            errors,
            direct_check_s,
            energy,
            sources: kind.name().to_string(),
            inputs_bytes,
            separate_targets,
        },
    ))
}

/// The builder of a run: the points (in f64, rounded to `T` relative to
/// the tree's origin), kernel, source kind, mode and the settings' order,
/// leaf size, cache, cell and tolerance.
pub(super) fn configured<'a, T: Real, K: Kernel>(
    kernel: K,
    kind: SourceKind,
    mode: EvalMode,
    sources: &'a [f64],
    targets: Option<&'a [f64]>,
    settings: &Settings,
) -> FmmBuilder<'a, T, K> {
    let mut builder = FmmBuilder::<T, _>::from_f64(sources)
        .kernel(kernel)
        .source_kind(kind)
        .mode(mode)
        .memory_limit(if settings.force {
            MemoryLimit::Unlimited
        } else {
            MemoryLimit::Auto
        });
    if let Some(t) = targets {
        builder = builder.targets_f64(t);
    }
    if let Some(p) = settings.order {
        builder = builder.order(p);
    }
    if let Some(s) = settings.leaf_size {
        builder = builder.leaf_size(s);
    }
    builder = builder.cache(settings.cache.clone());
    if let Some(cell) = settings.periodic {
        builder = builder.periodic(cell);
    }
    if let Some(eps) = settings.tolerance {
        builder = builder.tolerance(eps).verify(settings.verify);
    }
    builder
}

/// What a run measured, for its [`RunReport`].
pub(super) struct Outcome {
    pub(super) start: Instant,
    pub(super) geometry: Option<String>,
    pub(super) charges: Option<String>,
    pub(super) verification: Option<Verification>,
    pub(super) repeats: usize,
    pub(super) best: EvalTimings,
    pub(super) median: f64,
    pub(super) errors: Option<ErrorFigures>,
    pub(super) direct_check_s: Option<f64>,
    pub(super) energy: Option<f64>,
    /// The source kind's name.
    pub(super) sources: String,
    pub(super) inputs_bytes: u64,
    pub(super) separate_targets: bool,
}

/// The report of a run of `fmm` (the Stokes FMM of a run with stresslets
/// or the pressure).
pub(super) fn report<T: Real, K: Kernel, S: M2lScheme<T>>(
    fmm: &Fmm<T, K, S>,
    settings: &Settings,
    kernel: &K,
    outcome: Outcome,
) -> RunReport {
    let Outcome {
        start,
        geometry,
        charges: charge_kind,
        verification,
        repeats,
        best,
        median,
        errors,
        direct_check_s,
        energy,
        sources,
        inputs_bytes,
        separate_targets,
    } = outcome;
    let mode = fmm.mode();
    let summary = fmm.summary();
    let (cache, cache_dir) = cache_report(
        &settings.cache,
        fmm.operators().cache_status(),
        &fmm.m2l_scheme().cache_status(),
    );
    RunReport {
        command: settings.command.to_string(),
        geometry,
        n_sources: fmm.n_sources(),
        n_targets: fmm.n_targets(),
        order: fmm.order(),
        leaf_size: summary.leaf_size,
        tolerance: settings.tolerance,
        default_tolerance: settings.default_tolerance,
        predicted_error: fmm.chosen_parameters().map(|c| c.predicted_error),
        charges: charge_kind,
        verify: match (settings.tolerance, settings.verify) {
            (None, _) => "n/a",
            (Some(_), true) => "on",
            (Some(_), false) => "off",
        }
        .to_string(),
        verification,
        scheme: settings.scheme,
        method: if fmm.chosen_parameters().is_some_and(|c| c.direct) {
            "direct"
        } else {
            "fmm"
        }
        .to_string(),
        direct_predicted_s: fmm.chosen_parameters().and_then(|c| c.direct_seconds),
        cost_model: fmm.chosen_parameters().map(|c| c.model.clone()),
        fmm_predicted_s: fmm
            .chosen_parameters()
            .map(|c| c.predicted_seconds + c.precompute_seconds),
        precision: settings.precision,
        gradients: mode.has_gradient(),
        hessians: mode.has_hessian(),
        kernel: settings.kernel.name(),
        periodic: settings.periodic.map(|c| {
            use ferrofmm_fmm::PeriodicAxes;
            format!(
                "box {} ({}{}, {}), origin {:?}",
                c.width(),
                c.axes(),
                match c.axes() {
                    PeriodicAxes::Xyz => "",
                    PeriodicAxes::Xy => ": slab, z free space",
                    PeriodicAxes::X => ": rod, y and z free space",
                },
                {
                    use ferrofmm_fmm::periodic::LatticeSum;
                    match (ferrofmm_fmm::periodic::lattice_sum(kernel), c.surface()) {
                        (Some(LatticeSum::Yukawa { .. }), _) => "screened, absolutely convergent",
                        (Some(LatticeSum::Images { .. }), _) => {
                            "absolutely convergent, summed over super-cells of images"
                        }
                        (Some(LatticeSum::Stokes { .. }), _) => {
                            "Hasimoto: zero mean velocity, net force balanced by pressure"
                        }
                        _ if c.axes() != PeriodicAxes::Xyz => "neutral, no surface term",
                        (_, ferrofmm_fmm::SurfaceTerm::TinFoil) => "tin-foil",
                        (_, ferrofmm_fmm::SurfaceTerm::Vacuum) => "vacuum",
                    }
                },
                c.origin()
            )
        }),
        energy,
        sources,
        threads: rayon::current_num_threads(),
        cache,
        cache_dir,
        tree: TreeFigures::from(&summary),
        setup: SetupSeconds::from(fmm.setup_timings()),
        evaluation: EvalSeconds {
            repeats,
            best_s: best.total.as_secs_f64(),
            median_s: median,
            operators_s: OperatorSeconds::from(&best),
        },
        errors,
        direct_check_s,
        peak_rss_bytes: peak_rss_bytes(),
        wall_s: start.elapsed().as_secs_f64(),
        memory: Some(MemoryFigures::new(
            &fmm.memory(),
            inputs_bytes,
            fmm.n_sources() + if separate_targets { fmm.n_targets() } else { 0 },
            peak_rss_bytes(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_fmm::{ErrorReport, VerificationAttempt};

    fn verification(met: bool) -> Verification {
        let attempt = |order, potential| VerificationAttempt {
            order,
            svd_tolerance: None,
            predicted_error: 1e-7,
            measured: ErrorReport {
                n_sampled: 40,
                potential,
                gradient: None,
                hessian: None,
            },
            evaluation_s: 0.1,
            check_s: 0.01,
        };
        Verification {
            tolerance: 1e-6,
            attempts: vec![attempt(6, 4e-6), attempt(7, 3e-6), attempt(8, 2e-6)],
            met,
            rebuild_s: 0.2,
        }
    }

    /// Equal forces in a periodic Stokes cell explain a missed tolerance;
    /// zero-sum forces, free space and other kernels add nothing.
    #[test]
    fn a_net_force_explains_a_periodic_stokes_shortfall() {
        let stokes = ferrofmm_kernels::Stokes3d::default();
        let equal: Vec<f64> = (0..400).flat_map(|_| [0.0, 0.0, -1.0]).collect();
        let why = net_force_reason(&stokes, true, &equal);
        assert!(why.contains("net force") && why.contains("20x"), "{why}");
        assert!(net_force_reason(&stokes, false, &equal).is_empty());
        let zero_sum: Vec<f64> = (0..400)
            .flat_map(|i| {
                if i % 2 == 0 {
                    [1.0, 0.0, 0.0]
                } else {
                    [-1.0, 0.0, 0.0]
                }
            })
            .collect();
        assert!(net_force_reason(&stokes, true, &zero_sum).is_empty());
        assert!(net_force_reason(&ferrofmm_kernels::Laplace3d, true, &equal).is_empty());
        let e = require_met(Some(&verification(false)), Precision::F64, why).unwrap_err();
        assert!(e.to_string().ends_with("(docs/periodic.md)"), "{e}");
    }

    #[test]
    fn a_missed_tolerance_fails_the_command() {
        assert!(require_met(None, Precision::F64, String::new()).is_ok());
        assert!(require_met(Some(&verification(true)), Precision::F64, String::new()).is_ok());
        let e = require_met(Some(&verification(false)), Precision::F32, String::new()).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("tolerance 1e-6 not met") && m.contains("2.00e-6") && m.contains("order 8"),
            "{m}"
        );
        assert!(
            m.contains("3 attempt(s)") && m.contains("--precision f64"),
            "{m}"
        );
    }
}
