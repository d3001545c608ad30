//! Evaluation time per operator as stacked bars per order, one panel per
//! scheme and precision (the fastest leaf size per order).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::data::{SweepData, label, order_label};
use super::{COLORS, Chart, DrawResult, FAMILY};
use crate::report::OperatorSeconds;

/// The chart (see the [module docs](self)).
pub(super) struct Operators<'a>(pub(super) &'a SweepData<'a>);

impl Chart for Operators<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let data = self.0;
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
