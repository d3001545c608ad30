//! Charts of a sweep (plotters), each written as PNG and SVG, one module
//! per chart (the runs grouped by series and the axis helpers in `data`):
//!
//! 1. [`time_vs_error`]: evaluation time against the relative L2 error of the
//!    potential, log-log, one line per scheme and precision (through the
//!    fastest leaf size at each order, labelled with the order), every
//!    configuration as a dot, and the Pareto front (no other configuration
//!    is both faster and more accurate) as a dashed black line; when
//!    gradients were evaluated, the same lines against the gradient's error
//!    dashed in the series' colour (squares at the orders);
//! 2. [`operators`]: evaluation time per operator as stacked bars per order,
//!    one panel per scheme and precision (fastest leaf size per order);
//! 3. [`error_vs_order`]: relative error against the order, one line per
//!    scheme and precision (potential solid, gradient dashed).
//!
//! Text is drawn with DejaVu Sans, compiled into the binary
//! (`assets/DejaVuSans.ttf`, Bitstream Vera licence in
//! `assets/DejaVuSans-LICENSE.txt`), so no system fonts are needed.

mod data;
mod error_vs_order;
mod operators;
mod time_vs_error;

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::chart::SeriesAnno;
use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;

use crate::error::{CliError, Result};
use crate::report::RunReport;
use data::{SeriesKey, SweepData, label};
use error_vs_order::ErrorVsOrder;
use operators::Operators;
use time_vs_error::{Time, TimeVsError};

/// The font every chart uses, registered once as `sans-serif`.
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
pub(super) const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (960, 640);

/// Series colours (Tableau 10).
pub(super) const COLORS: [RGBColor; 10] = [
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
pub(super) type DrawResult = std::result::Result<(), DrawError>;

fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is compiled in and known to parse; a failure would only
        // mean text-less charts, which `draw` then reports as an error.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// One chart, drawable on any backend (on a white background that
/// [`render`] fills first).
pub(super) trait Chart {
    /// Draws the chart on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static;
}

/// Write the four charts for `runs` into `dir`; returns the files written.
pub fn write_all(dir: &Path, runs: &[RunReport]) -> Result<Vec<PathBuf>> {
    if runs.is_empty() {
        return Ok(Vec::new());
    }
    register_font();
    let data = SweepData::new(runs);
    let mut files = Vec::new();
    files.extend(render(
        dir,
        "time_vs_error",
        &TimeVsError(&data, Time::Evaluation),
    )?);
    files.extend(render(
        dir,
        "total_time_vs_error",
        &TimeVsError(&data, Time::SetupAndEvaluation),
    )?);
    files.extend(render(dir, "operators", &Operators(&data))?);
    files.extend(render(dir, "error_vs_order", &ErrorVsOrder(&data))?);
    Ok(files)
}

/// Draws `chart` into `dir/stem.png` and `dir/stem.svg`.
fn render<C: Chart>(dir: &Path, stem: &str, chart: &C) -> Result<[PathBuf; 2]> {
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail = |path: &Path| {
        let path = path.to_path_buf();
        move |source: DrawError| CliError::Chart { path, source }
    };
    {
        let root = BitMapBackend::new(&png, SIZE).into_drawing_area();
        paint(chart, &root).map_err(fail(&png))?;
    }
    {
        let root = SVGBackend::new(&svg, SIZE).into_drawing_area();
        paint(chart, &root).map_err(fail(&svg))?;
    }
    Ok([png, svg])
}

/// `chart` on a white background, written out.
fn paint<C: Chart, DB: DrawingBackend>(chart: &C, root: &DrawingArea<DB, Shift>) -> DrawResult
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    chart.draw(root)?;
    root.present()?;
    Ok(())
}

/// A chart of `title` with the margins and label areas of the full-page
/// charts.
pub(super) fn full_page<'a, 'b, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    title: String,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, (FAMILY, 20))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72);
    builder
}

/// A gradient's errors as a dashed line in `color`, named for `key` in
/// the legend (whose sample the caller draws).
fn gradient_line<'c, 'a, DB, CT>(
    chart: &'c mut ChartContext<'a, DB, CT>,
    points: &[(f64, f64)],
    color: RGBColor,
    key: &SeriesKey,
) -> Result<&'c mut SeriesAnno<'a, DB>, DrawError>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate<From = (f64, f64)>,
{
    let line = DashedLineSeries::new(points.to_vec(), 8, 4, color.stroke_width(2));
    Ok(chart
        .draw_series(line)?
        .label(format!("{} gradient", label(key))))
}

/// The series legend of a chart, in its upper right corner.
pub(super) fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FAMILY, 14))
        .draw()?;
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::commands::{PrecisionArg, SchemeArg};
    use crate::report::{ErrorFigures, EvalSeconds, OperatorSeconds, SetupSeconds, TreeFigures};

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
            default_tolerance: false,
            predicted_error: None,
            charges: Some("signed".into()),
            verify: "n/a".into(),
            verification: None,
            scheme,
            method: "fmm".into(),
            direct_predicted_s: None,
            cost_model: None,
            fmm_predicted_s: None,
            precision,
            gradients: true,
            hessians: false,
            kernel: "laplace".into(),
            periodic: None,
            energy: None,
            sources: "charge".into(),
            threads: 2,
            cache: None,
            cache_dir: None,
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
                root_scale: 1.0,
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
                pressure: None,
                pressure_gradient: None,
            }),
            direct_check_s: Some(0.01),
            peak_rss_bytes: Some(50 << 20),
            wall_s: 1.0,
            memory: None,
        }
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
        // Runs whose parameters were chosen: starred, not in the series.
        let mut asked = fake_run(SchemeArg::Fft, PrecisionArg::F64, 7, 384);
        asked.tolerance = Some(1e-5);
        let mut defaults = fake_run(SchemeArg::Fft, PrecisionArg::F64, 8, 384);
        (defaults.tolerance, defaults.default_tolerance) = (Some(1e-6), true);
        runs.extend([asked, defaults]);
        let dir = std::env::temp_dir().join(format!("ferrofmm-charts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = write_all(&dir, &runs).unwrap();
        assert_eq!(files.len(), 8);
        for f in &files {
            let bytes = std::fs::read(f).unwrap();
            assert!(bytes.len() > 1000, "{} is nearly empty", f.display());
            if f.extension().unwrap() == "png" {
                assert_eq!(&bytes[1..4], b"PNG");
            } else {
                let text = String::from_utf8(bytes).unwrap();
                let name = f.file_name().unwrap().to_string_lossy();
                let time_chart = name.ends_with("time_vs_error.svg");
                assert!(text.contains("<svg"), "{}", f.display());
                assert_eq!(text.contains("Pareto"), time_chart, "{}", f.display());
                // The chosen runs are labelled on both time charts only,
                // and the series hold no fft line (all fft runs were chosen).
                for label in ["eps 1e-5: p 7 fft 384", "defaults: p 8 fft 384"] {
                    assert_eq!(text.contains(label), time_chart, "{}", f.display());
                }
                assert!(!text.contains("fft f64"), "{}", f.display());
            }
        }
        // A single run still draws.
        write_all(&dir, &runs[..1]).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
