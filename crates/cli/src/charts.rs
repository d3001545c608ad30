//! Charts of a sweep (plotters), each written as PNG and SVG:
//!
//! 1. `time_vs_error`: evaluation time against the relative L2 error of the
//!    potential, log-log, one line per scheme and precision (through the
//!    fastest leaf size at each order, labelled with the order), every
//!    configuration as a dot, and the Pareto front (no other configuration
//!    is both faster and more accurate) as a dashed black line; when
//!    gradients were evaluated, the same lines against the gradient's error
//!    dashed in the series' colour (squares at the orders);
//! 2. `operators`: evaluation time per operator as stacked bars per order,
//!    one panel per scheme and precision (fastest leaf size per order);
//! 3. `error_vs_order`: relative error against the order, one line per
//!    scheme and precision (potential solid, gradient dashed).
//!
//! Text is drawn with DejaVu Sans, compiled into the binary
//! (`assets/DejaVuSans.ttf`, Bitstream Vera licence in
//! `assets/DejaVuSans-LICENSE.txt`), so no system fonts are needed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::commands::{PrecisionArg, SchemeArg};
use crate::error::{CliError, Result};
use crate::report::{OperatorSeconds, RunReport};

/// The font every chart uses, registered once as `sans-serif`.
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (960, 640);

/// Series colours (Tableau 10).
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// What drawing a chart can fail with: plotters' error for the backend
/// (`DrawingAreaErrorKind<DB::ErrorType>`: a backend error such as an
/// unwritable file, or a layout error), kept as the typed source of
/// [`CliError::Chart`].
type DrawError = Box<dyn std::error::Error + Send + Sync>;
type DrawResult = std::result::Result<(), DrawError>;

fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is compiled in and known to parse; a failure would only
        // mean text-less charts, which `draw` then reports as an error.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// One chart, drawable on any backend.
trait Chart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static;
}

/// Write the three charts for `runs` into `dir`; returns the files written.
pub fn write_all(dir: &Path, runs: &[RunReport]) -> Result<Vec<PathBuf>> {
    if runs.is_empty() {
        return Ok(Vec::new());
    }
    register_font();
    let data = SweepData::new(runs);
    let mut files = Vec::new();
    files.extend(render(dir, "time_vs_error", &TimeVsError(&data))?);
    files.extend(render(dir, "operators", &Operators(&data))?);
    files.extend(render(dir, "error_vs_order", &ErrorVsOrder(&data))?);
    Ok(files)
}

fn render<C: Chart>(dir: &Path, stem: &str, chart: &C) -> Result<[PathBuf; 2]> {
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail = |path: &Path| {
        let path = path.to_path_buf();
        move |source: DrawError| CliError::Chart { path, source }
    };
    {
        let root = BitMapBackend::new(&png, SIZE).into_drawing_area();
        chart.draw(&root).map_err(fail(&png))?;
        root.present().map_err(|e| fail(&png)(e.into()))?;
    }
    {
        let root = SVGBackend::new(&svg, SIZE).into_drawing_area();
        chart.draw(&root).map_err(fail(&svg))?;
        root.present().map_err(|e| fail(&svg)(e.into()))?;
    }
    Ok([png, svg])
}

/// Key of a line: scheme and precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct SeriesKey {
    scheme: SchemeArg,
    precision: PrecisionArg,
}

/// The sweep's runs grouped the way the charts need them.
struct SweepData<'a> {
    runs: &'a [RunReport],
    /// Per series, per order: the fastest run over leaf sizes.
    series: BTreeMap<SeriesKey, BTreeMap<usize, &'a RunReport>>,
    /// More than one leaf size in the sweep.
    several_leaf_sizes: bool,
    title: String,
}

impl<'a> SweepData<'a> {
    fn new(runs: &'a [RunReport]) -> Self {
        let mut series: BTreeMap<SeriesKey, BTreeMap<usize, &RunReport>> = BTreeMap::new();
        for run in runs {
            let by_order = series.entry(key(run)).or_default();
            let slot = by_order.entry(run.order).or_insert(run);
            if run.evaluation.best_s < slot.evaluation.best_s {
                *slot = run;
            }
        }
        let first = &runs[0];
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
            series,
            several_leaf_sizes,
            title,
        }
    }

    fn color(&self, key: &SeriesKey) -> RGBColor {
        let index = self.series.keys().position(|k| k == key).unwrap_or(0);
        COLORS[index % COLORS.len()]
    }

    /// Targets sampled for the errors (the most of any run).
    fn sampled(&self) -> usize {
        self.runs
            .iter()
            .filter_map(|r| r.errors.as_ref().map(|e| e.n_sampled))
            .max()
            .unwrap_or(0)
    }

    fn orders(&self) -> (usize, usize) {
        let min = self.runs.iter().map(|r| r.order).min().unwrap_or(0);
        let max = self.runs.iter().map(|r| r.order).max().unwrap_or(0);
        (min, max)
    }
}

fn key(run: &RunReport) -> SeriesKey {
    SeriesKey {
        scheme: run.scheme,
        precision: run.precision,
    }
}

fn label(key: &SeriesKey) -> String {
    format!("{} {}", key.scheme, key.precision)
}

/// Smallest positive value an axis shows (an exact result has error 0).
const FLOOR: f64 = 1e-17;

/// A log-axis range covering `values`, widened to whole decades (plotters
/// places log ticks from the first power of ten inside the range, so a
/// range starting mid-decade would lose its lowest labels).
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
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
fn log_labels(range: &std::ops::Range<f64>) -> usize {
    if (range.end / range.start).log10() <= 2.01 {
        40
    } else {
        10
    }
}

/// Integer orders as tick labels, nothing between them.
fn order_label(x: &f64) -> String {
    if (x - x.round()).abs() < 1e-6 {
        format!("{}", x.round())
    } else {
        String::new()
    }
}

/// A tick value with few digits: `5`, `2.5`, `0.5`, `0.03`.
fn short(y: &f64) -> String {
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

fn sci(x: &f64) -> String {
    format!("{x:.0e}")
}

/// Runs not beaten in both time and error by another, fastest first.
fn pareto_front<'a>(runs: &[&'a RunReport]) -> Vec<&'a RunReport> {
    let mut sorted: Vec<&RunReport> = runs
        .iter()
        .copied()
        .filter(|r| r.errors.is_some())
        .collect();
    sorted.sort_by(|a, b| {
        a.evaluation
            .best_s
            .total_cmp(&b.evaluation.best_s)
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
fn gradient(run: &RunReport) -> Option<f64> {
    run.errors
        .as_ref()
        .and_then(|e| e.gradient)
        .map(|g| g.max(FLOOR))
}

fn potential(run: &RunReport) -> f64 {
    run.errors
        .as_ref()
        .map_or(f64::NAN, |e| e.potential.max(FLOOR))
}

struct TimeVsError<'a>(&'a SweepData<'a>);

impl Chart for TimeVsError<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
        root.fill(&WHITE)?;
        let checked: Vec<&RunReport> = data.runs.iter().filter(|r| r.errors.is_some()).collect();
        let x_range = log_range(
            checked
                .iter()
                .map(|r| potential(r))
                .chain(checked.iter().filter_map(|r| gradient(r))),
        );
        let y_range = log_range(checked.iter().map(|r| r.evaluation.best_s));
        let (x_labels, y_labels) = (log_labels(&x_range), log_labels(&y_range));
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("Evaluation time vs accuracy ({})", data.title),
                (FAMILY, 20),
            )
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())?;
        chart
            .configure_mesh()
            .x_desc(if checked.iter().any(|r| gradient(r).is_some()) {
                format!(
                    "relative L2 error ({} sampled targets): potential solid, gradient dashed",
                    data.sampled()
                )
            } else {
                format!(
                    "relative L2 error of the potential ({} sampled targets)",
                    data.sampled()
                )
            })
            .y_desc("evaluation time [s]")
            .x_label_formatter(&sci)
            .x_labels(x_labels)
            .y_labels(y_labels)
            .y_label_formatter(&short)
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 16))
            .draw()?;

        for (key, by_order) in &data.series {
            let color = data.color(key);
            let all: Vec<(f64, f64)> = checked
                .iter()
                .filter(|r| &self::key(r) == key)
                .map(|r| (potential(r), r.evaluation.best_s))
                .collect();
            chart.draw_series(
                all.iter()
                    .map(|&p| Circle::new(p, 3, color.mix(0.5).filled())),
            )?;
            let line: Vec<(f64, f64, usize)> = by_order
                .values()
                .filter(|r| r.errors.is_some())
                .map(|r| (potential(r), r.evaluation.best_s, r.order))
                .collect();
            chart
                .draw_series(LineSeries::new(
                    line.iter().map(|&(x, y, _)| (x, y)),
                    color.stroke_width(2),
                ))?
                .label(label(key))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart.draw_series(line.iter().map(|&(x, y, p)| {
                EmptyElement::at((x, y))
                    + Circle::new((0, 0), 4, color.filled())
                    + Text::new(
                        format!("p={p}"),
                        (6, -14),
                        (FAMILY, 12).into_font().color(&color),
                    )
            }))?;
        }

        for (key, by_order) in &data.series {
            let color = data.color(key);
            let line: Vec<(f64, f64)> = by_order
                .values()
                .filter_map(|r| gradient(r).map(|g| (g, r.evaluation.best_s)))
                .collect();
            if line.is_empty() {
                continue;
            }
            chart
                .draw_series(DashedLineSeries::new(
                    line.clone(),
                    8,
                    4,
                    color.stroke_width(2),
                ))?
                .label(format!("{} gradient", label(key)))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(1))
                });
            chart.draw_series(line.iter().map(|&(x, y)| {
                Rectangle::new([(x / 1.08, y / 1.04), (x * 1.08, y * 1.04)], color.filled())
            }))?;
        }

        let front = pareto_front(&checked);
        if !front.is_empty() {
            let mut points: Vec<(f64, f64)> = front
                .iter()
                .map(|r| (potential(r), r.evaluation.best_s))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(DashedLineSeries::new(
                    points.clone(),
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))?
                .label("Pareto front")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1))
                });
            chart.draw_series(
                points
                    .iter()
                    .map(|&p| Circle::new(p, 7, BLACK.stroke_width(1))),
            )?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FAMILY, 14))
            .draw()?;
        Ok(())
    }
}

struct Operators<'a>(&'a SweepData<'a>);

impl Chart for Operators<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
        root.fill(&WHITE)?;
        let title = format!("Evaluation time per operator ({})", data.title);
        let root = root.titled(&title, (FAMILY, 20))?;
        let (_, height) = root.dim_in_pixel();
        let (root, legend) = root.split_vertically(height.saturating_sub(36));
        let op_colors: Vec<RGBColor> = (0..OperatorSeconds::NAMES.len())
            .map(|k| COLORS[k % COLORS.len()])
            .collect();
        // One legend for all panels, in stacking order from the bottom.
        for (k, name) in OperatorSeconds::NAMES.iter().enumerate() {
            let x = 60 + 100 * k as i32;
            legend.draw(&Rectangle::new(
                [(x, 12), (x + 14, 26)],
                op_colors[k].filled(),
            ))?;
            legend.draw(&Text::new(*name, (x + 20, 12), (FAMILY, 14)))?;
        }
        let panels_n = data.series.len().max(1);
        let cols = panels_n.min(2);
        let rows = panels_n.div_ceil(cols);
        let panels = root.split_evenly((rows, cols));
        let (min_order, max_order) = data.orders();
        let y_max = data
            .series
            .values()
            .flat_map(|m| m.values())
            .map(|r| r.evaluation.operators_s.values().iter().sum::<f64>())
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1.05;
        for ((key, by_order), panel) in data.series.iter().zip(panels.iter()) {
            let caption = if data.several_leaf_sizes {
                format!("{} (fastest leaf size per order)", label(key))
            } else {
                format!("{} (leaf size {})", label(key), data.runs[0].leaf_size)
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(caption, (FAMILY, 16))
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(56)
                .build_cartesian_2d(
                    (min_order as f64 - 0.6)..(max_order as f64 + 0.6),
                    0.0..y_max,
                )?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_desc("order p")
                .y_desc("time [s]")
                .x_labels(max_order - min_order + 3)
                .x_label_formatter(&order_label)
                .label_style((FAMILY, 12))
                .axis_desc_style((FAMILY, 14))
                .draw()?;
            for (k, color) in op_colors.iter().copied().enumerate() {
                let bars: Vec<Rectangle<(f64, f64)>> = by_order
                    .values()
                    .map(|r| {
                        let v = r.evaluation.operators_s.values();
                        let base: f64 = v[..k].iter().sum();
                        let x = r.order as f64;
                        Rectangle::new([(x - 0.35, base), (x + 0.35, base + v[k])], color.filled())
                    })
                    .collect();
                chart.draw_series(bars)?;
            }
        }
        Ok(())
    }
}

struct ErrorVsOrder<'a>(&'a SweepData<'a>);

impl Chart for ErrorVsOrder<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
        root.fill(&WHITE)?;
        let (min_order, max_order) = data.orders();
        let errors = data.runs.iter().filter_map(|r| r.errors.as_ref());
        let y_range = log_range(
            errors
                .flat_map(|e| [Some(e.potential), e.gradient])
                .flatten(),
        );
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("Relative error vs order ({})", data.title),
                (FAMILY, 20),
            )
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(
                (min_order as f64 - 0.5)..(max_order as f64 + 0.5),
                y_range.log_scale(),
            )?;
        chart
            .configure_mesh()
            .x_desc("expansion order p")
            .y_desc(format!(
                "relative L2 error ({} sampled targets)",
                data.sampled()
            ))
            .x_labels(max_order - min_order + 2)
            .x_label_formatter(&order_label)
            .y_label_formatter(&sci)
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        for (key, by_order) in &data.series {
            let color = data.color(key);
            // Schemes often agree to plotting accuracy: the dense scheme gets
            // large hollow markers so that the SVD scheme's dots show inside.
            let hollow = key.scheme == SchemeArg::Dense;
            let style = if hollow {
                color.stroke_width(2)
            } else {
                color.filled()
            };
            let size = if hollow { 7 } else { 4 };
            let pot: Vec<(f64, f64)> = by_order
                .values()
                .filter_map(|r| {
                    r.errors
                        .as_ref()
                        .map(|e| (r.order as f64, e.potential.max(FLOOR)))
                })
                .collect();
            chart
                .draw_series(LineSeries::new(pot.clone(), color.stroke_width(2)))?
                .label(format!("{} potential", label(key)))
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (20, 0)], color.stroke_width(2))
                        + Circle::new((10, 0), size.min(6), style)
                });
            chart.draw_series(pot.iter().map(|&p| Circle::new(p, size, style)))?;
            let grad: Vec<(f64, f64)> = by_order
                .values()
                .filter_map(|r| {
                    r.errors
                        .as_ref()
                        .and_then(|e| e.gradient)
                        .map(|g| (r.order as f64, g.max(FLOOR)))
                })
                .collect();
            if !grad.is_empty() {
                chart
                    .draw_series(DashedLineSeries::new(
                        grad.clone(),
                        8,
                        4,
                        color.stroke_width(2),
                    ))?
                    .label(format!("{} gradient", label(key)))
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (6, 0)], color.stroke_width(2))
                            + PathElement::new(vec![(14, 0), (20, 0)], color.stroke_width(2))
                            + TriangleMarker::new((10, 0), size.min(6), style)
                    });
                chart.draw_series(grad.iter().map(|&p| TriangleMarker::new(p, size, style)))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FAMILY, 14))
            .draw()?;
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::report::{ErrorFigures, EvalSeconds, SetupSeconds, TreeFigures};

    /// A fake run for chart tests.
    pub(crate) fn fake_run(
        scheme: SchemeArg,
        precision: PrecisionArg,
        order: usize,
        leaf: usize,
    ) -> RunReport {
        let error = 10f64.powi(-(order as i32))
            * match precision {
                PrecisionArg::F32 => 3.0,
                _ => 1.0,
            };
        let time = 0.1 * order as f64 / leaf as f64
            * 150.0
            * match scheme {
                SchemeArg::Dense => 1.5,
                _ => 1.0,
            };
        RunReport {
            command: "demo".into(),
            geometry: Some("cube".into()),
            n_sources: 2000,
            n_targets: 2000,
            order,
            leaf_size: leaf,
            tolerance: None,
            predicted_error: None,
            charges: Some("signed".into()),
            verify: "n/a".into(),
            verification: None,
            scheme,
            precision,
            gradients: true,
            hessians: false,
            kernel: "laplace".into(),
            sources: "charge".into(),
            threads: 2,
            cache: None,
            tree: TreeFigures {
                depth: 3,
                n_boxes: 73,
                n_leaves: 64,
                n_surface: 6 * (order - 1) * (order - 1) + 2,
                u_list: 1000,
                v_list: 2000,
                w_list: 0,
                x_list: 0,
                m2l_bytes: 1 << 20,
                clusters: 1,
                far_points: 0,
            },
            setup: SetupSeconds {
                tree_s: 0.01,
                operators_s: 0.02,
                m2l_precompute_s: 0.03,
                layout_s: 0.001,
                total_s: 0.061,
            },
            evaluation: EvalSeconds {
                repeats: 1,
                best_s: time,
                median_s: time,
                operators_s: OperatorSeconds {
                    p2m: 0.1 * time,
                    m2m: 0.05 * time,
                    m2l: 0.4 * time,
                    p2l: 0.0,
                    l2l: 0.05 * time,
                    l2p: 0.1 * time,
                    m2p: 0.0,
                    p2p: 0.3 * time,
                    far: 0.0,
                },
            },
            errors: Some(ErrorFigures {
                n_sampled: 1000,
                potential: error,
                gradient: Some(10.0 * error),
                hessian: None,
            }),
            direct_check_s: Some(0.01),
            peak_rss_bytes: Some(50 << 20),
            wall_s: 1.0,
        }
    }

    #[test]
    fn pareto_front_keeps_undominated_runs() {
        use {PrecisionArg::F64, SchemeArg::Dense, SchemeArg::Svd};
        let a = fake_run(Svd, F64, 3, 150); // fast, inaccurate
        let b = fake_run(Svd, F64, 6, 150); // slower, accurate
        let c = fake_run(Dense, F64, 3, 150); // slower than a, same error: dominated
        let front = pareto_front(&[&a, &b, &c]);
        assert_eq!(front.len(), 2);
        assert_eq!((front[0].order, front[0].scheme), (3, Svd));
        assert_eq!(front[1].order, 6);
    }

    #[test]
    fn writes_non_empty_png_and_svg() {
        let mut runs = Vec::new();
        for scheme in [SchemeArg::Svd, SchemeArg::Dense] {
            for precision in [PrecisionArg::F32, PrecisionArg::F64] {
                for order in 3..=6 {
                    for leaf in [64, 150] {
                        runs.push(fake_run(scheme, precision, order, leaf));
                    }
                }
            }
        }
        let dir = std::env::temp_dir().join(format!("ferrofmm-charts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = write_all(&dir, &runs).unwrap();
        assert_eq!(files.len(), 6);
        for f in &files {
            let bytes = std::fs::read(f).unwrap();
            assert!(bytes.len() > 1000, "{} is nearly empty", f.display());
            if f.extension().unwrap() == "png" {
                assert_eq!(&bytes[1..4], b"PNG");
            } else {
                let text = String::from_utf8(bytes).unwrap();
                assert!(
                    text.contains("<svg")
                        && text.contains("Pareto") == f.ends_with("time_vs_error.svg")
                );
            }
        }
        // A single run still draws.
        write_all(&dir, &runs[..1]).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
