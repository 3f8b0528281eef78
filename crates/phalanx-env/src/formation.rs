//! The formation-training environment's episodes (docs/spec.md §5): agents placed at random, each
//! within the field of view of another, and a random target formation.

use phalanx_core::{Cell, Grid, Instance, formation_loss};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::EnvError;

/// Placements tried before [`formation_instance`] gives up.
pub const MAX_PLACEMENT_ATTEMPTS: u32 = 1000;

/// How far (cells, in each axis) the target layout's centre may lie from the team's.
const JITTER: i32 = 1;

/// A formation-training instance on `grid` (run it with [`crate::Task::Formation`]):
///
/// - agent 0 stands on a uniformly drawn free cell; agent `i > 0` on a free, unused cell
///   drawn uniformly in the `fov × fov` window of a uniformly drawn earlier agent, so every
///   agent sees at least one other;
/// - the target formation is `n_agents` distinct cells drawn uniformly in an `s × s` square,
///   `s = max(fov / 2 + 1, ⌈√n_agents⌉)`, placed on the team: its centroid on the agents'
///   centroid (rounded), moved by up to one cell in each axis at random. Its cells are the
///   goals (agent `i` gets cell `i`), all free and reachable. `L_f` ignores where the layout
///   lies, so the goals mark a placement next to the team: the task is to reshape, not to
///   travel;
/// - the start is not already in formation (`L_f > 0`).
///
/// # Panics
/// If `n_agents` is 0.
pub fn formation_instance(
    grid: &Grid,
    n_agents: usize,
    fov: u32,
    rng: &mut ChaCha8Rng,
) -> Result<Instance, EnvError> {
    assert!(n_agents > 0, "a formation needs agents");
    let free: Vec<Cell> = grid.free_cells().collect();
    let r = (fov / 2) as i32;
    let side = ((fov / 2 + 1) as usize).max(n_agents.isqrt() + usize::from(!is_square(n_agents)));
    let side = side as u32;
    for _ in 0..MAX_PLACEMENT_ATTEMPTS {
        if free.len() < n_agents {
            break;
        }
        let mut starts = Vec::with_capacity(n_agents);
        starts.push(free[rng.random_range(0..free.len() as u32) as usize]);
        let mut ok = true;
        for _ in 1..n_agents {
            let mut placed = false;
            for _ in 0..64 {
                let anchor = starts[rng.random_range(0..starts.len() as u32) as usize];
                let cell = anchor.offset(rng.random_range(-r..=r), rng.random_range(-r..=r));
                if grid.is_free(cell) && !starts.contains(&cell) {
                    starts.push(cell);
                    placed = true;
                    break;
                }
            }
            ok &= placed;
            if !ok {
                break;
            }
        }
        if !ok {
            continue;
        }
        // The target layout, centred on the team (its centroid on the starts' centroid, up
        // to rounding and a jitter of one cell): the loss ignores where the layout lies, so
        // the goals mark a placement next to the team rather than a place to travel to.
        let cells = phalanx_gen::random_formation(side, n_agents, rng);
        let centre = |cs: &[Cell]| {
            let n = cs.len() as f64;
            let sx: f64 = cs.iter().map(|c| f64::from(c.x)).sum();
            let sy: f64 = cs.iter().map(|c| f64::from(c.y)).sum();
            ((sx / n).round() as i32, (sy / n).round() as i32)
        };
        let (tx, ty) = centre(&starts);
        let (fx, fy) = centre(&cells);
        let (dx, dy) = (
            tx - fx + rng.random_range(-JITTER..=JITTER),
            ty - fy + rng.random_range(-JITTER..=JITTER),
        );
        let goals: Vec<Cell> = cells.iter().map(|c| c.offset(dx, dy)).collect();
        if goals.iter().any(|&g| grid.is_blocked(g)) || formation_loss(&starts, &goals) == 0.0 {
            continue;
        }
        if let Ok(inst) = Instance::new(grid.clone(), starts, goals) {
            return Ok(inst);
        }
    }
    Err(EnvError::Placement { n_agents, attempts: MAX_PLACEMENT_ATTEMPTS })
}

fn is_square(n: usize) -> bool {
    n.isqrt() * n.isqrt() == n
}
