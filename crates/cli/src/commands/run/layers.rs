//! `eval --kernel stokes` with stresslets (`--strslet`, `--strsvec`) or
//! the pressure (`--pressure`): a [`StokesLayers`] run, reported as the
//! Stokes FMM's, with the pressure's columns after the velocity's.

use std::path::Path;
use std::time::Instant;

use ferrofmm_fmm::{BuildScheme, PrecomputeMonitor, StokesLayers, StokesRequest, sample_indices};
use ferrofmm_kernels::{Real, SourceKind, Stokes3d};

use super::{Input, Outcome, Settings, as_values, configured, output_names, report, require_met};
use crate::error::{CliError, Result};
use crate::progress::with_stage;
use crate::report::{ErrorFigures, RunReport};
use ferrofmm_io as io;

/// Whether `input` and `settings` ask for a [`StokesLayers`] run.
pub(super) fn wanted(input: &Input, settings: &Settings) -> bool {
    settings.pressure
        || matches!(
            input,
            Input::Given {
                stresslets: Some(_),
                ..
            }
        )
}

/// Run forces and stresslets with the pressure, float type `T`, scheme `S`.
pub(super) fn run<T: Real, S: BuildScheme<T>>(
    input: Input,
    settings: &Settings,
    output: Option<&Path>,
) -> Result<RunReport> {
    let start = Instant::now();
    let Input::Given {
        sources,
        targets,
        charges,
        dipoles: None,
        stresslets,
    } = input
    else {
        return Err(CliError::InvalidArgument(
            "stresslets and the pressure need --sources and --charges or --strslet files"
                .to_string(),
        ));
    };
    if settings.periodic.is_some() {
        return Err(CliError::InvalidArgument(
            "stresslets and --pressure run in free space only (no --box)".to_string(),
        ));
    }
    let request = StokesRequest {
        forces: charges.is_some(),
        stresslets: stresslets.is_some(),
        pressure: settings.pressure,
    };
    let mode = settings.mode();
    let convert = |v: &[f64]| -> Result<Vec<T>> {
        ferrofmm_fmm::check_representable::<T>(v)?;
        Ok(v.iter().map(|&x| T::from_f64(x)).collect())
    };
    let forces = charges.as_deref().map(convert).transpose()?;
    let mn = match &stresslets {
        Some((m, n)) => Some((convert(m)?, convert(n)?)),
        None => None,
    };
    let mn_ref = mn.as_ref().map(|(m, n)| (m.as_slice(), n.as_slice()));

    let mut layers = {
        let stage = crate::progress::stage("setup");
        let monitor = PrecomputeMonitor::new().with_cancel_flag(crate::interrupt::flag());
        let _precomputing = crate::interrupt::precomputing();
        // The source kind is set by the layers from the request.
        let builder = configured::<T, _>(
            Stokes3d::default(),
            SourceKind::Charge,
            mode,
            &sources,
            targets.as_deref(),
            settings,
        )
        .monitor(monitor)
        .setup_progress(stage.setup_progress());
        StokesLayers::<T, S>::build(builder, request)
    }?;

    let verified = settings.tolerance.is_some() && settings.verify;
    let label = if verified {
        "evaluation (verified)"
    } else {
        "evaluation"
    };
    let stage = crate::progress::stage(label.to_string());
    layers.set_progress(Some(stage.eval_progress(label.to_string())));
    let result = if verified {
        layers.evaluate_verified(forces.as_deref(), mn_ref)
    } else {
        layers.evaluate_timed(forces.as_deref(), mn_ref)
    };
    layers.set_progress(None);
    drop(stage);
    let evaluated = result?;
    let verification = evaluated.verification().cloned();
    let (values, stokes_check, laplace_check) =
        (evaluated.values, evaluated.stokes, evaluated.laplace);
    let best = evaluated.timings;
    require_met(stokes_check.as_ref(), T::PRECISION, String::new())?;
    require_met(
        laplace_check.as_ref(),
        T::PRECISION,
        " (the Laplace FMM of the stresslets' source flow and the pressure)".to_string(),
    )?;

    let (errors, direct_check_s) = if settings.check > 0 {
        let t0 = Instant::now();
        let sample = sample_indices(layers.stokes().n_targets(), settings.check);
        let e = with_stage(
            format!("direct summation on {} sampled targets", sample.len()),
            || layers.relative_errors(forces.as_deref(), mn_ref, &values, &sample),
        )?;
        let figures = ErrorFigures {
            n_sampled: e.n_sampled,
            potential: e.velocity,
            gradient: e.velocity_gradient,
            hessian: None,
            pressure: e.pressure,
            pressure_gradient: e.pressure_gradient,
        };
        (Some(figures), Some(t0.elapsed().as_secs_f64()))
    } else {
        (None, None)
    };

    if let Some(path) = output {
        with_stage(format!("writing {}", path.display()), || {
            let mut names = output_names(mode, settings.kernel);
            names.extend(layers.plan().pressure_column_names());
            let per_target = names.len();
            let flat = layers.plan().rows(&values);
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            match &settings.out_sources {
                Some((at_sources, n)) => {
                    let split = n * per_target;
                    io::write(at_sources, as_values(&flat[..split]), &names)?;
                    io::write(path, as_values(&flat[split..]), &names)
                }
                None => io::write(path, as_values(&flat), &names),
            }
        })?;
    }

    let sources_name = match (request.forces, request.stresslets) {
        (true, true) => "force+stresslet",
        (false, true) => "stresslet",
        _ => "force",
    };
    let bytes = |v: &Option<Vec<T>>| v.as_ref().map_or(0, |v| std::mem::size_of_val(&v[..]));
    let pair = mn.as_ref().map_or(0, |(m, n)| {
        std::mem::size_of_val(&m[..]) + std::mem::size_of_val(&n[..])
    });
    let inputs_bytes = (bytes(&forces) + pair) as u64;
    Ok(report(
        layers.stokes(),
        settings,
        &Stokes3d::default(),
        Outcome {
            start,
            geometry: None,
            charges: None,
            verification,
            repeats: 1,
            best,
            median: best.total.as_secs_f64(),
            errors,
            direct_check_s,
            energy: None,
            sources: sources_name.to_string(),
            inputs_bytes,
            separate_targets: targets.is_some(),
        },
    ))
}
