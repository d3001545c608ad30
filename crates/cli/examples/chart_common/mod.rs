//! What the two-panel chart examples (`peer_chart`, `scaling_chart`)
//! share: the font and colours, the command line, reading their CSV
//! files, the series in file order, and drawing one series as a line
//! with points.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::error::Error;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
/// The font family every label uses.
pub const FAMILY: &str = "sans-serif";
/// The series colours, in turn.
pub const COLORS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
];

/// `fn main` of a chart example `$name`: the command line
/// `OUT.svg|OUT.png TITLE FILE.csv`, the CSV read by `$read`, the chart
/// drawn by `$draw(root, title, &rows)` (generic over the plotters
/// backend) at `$size` pixels in SVG or PNG, as the output's extension
/// says.
macro_rules! chart_main {
    ($name:literal, $size:expr, $read:path, $draw:path) => {
        fn main() -> Result<(), Box<dyn std::error::Error>> {
            chart_common::run(
                $name,
                $read,
                |out, title, rows| {
                    $draw(SVGBackend::new(out, $size).into_drawing_area(), title, rows)
                },
                |out, title, rows| {
                    $draw(
                        BitMapBackend::new(out, $size).into_drawing_area(),
                        title,
                        rows,
                    )
                },
            )
        }
    };
}
pub(crate) use chart_main;

/// What [`chart_main`] runs: registers the font, reads the CSV with
/// `read` and draws it with `svg` or `png`.
pub fn run<R>(
    name: &str,
    read: impl FnOnce(&str) -> Result<R, Box<dyn Error>>,
    svg: impl FnOnce(&str, &str, &R) -> Result<(), Box<dyn Error>>,
    png: impl FnOnce(&str, &str, &R) -> Result<(), Box<dyn Error>>,
) -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, title, csv] = args.as_slice() else {
        return Err(format!("usage: {name} OUT.svg|OUT.png TITLE FILE.csv").into());
    };
    let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    let rows = read(csv)?;
    if out.ends_with(".png") {
        png(out, title, &rows)
    } else {
        svg(out, title, &rows)
    }
}

/// The rows of the CSV file `path` after its header: each line of
/// `columns` comma-separated fields made a row by `row(fields, num)`,
/// where `num` parses a field as a number (errors are prefixed with the
/// file and line). No rows is an error.
pub fn read_rows<T>(
    path: &str,
    columns: usize,
    mut row: impl FnMut(&[&str], &dyn Fn(&str) -> Result<f64, String>) -> Result<T, String>,
) -> Result<Vec<T>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != columns {
            return Err(format!("{path}:{}: expected {columns} columns", k + 1).into());
        }
        let num = |s: &str| s.trim().parse::<f64>().map_err(|e| e.to_string());
        rows.push(row(&f, &num).map_err(|e| format!("{path}:{}: {e}", k + 1))?);
    }
    if rows.is_empty() {
        return Err(format!("{path}: no rows").into());
    }
    Ok(rows)
}

/// The distinct `names` in order of first appearance (one series each).
pub fn series<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for name in names {
        if !out.contains(&name) {
            out.push(name);
        }
    }
    out
}

/// `root` filled white under `title`, split into two panels side by side.
pub fn two_panels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<Vec<DrawingArea<DB, Shift>>, Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FAMILY, 17))?;
    Ok(root.split_evenly((1, 2)))
}

/// Series `name` through `pts` in `color`: a line (with its legend
/// entry) and a dot at each point.
pub fn line_with_points<DB, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<LogCoord<f64>, Y>>,
    pts: Vec<(f64, f64)>,
    name: &str,
    color: RGBColor,
) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    Y: Ranged<ValueType = f64>,
{
    chart
        .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
        .label(name)
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color.stroke_width(2)));
    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
    Ok(())
}

/// The legend of `chart` at `position`, in the charts' style.
pub fn legend<'a, DB, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, Y>>,
    position: SeriesLabelPosition,
) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .label_font((FAMILY, 13))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.3))
        .position(position)
        .draw()?;
    Ok(())
}
