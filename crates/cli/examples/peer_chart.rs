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
mod chart_common;

use chart_common::{COLORS, FAMILY, legend, line_with_points, read_rows, series, two_panels};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::error::Error;

const SIZE: (u32, u32) = (1100, 480);

/// One run.
struct Row {
    code: String,
    setting: String,
    total_s: f64,
    errors: [f64; 2],
}

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    read_rows(path, 5, |f, num| {
        Ok(Row {
            code: f[0].trim().to_string(),
            setting: f[1].trim().to_string(),
            total_s: num(f[2])?,
            errors: [num(f[3])?, num(f[4])?],
        })
    })
}

chart_common::chart_main!("peer_chart", SIZE, read, draw);

/// Both panels on `root` (any plotters backend).
fn draw<DB>(root: DrawingArea<DB, Shift>, title: &str, rows: &[Row]) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
{
    let panels = two_panels(&root, title)?;
    let codes = series(rows.iter().map(|r| r.code.as_str()));
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
            let runs: Vec<&Row> = rows
                .iter()
                .filter(|r| r.code == *code && positive(r.errors[which]))
                .collect();
            let pts = runs.iter().map(|r| (r.total_s, r.errors[which])).collect();
            line_with_points(&mut chart, pts, code, color)?;
            chart.draw_series(runs.iter().map(|r| {
                Text::new(
                    r.setting.clone(),
                    (r.total_s * 1.02, r.errors[which] * 1.15),
                    (FAMILY, 11).into_font().color(&color),
                )
            }))?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    root.present()?;
    Ok(())
}
