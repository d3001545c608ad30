//! Relative error against the order, one line per scheme and precision
//! (potential solid, gradient dashed).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::data::{FLOOR, SweepData, label, log_range, order_label, sci};
use super::{Chart, DrawResult, FAMILY, full_page, gradient_line, legend};
use crate::commands::SchemeArg;

/// The chart (see the [module docs](self)).
pub(super) struct ErrorVsOrder<'a>(pub(super) &'a SweepData<'a>);

impl Chart for ErrorVsOrder<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
        let (min_order, max_order) = data.orders();
        let errors = data.runs.iter().filter_map(|r| r.errors.as_ref());
        let y_range = log_range(
            errors
                .flat_map(|e| [Some(e.potential), e.gradient])
                .flatten(),
        );
        let mut chart = full_page(root, format!("Relative error vs order ({})", data.title))
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
                gradient_line(&mut chart, &grad, color, key)?.legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (6, 0)], color.stroke_width(2))
                        + PathElement::new(vec![(14, 0), (20, 0)], color.stroke_width(2))
                        + TriangleMarker::new((10, 0), size.min(6), style)
                });
                chart.draw_series(grad.iter().map(|&p| TriangleMarker::new(p, size, style)))?;
            }
        }
        legend(&mut chart)
    }
}
