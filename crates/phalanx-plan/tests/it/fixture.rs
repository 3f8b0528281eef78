//! ASCII fixtures: `#` wall, `.` free, `a`..`z` start of agent 0.., `A`..`Z` its goal. The
//! first line is the top row (largest `y`).

use phalanx_core::{Cell, Grid, Instance};

/// Parses a fixture into an instance.
#[track_caller]
pub(crate) fn instance(fixture: &str) -> Instance {
    let rows: Vec<&str> = fixture.lines().map(str::trim).filter(|line| !line.is_empty()).collect();
    let height = rows.len() as u32;
    let width = rows[0].len() as u32;
    let mut starts = Vec::new();
    let mut goals = Vec::new();
    let grid = Grid::from_fn(width, height, |c| {
        rows[(height as i32 - 1 - c.y) as usize].as_bytes()[c.x as usize] == b'#'
    });
    for (row, line) in rows.iter().enumerate() {
        for (x, ch) in line.bytes().enumerate() {
            let cell = Cell::new(x as i32, height as i32 - 1 - row as i32);
            match ch {
                b'a'..=b'z' => starts.push((ch - b'a', cell)),
                b'A'..=b'Z' => goals.push((ch - b'A', cell)),
                _ => {}
            }
        }
    }
    starts.sort();
    goals.sort();
    Instance::new(
        grid,
        starts.into_iter().map(|(_, c)| c).collect(),
        goals.into_iter().map(|(_, c)| c).collect(),
    )
    .expect("valid fixture")
}
