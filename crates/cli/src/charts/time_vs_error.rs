//! Time against the relative L2 error of the potential, log-log, drawn
//! twice: with the evaluation time alone and with setup + evaluation
//! (tree, operators, precomputation: what a single run costs). One line
//! per scheme and precision through the fastest leaf size at each order
//! (labelled with the order), every configuration of the grid as a dot,
//! the Pareto front of the grid as a dashed black line, with gradients the
//! same lines against the gradient's error, dashed, and the runs whose
//! parameters the library chose (the defaults, `--tolerance`) as black
//! stars labelled with what was asked and what was chosen.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::data::{
    SweepData, chosen_label, gradient, key, label, log_labels, log_range, pareto_front, potential,
    sci, short,
};
use super::{Chart, DrawResult, FAMILY, full_page, gradient_line, legend};
use crate::report::RunReport;

/// Which time a chart plots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Time {
    /// The fastest evaluation.
    Evaluation,
    /// The setup (tree, operators, M2L precomputation) plus the fastest
    /// evaluation.
    SetupAndEvaluation,
}

impl Time {
    /// The time of `run`, in seconds.
    fn of(self, run: &RunReport) -> f64 {
        match self {
            Time::Evaluation => run.evaluation.best_s,
            Time::SetupAndEvaluation => run.setup.total_s + run.evaluation.best_s,
        }
    }

    fn title(self) -> &'static str {
        match self {
            Time::Evaluation => "Evaluation time vs accuracy",
            Time::SetupAndEvaluation => "Setup + evaluation time vs accuracy",
        }
    }

    fn axis(self) -> &'static str {
        match self {
            Time::Evaluation => "evaluation time [s]",
            Time::SetupAndEvaluation => "setup + evaluation time [s]",
        }
    }
}

/// The chart (see the [module docs](self)).
pub(super) struct TimeVsError<'a>(pub(super) &'a SweepData<'a>, pub(super) Time);

impl Chart for TimeVsError<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let (data, time) = (self.0, self.1);
        let checked: Vec<&RunReport> = data
            .runs
            .iter()
            .copied()
            .filter(|r| r.errors.is_some())
            .collect();
        let chosen: Vec<&RunReport> = data
            .chosen
            .iter()
            .copied()
            .filter(|r| r.errors.is_some())
            .collect();
        let both = || checked.iter().chain(&chosen);
        let x_range = log_range(
            both()
                .map(|r| potential(r))
                .chain(both().filter_map(|r| gradient(r))),
        );
        let y_range = log_range(both().map(|r| time.of(r)));
        let (x_labels, y_labels) = (log_labels(&x_range), log_labels(&y_range));
        let mut chart = full_page(root, format!("{} ({})", time.title(), data.title))
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
            .y_desc(time.axis())
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
                .map(|r| (potential(r), time.of(r)))
                .collect();
            chart.draw_series(
                all.iter()
                    .map(|&p| Circle::new(p, 3, color.mix(0.5).filled())),
            )?;
            let line: Vec<(f64, f64, usize)> = by_order
                .values()
                .filter(|r| r.errors.is_some())
                .map(|r| (potential(r), time.of(r), r.order))
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
                .filter_map(|r| gradient(r).map(|g| (g, time.of(r))))
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

        let front = pareto_front(&checked, |r| time.of(r));
        if !front.is_empty() {
            let mut points: Vec<(f64, f64)> =
                front.iter().map(|r| (potential(r), time.of(r))).collect();
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
        if !chosen.is_empty() {
            chart
                .draw_series(chosen.iter().enumerate().map(|(i, r)| {
                    // Labels alternately below and above their star, so
                    // that neighbours' labels do not run into each other.
                    let dy = if i % 2 == 0 { 4 } else { -16 };
                    EmptyElement::at((potential(r), time.of(r)))
                        + Polygon::new(star(9), BLACK.filled())
                        + Text::new(chosen_label(r), (10, dy), (FAMILY, 12).into_font())
                }))?
                .label("parameters chosen (defaults, eps)")
                .legend(|(x, y)| {
                    EmptyElement::at((x + 10, y)) + Polygon::new(star(6), BLACK.filled())
                });
        }
        legend(&mut chart)
    }
}

/// A five-pointed star of outer radius `r` pixels around the origin.
fn star(r: i32) -> Vec<(i32, i32)> {
    (0..10)
        .map(|i| {
            let radius = if i % 2 == 0 {
                r as f64
            } else {
                0.45 * r as f64
            };
            let angle = std::f64::consts::PI * (i as f64 / 5.0 - 0.5);
            (
                (radius * angle.cos()).round() as i32,
                (radius * angle.sin()).round() as i32,
            )
        })
        .collect()
}
