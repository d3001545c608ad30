//! Draws a time-against-error chart of ferrofmm beside a peer code (e.g.
//! `docs/charts/exafmm_side_by_side.svg`): two panels (potential error,
//! gradient error), seconds on the horizontal axis, one series per code,
//! each point labelled with its setting.
//!
//! ```text
//! cargo run --release -p ferrofmm-cli --features sweeps --example peer_chart -- \
//!     docs/charts/exafmm_side_by_side.svg "TITLE" docs/charts/exafmm_side_by_side.csv
//! ```
//!
//! The CSV has the header `code,setting,total_s,potential_error,gradient_error`
//! (one row per run; rows of one code form its series, in file order).
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::error::Error;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";
const SIZE: (u32, u32) = (1100, 480);
const COLORS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
];

/// One run.
struct Row {
    code: String,
    setting: String,
    total_s: f64,
    errors: [f64; 2],
}

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 5 {
            return Err(format!("{path}:{}: expected 5 columns", k + 1).into());
        }
        let num = |s: &str| {
            s.trim()
                .parse::<f64>()
                .map_err(|e| format!("{path}:{}: {e}", k + 1))
        };
        rows.push(Row {
            code: f[0].trim().to_string(),
            setting: f[1].trim().to_string(),
            total_s: num(f[2])?,
            errors: [num(f[3])?, num(f[4])?],
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
        return Err("usage: peer_chart OUT.svg|OUT.png TITLE FILE.csv".into());
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
    let mut codes: Vec<&str> = Vec::new();
    for r in rows {
        if !codes.contains(&r.code.as_str()) {
            codes.push(&r.code);
        }
    }
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let (t_lo, t_hi) = rows
        .iter()
        .map(|r| r.total_s)
        .filter(|v| positive(*v))
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    for (panel, (which, name)) in panels.iter().zip([(0, "potential"), (1, "gradient")]) {
        let (lo, hi) = rows
            .iter()
            .map(|r| r.errors[which])
            .filter(|v| positive(*v))
            .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{name} error (relative L2)"), (FAMILY, 15))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(
                (t_lo / 1.3..t_hi * 1.3).log_scale(),
                (lo / 3.0..hi * 3.0).log_scale(),
            )?;
        chart
            .configure_mesh()
            .x_desc("seconds (tree + operators + one evaluation)")
            .x_label_formatter(&|x| format!("{x:.1}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style((FAMILY, 12))
            .draw()?;
        for (code, color) in codes.iter().zip(COLORS.iter().cycle()) {
            let color = *color;
            let series: Vec<&Row> = rows
                .iter()
                .filter(|r| r.code == *code && positive(r.errors[which]))
                .collect();
            let pts: Vec<(f64, f64)> = series
                .iter()
                .map(|r| (r.total_s, r.errors[which]))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
                .label(*code)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
            chart.draw_series(series.iter().map(|r| {
                Text::new(
                    r.setting.clone(),
                    (r.total_s * 1.02, r.errors[which] * 1.15),
                    (FAMILY, 11).into_font().color(&color),
                )
            }))?;
        }
        chart
            .configure_series_labels()
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.3))
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
    }
    root.present()?;
    Ok(())
}
