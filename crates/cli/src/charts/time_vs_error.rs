//! Evaluation time against the relative L2 error of the potential,
//! log-log: one line per scheme and precision through the fastest leaf
//! size at each order (labelled with the order), every configuration as a
//! dot, the Pareto front as a dashed black line, and with gradients the
//! same lines against the gradient's error, dashed.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::data::{
    SweepData, gradient, key, label, log_labels, log_range, pareto_front, potential, sci, short,
};
use super::{Chart, DrawResult, FAMILY, full_page, gradient_line, legend};
use crate::report::RunReport;

/// The chart (see the [module docs](self)).
pub(super) struct TimeVsError<'a>(pub(super) &'a SweepData<'a>);

impl Chart for TimeVsError<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
        let checked: Vec<&RunReport> = data.runs.iter().filter(|r| r.errors.is_some()).collect();
        let x_range = log_range(
            checked
                .iter()
                .map(|r| potential(r))
                .chain(checked.iter().filter_map(|r| gradient(r))),
        );
        let y_range = log_range(checked.iter().map(|r| r.evaluation.best_s));
        let (x_labels, y_labels) = (log_labels(&x_range), log_labels(&y_range));
        let mut chart = full_page(
            root,
            format!("Evaluation time vs accuracy ({})", data.title),
        )
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
            gradient_line(&mut chart, &line, color, key)?.legend(move |(x, y)| {
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
        legend(&mut chart)
    }
}
