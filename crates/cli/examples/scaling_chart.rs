//! Draws the large-N chart of docs/performance.md ("Memory and large N",
//! `docs/charts/time_per_point.svg`): two panels against the number of
//! points N (log scale), the evaluation's microseconds a point and the
//! measured peak bytes a point, one series per code or setting.
//!
//! ```text
//! cargo run --release -p ferrofmm-cli --features sweeps --example scaling_chart -- \
//!     docs/charts/time_per_point.svg "TITLE" docs/charts/time_per_point.csv
//! ```
//!
//! The CSV has the header `series,n,eval_s,peak_bytes_per_point` (one row
//! per run; rows of one series form its line, in file order), as the JSON
//! of `ferrofmm demo --json` gives them (`evaluation.best_s`,
//! `memory.peak_bytes_per_point`).
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::error::Error;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (1100, 460);
const COLORS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
];

/// One run.
struct Row {
    series: String,
    n: f64,
    /// Microseconds a point, bytes a point.
    values: [f64; 2],
}

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 4 {
            return Err(format!("{path}:{}: expected 4 columns", k + 1).into());
        }
        let num = |s: &str| {
            s.trim()
                .parse::<f64>()
                .map_err(|e| format!("{path}:{}: {e}", k + 1))
        };
        let n = num(f[1])?;
        if !(n.is_finite() && n > 0.0) {
            return Err(format!("{path}:{}: N must be positive", k + 1).into());
        }
        rows.push(Row {
            series: f[0].trim().to_string(),
            n,
            values: [num(f[2])? / n * 1e6, num(f[3])?],
        });
    }
    if rows.is_empty() {
        return Err(format!("{path}: no rows").into());
    }
    Ok(rows)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, title, csv] = args.as_slice() else {
        return Err("usage: scaling_chart OUT.svg|OUT.png TITLE FILE.csv".into());
    };
    let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    let rows = read(csv)?;
    if out.ends_with(".png") {
        draw(
            BitMapBackend::new(out, SIZE).into_drawing_area(),
            title,
            &rows,
        )
    } else {
        draw(SVGBackend::new(out, SIZE).into_drawing_area(), title, &rows)
    }
}

/// Both panels on `root` (any plotters backend).
fn draw<DB>(root: DrawingArea<DB, Shift>, title: &str, rows: &[Row]) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 17))?;
    let panels = root.split_evenly((1, 2));
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.series.as_str()) {
            names.push(&r.series);
        }
    }
    let (n_lo, n_hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| {
        (a.min(r.n), b.max(r.n))
    });
    let panel_names = [
        ("evaluation, microseconds a point", "us a point"),
        ("peak memory, bytes a point", "bytes a point"),
    ];
    for (which, (panel, (caption, axis))) in panels.iter().zip(panel_names).enumerate() {
        let hi = rows
            .iter()
            .map(|r| r.values[which])
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, (FAMILY, 15))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d((n_lo / 1.5..n_hi * 1.5).log_scale(), 0.0..hi * 1.15)?;
        chart
            .configure_mesh()
            .x_desc("points N")
            .y_desc(axis)
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.1}"))
            .label_style((FAMILY, 12))
            .draw()?;
        for (name, color) in names.iter().zip(COLORS.iter().cycle()) {
            let color = *color;
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.series == *name && r.values[which].is_finite())
                .map(|r| (r.n, r.values[which]))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
        chart
            .configure_series_labels()
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.3))
            // Time rises with N and memory falls: keep the legend clear.
            .position(if which == 0 {
                SeriesLabelPosition::LowerRight
            } else {
                SeriesLabelPosition::UpperRight
            })
            .draw()?;
    }
    root.present()?;
    Ok(())
}
