//! `eval` with stresslets or the pressure (`--kernel stokes` with
//! `--strslet`/`--strsvec` or `--pressure`): a [`DistStokesLayers`] run,
//! the distributed Stokeslet FMM and its Laplace companion on the same
//! points. The output holds the velocity's columns, then the pressure's;
//! the report is the Stokeslet FMM's per-rank figures (evaluation times of
//! both FMMs added up), with a line for the Laplace FMM and, with
//! `--check`, the errors of velocity and pressure against direct sums.

use ferrofmm_fmm::{StokesErrors, StokesRequest};
use ferrofmm_kernels::{KernelChoice, Precision, SourceKind};
use ferrofmm_mpi::{DistSolver, DistStokesLayers};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::eval::EvalArgs;
use crate::eval_io::write_out;
use crate::eval_report::{Attempt, FIGURES, figures, report};

/// This rank's points and what they carry, for a run with layers.
pub(crate) struct LayerInputs {
    pub(crate) points: Vec<f64>,
    /// Separate targets (`None`: the points).
    pub(crate) targets: Option<Vec<f64>>,
    /// Forces, three values per point.
    pub(crate) forces: Option<Vec<f64>>,
    /// Stresslet strengths and orientations, three values each per point.
    pub(crate) stresslets: Option<(Vec<f64>, Vec<f64>)>,
}

/// The run: both FMMs (plan, build, evaluate, verify), the output and the
/// report.
pub(crate) fn go(
    world: &SimpleCommunicator,
    a: &EvalArgs,
    kernel: KernelChoice,
    threads: usize,
    input: LayerInputs,
    read_s: f64,
) -> Result<(), String> {
    let me = world.rank() as usize;
    let size = world.size() as usize;
    let request = crate::eval::request(a, kernel, SourceKind::Charge)?;
    let wanted = StokesRequest {
        forces: input.forces.is_some(),
        stresslets: input.stresslets.is_some(),
        pressure: a.pressure,
    };
    let mut layers = DistStokesLayers::build(world, input.points, input.targets, request, wanted)
        .map_err(|e| e.to_string())?;
    let forces = input.forces.as_deref();
    let mn = input.stresslets.as_ref().map(|(m, n)| (&m[..], &n[..]));
    let mut last = None;
    let mut verified = None;
    for _ in 0..a.repeats.max(1) {
        let s = layers
            .evaluate(world, forces, mn)
            .map_err(|e| e.to_string())?;
        // A missed tolerance is a failure with no output written.
        if let (Some(false), Some(e)) = (s.verified, s.check) {
            return Err(format!(
                "tolerance {:e} not met: the error of velocity and pressure measured on {} \
                 sampled points is {:.2e} (Stokeslet FMM at order {}{}); no output written (ask \
                 for a larger tolerance{}, or --verify off to take the unchecked result)",
                layers.stokes().plan().tolerance.unwrap_or(0.0),
                e.n_sampled,
                e.worst(),
                layers.stokes().plan().order,
                layers
                    .laplace()
                    .map(|l| format!(", Laplace FMM at order {}", l.plan().order))
                    .unwrap_or_default(),
                if layers.stokes().request().precision == Precision::F32 {
                    ", use --precision f64"
                } else {
                    ""
                }
            ));
        }
        verified = verified.or(s.check);
        last = Some(s);
    }
    let Some(solution) = last else {
        return Err("no evaluation".into());
    };
    // --check: measured on the last evaluation; else the verification's.
    let check = if a.check > 0 {
        Some(
            layers
                .sampled_errors(world, forces, mn, &solution.values, a.check)
                .map_err(|e| e.to_string())?,
        )
    } else {
        verified
    };
    let stokes = layers.stokes();
    if let Some(out) = &a.out {
        let counts = stokes.target_counts();
        let first: u64 = counts[..me].iter().sum();
        let total: u64 = counts.iter().sum();
        let mut names = ferrofmm_io::column_names(
            stokes.request().mode.values_per_target(),
            kernel.component_names(),
        );
        names.extend(layers.plan().pressure_column_names());
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let rows = layers.plan().rows(&solution.values);
        write_out(world, out, &rows, &names, (first, total), false)?;
    }
    let mut mine = figures(stokes.tree(), stokes.setup_stats(), &solution.stats);
    mine.push(solution.stats.compute_cpu_seconds);
    mine.push(stokes.setup_stats().active_boxes as f64);
    let mut all = vec![0.0f64; FIGURES * size];
    world.all_gather_into(&mine[..], &mut all[..]);
    if me == 0 && (a.json || !a.quiet) {
        let attempts: Vec<Attempt> = match stokes.attempts() {
            [] => vec![Attempt {
                order: stokes.plan().order,
                errors: None,
            }],
            tried => tried
                .iter()
                .map(|t| Attempt {
                    order: t.order,
                    errors: Some(t.errors),
                })
                .collect(),
        };
        let layers = Some(layers_report(&layers, check.as_ref()));
        let info = crate::eval::run_info(
            a,
            stokes,
            &attempts,
            stokes.samples(),
            read_s,
            threads,
            layers,
        );
        report(&info, &all, size);
    }
    Ok(())
}

/// The Laplace companion and the layers' check, as lines and as JSON.
fn layers_report(
    layers: &DistStokesLayers<SimpleCommunicator>,
    check: Option<&StokesErrors>,
) -> (Vec<String>, serde_json::Value) {
    let request = layers.plan().request();
    let sources = match (request.forces, request.stresslets) {
        (true, true) => "forces and stresslets",
        (false, true) => "stresslets",
        _ => "forces",
    };
    let mut lines = vec![format!(
        "Stokes: {sources}{}",
        if request.pressure {
            ", with the pressure"
        } else {
            ""
        }
    )];
    let laplace = layers.laplace().map(|l: &DistSolver<SimpleCommunicator>| {
        let p = l.plan();
        let tried = l.attempts().last();
        lines.push(format!(
            "Laplace FMM (the stresslets' source flow and the pressure): order {}, leaf {}, {} \
             M2L{}",
            p.order,
            p.leaf_size,
            p.scheme,
            tried
                .map(|t| format!(
                    ", verified: errors {:.2e} / {:.2e}",
                    t.errors[0], t.errors[1]
                ))
                .unwrap_or_default()
        ));
        serde_json::json!({
            "order": p.order,
            "leaf_size": p.leaf_size,
            "scheme": p.scheme,
            "attempts": l.attempts().iter().map(|t| serde_json::json!({
                "order": t.order,
                "potential_error": t.errors[0],
                "derivative_error": t.errors[1],
            })).collect::<Vec<_>>(),
        })
    });
    if let Some(e) = check {
        let more =
            |name: &str, v: Option<f64>| v.map(|v| format!(", {name} {v:.3e}")).unwrap_or_default();
        lines.push(format!(
            "check against direct summation at {} points: velocity error {:.3e}{}{}{}",
            e.n_sampled,
            e.velocity,
            more("velocity gradient", e.velocity_gradient),
            more("pressure", e.pressure),
            more("pressure gradient", e.pressure_gradient),
        ));
    }
    let json = serde_json::json!({
        "forces": request.forces,
        "stresslets": request.stresslets,
        "pressure": request.pressure,
        "laplace": laplace,
        "check": check.map(|e| serde_json::json!({
            "samples": e.n_sampled,
            "velocity_error": e.velocity,
            "velocity_gradient_error": e.velocity_gradient,
            "pressure_error": e.pressure,
            "pressure_gradient_error": e.pressure_gradient,
            "worst": e.worst(),
        })),
    });
    (lines, json)
}
