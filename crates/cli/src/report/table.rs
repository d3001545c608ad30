//! A report as the human-readable table ([`RunReport::table`]).

use std::fmt::Write as _;

use super::{MemoryFigures, OperatorSeconds, RunReport, mebibytes, seconds, thousands};

impl MemoryFigures {
    /// One line per component: bytes a point and MiB.
    pub(super) fn rows(&self, o: &mut String) {
        let per = |b: u64| b as f64 / self.n_points.max(1) as f64;
        let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
        let _ = writeln!(
            o,
            "memory by component   bytes a point (MiB), {} points",
            thousands(self.n_points)
        );
        for (name, b) in [
            ("points", self.points),
            ("tree", self.tree),
            ("expansions", self.expansions),
            ("evaluation", self.evaluation_scratch),
            ("M2L lists", self.m2l_interactions),
            ("operators", self.operators + self.m2l),
            ("inputs", self.inputs),
            ("total", self.total),
        ] {
            let _ = writeln!(o, "  {name:<19}{:>10.1} ({:.0})", per(b), mib(b));
        }
        if let Some(p) = self.peak_bytes_per_point {
            let _ = writeln!(o, "  {:<19}{p:>10.1}", "peak (measured)");
        }
    }
}

impl RunReport {
    /// The human-readable table.
    pub fn table(&self) -> String {
        let mut o = String::new();
        let row = |o: &mut String, label: &str, value: String| {
            let _ = writeln!(o, "  {label:<18} {value}");
        };
        let what = match (self.gradients, self.hessians) {
            (_, true) => "potential + gradient + Hessian",
            (true, false) => "potential + gradient",
            (false, false) => "potential",
        };
        let kernel = ferrofmm_kernels::KernelChoice::parse(&self.kernel)
            .map_or_else(|_| self.kernel.clone(), |k| k.title());
        let sources = match self.sources.as_str() {
            "charge" => String::new(),
            s => format!(", {s} sources"),
        };
        let _ = writeln!(
            o,
            "ferrofmm {}: {kernel}{sources}, {what}, {}",
            self.command, self.precision
        );
        let points = match &self.geometry {
            Some(g) => format!("{} ({g})", thousands(self.n_sources)),
            None => thousands(self.n_sources),
        };
        row(&mut o, "sources", points);
        if let Some(c) = &self.charges {
            let what = match c.as_str() {
                "signed" => "uniform in [-0.5, 0.5) (zero mean)",
                "positive" => "uniform in [0, 1) (all positive)",
                other => other,
            };
            row(&mut o, "charges", what.to_string());
        }
        row(&mut o, "targets", thousands(self.n_targets));
        if let Some(p) = &self.periodic {
            row(&mut o, "periodic", p.clone());
        }
        if let Some(e) = self.energy {
            row(&mut o, "energy", format!("{e:.12e} (1/2 sum q phi)"));
        }
        if self.method == "direct" {
            let predicted = match (self.direct_predicted_s, self.fmm_predicted_s) {
                (Some(d), Some(f)) => format!(
                    " (predicted {} against {} for the fastest FMM with its operators)",
                    seconds(d),
                    seconds(f)
                ),
                _ => String::new(),
            };
            row(
                &mut o,
                "method",
                format!("direct sum, exact to rounding{predicted}"),
            );
        } else {
            row(
                &mut o,
                "expansion",
                format!(
                    "order {} ({} points per surface), {} M2L ({:.1} MiB), leaf size {}",
                    self.order,
                    self.tree.n_surface,
                    self.scheme,
                    self.tree.m2l_bytes as f64 / (1024.0 * 1024.0),
                    self.leaf_size
                ),
            );
        }
        row(
            &mut o,
            "tree",
            format!(
                "depth {}, {} leaves, {} boxes{}{}",
                self.tree.depth,
                thousands(self.tree.n_leaves),
                thousands(self.tree.n_boxes),
                if self.tree.root_scale > 1.0 {
                    format!(
                        "; root {:.2}x the points' bounding cube",
                        self.tree.root_scale
                    )
                } else {
                    String::new()
                },
                if self.tree.clusters > 1 {
                    format!(
                        "; {} far clusters ({} points outside the largest)",
                        self.tree.clusters,
                        thousands(self.tree.far_points)
                    )
                } else {
                    String::new()
                }
            ),
        );
        row(
            &mut o,
            "lists",
            format!(
                "U {}, V {}, W {}, X {}",
                thousands(self.tree.u_list),
                thousands(self.tree.v_list),
                thousands(self.tree.w_list),
                thousands(self.tree.x_list)
            ),
        );
        row(&mut o, "threads", self.threads.to_string());
        if let Some(c) = &self.cache {
            let c = match &self.cache_dir {
                Some(dir) => format!("{c} in {dir}"),
                None => c.clone(),
            };
            row(&mut o, "operator cache", c);
        }

        let _ = writeln!(
            o,
            "setup                {:>10}",
            seconds(self.setup.total_s)
        );
        for (label, s) in [
            ("tree", self.setup.tree_s),
            ("operators", self.setup.operators_s),
            ("M2L precompute", self.setup.m2l_precompute_s),
            ("layout", self.setup.layout_s),
        ] {
            let _ = writeln!(o, "  {label:<18} {:>10}", seconds(s));
        }
        let e = &self.evaluation;
        let repeats = if e.repeats > 1 {
            format!(" (best of {}, median {})", e.repeats, seconds(e.median_s))
        } else {
            String::new()
        };
        let _ = writeln!(o, "evaluation           {:>10}{repeats}", seconds(e.best_s));
        for (name, s) in OperatorSeconds::NAMES.iter().zip(e.operators_s.values()) {
            if *name == "Far" && s == 0.0 {
                continue;
            }
            let share = if e.best_s > 0.0 {
                100.0 * s / e.best_s
            } else {
                0.0
            };
            let _ = writeln!(o, "  {name:<18} {:>10} {share:>5.1}%", seconds(s));
        }
        let _ = writeln!(
            o,
            "setup + evaluation   {:>10}",
            seconds(self.setup.total_s + e.best_s)
        );
        if let Some(eps) = self.tolerance {
            let predicted = self
                .predicted_error
                .map(|e| format!(", predicted error {e:.2e}"))
                .unwrap_or_default();
            row(
                &mut o,
                "tolerance",
                format!(
                    "{eps:.2e} {}{predicted}",
                    if self.default_tolerance {
                        "(the default; --tolerance or --order to change it)"
                    } else {
                        "requested"
                    }
                ),
            );
            if let Some(model) = &self.cost_model {
                row(
                    &mut o,
                    "cost model",
                    if model.contains("calibrated on this machine") {
                        "calibrated on this machine (ferrofmm calibrate)"
                    } else {
                        "built-in (ferrofmm calibrate fits it to this machine)"
                    }
                    .to_string(),
                );
            }
            match &self.verification {
                Some(v) => {
                    for (i, a) in v.attempts.iter().enumerate() {
                        let grad = a
                            .measured
                            .gradient
                            .map(|g| format!(", gradient {g:.2e}"))
                            .unwrap_or_default()
                            + &a.measured
                                .hessian
                                .map(|h| format!(", Hessian {h:.2e}"))
                                .unwrap_or_default();
                        let label = if i == 0 { "verified" } else { "  raised order" };
                        row(
                            &mut o,
                            label,
                            format!(
                                "order {}: potential {:.2e}{grad} on {} sampled targets ({})",
                                a.order,
                                a.measured.potential,
                                a.measured.n_sampled,
                                seconds(a.check_s)
                            ),
                        );
                    }
                    let verdict = if v.met {
                        "met".to_string()
                    } else {
                        format!(
                            "NOT met after {} attempts: the result is less accurate than asked",
                            v.attempts.len()
                        )
                    };
                    row(&mut o, "  tolerance", verdict);
                }
                None => row(
                    &mut o,
                    "verified",
                    "off (--verify off): the error is only predicted".to_string(),
                ),
            }
        }
        match &self.errors {
            Some(err) => {
                let check = self
                    .direct_check_s
                    .map(|s| format!(", {}", seconds(s)))
                    .unwrap_or_default();
                // A periodic run's truth is its lattice sum (Ewald's, Hasimoto's or
                // the images' own) over every image.
                let truth = if self.periodic.is_some() {
                    "the lattice sum"
                } else {
                    "direct summation"
                };
                let _ = writeln!(
                    o,
                    "relative L2 error vs {truth} ({} sampled targets{check})",
                    err.n_sampled
                );
                row(&mut o, "potential", format!("{:.2e}", err.potential));
                if let Some(g) = err.gradient {
                    row(&mut o, "gradient", format!("{g:.2e}"));
                }
                if let Some(h) = err.hessian {
                    row(&mut o, "Hessian", format!("{h:.2e}"));
                }
                if let Some(p) = err.pressure {
                    row(&mut o, "pressure", format!("{p:.2e}"));
                }
                if let Some(p) = err.pressure_gradient {
                    row(&mut o, "pressure gradient", format!("{p:.2e}"));
                }
            }
            None => {
                let _ = writeln!(o, "relative L2 error    not checked (use --check N)");
            }
        }
        let _ = writeln!(
            o,
            "peak memory          {:>10}",
            mebibytes(self.peak_rss_bytes)
        );
        if let Some(m) = &self.memory {
            m.rows(&mut o);
        }
        let _ = writeln!(o, "wall time            {:>10}", seconds(self.wall_s));
        o
    }
}
