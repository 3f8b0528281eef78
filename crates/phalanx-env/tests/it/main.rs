//! Integration tests of phalanx-env: the authors' environment test, the slow reference
//! implementation against the fast one, plan replays, sequential acting, lockstep
//! steps, pools and the `sim` command.

mod hier;
mod lockstep;
mod mater;
mod pool;
mod reference;
mod replay;
mod rewards;
mod sim;
mod turns;

use phalanx_core::{Cell, Grid, Instance};

/// Shorthand for a cell.
fn c(x: i32, y: i32) -> Cell {
    Cell::new(x, y)
}

/// An instance from a grid's size, its obstacles, starts and goals.
fn instance(w: u32, h: u32, obstacles: &[Cell], starts: &[Cell], goals: &[Cell]) -> Instance {
    let grid = Grid::from_fn(w, h, |cell| obstacles.contains(&cell));
    Instance::new(grid, starts.to_vec(), goals.to_vec()).unwrap()
}
