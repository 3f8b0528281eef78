//! Charts from plain data: panels of points and lines on linear or log axes, drawn as an SVG
//! (the benchmark's figures; phalanx-eval builds the [`Figure`] from its results).

use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::prelude::*;

use crate::RenderError;

/// Colours of the series, by [`Series::colour`] index (repeated past ten).
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// A figure: panels in a grid of `rows × columns`, filled row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Rows of panels.
    pub rows: usize,
    /// Columns of panels.
    pub columns: usize,
    /// The panels.
    pub panels: Vec<Panel>,
}

/// One panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// The caption.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// The series, drawn in order.
    pub series: Vec<Series>,
    /// Draw a legend of the named series.
    pub legend: bool,
}

/// An axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The description under or beside the axis, if any.
    pub label: Option<String>,
    /// The range shown (positive for a log axis).
    pub range: (f64, f64),
    /// A logarithmic axis.
    pub log: bool,
    /// Categories: the tick at `i` reads `categories[i]` (a range of `(-0.5, n - 0.5)` puts
    /// them at the integers).
    pub categories: Option<Vec<String>>,
}

impl Axis {
    /// A linear axis over `range` without a description.
    pub fn linear(range: (f64, f64)) -> Axis {
        Axis { label: None, range, log: false, categories: None }
    }
}

/// A series of points, joined by a line or not.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The name in the legend (`None`: not in it).
    pub name: Option<String>,
    /// The colour's index in the palette.
    pub colour: usize,
    /// Line width in pixels.
    pub width: u32,
    /// Join the points, in order, by a line.
    pub line: bool,
    /// The points.
    pub points: Vec<Point>,
}

/// A point and its marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Horizontal coordinate.
    pub x: f64,
    /// Vertical coordinate.
    pub y: f64,
    /// How the point is marked.
    pub marker: Marker,
}

/// A point's marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    /// None (a line's vertex).
    None,
    /// A filled circle.
    Circle,
    /// A hollow circle.
    Ring,
    /// A filled triangle.
    Triangle,
    /// A black cross.
    Cross,
}

/// The figure as an SVG.
///
/// # Errors
/// If plotters fails to draw (a range that is empty, or not positive on a log axis).
pub fn chart_svg(figure: &Figure) -> Result<String, RenderError> {
    for panel in &figure.panels {
        for (name, axis) in [("horizontal", &panel.x), ("vertical", &panel.y)] {
            check_range(axis.range).map_err(|why| {
                RenderError::Raster(format!(
                    "{}: the {name} axis from {} to {} {why}",
                    panel.title, axis.range.0, axis.range.1
                ))
            })?;
        }
    }
    let mut out = String::new();
    draw(figure, &mut out).map_err(|err| RenderError::Raster(err.to_string()))?;
    Ok(out)
}

/// The largest magnitude an axis may reach: beyond, the tick arithmetic of the plotting
/// library overflows or never ends.
const MAX_AXIS: f64 = 1e15;

/// Refuses an axis range the plotting library cannot divide into ticks: not finite, beyond
/// ±[`MAX_AXIS`], or narrower than a billionth of its magnitude (ticks that do not move).
fn check_range((lo, hi): (f64, f64)) -> Result<(), &'static str> {
    if !(lo.abs() <= MAX_AXIS && hi.abs() <= MAX_AXIS) {
        Err("reaches beyond ±1e15")
    } else if hi > lo && hi - lo <= 1e-9 * lo.abs().max(hi.abs()) {
        Err("is too narrow for its magnitude to draw")
    } else {
        Ok(())
    }
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(figure: &Figure, out: &mut String) -> DrawResult {
    let root = SVGBackend::with_string(out, (figure.width, figure.height)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((figure.rows.max(1), figure.columns.max(1)));
    for (area, panel) in areas.iter().zip(&figure.panels) {
        let (x, y) = (panel.x.range.0..panel.x.range.1, panel.y.range.0..panel.y.range.1);
        let mut builder = ChartBuilder::on(area);
        builder
            .caption(&panel.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64);
        match (panel.x.log, panel.y.log) {
            (false, false) => fill(builder.build_cartesian_2d(x, y)?, panel)?,
            (false, true) => fill(builder.build_cartesian_2d(x, y.log_scale())?, panel)?,
            (true, false) => fill(builder.build_cartesian_2d(x.log_scale(), y)?, panel)?,
            (true, true) => fill(builder.build_cartesian_2d(x.log_scale(), y.log_scale())?, panel)?,
        }
    }
    root.present()?;
    Ok(())
}

/// A tick at a whole number of 1 000 or more, in groups of three digits (`50 000`, not
/// `50000.0`); `None` for other values, which the axis formats itself.
fn large_integer(v: f64) -> Option<String> {
    if v.abs() < 1000.0 || v.abs() >= 1e15 || (v - v.round()).abs() > 1e-9 {
        return None;
    }
    let digits = (v.round().abs() as u64).to_string();
    let mut grouped = String::new();
    for (i, digit) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            grouped.push(' ');
        }
        grouped.push(digit);
    }
    Some(if v < 0.0 { format!("-{grouped}") } else { grouped })
}

/// The mesh, the series and the legend of `panel`.
fn fill<'a, DB, X, Y>(
    mut chart: ChartContext<'a, DB, Cartesian2d<X, Y>>,
    panel: &Panel,
) -> DrawResult
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let category = |v: &f64| -> String {
        let cats = panel.x.categories.as_deref().unwrap_or_default();
        let i = v.round();
        if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < cats.len() {
            cats[i as usize].clone()
        } else {
            String::new()
        }
    };
    let plain = |v: &f64| large_integer(*v).unwrap_or_else(|| X::format(v));
    let y_plain = |v: &f64| large_integer(*v).unwrap_or_else(|| Y::format(v));
    let mut mesh = chart.configure_mesh();
    mesh.y_label_formatter(&y_plain);
    if let Some(label) = &panel.x.label {
        mesh.x_desc(label);
    }
    if let Some(label) = &panel.y.label {
        mesh.y_desc(label);
    }
    match &panel.x.categories {
        Some(cats) => mesh.x_labels(cats.len() + 1).x_label_formatter(&category).draw()?,
        None => mesh.x_label_formatter(&plain).draw()?,
    }
    for series in &panel.series {
        let colour = PALETTE[series.colour % PALETTE.len()];
        let width = series.width.max(1);
        let line: Vec<(f64, f64)> = series.points.iter().map(|p| (p.x, p.y)).collect();
        let mut legend_line = false;
        if series.line {
            let drawn = chart.draw_series(LineSeries::new(line, colour.stroke_width(width)))?;
            if let (Some(name), true) = (&series.name, panel.legend) {
                legend_line = true;
                drawn.label(name.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(width))
                });
            }
        }
        let mut first = true;
        for marker in [Marker::Circle, Marker::Ring, Marker::Triangle, Marker::Cross] {
            let at: Vec<(f64, f64)> =
                series.points.iter().filter(|p| p.marker == marker).map(|p| (p.x, p.y)).collect();
            if at.is_empty() {
                continue;
            }
            let drawn = match marker {
                Marker::Circle => {
                    chart.draw_series(at.iter().map(|&p| Circle::new(p, 5, colour.filled())))?
                }
                Marker::Ring => chart
                    .draw_series(at.iter().map(|&p| Circle::new(p, 5, colour.stroke_width(2))))?,
                Marker::Triangle => chart
                    .draw_series(at.iter().map(|&p| TriangleMarker::new(p, 7, colour.filled())))?,
                Marker::Cross => chart
                    .draw_series(at.iter().map(|&p| Cross::new(p, 7, BLACK.stroke_width(2))))?,
                Marker::None => continue,
            };
            if let (Some(name), true, false, true) =
                (&series.name, panel.legend, legend_line, first)
            {
                first = false;
                match marker {
                    Marker::Cross => drawn
                        .label(name.as_str())
                        .legend(|(x, y)| Cross::new((x, y), 5, BLACK.stroke_width(2))),
                    _ => drawn
                        .label(name.as_str())
                        .legend(move |(x, y)| Circle::new((x, y), 5, colour.filled())),
                };
            }
        }
    }
    if panel.legend && panel.series.iter().any(|s| s.name.is_some()) {
        chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::large_integer;

    #[test]
    fn large_whole_ticks_are_grouped_and_others_left_to_the_axis() {
        assert_eq!(large_integer(50_000.0).as_deref(), Some("50 000"));
        assert_eq!(large_integer(1_234_567.0).as_deref(), Some("1 234 567"));
        assert_eq!(large_integer(-2000.0).as_deref(), Some("-2 000"));
        assert_eq!(large_integer(999.0), None);
        assert_eq!(large_integer(1500.5), None);
        assert_eq!(large_integer(0.25), None);
    }
}
