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
mod chart_common;

use chart_common::{COLORS, FAMILY, legend, line_with_points, read_rows, series, two_panels};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::error::Error;

const SIZE: (u32, u32) = (1100, 460);

/// One run.
struct Row {
    series: String,
    n: f64,
    /// Microseconds a point, bytes a point.
    values: [f64; 2],
}

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    read_rows(path, 4, |f, num| {
        let n = num(f[1])?;
        if !(n.is_finite() && n > 0.0) {
            return Err("N must be positive".to_string());
        }
        Ok(Row {
            series: f[0].trim().to_string(),
            n,
            values: [num(f[2])? / n * 1e6, num(f[3])?],
        })
    })
}

chart_common::chart_main!("scaling_chart", SIZE, read, draw);

/// Both panels on `root` (any plotters backend).
fn draw<DB>(root: DrawingArea<DB, Shift>, title: &str, rows: &[Row]) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
{
    let panels = two_panels(&root, title)?;
    let names = series(rows.iter().map(|r| r.series.as_str()));
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
            line_with_points(&mut chart, pts, name, color)?;
        }
        // Time rises with N and memory falls: keep the legend clear.
        let position = if which == 0 {
            SeriesLabelPosition::LowerRight
        } else {
            SeriesLabelPosition::UpperRight
        };
        legend(&mut chart, position)?;
    }
    root.present()?;
    Ok(())
}
