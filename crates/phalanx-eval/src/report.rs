//! What a benchmark shows: per (case, method) aggregates of the runs, the Markdown table with
//! the paper's figures beside ours, and the SVG figures.
//!
//! Aggregates: the success rate over every run; makespan, formation losses and sum of costs
//! as means over the solved runs (as the paper reports them); runtime as the mean over
//! every run (a timed-out run counts its time limit's worth).

use std::path::Path;

use phalanx_render::chart::{Axis, Figure, Marker, Panel, Point, Series};
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
    /// Runs of a learned method that ended short of the goals with the team standing still
    /// or oscillating (`phalanx_core::Stall`).
    pub stalled: usize,
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
                stalled: runs.iter().filter(|r| r.run.stall.is_some()).count(),
            });
        }
    }
    res
}

/// `cells.csv`: one line per cell, the fields of [`Cell`] (an empty field where a mean has no
/// solved run).
pub fn cells_csv(cells: &[Cell]) -> String {
    let mut out = String::from(
        "case,method,runs,solved,success_rate,makespan,formation_loss,formation_loss_mean,\
         sum_of_costs,runtime_s,timeouts,stalled\n",
    );
    let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
    for c in cells {
        let fields = [
            crate::runs::quote(&c.case),
            crate::runs::quote(&c.method),
            c.runs.to_string(),
            c.solved.to_string(),
            c.success_rate.to_string(),
            opt(c.makespan),
            opt(c.formation_loss),
            opt(c.formation_loss_mean),
            opt(c.sum_of_costs),
            c.runtime_s.to_string(),
            c.timeouts.to_string(),
            c.stalled.to_string(),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// Whether `method` is the paper's method (the hierarchy), whose row figures stand beside it.
fn is_hierarchy(method: &str) -> bool {
    method == "hrl" || method.starts_with("hrl:")
}

/// The Markdown table: one line per (case, method) with our figures and, for the hierarchy
/// and CBS on Table II's rows, the paper's.
pub fn markdown(cases: &[Case], cells: &[Cell]) -> String {
    let mut out = String::from(
        "| map | agents | density | method | runs | success | stalled | makespan | formation loss | \
         runtime s | paper: makespan | paper: formation loss | paper: success | paper: runtime s |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
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
                "| {map} | {} | {} | {} | {} | {:.2} | {} | {} | {} | {:.4} | {paper} |\n",
                case.agents,
                case.density,
                cell.method,
                cell.runs,
                cell.success_rate,
                cell.stalled,
                opt(cell.makespan, 1),
                opt(cell.formation_loss, 3),
                cell.runtime_s,
            ));
        }
    }
    out
}

/// Writes `figure` as an SVG to `path` (atomically).
fn write_figure(figure: &Figure, path: &Path) -> Result<(), BenchError> {
    let plot_err = |message: String| BenchError::Plot { path: path.display().to_string(), message };
    let svg = phalanx_render::chart::chart_svg(figure).map_err(|err| plot_err(err.to_string()))?;
    phalanx_io::write_text(path, &svg).map_err(|err| plot_err(err.to_string()))
}

/// A series of markers (no line) named `name`.
fn dots(name: Option<&str>, colour: usize, points: &[(f64, f64)], marker: Marker) -> Series {
    Series {
        name: name.map(str::to_owned),
        colour,
        width: 1,
        line: false,
        points: points.iter().map(|&(x, y)| Point { x, y, marker }).collect(),
    }
}

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
    let values = |f: &dyn Fn(&Cell) -> Option<f64>| -> Vec<Vec<(f64, f64)>> {
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
                            .map(|v| (i as f64, v))
                    })
                    .collect()
            })
            .collect()
    };
    let makespan = values(&|c| c.makespan);
    let loss = values(&|c| c.formation_loss);
    let hi = |series: &[Vec<(f64, f64)>]| {
        series.iter().flatten().map(|p| p.1).fold(1.0_f64, f64::max) * 1.2
    };
    let n = cases.len().max(1) as f64;
    let categories = Some(cases.iter().map(|c| c.label.clone()).collect::<Vec<_>>());
    let x = Axis { label: None, range: (-0.5, n - 0.5), log: false, categories };
    let named = |k: usize| Some(methods[k].as_str());
    let left = Panel {
        title: "makespan (solved runs, mean)".into(),
        x: x.clone(),
        y: Axis { log: true, ..Axis::linear((1.0, hi(&makespan))) },
        series: makespan
            .iter()
            .enumerate()
            .map(|(k, p)| dots(named(k), k, p, Marker::Circle))
            .collect(),
        legend: true,
    };
    let right = Panel {
        title: "Table II formation loss (solved runs, mean)".into(),
        x,
        y: Axis::linear((0.0, hi(&loss))),
        series: loss.iter().enumerate().map(|(k, p)| dots(None, k, p, Marker::Circle)).collect(),
        legend: false,
    };
    let figure =
        Figure { width: 1400, height: 600, rows: 1, columns: 2, panels: vec![left, right] };
    write_figure(&figure, path)
}

/// `pareto.svg`: per case (one panel each), every method's point (mean makespan, mean Table
/// II formation loss over its solved runs); the points of one family (the name before `:`,
/// e.g. `jsa` for `jsa:0.1`, `jsa:1`) are joined in order of makespan, a ring for a method
/// that did not solve every instance; on Table II's rows a cross marks the paper's method.
///
/// # Errors
/// If the file cannot be written.
pub fn plot_pareto(
    cases: &[Case],
    methods: &[String],
    cells: &[Cell],
    path: &Path,
) -> Result<(), BenchError> {
    let mut families: Vec<&str> = Vec::new();
    for m in methods {
        let family = m.split(':').next().unwrap_or(m);
        if !families.contains(&family) {
            families.push(family);
        }
    }
    let panels = cases
        .iter()
        .map(|case| {
            let here: Vec<&Cell> = cells.iter().filter(|c| c.case == case.label).collect();
            // A method that solved only some instances is drawn as a ring: its means are over
            // the solved ones, the easier instances.
            let points = |family: &str| -> Vec<Point> {
                let mut p: Vec<Point> = here
                    .iter()
                    .filter(|c| c.method.split(':').next() == Some(family))
                    .filter_map(|c| {
                        let marker =
                            if c.success_rate < 1.0 { Marker::Ring } else { Marker::Circle };
                        Some(Point { x: c.makespan?, y: c.formation_loss?, marker })
                    })
                    .collect();
                p.sort_by(|a, b| a.x.total_cmp(&b.x));
                p
            };
            let paper = case.paper.map(|p| (p.makespan, p.formation_loss));
            let all: Vec<(f64, f64)> =
                families.iter().flat_map(|f| points(f)).map(|p| (p.x, p.y)).chain(paper).collect();
            let x_lo = all.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
            let x_hi = all.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
            let y_hi = all.iter().map(|p| p.1).fold(0.0_f64, f64::max);
            let (x_lo, x_hi) =
                if x_lo.is_finite() { (x_lo * 0.95, x_hi * 1.05) } else { (0.0, 1.0) };
            let mut series: Vec<Series> = families
                .iter()
                .enumerate()
                .map(|(k, family)| Series {
                    name: Some((*family).to_owned()),
                    colour: k,
                    width: 1,
                    line: true,
                    points: points(family),
                })
                .collect();
            if let Some(point) = paper {
                series.push(dots(Some("the paper's method"), 0, &[point], Marker::Cross));
            }
            Panel {
                title: format!("{}: makespan vs formation loss", case.label),
                x: Axis {
                    label: Some("makespan (mean, solved)".into()),
                    ..Axis::linear((x_lo, x_hi.max(x_lo + 1.0)))
                },
                y: Axis {
                    label: Some("Table II formation loss (mean, solved)".into()),
                    ..Axis::linear((0.0, (y_hi * 1.1).max(0.1)))
                },
                series,
                legend: true,
            }
        })
        .collect();
    let columns = cases.len().max(1);
    let figure = Figure { width: 600 * columns as u32, height: 560, rows: 1, columns, panels };
    write_figure(&figure, path)
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
    let mut teams: Vec<usize> = cases.iter().map(|c| c.agents).collect();
    teams.sort_unstable();
    teams.dedup();
    let side_of = |label: &str| cases.iter().find(|c| c.label == label).map(|c| c.side);
    let agents_of = |label: &str| cases.iter().find(|c| c.label == label).map(|c| c.agents);
    let x_hi = cases.iter().map(|c| f64::from(c.side)).fold(2.0_f64, f64::max) * 1.2;
    let x_lo = cases.iter().map(|c| f64::from(c.side)).fold(f64::INFINITY, f64::min) / 1.2;
    let x_lo = if x_lo.is_finite() { x_lo } else { 1.0 };
    let t_hi = cells.iter().map(|c| c.runtime_s).fold(1e-3_f64, f64::max) * 2.0;
    let t_lo = cells.iter().map(|c| c.runtime_s).filter(|&t| t > 0.0).fold(t_hi, f64::min) / 2.0;
    let (mut runtime, mut success) = (Vec::new(), Vec::new());
    for (k, m) in methods.iter().enumerate() {
        for &team in &teams {
            let here: Vec<&Cell> = cells
                .iter()
                .filter(|c| &c.method == m && agents_of(&c.case) == Some(team))
                .collect();
            if here.is_empty() {
                continue;
            }
            let width = 1 + teams.iter().position(|&t| t == team).unwrap_or(0) as u32;
            let mut points: Vec<(f64, &Cell)> =
                here.iter().filter_map(|c| Some((f64::from(side_of(&c.case)?), *c))).collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let marker = |c: &Cell| if c.timeouts > 0 { Marker::Triangle } else { Marker::Circle };
            runtime.push(Series {
                name: Some(format!("{m}, {team} agents")),
                colour: k,
                width,
                line: true,
                points: points
                    .iter()
                    .map(|&(x, c)| Point { x, y: c.runtime_s.max(t_lo), marker: marker(c) })
                    .collect(),
            });
            success.push(Series {
                name: None,
                colour: k,
                width,
                line: true,
                points: points
                    .iter()
                    .map(|&(x, c)| Point { x, y: c.success_rate, marker: Marker::Circle })
                    .collect(),
            });
        }
    }
    let side = |label: &str, range: (f64, f64)| Axis {
        label: Some(label.into()),
        range,
        log: true,
        categories: None,
    };
    let left = Panel {
        title: "runtime per instance (mean, s)".into(),
        x: side("map side", (x_lo, x_hi)),
        y: side("seconds", (t_lo, t_hi)),
        series: runtime,
        legend: true,
    };
    let right = Panel {
        title: "success rate (triangles: some runs timed out)".into(),
        x: side("map side", (x_lo, x_hi)),
        y: Axis { label: Some("success".into()), ..Axis::linear((0.0, 1.05)) },
        series: success,
        legend: false,
    };
    let figure =
        Figure { width: 1400, height: 600, rows: 1, columns: 2, panels: vec![left, right] };
    write_figure(&figure, path)
}
