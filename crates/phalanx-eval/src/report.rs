//! What a benchmark shows: per (case, method) aggregates of the runs, the Markdown table with
//! the paper's figures beside ours, and the SVG figures.
//!
//! Aggregates: the success rate over every run; makespan, formation losses and sum of costs
//! as means over the solved runs (as the paper reports them); runtime as the mean over
//! every run (a timed-out run counts its time limit's worth).

use std::path::Path;

use plotters::prelude::*;
use serde::Serialize;

use phalanx_plan::planner::Outcome;

use crate::BenchError;
use crate::runs::RunRecord;
use crate::suite::Case;

/// The aggregate of one method on one case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cell {
    /// The case's label.
    pub case: String,
    /// The method's name.
    pub method: String,
    /// Runs.
    pub runs: usize,
    /// Runs that returned a valid plan reaching the goals.
    pub solved: usize,
    /// `solved / runs`.
    pub success_rate: f64,
    /// Mean makespan of the solved runs.
    pub makespan: Option<f64>,
    /// Mean Table II formation loss of the solved runs.
    pub formation_loss: Option<f64>,
    /// Mean per-step `L_f` of the solved runs.
    pub formation_loss_mean: Option<f64>,
    /// Mean sum of costs of the solved runs.
    pub sum_of_costs: Option<f64>,
    /// Mean runtime of every run, seconds.
    pub runtime_s: f64,
    /// Runs that hit the time limit.
    pub timeouts: usize,
}

/// The cells of every (case, method) pair with runs, cases then methods in the given order.
pub fn cells(records: &[RunRecord], cases: &[Case], methods: &[String]) -> Vec<Cell> {
    let mut res = Vec::new();
    for case in cases {
        for method in methods {
            let runs: Vec<&RunRecord> =
                records.iter().filter(|r| r.case == case.label && &r.method == method).collect();
            if runs.is_empty() {
                continue;
            }
            let solved: Vec<&RunRecord> = runs.iter().copied().filter(|r| r.solved()).collect();
            let mean = |f: &dyn Fn(&RunRecord) -> f64| {
                (!solved.is_empty())
                    .then(|| solved.iter().map(|r| f(r)).sum::<f64>() / solved.len() as f64)
            };
            let metric = |r: &RunRecord| r.run.metrics.clone().expect("a solved run has metrics");
            res.push(Cell {
                case: case.label.clone(),
                method: method.clone(),
                runs: runs.len(),
                solved: solved.len(),
                success_rate: solved.len() as f64 / runs.len() as f64,
                makespan: mean(&|r| metric(r).makespan as f64),
                formation_loss: mean(&|r| metric(r).formation_loss),
                formation_loss_mean: mean(&|r| metric(r).formation_loss_mean),
                sum_of_costs: mean(&|r| metric(r).sum_of_costs as f64),
                runtime_s: runs.iter().map(|r| r.run.runtime_s).sum::<f64>() / runs.len() as f64,
                timeouts: runs.iter().filter(|r| r.run.outcome == Outcome::Timeout).count(),
            });
        }
    }
    res
}

/// Whether `method` is the paper's method (the hierarchy), whose row figures stand beside it.
fn is_hierarchy(method: &str) -> bool {
    method == "hrl" || method.starts_with("hrl:")
}

/// The Markdown table: one line per (case, method) with our figures and, for the hierarchy
/// and CBS on Table II's rows, the paper's.
pub fn markdown(cases: &[Case], cells: &[Cell]) -> String {
    let mut out = String::from(
        "| map | agents | density | method | runs | success | makespan | formation loss | \
         runtime s | paper: makespan | paper: formation loss | paper: success | paper: runtime s |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let opt =
        |v: Option<f64>, digits: usize| v.map_or("—".to_owned(), |v| format!("{v:.digits$}"));
    for case in cases {
        for cell in cells.iter().filter(|c| c.case == case.label) {
            let paper = match (case.paper, cell.method.as_str()) {
                (Some(p), m) if is_hierarchy(m) => format!(
                    "{} | {} | {} | {}",
                    p.makespan, p.formation_loss, p.success, p.runtime_s
                ),
                (Some(p), "cbs") => format!("| | | {}", p.cbs_runtime),
                _ => " | | |".to_owned(),
            };
            let map = if !matches!(case.source, crate::suite::Source::Generated) {
                format!("{} ({}²)", case.label, case.side)
            } else if case.side == case.paper.map_or(case.side, |p| p.side) {
                format!("{}²", case.side)
            } else {
                format!("{}² (row {}²)", case.side, case.paper.map_or(case.side, |p| p.side))
            };
            out.push_str(&format!(
                "| {map} | {} | {} | {} | {} | {:.2} | {} | {} | {:.4} | {paper} |\n",
                case.agents,
                case.density,
                cell.method,
                cell.runs,
                cell.success_rate,
                opt(cell.makespan, 1),
                opt(cell.formation_loss, 3),
                cell.runtime_s,
            ));
        }
    }
    out
}

/// A panel's chart builder: its caption and the house margins and label areas.
fn panel<'a, 'b, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64);
    builder
}

/// Colours of the methods in the figures, in order.
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

/// `table2.svg`: per case (x, in order), each method's mean makespan (left panel, log axis)
/// and Table II formation loss (right panel) over its solved runs; a method that solved
/// nothing on a case has no point there.
///
/// # Errors
/// If the file cannot be written.
pub fn plot_table2(
    cases: &[Case],
    methods: &[String],
    cells: &[Cell],
    path: &Path,
) -> Result<(), BenchError> {
    let plot_err = |err: &dyn std::fmt::Display| BenchError::Plot {
        path: path.display().to_string(),
        message: err.to_string(),
    };
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::new(path, (1400, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 2));
        let values = |f: &dyn Fn(&Cell) -> Option<f64>| -> Vec<Vec<(usize, f64)>> {
            methods
                .iter()
                .map(|m| {
                    cases
                        .iter()
                        .enumerate()
                        .filter_map(|(i, case)| {
                            cells
                                .iter()
                                .find(|c| c.case == case.label && &c.method == m)
                                .and_then(f)
                                .map(|v| (i, v))
                        })
                        .collect()
                })
                .collect()
        };
        let makespan = values(&|c| c.makespan);
        let loss = values(&|c| c.formation_loss);
        let label = |i: &usize| cases.get(*i).map(|c| c.label.clone()).unwrap_or_default();
        let hi = |series: &[Vec<(usize, f64)>]| {
            series.iter().flatten().map(|p| p.1).fold(1.0_f64, f64::max) * 1.2
        };
        let n = cases.len().max(1);
        {
            let mut chart = panel(&panels[0], "makespan (solved runs, mean)")
                .build_cartesian_2d(0..n, (1.0..hi(&makespan)).log_scale())?;
            chart.configure_mesh().x_labels(n).x_label_formatter(&label).draw()?;
            for (k, (name, points)) in methods.iter().zip(&makespan).enumerate() {
                let colour = PALETTE[k % PALETTE.len()];
                chart
                    .draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))?
                    .label(name.as_str())
                    .legend(move |(x, y)| Circle::new((x, y), 5, colour.filled()));
            }
            chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        }
        let mut chart = panel(&panels[1], "Table II formation loss (solved runs, mean)")
            .build_cartesian_2d(0..n, 0.0..hi(&loss))?;
        chart.configure_mesh().x_labels(n).x_label_formatter(&label).draw()?;
        for (k, points) in loss.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|err| plot_err(&err))
}

/// `pareto.svg`: per case (one panel each), every method's point (mean makespan, mean Table
/// II formation loss over its solved runs); the points of one family (the name before `:`,
/// e.g. `jsa` for `jsa:0.1`, `jsa:1`) are joined in order of makespan; on Table II's rows a
/// cross marks the paper's method.
///
/// # Errors
/// If the file cannot be written.
pub fn plot_pareto(
    cases: &[Case],
    methods: &[String],
    cells: &[Cell],
    path: &Path,
) -> Result<(), BenchError> {
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root =
            SVGBackend::new(path, (600 * cases.len().max(1) as u32, 560)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut families: Vec<&str> = Vec::new();
        for m in methods {
            let family = m.split(':').next().unwrap_or(m);
            if !families.contains(&family) {
                families.push(family);
            }
        }
        for (area, case) in root.split_evenly((1, cases.len().max(1))).iter().zip(cases) {
            let here: Vec<&Cell> = cells.iter().filter(|c| c.case == case.label).collect();
            let points = |family: &str| -> Vec<(f64, f64)> {
                let mut p: Vec<(f64, f64)> = here
                    .iter()
                    .filter(|c| c.method.split(':').next() == Some(family))
                    .filter_map(|c| Some((c.makespan?, c.formation_loss?)))
                    .collect();
                p.sort_by(|a, b| a.0.total_cmp(&b.0));
                p
            };
            let paper = case.paper.map(|p| (p.makespan, p.formation_loss));
            let all: Vec<(f64, f64)> =
                families.iter().flat_map(|f| points(f)).chain(paper).collect();
            let x_lo = all.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
            let x_hi = all.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
            let y_hi = all.iter().map(|p| p.1).fold(0.0_f64, f64::max);
            let (x_lo, x_hi) =
                if x_lo.is_finite() { (x_lo * 0.95, x_hi * 1.05) } else { (0.0, 1.0) };
            let mut chart = panel(area, &format!("{}: makespan vs formation loss", case.label))
                .build_cartesian_2d(x_lo..x_hi.max(x_lo + 1.0), 0.0..(y_hi * 1.1).max(0.1))?;
            chart
                .configure_mesh()
                .x_desc("makespan (mean, solved)")
                .y_desc("Table II formation loss (mean, solved)")
                .draw()?;
            for (k, family) in families.iter().enumerate() {
                let colour = PALETTE[k % PALETTE.len()];
                let p = points(family);
                chart.draw_series(LineSeries::new(p.clone(), colour))?;
                chart
                    .draw_series(p.iter().map(|&q| Circle::new(q, 5, colour.filled())))?
                    .label(*family)
                    .legend(move |(x, y)| Circle::new((x, y), 5, colour.filled()));
            }
            if let Some(point) = paper {
                chart
                    .draw_series(std::iter::once(Cross::new(point, 7, BLACK.stroke_width(2))))?
                    .label("the paper's method")
                    .legend(|(x, y)| Cross::new((x, y), 5, BLACK.stroke_width(2)));
            }
            chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|err| BenchError::Plot {
        path: path.display().to_string(),
        message: err.to_string(),
    })
}

/// `scaling.svg`: mean runtime (left, log–log) and success rate (right, log side axis)
/// against the map side, one line per method and team size; a method's point on a side
/// where some run timed out is drawn as a triangle (its mean counts those runs at the time
/// limit).
///
/// # Errors
/// If the file cannot be written.
pub fn plot_scaling(
    cases: &[Case],
    methods: &[String],
    cells: &[Cell],
    path: &Path,
) -> Result<(), BenchError> {
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::new(path, (1400, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 2));
        let mut teams: Vec<usize> = cases.iter().map(|c| c.agents).collect();
        teams.sort_unstable();
        teams.dedup();
        let side_of = |label: &str| cases.iter().find(|c| c.label == label).map(|c| c.side);
        let agents_of = |label: &str| cases.iter().find(|c| c.label == label).map(|c| c.agents);
        let lines: Vec<(String, usize, Vec<&Cell>)> = methods
            .iter()
            .enumerate()
            .flat_map(|(k, m)| {
                teams.iter().map(move |&team| {
                    let here: Vec<&Cell> = cells
                        .iter()
                        .filter(|c| &c.method == m && agents_of(&c.case) == Some(team))
                        .collect();
                    (format!("{m}, {team} agents"), k, here)
                })
            })
            .filter(|(_, _, here)| !here.is_empty())
            .collect();
        let x_hi = cases.iter().map(|c| f64::from(c.side)).fold(2.0_f64, f64::max) * 1.2;
        let x_lo = cases.iter().map(|c| f64::from(c.side)).fold(f64::INFINITY, f64::min) / 1.2;
        let x_lo = if x_lo.is_finite() { x_lo } else { 1.0 };
        let t_hi = cells.iter().map(|c| c.runtime_s).fold(1e-3_f64, f64::max) * 2.0;
        let t_lo =
            cells.iter().map(|c| c.runtime_s).filter(|&t| t > 0.0).fold(t_hi, f64::min) / 2.0;
        let style = |k: usize, team: usize| {
            let colour = PALETTE[k % PALETTE.len()];
            let width = 1 + teams.iter().position(|&t| t == team).unwrap_or(0) as u32;
            (colour, width)
        };
        let mut left = panel(&panels[0], "runtime per instance (mean, s)")
            .build_cartesian_2d((x_lo..x_hi).log_scale(), (t_lo..t_hi).log_scale())?;
        left.configure_mesh().x_desc("map side").y_desc("seconds").draw()?;
        for (label, k, here) in &lines {
            let team = agents_of(&here[0].case).unwrap_or(0);
            let (colour, width) = style(*k, team);
            let mut points: Vec<(f64, f64, bool)> = here
                .iter()
                .filter_map(|c| {
                    Some((f64::from(side_of(&c.case)?), c.runtime_s.max(t_lo), c.timeouts > 0))
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let line: Vec<(f64, f64)> = points.iter().map(|p| (p.0, p.1)).collect();
            left.draw_series(LineSeries::new(line, colour.stroke_width(width)))?
                .label(label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(width))
                });
            left.draw_series(
                points.iter().filter(|p| !p.2).map(|p| Circle::new((p.0, p.1), 4, colour.filled())),
            )?;
            left.draw_series(
                points
                    .iter()
                    .filter(|p| p.2)
                    .map(|p| TriangleMarker::new((p.0, p.1), 7, colour.filled())),
            )?;
        }
        left.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
        let mut right = panel(&panels[1], "success rate (triangles: some runs timed out)")
            .build_cartesian_2d((x_lo..x_hi).log_scale(), 0.0..1.05)?;
        right.configure_mesh().x_desc("map side").y_desc("success").draw()?;
        for (_, k, here) in &lines {
            let team = agents_of(&here[0].case).unwrap_or(0);
            let (colour, width) = style(*k, team);
            let mut points: Vec<(f64, f64)> = here
                .iter()
                .filter_map(|c| Some((f64::from(side_of(&c.case)?), c.success_rate)))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            right.draw_series(LineSeries::new(points.clone(), colour.stroke_width(width)))?;
            right.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|err| BenchError::Plot {
        path: path.display().to_string(),
        message: err.to_string(),
    })
}
