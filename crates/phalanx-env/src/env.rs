//! One episode: the joint state, the step with collision resolution (docs/spec.md §1), rewards and
//! termination (docs/spec.md §5), observations written into flat buffers (docs/spec.md §4) and leader-ordered
//! sequential acting (docs/spec.md §6).
//!
//! Everything the step touches is preallocated on reset: the map is stored padded by
//! `R = F / 2` blocked cells on every side, so windows and neighbours need no bounds checks;
//! each agent's BFS distance map lives in the same padded layout; an occupancy grid holds the
//! agent index per cell and is updated incrementally.

use phalanx_core::{Action, Cell, Grid, Instance, formation_loss};
use phalanx_gen::GenConfig;
use rayon::prelude::*;

use crate::config::MAX_AGENTS;
use crate::marl::{ObsBuffers, ObsShape, StepOut};
use crate::obs::{CHANNELS, COST_SENTINEL, N_ACTIONS, VECTOR_LEN};
use crate::{Clip, EnvConfig, EnvError, LeaderRule, Task};

pub(crate) mod frame;

/// Padded cells from which the agents' BFS maps are computed in parallel on reset.
const PARALLEL_BFS_CELLS: usize = 1 << 16;

/// Occupancy value of an empty cell.
const NONE: u16 = u16::MAX;
/// Claim value of a cell that two or more agents want.
const MULTI: u16 = u16::MAX - 1;
/// Distance of a free cell cut off from the goal.
const UNREACHABLE: u32 = u32::MAX;
/// Distance of a blocked or outside cell (so the BFS reads one array, not two).
const BLOCKED: u32 = u32::MAX - 1;

/// Table I of the paper, per agent per step.
mod reward {
    pub(super) const COLLISION: f32 = -50.0;
    pub(super) const TOWARDS_GOAL: f32 = 1.0;
    pub(super) const NO_MOVE: f32 = -0.25;
    pub(super) const FINISHED: f32 = 100.0;
    pub(super) const FORMATION_KEPT: f32 = 100.0;
}

/// What one step returns: per-agent rewards, the team reward (their sum), the two ways an
/// episode ends, and the info.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step<'a> {
    /// Reward of each agent.
    pub rewards: &'a [f32],
    /// Sum of the agents' rewards (VDN's team reward).
    pub team_reward: f32,
    /// The task is done: every agent on its goal (path finding, meta) or `L_f = 0`
    /// (formation).
    pub terminated: bool,
    /// The step limit was reached without termination.
    pub truncated: bool,
    /// Collisions, formation loss and goal flags.
    pub info: StepInfo<'a>,
}

/// Step information beyond the reward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInfo<'a> {
    /// Whether each agent's move was cancelled (a collision).
    pub cancelled: &'a [bool],
    /// Number of cancelled moves this step.
    pub n_cancelled: u32,
    /// `L_f` of the positions after the step.
    pub formation_loss: f64,
    /// Whether each agent stands on its goal after the step.
    pub on_goal: &'a [bool],
}

/// The scalar part of a step's outcome.
#[derive(Debug, Clone, Copy)]
struct StepFlags {
    team_reward: f32,
    terminated: bool,
    truncated: bool,
    n_cancelled: u32,
}

/// One episode of the environment.
///
/// ```ignore
/// let mut env = Env::new(EnvConfig::default())?;
/// env.reset(&instance)?;
/// let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
/// env.observe(&mut obs);
/// let step = env.step(&actions);
/// ```
#[derive(Debug, Clone)]
pub struct Env {
    config: EnvConfig,
    fov: usize,
    /// `R = F / 2`, the padding on every side.
    pad: usize,
    width: u32,
    height: u32,
    /// Padded width `width + 2R`.
    pw: usize,
    step_limit: u32,
    /// Padded obstacle flags (1 = blocked, the padding included).
    blocked: Vec<u8>,
    /// Per agent, padded BFS distances to its goal, `n_agents` blocks of padded cells.
    dist: Vec<u32>,
    /// Number of padded cells.
    n_padded: usize,
    goals: Vec<Cell>,
    goal_idx: Vec<u32>,
    starts: Vec<Cell>,
    /// `(j + 1) / n_agents` per agent.
    ident: Vec<f32>,
    /// Per agent, its precomputed formation channel (`F · F`).
    formation_obs: Vec<f32>,
    /// One BFS queue per agent.
    queues: Vec<Vec<u32>>,
    // Dynamic state.
    pos: Vec<Cell>,
    pos_idx: Vec<u32>,
    /// Padded occupancy: agent index or `NONE`.
    occ: Vec<u16>,
    /// Padded claims of the step being resolved (`NONE` between steps).
    claim: Vec<u16>,
    target: Vec<u32>,
    stack: Vec<u16>,
    t: u32,
    done: bool,
    rewards: Vec<f32>,
    cancelled: Vec<bool>,
    /// Whether each agent's move lowered its distance to its goal this step.
    closer: Vec<bool>,
    on_goal: Vec<bool>,
    loss: f64,
    // Sequential acting.
    order: Vec<u16>,
    rank: Vec<u16>,
    chosen: Vec<Action>,
    n_chosen: usize,
    /// Counts the maps (and goals) searched: a part that caches searches of the map (the
    /// hierarchy's formation frame) knows from it when they are stale.
    map_epoch: u64,
    /// The map the obstacles and distance maps were last built for (with `goals`).
    searched_map: Option<Grid>,
}

impl Env {
    /// An environment with no episode yet; call [`Env::reset`].
    pub fn new(config: EnvConfig) -> Result<Env, EnvError> {
        if config.fov < 3 || config.fov.is_multiple_of(2) {
            return Err(EnvError::Fov(config.fov));
        }
        let fov = config.fov as usize;
        Ok(Env {
            config,
            fov,
            pad: fov / 2,
            width: 0,
            height: 0,
            pw: 0,
            step_limit: 0,
            blocked: Vec::new(),
            dist: Vec::new(),
            n_padded: 0,
            goals: Vec::new(),
            goal_idx: Vec::new(),
            starts: Vec::new(),
            ident: Vec::new(),
            formation_obs: Vec::new(),
            queues: Vec::new(),
            pos: Vec::new(),
            pos_idx: Vec::new(),
            occ: Vec::new(),
            claim: Vec::new(),
            target: Vec::new(),
            stack: Vec::new(),
            t: 0,
            done: true,
            rewards: Vec::new(),
            cancelled: Vec::new(),
            closer: Vec::new(),
            on_goal: Vec::new(),
            loss: 0.0,
            order: Vec::new(),
            rank: Vec::new(),
            chosen: Vec::new(),
            n_chosen: 0,
            map_epoch: 0,
            searched_map: None,
        })
    }

    /// The settings.
    #[inline]
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// Sets the meta task's formation weight `w_f` for the following steps (the weight of an
    /// episode can differ from the configured one: each team size has its own).
    pub fn set_formation_weight(&mut self, formation_weight: f64) {
        self.config.formation_weight = formation_weight;
    }

    /// Sizes of one agent's observation: the four channels of the field of view, the goal
    /// vector and the five actions' mask.
    #[inline]
    pub fn obs_shape(&self) -> ObsShape {
        ObsShape { channels: CHANNELS, fov: self.fov, env_vec: VECTOR_LEN, n_actions: N_ACTIONS }
    }

    /// Starts a new episode on `instance`: the agents stand on their starts. Buffers are
    /// reused when the map size and agent count are those of the previous episode.
    pub fn reset(&mut self, instance: &Instance) -> Result<(), EnvError> {
        let n = instance.n_agents();
        if n > MAX_AGENTS {
            return Err(EnvError::TooManyAgents(n));
        }
        let grid = instance.grid();
        let (w, h, pad) = (grid.width() as usize, grid.height() as usize, self.pad);
        let pw = w + 2 * pad;
        let n_padded = pw * (h + 2 * pad);
        self.width = grid.width();
        self.height = grid.height();
        self.pw = pw;
        self.n_padded = n_padded;
        self.step_limit = self.config.step_limit.unwrap_or(3 * grid.side());
        // The obstacles and distance maps depend on the map and the goals only: an episode on
        // the same ones as the last (the test-time rollouts of one instance) keeps them.
        let same_map = self.searched_map.as_ref() == Some(grid) && self.goals == instance.goals();
        if !same_map {
            self.searched_map = None;
            self.search_map(instance);
            self.searched_map = Some(grid.clone());
        }
        self.starts.clear();
        self.starts.extend_from_slice(instance.starts());
        // Identity codes and formation channels.
        self.ident.clear();
        self.ident.extend((0..n).map(|j| (j + 1) as f32 / n as f32));
        let f = self.fov;
        self.formation_obs.clear();
        self.formation_obs.resize(n * f * f, 0.0);
        for i in 0..n {
            let block = &mut self.formation_obs[i * f * f..(i + 1) * f * f];
            for (j, &g) in self.goals.iter().enumerate() {
                let dx = g.x - self.goals[i].x + pad as i32;
                let dy = g.y - self.goals[i].y + pad as i32;
                if (0..f as i32).contains(&dx) && (0..f as i32).contains(&dy) {
                    block[dy as usize * f + dx as usize] = self.ident[j];
                }
            }
        }
        // Dynamic state.
        self.occ.clear();
        self.occ.resize(n_padded, NONE);
        self.claim.clear();
        self.claim.resize(n_padded, NONE);
        self.pos.clear();
        self.pos.extend_from_slice(instance.starts());
        self.pos_idx.clear();
        self.pos_idx.extend(self.pos.iter().map(|&c| padded_idx(pw, pad, c)));
        for (i, &p) in self.pos_idx.iter().enumerate() {
            self.occ[p as usize] = i as u16;
        }
        self.target.clear();
        self.target.resize(n, 0);
        self.stack.clear();
        self.stack.reserve(n);
        self.rewards.clear();
        self.rewards.resize(n, 0.0);
        self.cancelled.clear();
        self.cancelled.resize(n, false);
        self.closer.clear();
        self.closer.resize(n, false);
        self.on_goal.clear();
        self.on_goal.extend(self.pos_idx.iter().zip(&self.goal_idx).map(|(p, g)| p == g));
        self.loss = formation_loss(&self.pos, &self.goals);
        self.t = 0;
        self.done = false;
        self.order.clear();
        self.order.extend(0..n as u16);
        self.rank.clear();
        self.rank.extend(0..n as u16);
        self.chosen.clear();
        self.chosen.resize(n, Action::Wait);
        self.n_chosen = 0;
        Ok(())
    }

    /// The padded obstacles, the goals and one BFS distance map per goal, for `instance`
    /// (whose sizes `reset` has set).
    fn search_map(&mut self, instance: &Instance) {
        let grid = instance.grid();
        let n = instance.n_agents();
        let (w, h, pad, pw, n_padded) =
            (grid.width() as usize, grid.height() as usize, self.pad, self.pw, self.n_padded);
        // Padded obstacles, row by row from the bit-packed grid.
        self.blocked.clear();
        self.blocked.resize(n_padded, 1);
        self.map_epoch += 1;
        for y in 0..h {
            let row = (y + pad) * pw + pad;
            for (x, slot) in self.blocked[row..row + w].iter_mut().enumerate() {
                *slot = u8::from(grid.is_blocked(Cell::new(x as i32, y as i32)));
            }
        }
        self.goals.clear();
        self.goals.extend_from_slice(instance.goals());
        self.goal_idx.clear();
        self.goal_idx.extend(self.goals.iter().map(|&g| padded_idx(pw, pad, g)));
        // Distance maps, each from a template with the blocked cells marked.
        self.dist.resize(n * n_padded, UNREACHABLE);
        let (template, maps) = self.dist.split_at_mut(n_padded);
        unsearched(template, &self.blocked);
        for map in maps.chunks_exact_mut(n_padded) {
            map.copy_from_slice(template);
        }
        // One BFS per agent, in parallel when the maps are large enough to pay for it.
        self.queues.resize_with(n, Vec::new);
        let searches =
            self.dist.chunks_exact_mut(n_padded).zip(&mut self.queues).zip(&self.goal_idx);
        if n > 1 && n_padded >= PARALLEL_BFS_CELLS && rayon::current_num_threads() > 1 {
            let searches: Vec<_> = searches.collect();
            searches.into_par_iter().for_each(|((map, queue), &goal)| {
                padded_bfs(pw, goal, map, queue);
            });
        } else {
            for ((map, queue), &goal) in searches {
                padded_bfs(pw, goal, map, queue);
            }
        }
    }

    /// Agent `agent`'s map of the path-finding cost channel and mask: its BFS distances.
    #[inline]
    fn cost_map(&self, agent: usize) -> &[u32] {
        &self.dist[agent * self.n_padded..(agent + 1) * self.n_padded]
    }

    /// Generates the instance for `config` (with this environment's field of view) and
    /// starts an episode on it; returns the instance.
    pub fn reset_generated(&mut self, config: &GenConfig) -> Result<Instance, EnvError> {
        let instance =
            phalanx_gen::generate(&GenConfig { fov: self.config.fov, ..config.clone() })?;
        self.reset(&instance)?;
        Ok(instance)
    }

    /// Number of agents.
    #[inline]
    pub fn n_agents(&self) -> usize {
        self.pos.len()
    }

    /// Current positions.
    #[inline]
    pub fn positions(&self) -> &[Cell] {
        &self.pos
    }

    /// Goals.
    #[inline]
    pub fn goals(&self) -> &[Cell] {
        &self.goals
    }

    /// Starts of the episode.
    #[inline]
    pub fn starts(&self) -> &[Cell] {
        &self.starts
    }

    /// Steps taken in this episode.
    #[inline]
    pub fn t(&self) -> u32 {
        self.t
    }

    /// The step limit of this episode (`3 × map side` unless configured).
    #[inline]
    pub fn step_limit(&self) -> u32 {
        self.step_limit
    }

    /// Whether the episode has ended (terminated or truncated); stepping it again panics.
    #[inline]
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// `L_f` of the current positions.
    #[inline]
    pub fn formation_loss(&self) -> f64 {
        self.loss
    }

    /// Whether each agent stands on its goal.
    #[inline]
    pub fn on_goal(&self) -> &[bool] {
        &self.on_goal
    }

    /// BFS distance from agent `agent`'s cell to its goal.
    #[inline]
    pub fn cost_to_go(&self, agent: usize) -> u32 {
        self.dist[agent * self.n_padded + self.pos_idx[agent] as usize]
    }

    /// BFS distance from `cell` to agent `agent`'s goal, `None` when blocked, outside or cut
    /// off.
    pub fn distance(&self, agent: usize, cell: Cell) -> Option<u32> {
        let pad = self.pad as i32;
        let inside = |v: i32, side: u32| (-pad..side as i32 + pad).contains(&v);
        if !inside(cell.x, self.width) || !inside(cell.y, self.height) {
            return None;
        }
        let d = self.dist[agent * self.n_padded + padded_idx(self.pw, self.pad, cell) as usize];
        (d < BLOCKED).then_some(d)
    }

    /// Agent `agent`'s unscaled goal vector: the unit direction `(dx, dy)` to its goal and
    /// the Euclidean distance (zeros on the goal).
    pub fn goal_vector(&self, agent: usize) -> [f64; 3] {
        let (p, g) = (self.pos[agent], self.goals[agent]);
        let (dx, dy) = (f64::from(g.x - p.x), f64::from(g.y - p.y));
        let norm = (dx * dx + dy * dy).sqrt();
        if norm == 0.0 { [0.0; 3] } else { [dx / norm, dy / norm, norm] }
    }

    /// Steps with the joint action `actions` (action indices; `scratch` holds one [`Action`]
    /// per agent) and returns the step's team reward, end flags and cancelled moves: the step
    /// of the environments that train on this one.
    ///
    /// # Panics
    /// If the lengths differ from the agent count, an index is above 4 or the episode has ended.
    pub(crate) fn step_indices(&mut self, actions: &[u8], scratch: &mut [Action]) -> StepOut {
        assert_eq!(actions.len(), scratch.len(), "one action per agent");
        for (slot, &action) in scratch.iter_mut().zip(actions) {
            *slot = Action::from_index(usize::from(action)).expect("action index below 5");
        }
        let step = self.step(scratch);
        StepOut {
            team_reward: step.team_reward,
            terminated: step.terminated,
            truncated: step.truncated,
            collisions: step.info.n_cancelled,
            formation_loss: self.formation_loss(),
        }
    }

    /// Advances the episode by one joint action (one per agent, in agent order).
    ///
    /// Moves into blocked or outside cells, into a cell another agent ends in, and swaps are
    /// cancelled, to a fixed point (docs/spec.md §1); following a moving agent is allowed.
    ///
    /// # Panics
    /// If the episode has ended or `actions` has another length than the agent count.
    pub fn step(&mut self, actions: &[Action]) -> Step<'_> {
        let flags = self.advance(actions);
        self.step_view(flags)
    }

    /// The step itself; returns `(team reward, terminated, truncated, cancelled moves)`.
    fn advance(&mut self, actions: &[Action]) -> StepFlags {
        assert!(!self.done, "step after the episode ended; reset first");
        assert_eq!(actions.len(), self.pos.len(), "one action per agent");
        let n_cancelled = self.resolve(actions);
        // Apply: vacate, then occupy (targets are pairwise distinct by now).
        let n_padded = self.n_padded;
        for (&from, &to) in self.pos_idx.iter().zip(&self.target) {
            if from != to {
                self.occ[from as usize] = NONE;
            }
        }
        for (i, &action) in actions.iter().enumerate() {
            let (from, to) = (self.pos_idx[i], self.target[i]);
            self.closer[i] = false;
            if from != to {
                self.occ[to as usize] = i as u16;
                self.pos_idx[i] = to;
                self.pos[i] = action.apply(self.pos[i]);
                let dist = &self.dist[i * n_padded..(i + 1) * n_padded];
                self.closer[i] = dist[to as usize] < dist[from as usize];
            }
        }
        self.t += 1;
        let mut all_on_goal = true;
        for ((on, &p), &g) in self.on_goal.iter_mut().zip(&self.pos_idx).zip(&self.goal_idx) {
            *on = p == g;
            all_on_goal &= *on;
        }
        self.loss = formation_loss(&self.pos, &self.goals);
        let terminated = match self.config.task {
            Task::Formation => self.loss == 0.0,
            Task::PathFinding | Task::Meta => all_on_goal,
        };
        let truncated = !terminated && self.t >= self.step_limit;
        self.done = terminated || truncated;
        // Rewards (Table I). A cancelled move is a collision only, not also "no movement".
        let task = self.config.task;
        let loss = self.loss as f32;
        let w_f = self.config.formation_weight as f32;
        let c_idle = self.config.idle_cost as f32;
        let mut team = 0.0;
        for (i, &action) in actions.iter().enumerate() {
            let r = if self.cancelled[i] {
                reward::COLLISION
            } else if action == Action::Wait {
                match task {
                    Task::PathFinding | Task::Formation => reward::NO_MOVE,
                    Task::Meta => 0.0,
                }
            } else {
                match task {
                    Task::PathFinding | Task::Meta if self.closer[i] => reward::TOWARDS_GOAL,
                    _ => 0.0,
                }
            };
            let r = r + match task {
                Task::PathFinding => {
                    if all_on_goal {
                        reward::FINISHED
                    } else {
                        0.0
                    }
                }
                Task::Formation => {
                    if self.loss == 0.0 {
                        reward::FORMATION_KEPT
                    } else {
                        -loss
                    }
                }
                Task::Meta => {
                    let idle = !self.on_goal[i] && !self.closer[i];
                    -w_f * loss - if idle { c_idle } else { 0.0 }
                }
            };
            self.rewards[i] = r;
            team += r;
        }
        self.n_chosen = 0;
        StepFlags { team_reward: team, terminated, truncated, n_cancelled }
    }

    /// Fills `target` with every agent's cell after the step and `cancelled` with the
    /// cancelled moves; returns their number.
    fn resolve(&mut self, actions: &[Action]) -> u32 {
        let pw = self.pw as isize;
        self.stack.clear();
        // Targets; moves into blocked cells are cancelled at once.
        for (i, &action) in actions.iter().enumerate() {
            let p = self.pos_idx[i];
            let delta = match action {
                Action::Up => pw,
                Action::Down => -pw,
                Action::Left => -1,
                Action::Right => 1,
                Action::Wait => 0,
            };
            let t = (p as isize + delta) as u32;
            let blocked = self.blocked[t as usize] != 0;
            self.cancelled[i] = blocked;
            self.target[i] = if blocked {
                self.stack.push(i as u16);
                p
            } else {
                t
            };
        }
        for (i, &t) in self.target.iter().enumerate() {
            let c = &mut self.claim[t as usize];
            *c = if *c == NONE { i as u16 } else { MULTI };
        }
        // Vertex conflicts (two claims on one cell) and swaps.
        for i in 0..self.pos.len() {
            let (p, t) = (self.pos_idx[i], self.target[i]);
            if p == t {
                continue;
            }
            let conflict = self.claim[t as usize] == MULTI || {
                let j = self.occ[t as usize];
                j != NONE && self.target[j as usize] == p
            };
            if conflict {
                self.cancelled[i] = true;
                self.stack.push(i as u16);
            }
        }
        // A cancelled agent stays, so a single mover into its cell must stay too.
        while let Some(i) = self.stack.pop() {
            let c = self.claim[self.pos_idx[i as usize] as usize];
            if c != NONE && c != MULTI && c != i && !self.cancelled[c as usize] {
                self.cancelled[c as usize] = true;
                self.stack.push(c);
            }
        }
        let mut n_cancelled = 0;
        for i in 0..self.pos.len() {
            self.claim[self.target[i] as usize] = NONE;
            if self.cancelled[i] {
                self.target[i] = self.pos_idx[i];
                n_cancelled += 1;
            }
        }
        n_cancelled
    }

    /// Writes every agent's observation (channels, goal vector and mask of the task's
    /// clipping) into `out`; the acting order is [`Env::begin_turns`]'s.
    ///
    /// # Panics
    /// If the buffers do not have this episode's agent count and [`Env::obs_shape`].
    pub fn observe(&self, out: &mut ObsBuffers) {
        self.observe_clipped(out, self.config.task.clip());
    }

    /// [`Env::observe`] with the mask of `clip` instead of the task's.
    ///
    /// # Panics
    /// As [`Env::observe`].
    pub fn observe_clipped(&self, out: &mut ObsBuffers, clip: Clip) {
        assert_eq!(out.n_agents, self.pos.len(), "buffers of another agent count");
        assert_eq!(out.shape, self.obs_shape(), "buffers of another shape");
        let shape = out.shape;
        for (i, ((grid, vector), mask)) in out
            .grid
            .chunks_exact_mut(shape.grid_len())
            .zip(out.vec.chunks_exact_mut(VECTOR_LEN))
            .zip(out.action_mask.chunks_exact_mut(N_ACTIONS))
            .enumerate()
        {
            self.write_grid(i, grid);
            self.write_vector(i, vector);
            self.write_mask(i, clip, mask);
        }
    }

    /// Writes agent `agent`'s four channels, `[4, F, F]`.
    pub fn write_grid(&self, agent: usize, out: &mut [f32]) {
        let f = self.fov;
        let ff = f * f;
        assert_eq!(out.len(), CHANNELS * ff, "channel buffer of another size");
        let (obstacles, rest) = out.split_at_mut(ff);
        let (positions, rest) = rest.split_at_mut(ff);
        let (cost, formation) = rest.split_at_mut(ff);
        let pw = self.pw;
        // The window's bottom-left cell is (x - R, y - R), padded (x, y).
        let p = self.pos_idx[agent] as usize;
        let corner = p - self.pad * pw - self.pad;
        let dist = self.cost_map(agent);
        // Distances below 2^24 are exact in f32, so clamping in f32 equals clamping the
        // integer difference (and vectorises without SSE4.1's integer min/max).
        let own = dist[p] as f32;
        let k = (f - 1) as f32;
        let inv_k = 1.0 / k;
        let rows = obstacles
            .chunks_exact_mut(f)
            .zip(positions.chunks_exact_mut(f))
            .zip(cost.chunks_exact_mut(f))
            .enumerate();
        for (r, ((obstacle_row, position_row), cost_row)) in rows {
            let base = corner + r * pw;
            for (o, &b) in obstacle_row.iter_mut().zip(&self.blocked[base..base + f]) {
                *o = f32::from(b);
            }
            for (o, &d) in cost_row.iter_mut().zip(&dist[base..base + f]) {
                let rel = ((d as i32) as f32 - own).clamp(-k, k) * inv_k;
                *o = if d >= BLOCKED { COST_SENTINEL } else { rel };
            }
            let occ = &self.occ[base..base + f];
            // All `NONE` (all bits set) exactly when the AND of the row is `NONE`; unlike
            // an early-exit search, the fold vectorises.
            if occ.iter().fold(NONE, |acc, &v| acc & v) == NONE {
                position_row.fill(0.0);
                continue;
            }
            for ((o, c), &v) in position_row.iter_mut().zip(cost_row.iter_mut()).zip(occ) {
                *o = match self.ident.get(v as usize) {
                    Some(&id) => {
                        if v as usize != agent && self.on_goal[v as usize] {
                            *c = COST_SENTINEL;
                        }
                        id
                    }
                    None => 0.0,
                };
            }
        }
        formation.copy_from_slice(&self.formation_obs[agent * ff..(agent + 1) * ff]);
    }

    /// Writes agent `agent`'s scaled goal vector `(dx/‖d‖, dy/‖d‖, ‖d‖/(‖d‖ + F))`.
    pub fn write_vector(&self, agent: usize, out: &mut [f32]) {
        frame::write_goal_vector(self.pos[agent], self.goals[agent], self.fov, out);
    }

    /// Writes agent `agent`'s action mask under `clip`, in action index order.
    pub fn write_mask(&self, agent: usize, clip: Clip, out: &mut [bool]) {
        let p = self.pos_idx[agent] as usize;
        let pw = self.pw;
        let neighbours = [p + pw, p - pw, p - 1, p + 1];
        match clip {
            Clip::None => out[..4].fill(true),
            Clip::Formation => {
                for (o, n) in out.iter_mut().zip(neighbours) {
                    *o = self.blocked[n] == 0;
                }
            }
            Clip::PathFinding => {
                let dist = self.cost_map(agent);
                for (o, n) in out.iter_mut().zip(neighbours) {
                    *o = dist[n] <= dist[p];
                }
            }
        }
        out[4] = true;
    }

    /// Computes the acting order of this step under `rule` (docs/spec.md §6; ties by agent index)
    /// and forgets any actions chosen so far; returns the order.
    pub fn begin_turns(&mut self, rule: LeaderRule) -> &[u16] {
        let n = self.pos.len();
        self.order.clear();
        self.order.extend(0..n as u16);
        match rule {
            LeaderRule::PathFinding => {
                let (dist, pos_idx, n_padded) = (&self.dist, &self.pos_idx, self.n_padded);
                self.order.sort_unstable_by_key(|&i| {
                    let i = i as usize;
                    (dist[i * n_padded + pos_idx[i] as usize], i)
                });
            }
            LeaderRule::Formation => {
                let (sx, sy) = self
                    .pos
                    .iter()
                    .fold((0i64, 0i64), |(sx, sy), c| (sx + i64::from(c.x), sy + i64::from(c.y)));
                let n64 = n as i64;
                let pos = &self.pos;
                self.order.sort_unstable_by_key(|&i| {
                    let c = pos[i as usize];
                    let (dx, dy) = (n64 * i64::from(c.x) - sx, n64 * i64::from(c.y) - sy);
                    (dx * dx + dy * dy, i)
                });
            }
        }
        for (k, &i) in self.order.iter().enumerate() {
            self.rank[i as usize] = k as u16;
        }
        self.n_chosen = 0;
        &self.order
    }

    /// The acting order of the current step (agent indices, leader first).
    #[inline]
    pub fn turn_order(&self) -> &[u16] {
        &self.order
    }

    /// The agent whose turn it is, `None` when every agent has chosen.
    #[inline]
    pub fn current_agent(&self) -> Option<usize> {
        self.order.get(self.n_chosen).map(|&i| i as usize)
    }

    /// Writes agent `agent`'s message: the one-hot actions of the agents before it in the
    /// order that have chosen, zero rows elsewhere (`[n_agents, 5]`).
    pub fn write_message(&self, agent: usize, out: &mut [f32]) {
        out.fill(0.0);
        let before = (self.rank[agent] as usize).min(self.n_chosen);
        for &j in &self.order[..before] {
            let j = j as usize;
            out[j * N_ACTIONS + self.chosen[j].index()] = 1.0;
        }
    }

    /// Records the action of the agent whose turn it is; returns the next agent, if any.
    ///
    /// # Panics
    /// If every agent has already chosen.
    pub fn choose(&mut self, action: Action) -> Option<usize> {
        let agent = self.current_agent().expect("every agent has chosen this step");
        self.chosen[agent] = action;
        self.n_chosen += 1;
        self.current_agent()
    }

    /// Steps with the actions chosen in turn.
    ///
    /// # Panics
    /// If some agent has not chosen yet.
    pub fn step_chosen(&mut self) -> Step<'_> {
        assert_eq!(self.n_chosen, self.pos.len(), "not every agent has chosen");
        // `advance` reads the actions from a slice; the buffer goes back afterwards.
        let chosen = std::mem::take(&mut self.chosen);
        let flags = self.advance(&chosen);
        self.chosen = chosen;
        self.step_view(flags)
    }

    /// The last step's outcome, viewing the per-agent buffers.
    fn step_view(&self, flags: StepFlags) -> Step<'_> {
        let StepFlags { team_reward, terminated, truncated, n_cancelled } = flags;
        Step {
            rewards: &self.rewards,
            team_reward,
            terminated,
            truncated,
            info: StepInfo {
                cancelled: &self.cancelled,
                n_cancelled,
                formation_loss: self.loss,
                on_goal: &self.on_goal,
            },
        }
    }
}

/// A distance map before its search: `BLOCKED` on the blocked cells of `blocked`,
/// `UNREACHABLE` on the others.
fn unsearched(map: &mut [u32], blocked: &[u8]) {
    for (d, &b) in map.iter_mut().zip(blocked) {
        *d = if b != 0 { BLOCKED } else { UNREACHABLE };
    }
}

/// Padded index of an in-bounds (or padding) cell.
#[inline]
fn padded_idx(pw: usize, pad: usize, c: Cell) -> u32 {
    ((c.y as isize + pad as isize) as usize * pw + (c.x as isize + pad as isize) as usize) as u32
}

/// BFS over the padded grid from `source`; `dist` must hold `BLOCKED` on blocked cells
/// and `UNREACHABLE` on free ones. The padding is blocked, so neighbours never leave the
/// buffer.
///
/// Branch-free inner step: every neighbour is written to the queue's tail, and the tail
/// only advances (and the distance only changes) when the neighbour is new, which avoids
/// the mispredicted branch per neighbour.
fn padded_bfs(pw: usize, source: u32, dist: &mut [u32], queue: &mut Vec<u32>) {
    // At most every cell enters the queue once, plus one speculative write.
    if queue.len() < dist.len() + 1 {
        queue.resize(dist.len() + 1, 0);
    }
    let queue = &mut queue[..];
    dist[source as usize] = 0;
    queue[0] = source;
    let (mut head, mut tail) = (0, 1);
    while head < tail {
        let id = queue[head] as usize;
        head += 1;
        let next = dist[id] + 1;
        for n in [id + pw, id - pw, id - 1, id + 1] {
            let d = dist[n];
            let fresh = d == UNREACHABLE;
            queue[tail] = n as u32;
            tail += usize::from(fresh);
            dist[n] = if fresh { next } else { d };
        }
    }
}
