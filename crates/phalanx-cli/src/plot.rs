//! Training curves: `metrics.jsonl` of training runs read into panels that
//! `phalanx_render::training_curves` draws, each a moving average against environment steps.
//!
//! - A run's own `curves.svg` (redrawn at each checkpoint of `phalanx train`): success rate,
//!   episodic return, episode length, mean `L_f`, TD loss and collisions per episode.
//! - `phalanx curves RUN... -o FILE.svg`: several runs on the same panels, one line each (the
//!   paper's Fig. 4: team reward, episode length and formation loss against environment steps,
//!   and the success rate), e.g. the meta policy beside the end-to-end baselines.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_render::{Curve, Line};
use phalanx_rl::metrics;

use crate::util;

/// Points averaged in each curve's moving average, unless `--window` says otherwise.
const WINDOW: u64 = 100;

/// The panels of a run's `curves.svg`: metric, title.
const RUN_PANELS: [(&str, &str); 6] = [
    (metrics::SUCCESS, "success rate"),
    (metrics::EPISODIC_RETURN, "episodic return (team)"),
    (metrics::EPISODIC_LENGTH, "episode length (steps)"),
    (metrics::FORMATION_LOSS, "formation loss (mean L_f per step)"),
    (metrics::TD_LOSS, "TD loss"),
    (metrics::COLLISIONS, "collisions per episode"),
];

/// The panels of an imitation run's `curves.svg` (the step axis counts updates).
const IMITATION_PANELS: [(&str, &str); 6] = [
    (metrics::IMITATION_LOSS, "cloning loss (cross-entropy)"),
    (metrics::IMITATION_ACCURACY, "label accuracy"),
    (metrics::FINETUNE_RETURN, "fine-tuning return (rollouts)"),
    (metrics::FINETUNE_FORMATION_LOSS, "fine-tuning Table II loss (rollouts)"),
    (metrics::VAL_SUCCESS, "validation success (greedy)"),
    (metrics::VAL_FORMATION_LOSS, "validation Table II loss"),
];

/// The panels of `phalanx curves`: the paper's Fig. 4 and the success rate.
const COMPARE_PANELS: [(&str, &str); 4] = [
    (metrics::EPISODIC_RETURN, "team reward per episode"),
    (metrics::EPISODIC_LENGTH, "episode length (steps)"),
    (metrics::FORMATION_LOSS, "formation loss (mean L_f per step)"),
    (metrics::SUCCESS, "success rate"),
];

/// Draws several training runs' curves on one figure.
#[derive(Debug, clap::Args)]
pub(crate) struct CurvesCmd {
    /// Training runs: a run's directory (holding metrics.jsonl) or a metrics file, each
    /// `LABEL=PATH` or `PATH` (labelled by its directory's name).
    #[arg(required = true, value_name = "[LABEL=]RUN")]
    runs: Vec<String>,
    /// The figure to write (SVG).
    #[arg(short, long, value_name = "FILE.svg")]
    out: PathBuf,
    /// Points in each moving average.
    #[arg(long, default_value_t = WINDOW, value_parser = clap::value_parser!(u64).range(1..))]
    window: u64,
}

/// Runs `phalanx curves`.
pub(crate) fn run(cmd: CurvesCmd) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        cmd.out.extension().is_some_and(|ext| ext.eq_ignore_ascii_case("svg")),
        "{}: the figure is an SVG: name it .svg",
        cmd.out.display()
    );
    let mut panels = empty_panels(&COMPARE_PANELS);
    for spec in &cmd.runs {
        let (label, path) = match spec.split_once('=') {
            Some((label, path)) if !label.is_empty() => (label.to_owned(), PathBuf::from(path)),
            _ => {
                let path = PathBuf::from(spec);
                let dir =
                    if path.is_dir() { path.as_path() } else { path.parent().unwrap_or(&path) };
                let label = crate::render::file_name(dir);
                (if label.is_empty() { spec.clone() } else { label }, path)
            }
        };
        let file = if path.is_dir() { path.join("metrics.jsonl") } else { path };
        let (lines, bad) = read_lines(&file, &COMPARE_PANELS, Some(&label))?;
        if let Some(line) = bad {
            util::warn(&format!(
                "warning: {}:{line}: skipped lines that are not metrics",
                file.display()
            ));
        }
        anyhow::ensure!(
            lines.iter().any(|it| !it.points.is_empty()),
            "{}: no training episode recorded (none of {})",
            file.display(),
            COMPARE_PANELS.map(|(name, _)| name).join(", ")
        );
        for (panel, line) in panels.iter_mut().zip(lines) {
            panel.lines.push(line);
        }
    }
    let drawn = phalanx_render::training_curves(&panels, cmd.window as usize)
        .with_context(|| format!("drawing {}", cmd.out.display()))?;
    util::written(phalanx_io::write_text(&cmd.out, &drawn), &cmd.out)?;
    Ok(ExitCode::SUCCESS)
}

/// Reads `metrics` (JSON lines `{"name", "step", "value"}`) and writes the curves to `svg`
/// atomically. Lines that do not parse (the last line of a run killed while writing) are
/// skipped; returns the first such line number, if any.
pub(crate) fn training_curves(metrics_path: &Path, svg: &Path) -> anyhow::Result<Option<usize>> {
    run_curves(metrics_path, svg, &RUN_PANELS)
}

/// [`training_curves`] of an imitation run: the cloning loss and accuracy, the validation
/// figures.
pub(crate) fn imitation_curves(metrics_path: &Path, svg: &Path) -> anyhow::Result<Option<usize>> {
    run_curves(metrics_path, svg, &IMITATION_PANELS)
}

fn run_curves(
    metrics_path: &Path,
    svg: &Path,
    panels: &[(&str, &str)],
) -> anyhow::Result<Option<usize>> {
    let (lines, first_bad) = read_lines(metrics_path, panels, None)?;
    let mut curves = empty_panels(panels);
    for (curve, line) in curves.iter_mut().zip(lines) {
        curve.lines.push(line);
    }
    let drawn = phalanx_render::training_curves(&curves, WINDOW as usize)
        .with_context(|| format!("drawing {}", svg.display()))?;
    phalanx_io::write_text(svg, &drawn).with_context(|| format!("writing {}", svg.display()))?;
    Ok(first_bad)
}

/// One panel per entry of `panels`, without lines.
fn empty_panels(panels: &[(&str, &str)]) -> Vec<Curve> {
    panels
        .iter()
        .map(|(_, title)| Curve { title: (*title).to_owned(), lines: Vec::new() })
        .collect()
}

/// The points of each of `panels`' metrics in the metrics file `path`, as lines named
/// `name`, and the first line number that does not parse, if any.
fn read_lines(
    path: &Path,
    panels: &[(&str, &str)],
    name: Option<&str>,
) -> anyhow::Result<(Vec<Line>, Option<usize>)> {
    let text = fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines: Vec<Line> =
        panels.iter().map(|_| Line { name: name.map(str::to_owned), points: Vec::new() }).collect();
    let mut first_bad = None;
    for (idx, line) in text.lines().enumerate() {
        let parsed: Option<serde_json::Value> = serde_json::from_str(line).ok();
        let fields = parsed.as_ref().and_then(|it| {
            Some((it["name"].as_str()?, it["step"].as_f64()?, it["value"].as_f64()?))
        });
        let Some((metric, step, value)) = fields else {
            first_bad = first_bad.or(Some(idx + 1));
            continue;
        };
        if let Some(panel) = panels.iter().position(|(it, _)| *it == metric) {
            lines[panel].points.push((step, value));
        }
    }
    Ok((lines, first_bad))
}
