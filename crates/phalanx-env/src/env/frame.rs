//! The formation frame: what the formation policy observes when it runs inside the hierarchy.
//!
//! The formation policy was trained with its goals on a placement of the target layout next
//! to the team (`formation_instance`): its cost channel and goal vector lead each agent to its
//! slot of the layout, which is how it reshapes. On the way to far goals those inputs would
//! lead it to the far goals instead. The frame gives it the inputs of its training: the goal
//! layout translated onto the team so that an *anchor* agent's slot is a given cell (the
//! anchor's cell after its move this step, see [`Frame::update`]); each agent's *frame
//! goal* is its cell of that placement, with BFS distances from each frame goal within a
//! window of radius [`RADIUS`] around it (cells beyond the window count as blocked, as the
//! training maps' walls do). The placement is exact: a slot inside a wall stays there and its
//! agent gets as close as the BFS allows (moving the whole placement to free cells instead put
//! the anchor off its own slot, and measured worse; `docs/hierarchy.md`). Anchored at the leader's next cell, the formation policy brings
//! the others along with the leader: when the team is in formation and the leader moves, the
//! others' frame goals move with it, one step away in the same direction. The formation
//! channel, the other channels, the mask and the leader order are the episode's own: they do
//! not depend on where the goals lie.
//!
//! The frame is derived from the joint state, as the leader order is: the world supplies it
//! with each agent's observation. It is a part of the hierarchy's environment
//! (`crate::HierEnv` owns one), read from an [`Env`]'s state; this module sits below `env`
//! because it reads the simulator's padded map.

use phalanx_core::Cell;

use super::{BLOCKED, Env, UNREACHABLE};
use crate::obs::{CHANNELS, COST_SENTINEL};

/// Radius of the window of each frame goal's distances (a window of `2R + 1` cells a side).
pub(crate) const RADIUS: i32 = 16;

/// Side of a frame goal's window.
const SIDE: usize = (2 * RADIUS + 1) as usize;

/// Side of a window with its border of blocked cells (the BFS never leaves it).
const PADDED: usize = SIDE + 2;

/// A window's cells (`PADDED × PADDED`, with the border).
const CELLS: usize = PADDED * PADDED;

/// The frame of the current state (see the module docs); empty until [`Frame::update`].
#[derive(Debug, Clone, Default)]
pub(crate) struct Frame {
    /// The simulator's map the windows were searched on ([`Env::map_epoch`]).
    epoch: u64,
    /// Each agent's frame goal.
    goals: Vec<Cell>,
    /// Per agent, `PADDED × PADDED` BFS distances from its frame goal, row-major from the
    /// window's bottom-left cell `goal - (R, R)` at `(1, 1)` (a border around it).
    dist: Vec<u32>,
    /// The BFS queue (window indices).
    queue: Vec<u32>,
    /// Which cells of the window being searched are free (the border is not).
    free: Vec<bool>,
    /// Cells of the window being searched that the agent's view still needs.
    wanted: Vec<bool>,
    /// What each agent's window holds: the frame goal it was searched from, and the agent's
    /// cell when the search stopped once the cells of that agent's view were settled (`None`:
    /// the whole window).
    searched: Vec<Option<(Cell, Option<Cell>)>>,
    /// Whether each agent stands on its frame goal.
    on_goal: Vec<bool>,
}

impl Frame {
    /// Computes the formation frame of `env`'s state with agent `anchor`'s slot on
    /// `anchor_cell`: the frame goals and their distance windows. Call it after every reset
    /// and step whose frame observations are read ([`Frame::write_grid`],
    /// [`Frame::write_vector`]).
    ///
    /// # Panics
    /// If `anchor` is not an agent.
    pub(crate) fn update(&mut self, env: &Env, anchor: usize, anchor_cell: Cell) {
        let n = env.pos.len();
        let (ox, oy) = (anchor_cell.x - env.goals[anchor].x, anchor_cell.y - env.goals[anchor].y);
        if self.epoch != env.map_epoch {
            // Another map or other goals: no window searched before holds.
            self.searched.clear();
            self.epoch = env.map_epoch;
        }
        let frame = self;
        frame.goals.clear();
        frame.goals.extend(env.goals.iter().map(|g| g.offset(ox, oy)));
        frame.dist.resize(n * CELLS, UNREACHABLE);
        frame.queue.resize(CELLS, 0);
        frame.free.resize(CELLS, false);
        frame.wanted.resize(CELLS, false);
        frame.searched.resize(n, None);
        for (agent, window) in frame.dist.chunks_exact_mut(CELLS).enumerate() {
            // The map does not change within an episode (resets clear `searched`), so a
            // window searched from the same goal is still right: the whole window, or the
            // part the agent's view reads from where it stands.
            let (goal, here) = (frame.goals[agent], env.pos[agent]);
            let fresh = match frame.searched[agent] {
                Some((searched, part)) => searched != goal || part.is_some_and(|at| at != here),
                None => true,
            };
            if fresh {
                let (queue, free, wanted) = (&mut frame.queue, &mut frame.free, &mut frame.wanted);
                let whole = env.window_bfs(goal, here, window, queue, free, wanted);
                frame.searched[agent] = Some((goal, (!whole).then_some(here)));
            }
        }
        frame.on_goal.clear();
        frame.on_goal.extend(env.pos.iter().zip(&frame.goals).map(|(p, g)| p == g));
    }

    /// The frame goals of the last [`Frame::update`].
    pub(crate) fn goals(&self) -> &[Cell] {
        &self.goals
    }

    /// Agent `agent`'s channels in the formation frame of `env`'s state, `[4, F, F]`: the
    /// episode's channels ([`Env::write_grid`]) with the cost channel measured to the frame
    /// goal. When the agent stands outside its frame goal's window, the cost channel uses
    /// Manhattan distances to the frame goal instead (blocked cells keep the sentinel).
    ///
    /// # Panics
    /// If the frame was never computed.
    pub(crate) fn write_grid(&self, env: &Env, agent: usize, out: &mut [f32]) {
        assert_eq!(self.goals.len(), env.pos.len(), "update the frame first");
        env.write_grid(agent, out);
        let f = env.fov;
        let r = env.pad as i32;
        let cost = &mut out[2 * f * f..3 * f * f];
        debug_assert_eq!(CHANNELS, 4);
        let here = env.pos[agent];
        let goal = self.goals[agent];
        let window = &self.dist[agent * CELLS..(agent + 1) * CELLS];
        debug_assert!(
            matches!(self.searched[agent], Some((g, part)) if g == goal && part.is_none_or(|at| at == here)),
            "the window was searched for this goal and cell"
        );
        let manhattan = |c: Cell| (c.x - goal.x).unsigned_abs() + (c.y - goal.y).unsigned_abs();
        let own = window_at(window, goal, here);
        let k = (f - 1) as f32;
        for (row, line) in cost.chunks_exact_mut(f).enumerate() {
            for (col, value) in line.iter_mut().enumerate() {
                let cell = here.offset(col as i32 - r, row as i32 - r);
                if !env.padded_free(cell) {
                    *value = COST_SENTINEL;
                    continue;
                }
                let other_on_goal = env
                    .occupant(cell)
                    .is_some_and(|j| j != agent && self.on_goal.get(j).copied().unwrap_or(false));
                let rel = match own {
                    Some(own) => window_at(window, goal, cell).map(|d| d as f32 - own as f32),
                    None => Some(manhattan(cell) as f32 - manhattan(here) as f32),
                };
                *value = match rel {
                    Some(rel) if !other_on_goal => rel.clamp(-k, k) / k,
                    _ => COST_SENTINEL,
                };
            }
        }
    }

    /// Agent `agent`'s goal vector towards its frame goal, scaled as [`Env::write_vector`].
    ///
    /// # Panics
    /// If the frame was never computed.
    pub(crate) fn write_vector(&self, env: &Env, agent: usize, out: &mut [f32]) {
        write_goal_vector(env.pos[agent], self.goals[agent], env.fov, out);
    }
}

impl Env {
    /// Agent `agent`'s goal vector towards its *place*: its cell of the goal layout placed
    /// so that agent `front`'s cell is `front`'s goal cell of the layout (scaled as
    /// [`Env::write_vector`]; zeros for `front` itself and for an agent on its place). Unlike
    /// the frame, it is placed on where the front agent stands, before anyone moves.
    ///
    /// # Panics
    /// If `agent` or `front` is not an agent.
    pub fn write_place_vector(&self, agent: usize, front: usize, out: &mut [f32]) {
        let (goal, anchor) = (self.goals[agent], self.goals[front]);
        let place = self.pos[front].offset(goal.x - anchor.x, goal.y - anchor.y);
        write_goal_vector(self.pos[agent], place, self.fov, out);
    }

    /// The translation that places the goal layout on the team: the mean of the agents'
    /// cells less the mean of their goals (`(0, 0)` when every agent is on its goal).
    pub fn team_shift(&self) -> (f64, f64) {
        let n = self.pos.len().max(1) as f64;
        let sum = |cells: &[Cell], f: fn(&Cell) -> i32| {
            cells.iter().map(|c| f64::from(f(c))).sum::<f64>()
        };
        let dx = sum(&self.pos, |c| c.x) - sum(&self.goals, |c| c.x);
        let dy = sum(&self.pos, |c| c.y) - sum(&self.goals, |c| c.y);
        (dx / n, dy / n)
    }

    /// Agent `agent`'s vector towards its place in the goal layout translated by `shift`
    /// ([`Env::team_shift`]: the layout placed on the team's centre), scaled as
    /// [`Env::write_vector`]; zeros when it is shorter than the dead band
    /// ([`crate::EnvConfig::team_deadband`]). For the agent
    /// in front of a team that fell behind, it points back by the others' mean lag: what
    /// it needs to know to wait for them ([`Env::write_vectors`] writes it for that agent
    /// only).
    ///
    /// # Panics
    /// If `agent` is not an agent.
    pub fn write_team_vector(&self, agent: usize, shift: (f64, f64), out: &mut [f32]) {
        let (p, g) = (self.pos[agent], self.goals[agent]);
        let dx = f64::from(g.x - p.x) + shift.0;
        let dy = f64::from(g.y - p.y) + shift.1;
        let band = self.config.team_deadband;
        if dx * dx + dy * dy < band * band {
            out[..3].fill(0.0);
        } else {
            write_scaled(dx, dy, self.fov, out);
        }
    }

    /// Whether `cell` is a free cell of the map (outside the map is blocked).
    fn padded_free(&self, cell: Cell) -> bool {
        let inside = |v: i32, side: u32| (0..side as i32).contains(&v);
        inside(cell.x, self.width)
            && inside(cell.y, self.height)
            && self.blocked[super::padded_idx(self.pw, self.pad, cell) as usize] == 0
    }

    /// The agent standing on `cell`, if any (`cell` on the map or its padding).
    fn occupant(&self, cell: Cell) -> Option<usize> {
        let r = self.pad as i32;
        let inside = |v: i32, side: u32| (-r..side as i32 + r).contains(&v);
        if !inside(cell.x, self.width) || !inside(cell.y, self.height) {
            return None;
        }
        let v = self.occ[super::padded_idx(self.pw, self.pad, cell) as usize];
        (usize::from(v) < self.pos.len()).then_some(usize::from(v))
    }

    /// BFS from `source` over the free cells of its window (the source itself counts as
    /// free); `window` is overwritten (`PADDED × PADDED`). It stops once every free cell of
    /// the window within the field of view around `view` is settled (the cells farther away
    /// keep `UNREACHABLE`) and returns whether it searched the whole window. `wanted` is all
    /// `false` before and after.
    fn window_bfs(
        &self,
        source: Cell,
        view: Cell,
        window: &mut [u32],
        queue: &mut [u32],
        free: &mut [bool],
        wanted: &mut [bool],
    ) -> bool {
        free.fill(false);
        let origin = source.offset(-RADIUS, -RADIUS);
        let (width, height) = (self.width as i32, self.height as i32);
        let (x0, x1) = (origin.x.max(0), (origin.x + SIDE as i32).min(width));
        for wy in 0..SIDE {
            let y = origin.y + wy as i32;
            if !(0..height).contains(&y) || x0 >= x1 {
                continue;
            }
            let at = super::padded_idx(self.pw, self.pad, Cell::new(x0, y)) as usize;
            let map = &self.blocked[at..at + (x1 - x0) as usize];
            let row = &mut free[(wy + 1) * PADDED + (x0 - origin.x) as usize + 1..][..map.len()];
            for (cell, &blocked) in row.iter_mut().zip(map) {
                *cell = blocked == 0;
            }
        }
        let start = (RADIUS as usize + 1) * (PADDED + 1);
        free[start] = true;
        window.fill(UNREACHABLE);
        window[start] = 0;
        // The free cells of the window within the view of `view`: once each is settled, the
        // rest of the window is never read from there.
        let r = self.pad as i32;
        let index = |cell: Cell| {
            let (x, y) = (cell.x - origin.x, cell.y - origin.y);
            ((0..SIDE as i32).contains(&x) && (0..SIDE as i32).contains(&y))
                .then(|| (y as usize + 1) * PADDED + x as usize + 1)
        };
        let mut pending = 0_usize;
        for dy in -r..=r {
            for dx in -r..=r {
                if let Some(id) = index(view.offset(dx, dy))
                    && free[id]
                    && id != start
                {
                    wanted[id] = true;
                    pending += 1;
                }
            }
        }
        queue[0] = start as u32;
        let (mut head, mut tail) = (0, 1);
        while head < tail && pending > 0 {
            let id = queue[head] as usize;
            head += 1;
            let next = window[id] + 1;
            for n in [id + PADDED, id - PADDED, id - 1, id + 1] {
                if free[n] && window[n] == UNREACHABLE {
                    window[n] = next;
                    queue[tail] = n as u32;
                    tail += 1;
                    if wanted[n] {
                        wanted[n] = false;
                        pending -= 1;
                    }
                }
            }
        }
        let whole = head == tail;
        if pending > 0 {
            wanted.fill(false);
        }
        whole
    }
}

/// The distance stored for `cell` in the window of the frame goal `goal`, `None` outside the
/// window, blocked or cut off.
fn window_at(window: &[u32], goal: Cell, cell: Cell) -> Option<u32> {
    let (x, y) = (cell.x - goal.x + RADIUS, cell.y - goal.y + RADIUS);
    if !(0..SIDE as i32).contains(&x) || !(0..SIDE as i32).contains(&y) {
        return None;
    }
    let d = window[(y as usize + 1) * PADDED + x as usize + 1];
    (d < BLOCKED).then_some(d)
}

/// The scaled goal vector `(dx/‖d‖, dy/‖d‖, ‖d‖/(‖d‖ + F))` from `p` to `g`, zeros on the goal.
pub(super) fn write_goal_vector(p: Cell, g: Cell, fov: usize, out: &mut [f32]) {
    write_scaled(f64::from(g.x - p.x), f64::from(g.y - p.y), fov, out);
}

/// The scaled vector `(dx/‖d‖, dy/‖d‖, ‖d‖/(‖d‖ + F))` of `d = (dx, dy)`; zeros for a
/// vector shorter than a hundredth of a cell.
fn write_scaled(dx: f64, dy: f64, fov: usize, out: &mut [f32]) {
    let norm = (dx * dx + dy * dy).sqrt();
    if norm < 0.01 {
        out[..3].fill(0.0);
    } else {
        out[0] = (dx / norm) as f32;
        out[1] = (dy / norm) as f32;
        out[2] = (norm / (norm + fov as f64)) as f32;
    }
}

#[cfg(test)]
mod tests {
    use phalanx_core::{Action, Cell};
    use phalanx_gen::GenConfig;

    use super::Frame;
    use crate::{Env, EnvConfig, ObsBuffers};

    /// An environment reset on the map and goals of its last episode keeps its obstacles,
    /// distance maps and frame windows; a reset on another map with the same goals must not:
    /// every observation (the formation frame's included) equals a fresh environment's.
    #[test]
    fn a_reset_keeps_the_distance_maps_of_the_same_map_only() {
        let config = GenConfig { size: 24, density: 0.15, n_agents: 3, seed: 5, fov: 9 };
        let a = phalanx_gen::generate(&config).unwrap();
        // The same starts and goals on a map with a wall beside the first agent.
        let mut grid = a.grid().clone();
        let keep = |cell| a.starts().contains(&cell) || a.goals().contains(&cell);
        let start = a.starts()[0];
        for dy in -2..=2 {
            for dx in [-2, 2] {
                let cell = Cell::new(start.x + dx, start.y + dy);
                if grid.in_bounds(cell) && !keep(cell) {
                    grid.set_blocked(cell, true);
                }
            }
        }
        let b = phalanx_core::Instance::new(grid, a.starts().to_vec(), a.goals().to_vec()).unwrap();
        assert_ne!(a.grid(), b.grid());
        let views = |env: &mut Env, frame: &mut Frame| {
            let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
            env.observe(&mut obs);
            let mut frames = vec![0.0; env.n_agents() * obs.shape.grid_len()];
            frame.update(env, 0, env.positions()[0]);
            for (agent, out) in frames.chunks_exact_mut(obs.shape.grid_len()).enumerate() {
                frame.write_grid(env, agent, out);
            }
            let costs: Vec<u32> = (0..env.n_agents()).map(|i| env.cost_to_go(i)).collect();
            (obs.grid, frames, costs)
        };
        let fresh = |inst: &phalanx_core::Instance| {
            let mut env = Env::new(EnvConfig::default()).unwrap();
            env.reset(inst).unwrap();
            views(&mut env, &mut Frame::default())
        };
        let (mut env, mut frame) = (Env::new(EnvConfig::default()).unwrap(), Frame::default());
        for (i, inst) in [&a, &a, &b, &b, &a].into_iter().enumerate() {
            env.reset(inst).unwrap();
            let kept = views(&mut env, &mut frame);
            assert!(kept == fresh(inst), "reset {i} differs from a fresh environment");
        }
        assert!(fresh(&a) != fresh(&b), "the wall changes what the agents see");
    }

    /// Frame windows are kept from step to step (and searched only as far as an agent's view):
    /// after every step the frame views equal those of a fresh environment placed in the same
    /// state, whether the frame goals moved, or stayed while the agents moved.
    #[test]
    fn frame_views_after_steps_equal_a_fresh_search() {
        let config = GenConfig { size: 32, density: 0.15, n_agents: 3, seed: 9, fov: 9 };
        let inst = phalanx_gen::generate(&config).unwrap();
        let frames = |env: &Env, frame: &mut Frame, anchor_cell| {
            frame.update(env, 0, anchor_cell);
            let len = env.obs_shape().grid_len();
            let mut out = vec![0.0; env.n_agents() * len];
            for (agent, grid) in out.chunks_exact_mut(len).enumerate() {
                frame.write_grid(env, agent, grid);
            }
            out
        };
        let (mut env, mut frame) = (Env::new(EnvConfig::default()).unwrap(), Frame::default());
        env.reset(&inst).unwrap();
        let fixed = inst.starts()[0];
        for t in 0..40 {
            // The frame anchored at a fixed cell for a few steps (the goals stay, the agents
            // move), then at the first agent (the goals move with it).
            let anchor = if t % 10 < 5 { fixed } else { env.positions()[0] };
            let kept = frames(&env, &mut frame, anchor);
            let placed = phalanx_core::Instance::new(
                inst.grid().clone(),
                env.positions().to_vec(),
                inst.goals().to_vec(),
            )
            .unwrap();
            let mut fresh = Env::new(EnvConfig::default()).unwrap();
            fresh.reset(&placed).unwrap();
            assert!(
                kept == frames(&fresh, &mut Frame::default(), anchor),
                "step {t}: a kept window differs"
            );
            if env.is_done() {
                break;
            }
            env.step(&[Action::ALL[t % 4], Action::ALL[(t / 3) % 4], Action::ALL[(t / 7) % 4]]);
        }
    }
}
