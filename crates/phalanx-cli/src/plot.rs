//! Training curves: `metrics.jsonl` of a training run drawn as an SVG of four panels
//! (success rate, episodic return, TD loss, collisions per episode against environment steps),
//! each a moving average.

use std::fs;
use std::path::Path;

use anyhow::Context as _;
use phalanx_rl::metrics;
use plotters::prelude::*;

/// Points averaged in each curve's moving average.
const WINDOW: usize = 100;

/// The panels: metric, title.
const PANELS: [(&str, &str); 4] = [
    (metrics::SUCCESS, "success rate"),
    (metrics::EPISODIC_RETURN, "episodic return (team)"),
    (metrics::TD_LOSS, "TD loss"),
    (metrics::COLLISIONS, "collisions per episode"),
];

/// Reads `metrics` (JSON lines `{"name", "step", "value"}`) and writes the curves to `svg`
/// (written to a temporary file first, then renamed). Lines that do not parse (the last line
/// of a run killed while writing) are skipped; returns the first such line number, if any.
pub(crate) fn training_curves(metrics_path: &Path, svg: &Path) -> anyhow::Result<Option<usize>> {
    let text = fs::read_to_string(metrics_path)
        .with_context(|| format!("reading {}", metrics_path.display()))?;
    let mut series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); PANELS.len()];
    let mut first_bad = None;
    for (idx, line) in text.lines().enumerate() {
        let parsed: Option<serde_json::Value> = serde_json::from_str(line).ok();
        let fields = parsed.as_ref().and_then(|it| {
            Some((it["name"].as_str()?, it["step"].as_f64()?, it["value"].as_f64()?))
        });
        let Some((name, step, value)) = fields else {
            first_bad = first_bad.or(Some(idx + 1));
            continue;
        };
        if let Some(panel) = PANELS.iter().position(|(metric, _)| *metric == name) {
            series[panel].push((step, value));
        }
    }
    let mut tmp_name = svg.file_name().map(|it| it.to_os_string()).unwrap_or_default();
    tmp_name.push(".tmp");
    let tmp = svg.with_file_name(tmp_name);
    draw(&series, &tmp).map_err(|err| anyhow::anyhow!("drawing {}: {err}", tmp.display()))?;
    fs::rename(&tmp, svg).with_context(|| format!("writing {}", svg.display()))?;
    Ok(first_bad)
}

fn draw(series: &[Vec<(f64, f64)>], path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1200, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_step = series.iter().flatten().map(|it| it.0).fold(1.0_f64, f64::max);
    for (area, (points, (_, title))) in
        root.split_evenly((2, 2)).iter().zip(series.iter().zip(PANELS))
    {
        let smooth = moving_average(points, WINDOW);
        let (lo, hi) = smooth
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), it| (lo.min(it.1), hi.max(it.1)));
        let (lo, hi) = if lo.is_finite() { (lo, hi.max(lo + 1e-9)) } else { (0.0, 1.0) };
        let pad = (hi - lo) * 0.05;
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{title} (moving average of {WINDOW})"), ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(32)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..max_step, (lo - pad)..(hi + pad))?;
        chart.configure_mesh().x_desc("environment steps").x_labels(6).y_labels(6).draw()?;
        chart.draw_series(LineSeries::new(smooth, &BLUE))?;
    }
    root.present()?;
    Ok(())
}

/// Trailing moving average over up to `window` points.
fn moving_average(points: &[(f64, f64)], window: usize) -> Vec<(f64, f64)> {
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
