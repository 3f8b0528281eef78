//! Training curves: panels of moving averages against environment steps, as an SVG (the
//! `curves.svg` of every training run).

use crate::RenderError;
use crate::chart::{Axis, Figure, Marker, Panel, Point, Series, chart_svg};

/// One panel: a title and one line per run.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// The panel's title.
    pub title: String,
    /// The runs' lines, in legend order.
    pub lines: Vec<Line>,
}

/// One run's `(environment step, value)` points in a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// The run's name in the legend (`None`: no legend, as for one run's curves).
    pub name: Option<String>,
    /// The points, in step order.
    pub points: Vec<(f64, f64)>,
}

/// The curves as an SVG of panels in two columns, each line the trailing moving average of
/// `window` points; every panel shares the step axis, and a panel with named lines has a
/// legend (the line of run `k` has colour `k` in every panel).
///
/// # Errors
/// If the chart cannot be drawn (a bug).
pub fn training_curves(curves: &[Curve], window: usize) -> Result<String, RenderError> {
    let rows = curves.len().div_ceil(2).max(1);
    let max_step = curves
        .iter()
        .flat_map(|c| &c.lines)
        .flat_map(|line| &line.points)
        .map(|it| it.0)
        .fold(1.0_f64, f64::max);
    let panels = curves
        .iter()
        .map(|curve| {
            let smooth: Vec<Vec<(f64, f64)>> =
                curve.lines.iter().map(|line| moving_average(&line.points, window)).collect();
            let (lo, hi) =
                smooth.iter().flatten().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), it| {
                    (lo.min(it.1), hi.max(it.1))
                });
            // A flat line gets a range of ±5 % of its value (at least ±0.05) around it.
            let flat = lo.abs().max(1.0) * 0.05;
            let (lo, hi) = match (lo.is_finite(), hi - lo > 1e-9) {
                (false, _) => (0.0, 1.0),
                (true, true) => (lo, hi),
                (true, false) => (lo - flat, hi + flat),
            };
            let pad = (hi - lo) * 0.05;
            let series = curve
                .lines
                .iter()
                .zip(&smooth)
                .enumerate()
                .map(|(colour, (line, points))| Series {
                    name: line.name.clone(),
                    colour,
                    width: 1,
                    line: true,
                    points: points
                        .iter()
                        .map(|&(x, y)| Point { x, y, marker: Marker::None })
                        .collect(),
                })
                .collect();
            Panel {
                title: format!("{} (moving average of {window})", curve.title),
                x: Axis {
                    label: Some("environment steps".into()),
                    ..Axis::linear((0.0, max_step))
                },
                y: Axis::linear((lo - pad, hi + pad)),
                series,
                legend: curve.lines.iter().any(|line| line.name.is_some()),
            }
        })
        .collect();
    chart_svg(&Figure { width: 1200, height: 400 * rows as u32, rows, columns: 2, panels })
}

/// Trailing moving average over up to `window` points.
fn moving_average(points: &[(f64, f64)], window: usize) -> Vec<(f64, f64)> {
    let window = window.max(1);
    let mut sum = 0.0;
    points
        .iter()
        .enumerate()
        .map(|(idx, &(step, value))| {
            sum += value;
            if idx >= window {
                sum -= points[idx - window].1;
            }
            (step, sum / (idx + 1).min(window) as f64)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_average_is_trailing() {
        let points = [(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)];
        assert_eq!(moving_average(&points, 2), [(0.0, 1.0), (1.0, 2.0), (2.0, 4.0)]);
    }
}
