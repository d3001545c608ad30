//! The report of an evaluation (`info` in Python) and its JSON parts.

use ferrofmm_field::{CacheLocation, CacheOff};
use ferrofmm_fmm::{EvalTimings, Periodic, SetupTimings, SurfaceTerm, Verification};
use serde_json::{Value, json};

use super::NativeFmm;
use super::erased::Engine;

impl NativeFmm {
    pub(super) fn read(&self) -> std::sync::RwLockReadGuard<'_, Box<dyn Engine>> {
        self.engine.read().unwrap_or_else(|p| p.into_inner())
    }

    /// The report of one evaluation (`info` in Python).
    pub(super) fn info(
        &self,
        timings: &EvalTimings,
        verification: Option<&Verification>,
        n_vectors: usize,
    ) -> Value {
        let (s, setup, cache) = {
            let engine = self.read();
            (
                engine.summary(),
                engine.setup_timings(),
                engine.cache_summary(),
            )
        };
        let cache = match &self.cache {
            CacheLocation::Folder { .. } => cache.unwrap_or_else(|| "not needed".into()),
            CacheLocation::Off(CacheOff::Requested) => "off (cache=False)".into(),
            CacheLocation::Off(why) => why.to_string(),
        };
        let chosen = s.chosen.as_ref();
        json!({
            "kernel": s.kernel,
            "dtype": self.dtype,
            "order": s.order,
            "leaf_size": s.leaf_size,
            "scheme": s.m2l_scheme,
            "method": if chosen.is_some_and(|c| c.direct) { "direct" } else { "fmm" },
            "model": chosen.map(|c| c.model.clone()),
            "eps": self.options.eps,
            "predicted_error": verification
                .map(Verification::predicted_error)
                .or(chosen.map(|c| c.predicted_error)),
            "measured_error": verification.map(|v| {
                let m = v.measured();
                json!({"potential": m.potential, "gradient": m.gradient, "hessian": m.hessian, "sampled_targets": m.n_sampled})
            }),
            "verified": verification.map(|v| v.met),
            "n_vectors": n_vectors,
            "threads": self.threads.count(),
            "depth": s.depth,
            "root_scale": chosen.map_or(1.0, |c| c.root_scale),
            "boxes": s.n_boxes,
            "leaves": s.n_leaves,
            "clusters": s.clusters,
            "cache": cache,
            "cache_dir": self.cache.dir().map(|d| d.display().to_string()),
            "periodic": self.options.periodic.as_ref().map(periodic_info),
            "timings": {
                "setup": setup_seconds(&setup),
                "evaluate": eval_seconds(timings),
            },
        })
    }
}

/// `info["periodic"]`: the cell of a periodic run.
fn periodic_info(cell: &Periodic) -> Value {
    json!({
        "box": cell.lengths(),
        "origin": cell.origin(),
        "axes": cell.axes().name(),
        "surface": surface_name(cell.surface()),
    })
}

/// `"tin-foil"` or `"vacuum"`.
fn surface_name(s: SurfaceTerm) -> &'static str {
    match s {
        SurfaceTerm::TinFoil => "tin-foil",
        SurfaceTerm::Vacuum => "vacuum",
    }
}

pub(super) fn setup_seconds(t: &SetupTimings) -> Value {
    json!({
        "tuning": t.tuning.as_secs_f64(),
        "tree": t.tree.as_secs_f64(),
        "operators": t.operators.as_secs_f64(),
        "m2l_precompute": t.m2l_precompute.as_secs_f64(),
        "layout": t.layout.as_secs_f64(),
        "total": t.total.as_secs_f64(),
    })
}

fn eval_seconds(t: &EvalTimings) -> Value {
    let mut map = serde_json::Map::new();
    for (name, d) in t.operators() {
        map.insert(name.to_lowercase(), json!(d.as_secs_f64()));
    }
    map.insert("total".into(), json!(t.total.as_secs_f64()));
    Value::Object(map)
}
