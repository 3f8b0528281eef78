//! Map kinds other than the paper's random walls, for training on the structure of real
//! benchmark maps without training on those maps: mazes of narrow corridors and grids of
//! rooms joined by one-cell doors (the two kinds of MovingAI map the learned methods fail
//! most, `maze-32-32-2` and `room-64-64-8`; docs/imitation.md). The maps are drawn here,
//! from the facts of the kind (corridor width, room size), not copied from any file.
//!
//! Randomness as the rest of the crate: one [`ChaCha8Rng`] from `seed_from_u64(seed)`,
//! `u32` draws only, so a map is the same for a seed everywhere.

use phalanx_core::{Cell, Grid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::GenError;

/// The corridor width of the mazes of training pools and `phalanx gen --kind maze`:
/// MovingAI's `maze-32-32-2`'s.
pub const MAZE_CORRIDOR: u32 = 2;

/// The room side of the room maps of training pools and `phalanx gen --kind rooms`:
/// MovingAI's `room-64-64-8`'s.
pub const ROOM_SIDE: u32 = 7;

/// In [`maze`], one wall in this many between neighbouring corridor cells that the
/// spanning tree left standing is opened too, so that a maze has a few loops.
const MAZE_LOOP_ONE_IN: u32 = 10;

/// In [`rooms`], one wall in this many between neighbouring rooms that the spanning tree
/// left without a door gets one too.
const ROOM_EXTRA_DOOR_ONE_IN: u32 = 2;

/// A `side × side` maze: a lattice of `corridor × corridor` cells one wall apart, joined
/// along a random spanning tree (depth-first, so long winding corridors) plus a few loops;
/// the first row and column and any margin past the last lattice cell are walls. Every free
/// cell reaches every other.
///
/// # Errors
/// If `corridor` is 0, the side is out of the generator's range (8 to 4096) or holds fewer
/// than two lattice cells (`side < 2 · corridor + 3`).
pub fn maze(side: u32, corridor: u32, seed: u64) -> Result<Grid, GenError> {
    check_side(side)?;
    let pitch = corridor.saturating_add(1);
    let m = (side - 1) / pitch;
    if corridor == 0 || m < 2 {
        let what = format!("maze of {corridor}-cell corridors");
        return Err(GenError::Kind { side, what });
    }
    let mut grid = Grid::from_fn(side, side, |_| true);
    for j in 0..m {
        for i in 0..m {
            carve(&mut grid, 1 + i * pitch, 1 + j * pitch, corridor, corridor);
        }
    }
    // The wall between lattice cell (i, j) and its right (`right`) or lower neighbour.
    let open = |grid: &mut Grid, i: u32, j: u32, right: bool| {
        let (x, y) = (1 + i * pitch, 1 + j * pitch);
        if right {
            carve(grid, x + corridor, y, 1, corridor);
        } else {
            carve(grid, x, y + corridor, corridor, 1);
        }
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tree = spanning_tree(m, &mut rng);
    for (i, j, right, in_tree) in tree {
        if in_tree || rng.random_range(0..MAZE_LOOP_ONE_IN) == 0 {
            open(&mut grid, i, j, right);
        }
    }
    Ok(grid)
}

/// A `side × side` grid of `room × room` rooms between one-cell walls (the walls on the
/// multiples of `room + 1`; the last room is cut by the map's edge), each wall between two
/// rooms with a one-cell door where a random spanning tree joins them and, elsewhere, one
/// time in two. Every free cell reaches every other.
///
/// # Errors
/// If `room` is 0, the side is out of the generator's range (8 to 4096) or holds fewer than
/// two rooms a side (`side < room + 3`).
pub fn rooms(side: u32, room: u32, seed: u64) -> Result<Grid, GenError> {
    check_side(side)?;
    let pitch = room.saturating_add(1);
    if room == 0 || side - 1 <= pitch {
        return Err(GenError::Kind { side, what: format!("two rooms of side {room} a side") });
    }
    let m = (side - 1).div_ceil(pitch);
    let mut grid = Grid::from_fn(side, side, |c| {
        (c.x as u32).is_multiple_of(pitch) || (c.y as u32).is_multiple_of(pitch)
    });
    // The free cells of room `k` along one axis.
    let span = |k: u32| (k * pitch + 1, ((k + 1) * pitch).min(side));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for (i, j, right, in_tree) in spanning_tree(m, &mut rng) {
        if !in_tree && rng.random_range(0..ROOM_EXTRA_DOOR_ONE_IN) != 0 {
            continue;
        }
        let (lo, hi) = span(if right { j } else { i });
        let along = rng.random_range(lo..hi) as i32;
        let across = ((if right { i } else { j }) + 1) * pitch;
        let door =
            if right { Cell::new(across as i32, along) } else { Cell::new(along, across as i32) };
        grid.set_blocked(door, false);
    }
    Ok(grid)
}

/// The generator's range of sides (checked before any arithmetic on the side).
fn check_side(side: u32) -> Result<(), GenError> {
    if !(8..=4096).contains(&side) {
        return Err(GenError::Size(side));
    }
    Ok(())
}

/// Frees the `w × h` cells from `(x0, y0)`.
fn carve(grid: &mut Grid, x0: u32, y0: u32, w: u32, h: u32) {
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            grid.set_blocked(Cell::new(x as i32, y as i32), false);
        }
    }
}

/// The walls between neighbouring cells of an `m × m` lattice, each as `(i, j, right,
/// in_tree)` (the wall between `(i, j)` and `(i + 1, j)` when `right`, else `(i, j + 1)`),
/// in a fixed order, marked when a random depth-first spanning tree from `(0, 0)` crosses
/// them.
fn spanning_tree(m: u32, rng: &mut ChaCha8Rng) -> Vec<(u32, u32, bool, bool)> {
    let n = (m * m) as usize;
    let index = |i: u32, j: u32| (j * m + i) as usize;
    let (mut seen, mut right, mut down) = (vec![false; n], vec![false; n], vec![false; n]);
    let mut stack = vec![(0u32, 0u32)];
    seen[0] = true;
    while let Some(&(i, j)) = stack.last() {
        let mut next: Vec<(u32, u32)> = Vec::with_capacity(4);
        if i > 0 && !seen[index(i - 1, j)] {
            next.push((i - 1, j));
        }
        if i + 1 < m && !seen[index(i + 1, j)] {
            next.push((i + 1, j));
        }
        if j > 0 && !seen[index(i, j - 1)] {
            next.push((i, j - 1));
        }
        if j + 1 < m && !seen[index(i, j + 1)] {
            next.push((i, j + 1));
        }
        if next.is_empty() {
            stack.pop();
            continue;
        }
        let (a, b) = next[rng.random_range(0..next.len() as u32) as usize];
        match (a.cmp(&i), b.cmp(&j)) {
            (std::cmp::Ordering::Greater, _) => right[index(i, j)] = true,
            (std::cmp::Ordering::Less, _) => right[index(a, b)] = true,
            (_, std::cmp::Ordering::Greater) => down[index(i, j)] = true,
            _ => down[index(a, b)] = true,
        }
        seen[index(a, b)] = true;
        stack.push((a, b));
    }
    let mut walls = Vec::with_capacity(2 * n);
    for j in 0..m {
        for i in 0..m {
            if i + 1 < m {
                walls.push((i, j, true, right[index(i, j)]));
            }
            if j + 1 < m {
                walls.push((i, j, false, down[index(i, j)]));
            }
        }
    }
    walls
}
