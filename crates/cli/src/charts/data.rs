//! The sweep's runs grouped by series (scheme and precision), the runs
//! whose parameters were chosen (defaults, `--tolerance`) apart, and the
//! helpers of the charts' axes: log ranges and ticks, labels, the errors
//! of a run, the Pareto front.

use std::collections::BTreeMap;

use plotters::style::RGBColor;

use super::COLORS;
use crate::commands::{PrecisionArg, SchemeArg};
use crate::report::RunReport;

/// Key of a line: scheme and precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct SeriesKey {
    pub(super) scheme: SchemeArg,
    pub(super) precision: PrecisionArg,
}

/// The sweep's runs grouped the way the charts need them.
pub(super) struct SweepData<'a> {
    /// The runs of the grid (order, scheme, precision and leaf size given).
    pub(super) runs: Vec<&'a RunReport>,
    /// The runs whose parameters the library chose (the defaults, or a
    /// `--tolerance`): marked on the time charts, outside the series.
    pub(super) chosen: Vec<&'a RunReport>,
    /// Per series, per order: the fastest run over leaf sizes.
    pub(super) series: BTreeMap<SeriesKey, BTreeMap<usize, &'a RunReport>>,
    /// More than one leaf size in the sweep.
    pub(super) several_leaf_sizes: bool,
    pub(super) title: String,
}

impl<'a> SweepData<'a> {
    /// Groups `all` (not empty).
    pub(super) fn new(all: &'a [RunReport]) -> Self {
        let (chosen, runs): (Vec<&RunReport>, Vec<&RunReport>) =
            all.iter().partition(|r| is_chosen(r));
        let mut series: BTreeMap<SeriesKey, BTreeMap<usize, &RunReport>> = BTreeMap::new();
        for &run in &runs {
            let by_order = series.entry(key(run)).or_default();
            let slot = by_order.entry(run.order).or_insert(run);
            if run.evaluation.best_s < slot.evaluation.best_s {
                *slot = run;
            }
        }
        let first = runs.first().copied().unwrap_or(&all[0]);
        let several_leaf_sizes = runs.iter().any(|r| r.leaf_size != first.leaf_size);
        let what = match (first.gradients, first.hessians) {
            (_, true) => "potential + gradient + Hessian",
            (true, false) => "potential + gradient",
            (false, false) => "potential",
        };
        let title = format!(
            "{}, N = {}, {}, {what}, {} threads",
            first.kernel,
            crate::report::thousands(first.n_sources),
            first.geometry.as_deref().unwrap_or("points from files"),
            first.threads
        );
        SweepData {
            runs,
            chosen,
            series,
            several_leaf_sizes,
            title,
        }
    }

    /// The colour of a series.
    pub(super) fn color(&self, key: &SeriesKey) -> RGBColor {
        let index = self.series.keys().position(|k| k == key).unwrap_or(0);
        COLORS[index % COLORS.len()]
    }

    /// Targets sampled for the errors (the most of any run).
    pub(super) fn sampled(&self) -> usize {
        self.runs
            .iter()
            .chain(&self.chosen)
            .filter_map(|r| r.errors.as_ref().map(|e| e.n_sampled))
            .max()
            .unwrap_or(0)
    }

    /// The smallest and largest order of the runs.
    pub(super) fn orders(&self) -> (usize, usize) {
        let min = self.runs.iter().map(|r| r.order).min().unwrap_or(0);
        let max = self.runs.iter().map(|r| r.order).max().unwrap_or(0);
        (min, max)
    }
}

/// Whether the library chose the run's parameters: the defaults (no
/// setting given) or a `--tolerance`.
pub(super) fn is_chosen(run: &RunReport) -> bool {
    run.tolerance.is_some() || run.default_tolerance
}

/// How a chosen run is named on a chart: `defaults` or `eps 1e-6`, and
/// what was chosen (order, scheme and leaf size: `p 7 fft 384`, or
/// `direct sum`).
pub(super) fn chosen_label(run: &RunReport) -> String {
    let what = if run.default_tolerance {
        "defaults".to_string()
    } else {
        format!("eps {}", sci(&run.tolerance.unwrap_or(f64::NAN)))
    };
    if run.method == "direct" {
        format!("{what}: direct sum")
    } else {
        format!("{what}: p {} {} {}", run.order, run.scheme, run.leaf_size)
    }
}

/// The series of a run.
pub(super) fn key(run: &RunReport) -> SeriesKey {
    SeriesKey {
        scheme: run.scheme,
        precision: run.precision,
    }
}

/// A series' name in legends and captions.
pub(super) fn label(key: &SeriesKey) -> String {
    format!("{} {}", key.scheme, key.precision)
}

/// Smallest positive value an axis shows (an exact result has error 0).
pub(super) const FLOOR: f64 = 1e-17;

/// A log-axis range covering `values`, widened to whole decades (plotters
/// places log ticks from the first power of ten inside the range, so a
/// range starting mid-decade would lose its lowest labels).
pub(super) fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values {
        let v = v.max(FLOOR);
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() || hi <= 0.0 {
        return 1e-3..1.0;
    }
    // Slightly below the decade, so that rounding in plotters' log10 of
    // the start cannot skip the first label.
    let lo = 10f64.powf((lo / 1.1).log10().floor()) * (1.0 - 1e-9);
    let hi = 10f64.powf((hi * 1.1).log10().ceil());
    lo..hi.max(lo * 10.0)
}

/// Tick count for a log axis: with at most two decades, ask for enough
/// that plotters labels 2, 3, ... 9 within each decade too.
pub(super) fn log_labels(range: &std::ops::Range<f64>) -> usize {
    if (range.end / range.start).log10() <= 2.01 {
        40
    } else {
        10
    }
}

/// Integer orders as tick labels, nothing between them.
pub(super) fn order_label(x: &f64) -> String {
    if (x - x.round()).abs() < 1e-6 {
        format!("{}", x.round())
    } else {
        String::new()
    }
}

/// A tick value with few digits: `5`, `2.5`, `0.5`, `0.03`.
pub(super) fn short(y: &f64) -> String {
    let decimals = if *y >= 1.0 {
        3
    } else {
        (-y.log10()).ceil().max(0.0) as usize + 1
    };
    let text = format!("{y:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

/// A tick value in scientific notation: `1e-6`.
pub(super) fn sci(x: &f64) -> String {
    format!("{x:.0e}")
}

/// Runs not beaten in both time (`time` of a run) and error by another,
/// fastest first.
pub(super) fn pareto_front<'a>(
    runs: &[&'a RunReport],
    time: impl Fn(&RunReport) -> f64,
) -> Vec<&'a RunReport> {
    let mut sorted: Vec<&RunReport> = runs
        .iter()
        .copied()
        .filter(|r| r.errors.is_some())
        .collect();
    sorted.sort_by(|a, b| {
        time(a)
            .total_cmp(&time(b))
            .then(potential(a).total_cmp(&potential(b)))
    });
    let mut front = Vec::new();
    let mut best_error = f64::INFINITY;
    for r in sorted {
        if potential(r) < best_error {
            best_error = potential(r);
            front.push(r);
        }
    }
    front
}

/// The gradient's error of a checked run with gradients.
pub(super) fn gradient(run: &RunReport) -> Option<f64> {
    run.errors
        .as_ref()
        .and_then(|e| e.gradient)
        .map(|g| g.max(FLOOR))
}

/// The potential's error of a run (`NaN` for an unchecked one).
pub(super) fn potential(run: &RunReport) -> f64 {
    run.errors
        .as_ref()
        .map_or(f64::NAN, |e| e.potential.max(FLOOR))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::charts::tests::fake_run;

    #[test]
    fn pareto_front_keeps_undominated_runs() {
        use {PrecisionArg::F64, SchemeArg::Dense, SchemeArg::Svd};
        let a = fake_run(Svd, F64, 3, 150); // fast, inaccurate
        let b = fake_run(Svd, F64, 6, 150); // slower, accurate
        let c = fake_run(Dense, F64, 3, 150); // slower than a, same error: dominated
        let eval = |r: &RunReport| r.evaluation.best_s;
        let front = pareto_front(&[&a, &b, &c], eval);
        assert_eq!(front.len(), 2);
        assert_eq!((front[0].order, front[0].scheme), (3, Svd));
        assert_eq!(front[1].order, 6);
        // By another time (here, a long setup of `a`), another front.
        let mut slow_setup = a.clone();
        slow_setup.setup.total_s = 100.0;
        let total = |r: &RunReport| r.setup.total_s + r.evaluation.best_s;
        let front = pareto_front(&[&slow_setup, &b, &c], total);
        assert_eq!(front.len(), 2);
        assert_eq!((front[0].order, front[0].scheme), (3, Dense));
    }
}
