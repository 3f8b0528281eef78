//! Training curves: `metrics.jsonl` of a training run read into the four panels that
//! `phalanx_render::training_curves` draws (success rate, episodic return, TD loss,
//! collisions per episode against environment steps, each a moving average).

use std::fs;
use std::path::Path;

use anyhow::Context as _;
use phalanx_render::Curve;
use phalanx_rl::metrics;

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
/// atomically. Lines that do not parse (the last line of a run killed while writing) are
/// skipped; returns the first such line number, if any.
pub(crate) fn training_curves(metrics_path: &Path, svg: &Path) -> anyhow::Result<Option<usize>> {
    let text = fs::read_to_string(metrics_path)
        .with_context(|| format!("reading {}", metrics_path.display()))?;
    let mut curves: Vec<Curve> = PANELS
        .iter()
        .map(|(_, title)| Curve { title: (*title).to_owned(), points: Vec::new() })
        .collect();
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
            curves[panel].points.push((step, value));
        }
    }
    let drawn = phalanx_render::training_curves(&curves, WINDOW)
        .with_context(|| format!("drawing {}", svg.display()))?;
    phalanx_io::write_text(svg, &drawn).with_context(|| format!("writing {}", svg.display()))?;
    Ok(first_bad)
}
