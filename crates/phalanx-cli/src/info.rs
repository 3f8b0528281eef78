//! `phalanx info`: describe an instance: size, density, agents, the formation (the goals'
//! layout) as an ASCII picture, and each agent's start, goal and BFS distance (the first
//! 100 agents, fewer on maps so large that their searches would take more than a second or
//! so).

use std::path::PathBuf;
use std::process::ExitCode;

use phalanx_core::{Cell, DistanceMap, Instance};

use crate::util;

/// Arguments of `phalanx info`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Instance file: .yaml/.yml or .scen.
    instance: PathBuf,
    /// Use only the first N agents (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
}

/// The most agents listed, each with its BFS distance.
const MAX_ROWS: usize = 100;
/// The most cells the listed agents' BFS searches visit in all (a second or so).
const MAX_BFS_CELLS: usize = 50_000_000;

/// Largest formation picture side drawn.
const MAX_PICTURE: i32 = 64;

pub(crate) fn run(args: Args) -> anyhow::Result<ExitCode> {
    let named = util::read_instance(&args.instance, args.agents)?;
    let inst = &named.instance;
    let grid = inst.grid();
    let mut text = util::table(&[
        ("instance", args.instance.display().to_string()),
        ("size", format!("{}x{}", grid.width(), grid.height())),
        ("obstacles", format!("{} (density {:.4})", grid.n_blocked(), grid.density())),
        ("agents", inst.n_agents().to_string()),
    ]);
    text.push_str("formation (goal layout, agent numbers; y grows upwards):\n");
    text.push_str(&formation_picture(inst));
    let mut rows = vec![["agent", "name", "start", "goal", "distance"].map(String::from).to_vec()];
    // One BFS per row: at most MAX_ROWS rows, fewer on large maps (MAX_BFS_CELLS in all).
    let shown = (MAX_BFS_CELLS / grid.n_cells().max(1)).clamp(1, MAX_ROWS).min(inst.n_agents());
    for (i, name) in named.names.iter().enumerate().take(shown) {
        let (start, goal) = (inst.starts()[i], inst.goals()[i]);
        let dist =
            DistanceMap::bfs(grid, goal).get(start).map_or("-".to_owned(), |d| d.to_string());
        rows.push(vec![i.to_string(), name.clone(), start.to_string(), goal.to_string(), dist]);
    }
    text.push_str(&util::columns(&rows));
    if shown < inst.n_agents() {
        text.push_str(&format!(
            "… and {} more agents (the first {shown} are listed; --agents N takes the first N)\n",
            inst.n_agents() - shown
        ));
    }
    util::print(&text)?;
    Ok(ExitCode::SUCCESS)
}

/// The goals' bounding box, top row = largest y; agents 0–9 then a–z, `*` beyond, `.` empty.
fn formation_picture(inst: &Instance) -> String {
    let formation = inst.formation();
    let width = formation.iter().map(|c| c.x).max().unwrap_or(0) + 1;
    let height = formation.iter().map(|c| c.y).max().unwrap_or(0) + 1;
    if width > MAX_PICTURE || height > MAX_PICTURE {
        return format!("  ({width}x{height}, too large to draw)\n");
    }
    let mut res = String::new();
    for y in (0..height).rev() {
        res.push_str("  ");
        for x in 0..width {
            let label = formation
                .iter()
                .position(|&c| c == Cell::new(x, y))
                .map_or('.', |i| char::from_digit(i as u32, 36).unwrap_or('*'));
            res.push(label);
        }
        res.push('\n');
    }
    res
}
