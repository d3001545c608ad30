//! Draws `docs/charts/outliers.svg`: error and time against the distance
//! of one outlier, one curve per CSV file written by `ferrofmm-fmm`'s
//! `outlier_sweep` example (compiled against different checkouts).
//!
//! ```text
//! cargo run --release -p ferrofmm-cli --features sweeps --example outlier_chart -- \
//!     docs/charts/outliers.svg "round 1=r1.csv" "exact origin=origin.csv" "forest=after.csv"
//! ```
//!
//! Each CSV has the header
//! `distance,potential_error,gradient_error,build_s,evaluate_s,p2p_s,depth`;
//! the row with distance 0 is the cloud without the outlier, drawn as a
//! dashed reference line.
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::error::Error;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (960, 440);
const COLORS: [RGBColor; 4] = [
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
];

/// One row of the sweep.
struct Row {
    distance: f64,
    potential: f64,
    total_s: f64,
    p2p_s: f64,
}

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let f: Vec<f64> = line
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{path}:{}: {e}", k + 1))?;
        if f.len() != 7 {
            return Err(format!("{path}:{}: expected 7 columns", k + 1).into());
        }
        rows.push(Row {
            distance: f[0],
            potential: f[1],
            total_s: f[3] + f[4],
            p2p_s: f[5],
        });
    }
    Ok(rows)
}

/// `(clean row, rows with an outlier)`.
fn split(rows: &[Row]) -> (Option<&Row>, Vec<&Row>) {
    (
        rows.iter().find(|r| r.distance == 0.0),
        rows.iter().filter(|r| r.distance > 0.0).collect(),
    )
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: outlier_chart OUT.svg LABEL=FILE.csv [LABEL=FILE.csv ...] (at most 4)";
    let Some((out, series)) = args.split_first() else {
        return Err(usage.into());
    };
    if series.is_empty() || series.len() > COLORS.len() {
        return Err(usage.into());
    }
    let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    let mut runs = Vec::new();
    for (arg, color) in series.iter().zip(COLORS) {
        let (label, path) = arg.split_once('=').ok_or(usage)?;
        runs.push((label.to_string(), read(path)?, color));
    }

    if out.ends_with(".png") {
        draw(BitMapBackend::new(out, SIZE).into_drawing_area(), &runs)
    } else {
        draw(SVGBackend::new(out, SIZE).into_drawing_area(), &runs)
    }
}

type Series = (String, Vec<Row>, RGBColor);

/// Both panels on `root` (any plotters backend).
fn draw<DB>(root: DrawingArea<DB, Shift>, runs: &[Series]) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(
        "One point at (D, D, D) beside a unit cloud: f64, p = 6, zero-mean charges",
        (FAMILY, 18),
    )?;
    let panels = root.split_evenly((1, 2));
    let x_range = 1.0..1e15;
    let positive = |v: f64| v.is_finite() && v > 0.0;

    let all = runs.iter().flat_map(|(_, rows, _)| rows.iter());
    let (lo, hi) = all
        .clone()
        .map(|r| r.potential)
        .filter(|v| positive(*v))
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let mut chart = ChartBuilder::on(&panels[0])
        .caption("potential error (relative L2)", (FAMILY, 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(
            x_range.clone().log_scale(),
            (lo / 3.0..hi * 3.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("outlier distance D (cloud widths)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style((FAMILY, 13))
        .draw()?;
    for (label, rows, color) in runs {
        let color = *color;
        let (clean, far) = split(rows);
        let pts: Vec<(f64, f64)> = far
            .iter()
            .filter(|r| positive(r.potential))
            .map(|r| (r.distance, r.potential))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        if let Some(c) = clean {
            chart.draw_series(DashedLineSeries::new(
                [(1.0, c.potential), (1e15, c.potential)],
                6,
                4,
                color.mix(0.6).stroke_width(1),
            ))?;
        }
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 13))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.3))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;

    let (lo, hi) = all
        .flat_map(|r| [r.total_s, r.p2p_s])
        .filter(|v| positive(*v))
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let mut chart = ChartBuilder::on(&panels[1])
        .caption(
            "seconds: build + evaluate (solid), P2P (dashed)",
            (FAMILY, 16),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x_range.log_scale(), (lo / 2.0..hi * 2.0).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("outlier distance D (cloud widths)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.2}"))
        .label_style((FAMILY, 13))
        .draw()?;
    for (_, rows, color) in runs {
        let color = *color;
        let (_, far) = split(rows);
        let total: Vec<(f64, f64)> = far.iter().map(|r| (r.distance, r.total_s)).collect();
        let p2p: Vec<(f64, f64)> = far
            .iter()
            .filter(|r| positive(r.p2p_s))
            .map(|r| (r.distance, r.p2p_s))
            .collect();
        chart.draw_series(LineSeries::new(total.clone(), color.stroke_width(2)))?;
        chart.draw_series(total.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        chart.draw_series(DashedLineSeries::new(p2p, 6, 4, color.stroke_width(2)))?;
    }
    root.present()?;
    Ok(())
}
