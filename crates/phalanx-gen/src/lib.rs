//! The paper's instance generator (docs/spec.md §2): square maps whose obstacles are straight wall
//! segments of at most half the field of view, a start region in the top-left corner and a
//! goal region in the bottom-right corner kept free, and a formation of `k` distinct cells
//! in the start region whose translate into the goal region is the goal layout.
//!
//! Randomness: one [`rand_chacha::ChaCha8Rng`] seeded with `seed_from_u64(seed)`, drawing
//! only fixed-width integers (`u32`) and `f64`-free decisions, so an instance is the same
//! for a seed on every platform and thread count. "Top-left" is the corner of the smallest
//! coordinates (`x` column, `y` row, as in MovingAI files where row 0 is printed first).
//!
//! ```
//! use phalanx_gen::{GenConfig, generate};
//! let inst = generate(&GenConfig { size: 20, density: 0.15, n_agents: 3, seed: 7, fov: 9 }).unwrap();
//! assert_eq!(inst.n_agents(), 3);
//! assert_eq!(inst, generate(&GenConfig { size: 20, density: 0.15, n_agents: 3, seed: 7, fov: 9 }).unwrap());
//! ```

use phalanx_core::{Cell, Grid, Instance, InstanceError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

/// The default map side: the paper's training maps (every default map setting of the
/// project, the generator's, the training pool's, the commands' flags, is one of these four).
pub const DEFAULT_SIZE: u32 = 32;
/// The default fraction of blocked cells.
pub const DEFAULT_DENSITY: f64 = 0.15;
/// The default team size.
pub const DEFAULT_AGENTS: usize = 3;
/// The default field of view side (the paper's 9 × 9).
pub const DEFAULT_FOV: u32 = 9;

/// Generator settings: a problem's inputs, so none of them has a hidden default in files.
#[derive(Debug, Clone, PartialEq)]
pub struct GenConfig {
    /// Map side, `8..=4096` (the paper uses 20, 32, 512 and 1024).
    pub size: u32,
    /// Fraction of cells blocked, `0.0..=0.4` (the paper uses 0.05 and 0.15).
    pub density: f64,
    /// Number of agents `k`, `1..=r²` for the start region side `r`.
    pub n_agents: usize,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
    /// Field of view side (odd, at least 3); walls are at most `fov / 2` cells long.
    pub fov: u32,
}

impl Default for GenConfig {
    /// 32×32, density 0.15, 3 agents, seed 0, 9×9 view ([`DEFAULT_SIZE`] and the others).
    fn default() -> GenConfig {
        GenConfig {
            size: DEFAULT_SIZE,
            density: DEFAULT_DENSITY,
            n_agents: DEFAULT_AGENTS,
            seed: 0,
            fov: DEFAULT_FOV,
        }
    }
}

/// Why no instance came out.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GenError {
    /// The map side is out of range.
    #[error("map size {0} is out of range (8 to 4096)")]
    Size(u32),
    /// The density is out of range.
    #[error("obstacle density {0} is out of range (0 to 0.4)")]
    Density(f64),
    /// The field of view is not an odd number of at least 3.
    #[error("field of view {0} must be odd and at least 3")]
    Fov(u32),
    /// More agents than cells in the start region.
    #[error("{n_agents} agents do not fit in the {side}x{side} start region (at most {max})")]
    Agents {
        /// Requested agents.
        n_agents: usize,
        /// Start region side.
        side: u32,
        /// Largest allowed count.
        max: usize,
    },
    /// A map of another kind than the paper's does not fit the side
    /// ([`maze`], [`rooms`]).
    #[error("a {side}x{side} map holds no {what}")]
    Kind {
        /// The map side.
        side: u32,
        /// What it cannot hold (`"maze of 2-cell corridors"`, …).
        what: String,
    },
    /// No map with the goals reachable came out within the attempt limit.
    #[error("no map with every goal reachable after {attempts} attempts (density {density})")]
    Unreachable {
        /// Attempts made.
        attempts: u32,
        /// The density asked for.
        density: f64,
    },
}

/// Side of the start and goal regions: 5 for maps below 512, 10 otherwise.
pub fn region_side(size: u32) -> u32 {
    if size < 512 { 5 } else { 10 }
}

/// How many fresh maps [`generate`] draws before it gives up on reachability.
pub const MAX_ATTEMPTS: u32 = 1000;

/// Generates the instance for `config` (deterministic for its seed).
pub fn generate(config: &GenConfig) -> Result<Instance, GenError> {
    let &GenConfig { size, density, n_agents, seed, fov } = config;
    if !(8..=4096).contains(&size) {
        return Err(GenError::Size(size));
    }
    if !(0.0..=0.4).contains(&density) {
        return Err(GenError::Density(density));
    }
    if fov < 3 || fov % 2 == 0 {
        return Err(GenError::Fov(fov));
    }
    let r = region_side(size);
    let max = (r * r) as usize;
    if n_agents == 0 || n_agents > max {
        return Err(GenError::Agents { n_agents, side: r, max });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let far = (size - r) as i32;
    let start_region = (Cell::new(0, 0), Cell::new(r as i32 - 1, r as i32 - 1));
    let goal_region = (Cell::new(far, far), Cell::new(size as i32 - 1, size as i32 - 1));
    let starts = random_formation(r, n_agents, &mut rng);
    let goals: Vec<Cell> = starts.iter().map(|c| c.offset(far, far)).collect();
    for _ in 0..MAX_ATTEMPTS {
        let grid =
            random_grid(size, size, density, fov / 2, &[start_region, goal_region], &mut rng);
        match Instance::new(grid, starts.clone(), goals.clone()) {
            Ok(inst) => return Ok(inst),
            Err(InstanceError::Unreachable { .. }) => continue,
            Err(other) => unreachable!("generator broke an instance invariant: {other}"),
        }
    }
    Err(GenError::Unreachable { attempts: MAX_ATTEMPTS, density })
}

/// `n_agents` distinct cells of the `r × r` region at the origin, in draw order (a partial
/// Fisher–Yates shuffle of the region's cells in row-major order).
///
/// # Panics
/// If `n_agents > r * r`.
pub fn random_formation(r: u32, n_agents: usize, rng: &mut ChaCha8Rng) -> Vec<Cell> {
    assert!(n_agents <= (r * r) as usize, "{n_agents} cells do not fit in {r}x{r}");
    let mut cells: Vec<Cell> =
        (0..r * r).map(|i| Cell::new((i % r) as i32, (i / r) as i32)).collect();
    for i in 0..n_agents {
        let j = rng.random_range(i as u32..r * r) as usize;
        cells.swap(i, j);
    }
    cells.truncate(n_agents);
    cells
}

/// A `width × height` grid with `round(density · width · height)` blocked cells laid as
/// straight wall segments: each segment picks an orientation, a length in `1..=max_wall` and
/// a first cell uniformly, then blocks its cells that are inside the grid, outside every
/// `keep_free` rectangle (inclusive corners) and not yet blocked, until the count is met.
/// The count is capped at the number of cells that may be blocked.
///
/// # Panics
/// If `max_wall` is 0 or `density` is not in `0.0..=1.0`.
pub fn random_grid(
    width: u32,
    height: u32,
    density: f64,
    max_wall: u32,
    keep_free: &[(Cell, Cell)],
    rng: &mut ChaCha8Rng,
) -> Grid {
    assert!(max_wall > 0, "walls need a positive length");
    assert!((0.0..=1.0).contains(&density), "density {density} out of range");
    let mut grid = Grid::new(width, height);
    let protected = |c: Cell| {
        keep_free
            .iter()
            .any(|&(lo, hi)| (lo.x..=hi.x).contains(&c.x) && (lo.y..=hi.y).contains(&c.y))
    };
    let n_protected = grid.free_cells().filter(|&c| protected(c)).count();
    let target =
        ((density * grid.n_cells() as f64).round() as usize).min(grid.n_cells() - n_protected);
    while grid.n_blocked() < target {
        let vertical = rng.random_range(0..2u32) == 1;
        let len = rng.random_range(1..=max_wall) as i32;
        let first =
            Cell::new(rng.random_range(0..width) as i32, rng.random_range(0..height) as i32);
        for i in 0..len {
            let cell = if vertical { first.offset(0, i) } else { first.offset(i, 0) };
            if grid.in_bounds(cell) && !protected(cell) && !grid.is_blocked(cell) {
                grid.set_blocked(cell, true);
                if grid.n_blocked() == target {
                    break;
                }
            }
        }
    }
    grid
}

/// One draw of a classic MAPF instance in the MovingAI "random" style (not the paper's
/// formation instances): every cell blocked with probability `density`, then `n_agents`
/// distinct starts and, independently, `n_agents` distinct goals drawn uniformly from the free
/// cells. `None` when fewer cells than agents are free or a goal is unreachable; callers that
/// need an instance draw again from the same stream.
///
/// # Panics
/// If `density` is not in `0.0..=1.0`.
pub fn random_mapf_instance(
    width: u32,
    height: u32,
    density: f64,
    n_agents: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Instance> {
    let grid = Grid::from_fn(width, height, |_| rng.random_bool(density));
    let mut free: Vec<Cell> = grid.free_cells().collect();
    if free.len() < n_agents {
        return None;
    }
    let mut pool = free.clone();
    let starts: Vec<Cell> =
        (0..n_agents).map(|_| pool.swap_remove(rng.random_range(0..pool.len()))).collect();
    let goals: Vec<Cell> =
        (0..n_agents).map(|_| free.swap_remove(rng.random_range(0..free.len()))).collect();
    Instance::new(grid, starts, goals).ok()
}

/// A formation instance on a given map, which has no start and goal regions (a MovingAI
/// map): `None` after [`MAX_ATTEMPTS`] draws without one. Each draw:
/// 1. a corner uniformly among the free cells; the formation is `n_agents` cells of the
///    `r × r` box at that corner ([`random_formation`] moved there), every one free and
///    reachable from the corner;
/// 2. the goal offset: a cell drawn uniformly among those of the corner's component whose
///    BFS distance from the corner is at least half the component's largest (the far half of
///    the map as the agents see it); the goals are the formation translated by it, and the
///    draw is kept when every goal is free and reachable.
///
/// So the goals are the start formation translated, as on the paper's maps, every agent can
/// reach its goal, and the trip is long. All draws come from `rng`.
pub fn formation_on_map(
    grid: &Grid,
    n_agents: usize,
    r: u32,
    rng: &mut ChaCha8Rng,
) -> Option<Instance> {
    let free: Vec<Cell> = grid.free_cells().collect();
    if free.is_empty() || n_agents > (r * r) as usize {
        return None;
    }
    for _ in 0..MAX_ATTEMPTS {
        let corner = free[rng.random_range(0..free.len())];
        let starts: Vec<Cell> = random_formation(r, n_agents, rng)
            .into_iter()
            .map(|c| corner.offset(c.x, c.y))
            .collect();
        let dist = phalanx_core::DistanceMap::bfs(grid, corner);
        let reachable = |c: &Cell| grid.in_bounds(*c) && dist.get(*c).is_some();
        if !starts.iter().all(reachable) {
            continue;
        }
        let far = free.iter().filter_map(|&c| dist.get(c)).max().unwrap_or(0);
        let targets: Vec<Cell> =
            free.iter().copied().filter(|&c| dist.get(c).is_some_and(|d| 2 * d >= far)).collect();
        if targets.is_empty() {
            continue;
        }
        let target = targets[rng.random_range(0..targets.len())];
        let (dx, dy) = (target.x - corner.x, target.y - corner.y);
        let goals: Vec<Cell> = starts.iter().map(|c| c.offset(dx, dy)).collect();
        if goals.iter().all(reachable)
            && let Ok(instance) = Instance::new(grid.clone(), starts, goals)
        {
            return Some(instance);
        }
    }
    None
}

mod kinds;

pub use kinds::{MAZE_CORRIDOR, ROOM_SIDE, maze, rooms};

#[cfg(test)]
mod tests;
