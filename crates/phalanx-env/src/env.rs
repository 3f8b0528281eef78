//! One episode: the joint state, the step with collision resolution (docs/spec.md §1), rewards and
//! termination (docs/spec.md §5), observations written into flat buffers (docs/spec.md §4) and leader-ordered
//! sequential acting (docs/spec.md §6).
//!
//! Everything the step touches is preallocated on reset: the map is stored padded by
//! `R = F / 2` blocked cells on every side, so windows and neighbours need no bounds checks;
//! each agent's BFS distance map lives in the same padded layout; an occupancy grid holds the
//! agent index per cell and is updated incrementally.

use phalanx_core::{Action, Cell, Grid, Instance, formation_loss, step_limit};
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

/// One distance of a BFS map as stored: `u16` on maps of fewer padded cells than
/// [`Distance::UNREACHABLE`] (every distance of a map is below its cell count), which halves
/// the maps that every step reads, else `u32`. The same type holds the search's queue of
/// padded indices (every index is below the cell count too), which then stays in the
/// first-level cache with the map.
trait Distance: Copy + Ord + Send + Sync {
    /// A free cell cut off from the goal.
    const UNREACHABLE: Self;
    /// A blocked or outside cell.
    const BLOCKED: Self;
    /// The goal's own distance.
    const ZERO: Self;
    /// The next distance.
    fn plus_one(self) -> Self;
    /// The distance as `u32`, `UNREACHABLE` and `BLOCKED` as theirs.
    fn wide(self) -> u32;
    /// The distance as `f32` (exact below `BLOCKED`).
    fn float(self) -> f32;
    /// A padded index as stored in the queue (below the map's cell count).
    fn from_index(index: usize) -> Self;
    /// The padded index a queue entry holds.
    fn index(self) -> usize;
}

impl Distance for u16 {
    const UNREACHABLE: u16 = u16::MAX;
    const BLOCKED: u16 = u16::MAX - 1;
    const ZERO: u16 = 0;
    #[inline(always)]
    fn plus_one(self) -> u16 {
        self + 1
    }
    #[inline(always)]
    fn wide(self) -> u32 {
        let d = u32::from(self);
        if d >= u32::from(Self::BLOCKED) { d | 0xFFFF_0000 } else { d }
    }
    #[inline(always)]
    fn float(self) -> f32 {
        f32::from(self)
    }
    #[inline(always)]
    fn from_index(index: usize) -> u16 {
        index as u16
    }
    #[inline(always)]
    fn index(self) -> usize {
        usize::from(self)
    }
}

impl Distance for u32 {
    const UNREACHABLE: u32 = UNREACHABLE;
    const BLOCKED: u32 = BLOCKED;
    const ZERO: u32 = 0;
    #[inline(always)]
    fn plus_one(self) -> u32 {
        self + 1
    }
    #[inline(always)]
    fn wide(self) -> u32 {
        self
    }
    #[inline(always)]
    fn float(self) -> f32 {
        (self as i32) as f32
    }
    #[inline(always)]
    fn from_index(index: usize) -> u32 {
        index as u32
    }
    #[inline(always)]
    fn index(self) -> usize {
        self as usize
    }
}

/// Every agent's padded BFS distance map, `n_agents` blocks of padded cells, narrow when the
/// map is small enough.
#[derive(Debug, Clone)]
enum DistMaps {
    Narrow(Vec<u16>),
    Wide(Vec<u32>),
}

impl DistMaps {
    /// The distance stored at padded index `idx` of the maps (agent block included).
    #[inline(always)]
    fn at(&self, idx: usize) -> u32 {
        match self {
            DistMaps::Narrow(maps) => maps[idx].wide(),
            DistMaps::Wide(maps) => maps[idx],
        }
    }
}

/// Each action's displacement `(dx, dy)` by action index ([`Action::delta`]).
const CELL_DELTAS: [(i32, i32); N_ACTIONS] = {
    let mut deltas = [(0, 0); N_ACTIONS];
    let mut k = 0;
    while k < N_ACTIONS {
        deltas[k] = Action::ALL[k].delta();
        k += 1;
    }
    deltas
};

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
    /// The same as the obstacle channel's values (1.0 = blocked), copied row by row.
    blocked_obs: Vec<f32>,
    /// Per agent, padded BFS distances to its goal, `n_agents` blocks of padded cells.
    dist: DistMaps,
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
    /// The search queue of narrow maps (searched one after the other).
    narrow_queue: Vec<u16>,
    // Dynamic state.
    pos: Vec<Cell>,
    pos_idx: Vec<u32>,
    /// Each agent's distance to its goal from where it stands (its map at `pos_idx`, kept
    /// here so that the step's order, masks and cost channel need not load it).
    own_dist: Vec<u32>,
    /// The leader order's sort keys, `(distance << 16) | agent`.
    order_keys: Vec<u64>,
    /// Padded occupancy: agent index or `NONE`.
    occ: Vec<u16>,
    /// Padded positions channel: the identity code of the agent on a cell, 0.0 for none
    /// (updated with `occ`, copied row by row).
    occ_obs: Vec<f32>,
    /// Padded flags: 1 on the goal cell of an agent that stands on it (goals are distinct,
    /// so one write per agent and step keeps it), read by the cost channel.
    parked: Vec<u8>,
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
    /// Whether each agent changed cells this step (all, after a reset).
    moved: Vec<bool>,
    on_goal: Vec<bool>,
    /// Whether an agent reached or left its goal this step (true after a reset): the cost
    /// channel marks other agents standing on their goals.
    goals_changed: bool,
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
    /// How many agents ahead a writer of every agent's channels prefetches the rows they
    /// read ([`Env::prefetch_view`]).
    pub const PREFETCH_AHEAD: usize = 2;

    /// An environment with no episode yet; call [`Env::reset`].
    pub fn new(config: EnvConfig) -> Result<Env, EnvError> {
        config.check()?;
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
            blocked_obs: Vec::new(),
            dist: DistMaps::Wide(Vec::new()),
            n_padded: 0,
            goals: Vec::new(),
            goal_idx: Vec::new(),
            starts: Vec::new(),
            ident: Vec::new(),
            formation_obs: Vec::new(),
            queues: Vec::new(),
            narrow_queue: Vec::new(),
            pos: Vec::new(),
            pos_idx: Vec::new(),
            own_dist: Vec::new(),
            order_keys: Vec::new(),
            occ: Vec::new(),
            occ_obs: Vec::new(),
            parked: Vec::new(),
            claim: Vec::new(),
            target: Vec::new(),
            stack: Vec::new(),
            t: 0,
            done: true,
            rewards: Vec::new(),
            cancelled: Vec::new(),
            closer: Vec::new(),
            moved: Vec::new(),
            goals_changed: true,
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
    /// vector (then the place vector with [`EnvConfig::place_vector`] and the team vector with
    /// [`EnvConfig::team_vector`]) and the five actions' mask.
    #[inline]
    pub fn obs_shape(&self) -> ObsShape {
        let env_vec = self.config.vector_len();
        ObsShape { channels: CHANNELS, fov: self.fov, env_vec, n_actions: N_ACTIONS }
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
        self.occ_obs.clear();
        self.occ_obs.resize(n_padded, 0.0);
        for (i, &p) in self.pos_idx.iter().enumerate() {
            self.occ[p as usize] = i as u16;
            self.occ_obs[p as usize] = self.ident[i];
        }
        self.order_keys.clear();
        self.order_keys.reserve(n);
        self.own_dist.clear();
        self.own_dist.extend(
            self.pos_idx.iter().enumerate().map(|(i, &p)| self.dist.at(i * n_padded + p as usize)),
        );
        let longest_route = self.own_dist.iter().copied().max().unwrap_or(0);
        self.step_limit =
            self.config.step_limit.unwrap_or_else(|| step_limit(grid.side(), longest_route));
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
        self.moved.clear();
        self.moved.resize(n, true);
        self.goals_changed = true;
        self.on_goal.clear();
        self.on_goal.extend(self.pos_idx.iter().zip(&self.goal_idx).map(|(p, g)| p == g));
        self.parked.clear();
        self.parked.resize(n_padded, 0);
        for (&on, &g) in self.on_goal.iter().zip(&self.goal_idx) {
            self.parked[g as usize] = u8::from(on);
        }
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
        self.blocked_obs.clear();
        self.blocked_obs.extend(self.blocked.iter().map(|&b| f32::from(b)));
        self.goals.clear();
        self.goals.extend_from_slice(instance.goals());
        self.goal_idx.clear();
        self.goal_idx.extend(self.goals.iter().map(|&g| padded_idx(pw, pad, g)));
        // Distance maps, narrow when every distance fits.
        self.queues.resize_with(n, Vec::new);
        let narrow = n_padded < usize::from(u16::MAX - 1);
        match (&mut self.dist, narrow) {
            (DistMaps::Narrow(maps), true) => {
                let queue = std::slice::from_mut(&mut self.narrow_queue);
                search_maps(maps, &self.blocked, &self.goal_idx, queue, pw);
            }
            (DistMaps::Wide(maps), false) => {
                search_maps(maps, &self.blocked, &self.goal_idx, &mut self.queues, pw);
            }
            (dist, true) => {
                let mut maps = Vec::new();
                let queue = std::slice::from_mut(&mut self.narrow_queue);
                search_maps(&mut maps, &self.blocked, &self.goal_idx, queue, pw);
                *dist = DistMaps::Narrow(maps);
            }
            (dist, false) => {
                let mut maps = Vec::new();
                search_maps(&mut maps, &self.blocked, &self.goal_idx, &mut self.queues, pw);
                *dist = DistMaps::Wide(maps);
            }
        }
    }

    /// The distance from padded cell `idx` to agent `agent`'s goal (`BLOCKED`, `UNREACHABLE`).
    #[inline]
    fn dist_at(&self, agent: usize, idx: usize) -> u32 {
        self.dist.at(agent * self.n_padded + idx)
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

    /// The step limit of this episode ([`phalanx_core::step_limit`] of the map side and the
    /// agents' longest shortest route, unless configured).
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
        self.own_dist[agent]
    }

    /// BFS distance from `cell` to agent `agent`'s goal, `None` when blocked, outside or cut
    /// off.
    pub fn distance(&self, agent: usize, cell: Cell) -> Option<u32> {
        let pad = self.pad as i32;
        let inside = |v: i32, side: u32| (-pad..side as i32 + pad).contains(&v);
        if !inside(cell.x, self.width) || !inside(cell.y, self.height) {
            return None;
        }
        let d = self.dist_at(agent, padded_idx(self.pw, self.pad, cell) as usize);
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
        // Apply: vacate, then occupy (targets are pairwise distinct by now). Every agent
        // vacates its cell and occupies its target, an agent that stays its own cell again,
        // and every agent's distance is read at its target (a stayer's is its own, so it is
        // not closer): no branch on who moved, which random actions would mispredict.
        let n_padded = self.n_padded;
        for &from in &self.pos_idx {
            self.occ[from as usize] = NONE;
            self.occ_obs[from as usize] = 0.0;
        }
        for (i, &action) in actions.iter().enumerate() {
            let (from, to) = (self.pos_idx[i], self.target[i]);
            self.occ[to as usize] = i as u16;
            self.occ_obs[to as usize] = self.ident[i];
            self.pos_idx[i] = to;
            // The action's displacement, or none for a stayer (a table, not a branch).
            let (dx, dy) = CELL_DELTAS[action.index()];
            let moved = from != to;
            self.moved[i] = moved;
            let moved = i32::from(moved);
            self.pos[i] = self.pos[i].offset(dx * moved, dy * moved);
            let d = self.dist.at(i * n_padded + to as usize);
            self.closer[i] = d < self.own_dist[i];
            self.own_dist[i] = d;
        }
        self.t += 1;
        let mut all_on_goal = true;
        let mut goals_changed = false;
        for ((on, &p), &g) in self.on_goal.iter_mut().zip(&self.pos_idx).zip(&self.goal_idx) {
            goals_changed |= *on != (p == g);
            *on = p == g;
            all_on_goal &= *on;
            self.parked[g as usize] = u8::from(*on);
        }
        self.goals_changed = goals_changed;
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
        let waiting = match task {
            Task::PathFinding | Task::Formation => reward::NO_MOVE,
            Task::Meta => 0.0,
        };
        let towards = match task {
            Task::PathFinding | Task::Meta => reward::TOWARDS_GOAL,
            Task::Formation => 0.0,
        };
        // The team's term of every agent's reward, and the idle cost of the meta task.
        let team_term = match task {
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
            Task::Meta => -w_f * loss,
        };
        let idle_cost = match task {
            Task::PathFinding | Task::Formation => 0.0,
            Task::Meta => c_idle,
        };
        let mut team = 0.0;
        for (i, &action) in actions.iter().enumerate() {
            // Tables indexed by flags rather than branches, which random actions mispredict.
            let moving = [0.0, towards][usize::from(self.closer[i])];
            let which = usize::from(self.cancelled[i]) << 1 | usize::from(action == Action::Wait);
            let r = [moving, waiting, reward::COLLISION, reward::COLLISION][which];
            let idle = !self.on_goal[i] && !self.closer[i];
            // `team_term - 0.0` is `team_term` itself: the sum is the one of every task.
            let r = r + (team_term - [0.0, idle_cost][usize::from(idle)]);
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
            // By action index, a table rather than a branch per action.
            let delta = [pw, -pw, -1, 1, 0][action.index()];
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

    /// Writes every agent's observation (channels, goal vector, the place vector with
    /// [`EnvConfig::place_vector`], and mask of the task's clipping) into `out`; the acting
    /// order is [`Env::begin_turns`]'s.
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
        for (i, (grid, mask)) in out
            .grid
            .chunks_exact_mut(shape.grid_len())
            .zip(out.action_mask.chunks_exact_mut(N_ACTIONS))
            .enumerate()
        {
            self.prefetch_view(i + Env::PREFETCH_AHEAD);
            self.write_grid(i, grid);
            self.write_mask(i, clip, mask);
        }
        self.write_vectors(&mut out.vec);
    }

    /// Writes every agent's vector into `out` (`[n_agents, env_vec]` of [`Env::obs_shape`]):
    /// its goal vector ([`Env::write_vector`]), then with [`EnvConfig::place_vector`] the
    /// vector towards its place on the agent in front ([`Env::write_place_vector`]), then with
    /// [`EnvConfig::team_vector`] the team vector: for the agent in front, the vector towards
    /// its place on the team ([`Env::write_team_vector`]); zeros for the others.
    ///
    /// # Panics
    /// If `out` has another length.
    pub fn write_vectors(&self, out: &mut [f32]) {
        let width = self.obs_shape().env_vec;
        assert_eq!(out.len(), self.pos.len() * width, "vectors of another size");
        let front = self.config.place_vector.then(|| self.front());
        let shift = self.config.team_vector.then(|| self.team_shift());
        for (agent, vector) in out.chunks_exact_mut(width).enumerate() {
            let (goal, rest) = vector.split_at_mut(VECTOR_LEN);
            self.write_vector(agent, goal);
            let (place, team) = rest.split_at_mut(rest.len().min(VECTOR_LEN));
            if let Some(front) = front {
                self.write_place_vector(agent, front, place);
            }
            if let Some(shift) = shift {
                if front == Some(agent) {
                    self.write_team_vector(agent, shift, team);
                } else {
                    team.fill(0.0);
                }
            }
        }
    }

    /// The agent in front: the first of the path-finding acting order (the smallest BFS
    /// distance to its goal, ties by agent index), as [`Env::begin_turns`] ranks it.
    pub fn front(&self) -> usize {
        let keyed = self.own_dist.iter().enumerate().map(|(i, &d)| (d, i));
        keyed.min().map_or(0, |(_, i)| i)
    }

    /// Asks the processor to start loading the rows agent `agent`'s channels will read (its
    /// distance map's and the padded maps' in its window), without waiting for
    /// them: a writer of every agent's channels calls it a few agents ahead, so that those
    /// loads overlap the writing instead of stalling it (the distance maps of many
    /// environments do not stay in the cache). Only a hint: nothing observable changes, and
    /// an agent index past the last one is ignored, as is an agent that stayed in a step in
    /// which no agent reached or left its goal (its window's rows were read the step before,
    /// and [`Env::write_grid_changing`] writes only its position channel).
    #[inline]
    pub fn prefetch_view(&self, agent: usize) {
        #[cfg(not(target_arch = "x86_64"))]
        let _ = agent;
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let Some(&p) = self.pos_idx.get(agent) else { return };
            if self.channels_kept(agent) {
                return;
            }
            let (f, pw) = (self.fov, self.pw);
            let corner = p as usize - self.pad * pw - self.pad;
            let (dist, size): (*const i8, usize) = match &self.dist {
                DistMaps::Narrow(maps) => (maps[agent * self.n_padded..].as_ptr().cast(), 2),
                DistMaps::Wide(maps) => (maps[agent * self.n_padded..].as_ptr().cast(), 4),
            };
            let occ = self.occ_obs.as_ptr().cast::<i8>();
            let blocked = self.blocked_obs.as_ptr().cast::<i8>();
            let parked = self.parked.as_ptr().cast::<i8>();
            for r in 0..f {
                let at = corner + r * pw;
                // SAFETY: a prefetch never faults and reads nothing the program sees; the
                // addresses are those of the window's rows, inside the maps.
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(dist.wrapping_add(at * size));
                    _mm_prefetch::<_MM_HINT_T0>(dist.wrapping_add((at + f - 1) * size));
                    _mm_prefetch::<_MM_HINT_T0>(occ.wrapping_add(at * 4));
                    _mm_prefetch::<_MM_HINT_T0>(occ.wrapping_add((at + f - 1) * 4));
                    _mm_prefetch::<_MM_HINT_T0>(blocked.wrapping_add(at * 4));
                    _mm_prefetch::<_MM_HINT_T0>(blocked.wrapping_add((at + f - 1) * 4));
                    _mm_prefetch::<_MM_HINT_T0>(parked.wrapping_add(at));
                }
            }
        }
    }

    /// Writes agent `agent`'s four channels, `[4, F, F]`.
    pub fn write_grid(&self, agent: usize, out: &mut [f32]) {
        self.write_channels(agent, out, true);
    }

    /// Writes into `out` (`[4, F, F]`, as [`Env::write_grid`]) those of agent `agent`'s
    /// channels that may have changed since the previous step, for a writer that keeps
    /// agent `agent`'s observations in `out`: written with [`Env::write_grid`] when the
    /// episode started, then with this after every step. The position channel is always
    /// written; the obstacle and cost channels only when the agent changed cells or an agent
    /// reached or left its goal in the last step (the cost channel marks the agents that
    /// stand on their goals); the formation channel is the same throughout an episode and
    /// never written. The result equals [`Env::write_grid`]'s bit for bit.
    pub fn write_grid_changing(&self, agent: usize, out: &mut [f32]) {
        self.write_channels(agent, out, false);
    }

    /// The channels, the formation channel too when `formation`; without it, only the
    /// position channel when the agent stayed and no agent reached or left its goal
    /// ([`Env::write_grid_changing`]).
    #[inline]
    fn write_channels(&self, agent: usize, out: &mut [f32], formation: bool) {
        if !formation && self.channels_kept(agent) {
            self.write_positions(agent, out);
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            unsafe { self.write_grid_avx2(agent, out, formation) };
            return;
        }
        self.write_grid_any(agent, out, formation);
    }

    /// Whether agent `agent`'s obstacle and cost channels are those of the previous step: it
    /// stayed, and no agent reached or left its goal (the cost channel marks the agents that
    /// stand on their goals).
    #[inline]
    fn channels_kept(&self, agent: usize) -> bool {
        !self.moved[agent] && !self.goals_changed
    }

    /// Writes agent `agent`'s position channel alone (the second of `out`'s four).
    fn write_positions(&self, agent: usize, out: &mut [f32]) {
        // Rows of a known length for the usual fields of view (copied inline).
        match self.fov {
            9 => self.write_positions_of(9, agent, out),
            11 => self.write_positions_of(11, agent, out),
            f => self.write_positions_of(f, agent, out),
        }
    }

    /// [`Env::write_positions`] for `f == self.fov`.
    #[inline(always)]
    fn write_positions_of(&self, f: usize, agent: usize, out: &mut [f32]) {
        let pw = self.pw;
        let ff = f * f;
        assert_eq!(out.len(), CHANNELS * ff, "channel buffer of another size");
        let corner = self.pos_idx[agent] as usize - self.pad * pw - self.pad;
        let occ = &self.occ_obs[corner..corner + (f - 1) * pw + f];
        for (r, row) in out[ff..2 * ff].chunks_exact_mut(f).enumerate() {
            row.copy_from_slice(&occ[r * pw..r * pw + f]);
        }
    }

    /// [`Env::write_grid`] compiled for AVX2 (eight lanes a row of the window instead of
    /// four): the same operations on the same values, so the same bits.
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn write_grid_avx2(&self, agent: usize, out: &mut [f32], formation: bool) {
        self.write_grid_any(agent, out, formation);
    }

    /// [`Env::write_grid`] for any processor.
    #[inline(always)]
    fn write_grid_any(&self, agent: usize, out: &mut [f32], formation: bool) {
        // The usual fields of view get loops of a known length (unrolled, bounds checks
        // hoisted); any other takes the same code with a run-time length.
        let n_padded = self.n_padded;
        match &self.dist {
            DistMaps::Narrow(maps) => {
                let map = &maps[agent * n_padded..(agent + 1) * n_padded];
                match self.fov {
                    9 => self.write_window(9, agent, map, out, formation),
                    11 => self.write_window(11, agent, map, out, formation),
                    _ => self.write_window(self.fov, agent, map, out, formation),
                }
            }
            DistMaps::Wide(maps) => {
                let map = &maps[agent * n_padded..(agent + 1) * n_padded];
                self.write_window(self.fov, agent, map, out, formation);
            }
        }
    }

    /// [`Env::write_grid`] for `f == self.fov`: the obstacle and position channels are row
    /// copies of padded maps of their values, the cost channel is computed row by row from
    /// the distance map, the formation channel is the episode's (written when `formation`).
    #[inline(always)]
    fn write_window<D: Distance>(
        &self,
        f: usize,
        agent: usize,
        dist: &[D],
        out: &mut [f32],
        formation_too: bool,
    ) {
        let ff = f * f;
        assert_eq!(out.len(), CHANNELS * ff, "channel buffer of another size");
        let (obstacles, rest) = out.split_at_mut(ff);
        let (positions, rest) = rest.split_at_mut(ff);
        let (cost, formation) = rest.split_at_mut(ff);
        let pw = self.pw;
        // The window's bottom-left cell is (x - R, y - R), padded (x, y).
        let p = self.pos_idx[agent] as usize;
        let corner = p - self.pad * pw - self.pad;
        // The window's rows of every padded map, checked once.
        let span = (f - 1) * pw + f;
        let blocked = &self.blocked_obs[corner..corner + span];
        let occ = &self.occ_obs[corner..corner + span];
        let parked = &self.parked[corner..corner + span];
        let window = &dist[corner..corner + span];
        // Distances below 2^24 are exact in f32, so clamping in f32 equals clamping the
        // integer difference (and vectorises without SSE4.1's integer min/max).
        let own = self.own_dist[agent] as f32;
        let k = (f - 1) as f32;
        let inv_k = 1.0 / k;
        let rows = obstacles
            .chunks_exact_mut(f)
            .zip(positions.chunks_exact_mut(f))
            .zip(cost.chunks_exact_mut(f))
            .enumerate();
        for (r, ((obstacle_row, position_row), cost_row)) in rows {
            let base = r * pw;
            obstacle_row.copy_from_slice(&blocked[base..base + f]);
            position_row.copy_from_slice(&occ[base..base + f]);
            let cells =
                cost_row.iter_mut().zip(&window[base..base + f]).zip(&parked[base..base + f]);
            for ((o, &d), &parked) in cells {
                let rel = (d.float() - own).clamp(-k, k) * inv_k;
                // Blocked, outside or cut off, or another agent standing on its goal.
                *o = if (d >= D::BLOCKED) | (parked != 0) { COST_SENTINEL } else { rel };
            }
        }
        // The centre is this agent (`parked` when on its own goal), always `d(own) - d(own)`.
        cost[self.pad * f + self.pad] = 0.0;
        if formation_too {
            formation.copy_from_slice(&self.formation_obs[agent * ff..(agent + 1) * ff]);
        }
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
                let own = self.own_dist[agent];
                for (o, n) in out.iter_mut().zip(neighbours) {
                    *o = self.dist_at(agent, n) <= own;
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
                // Sorting `(distance, agent)` pairs packed in one integer (agents < 2^16).
                self.order_keys.clear();
                self.order_keys.extend(
                    self.own_dist.iter().enumerate().map(|(i, &d)| u64::from(d) << 16 | i as u64),
                );
                self.order_keys.sort_unstable();
                self.order.clear();
                self.order.extend(self.order_keys.iter().map(|&key| key as u16));
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

/// Fills `maps` with one padded BFS map per goal of `goal_idx` over the padded obstacles
/// `blocked` (of width `pw`), searched in parallel when the maps are large enough to pay for it.
fn search_maps<D: Distance>(
    maps: &mut Vec<D>,
    blocked: &[u8],
    goal_idx: &[u32],
    queues: &mut [Vec<D>],
    pw: usize,
) {
    let (n, n_padded) = (goal_idx.len(), blocked.len());
    // Each map from a template with the blocked cells marked.
    maps.resize(n * n_padded, D::UNREACHABLE);
    let (template, rest) = maps.split_at_mut(n_padded);
    for (d, &b) in template.iter_mut().zip(blocked) {
        *d = if b != 0 { D::BLOCKED } else { D::UNREACHABLE };
    }
    for map in rest.chunks_exact_mut(n_padded) {
        map.copy_from_slice(template);
    }
    if n > 1 && n_padded >= PARALLEL_BFS_CELLS && rayon::current_num_threads() > 1 {
        let searches: Vec<_> = maps.chunks_exact_mut(n_padded).zip(queues).zip(goal_idx).collect();
        searches.into_par_iter().for_each(|((map, queue), &goal)| {
            padded_bfs(pw, goal, map, queue);
        });
    } else if let Some(queue) = queues.first_mut() {
        // One queue for all, so that it stays in the cache.
        for (map, &goal) in maps.chunks_exact_mut(n_padded).zip(goal_idx) {
            padded_bfs(pw, goal, map, queue);
        }
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
/// A branch per neighbour: on generated 64² maps with 25 goals this searches in two thirds
/// of the time of a branch-free step that writes every neighbour's distance and queue slot
/// (and advances the tail only for a new one), whose stores the next cells' loads then wait
/// for.
fn padded_bfs<D: Distance>(pw: usize, source: u32, dist: &mut [D], queue: &mut Vec<D>) {
    // The frame: the first and last rows and columns are blocked, so that a free cell's four
    // neighbours are in the buffer (checked here, in time linear in the perimeter, so that the
    // search can index without checks).
    let len = dist.len();
    assert!(pw >= 3 && len.is_multiple_of(pw) && len / pw >= 3, "a padded grid of at least 3x3");
    let frame = |i: usize| dist[i] == D::BLOCKED;
    assert!(
        (0..pw).all(|x| frame(x) && frame(len - pw + x))
            && (0..len / pw).all(|y| frame(y * pw) && frame(y * pw + pw - 1)),
        "the padding is blocked"
    );
    assert!(dist[source as usize] == D::UNREACHABLE, "the search starts on a free cell");
    // At most every cell enters the queue once (one slot to spare).
    if queue.len() < len + 1 {
        queue.resize(len + 1, D::ZERO);
    }
    let queue = &mut queue[..len + 1];
    dist[source as usize] = D::ZERO;
    queue[0] = D::from_index(source as usize);
    let (mut head, mut tail) = (0, 1);
    while head < tail {
        // SAFETY: the queue holds free cells only (a cell enters it when it was
        // `UNREACHABLE`, which only a free cell is, and at most once, as it then gets its
        // distance), so `head < tail <= len` and every write at `tail` is below `len`; a
        // free cell is off the blocked frame, so its neighbours `id ± 1` and `id ± pw` are
        // within `0..len`.
        unsafe {
            let id = queue.get_unchecked(head).index();
            head += 1;
            let next = dist.get_unchecked(id).plus_one();
            for n in [id + pw, id - pw, id - 1, id + 1] {
                if *dist.get_unchecked(n) == D::UNREACHABLE {
                    *dist.get_unchecked_mut(n) = next;
                    *queue.get_unchecked_mut(tail) = D::from_index(n);
                    tail += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use phalanx_core::{Action, Cell, Grid, Instance};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::{BLOCKED, Env, NONE};
    use crate::obs::{CHANNELS, COST_SENTINEL};
    use crate::{EnvConfig, Task};

    /// The channels as written before the padded maps of their values: cell by cell from
    /// the obstacle flags, the occupancy and the distance map (the reference the row copies
    /// must equal bit for bit).
    fn write_grid_cellwise(env: &Env, agent: usize, out: &mut [f32]) {
        let f = env.fov;
        let ff = f * f;
        let pw = env.pw;
        let p = env.pos_idx[agent] as usize;
        let corner = p - env.pad * pw - env.pad;
        let own = env.dist_at(agent, p) as f32;
        let k = (f - 1) as f32;
        for r in 0..f {
            for c in 0..f {
                let cell = corner + r * pw + c;
                let at = |ch: usize| ch * ff + r * f + c;
                out[at(0)] = f32::from(env.blocked[cell]);
                let d = env.dist_at(agent, cell);
                out[at(2)] = if d >= BLOCKED {
                    COST_SENTINEL
                } else {
                    ((d as i32) as f32 - own).clamp(-k, k) * (1.0 / k)
                };
                let v = env.occ[cell];
                out[at(1)] = 0.0;
                if v != NONE {
                    out[at(1)] = env.ident[v as usize];
                    if v as usize != agent && env.on_goal[v as usize] {
                        out[at(2)] = COST_SENTINEL;
                    }
                }
                out[at(3)] = env.formation_obs[agent * ff + r * f + c];
            }
        }
    }

    /// A random instance: `w × h`, cells blocked with probability `density` (cut-off pockets
    /// included), `n` agents on random free cells of the goal's component.
    fn random_instance(rng: &mut ChaCha8Rng, w: u32, h: u32, density: f64, n: usize) -> Instance {
        loop {
            let grid = Grid::from_fn(w, h, |_| rng.random_bool(density));
            let mut free: Vec<Cell> = grid.free_cells().collect();
            if free.len() < 2 * n {
                continue;
            }
            for i in 0..2 * n {
                let j = rng.random_range(i..free.len());
                free.swap(i, j);
            }
            let (starts, goals) = (free[..n].to_vec(), free[n..2 * n].to_vec());
            if let Ok(instance) = Instance::new(grid, starts, goals) {
                return instance;
            }
        }
    }

    /// Channels written every step without the formation channel, into rows that hold the
    /// episode's first observation, equal the whole observation written anew.
    #[test]
    fn the_changing_channels_over_the_first_observation_equal_the_whole_observation() {
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        // Steps in which some agent stayed, and in which an agent reached or left its goal
        // (small maps make the latter common): both must be met for the test to mean much.
        let (mut stays, mut goal_changes) = (0, 0);
        for case in 0..24 {
            let fov = [5, 9, 11][case % 3];
            let n = 1 + case % 5;
            let (w, h) = if case % 2 == 0 { (24, 20) } else { (4, 3) };
            let instance = random_instance(&mut rng, w, h, 0.2, n);
            let task = [Task::PathFinding, Task::Formation, Task::Meta][case % 3];
            let config = EnvConfig { fov, task, step_limit: Some(40), ..EnvConfig::default() };
            let mut env = Env::new(config).unwrap();
            env.reset(&instance).unwrap();
            let len = CHANNELS * (fov * fov) as usize;
            let mut kept: Vec<Vec<f32>> = (0..n)
                .map(|agent| {
                    let mut rows = vec![f32::NAN; len];
                    env.write_grid(agent, &mut rows);
                    rows
                })
                .collect();
            while !env.is_done() {
                let actions: Vec<Action> =
                    (0..n).map(|_| Action::ALL[rng.random_range(0..5)]).collect();
                let (before, on_goal) = (env.positions().to_vec(), env.on_goal().to_vec());
                env.step(&actions);
                stays += usize::from(before.iter().zip(env.positions()).any(|(a, b)| a == b));
                goal_changes += usize::from(on_goal != env.on_goal());
                for (agent, kept) in kept.iter_mut().enumerate() {
                    env.write_grid_changing(agent, kept);
                    let mut whole = vec![f32::NAN; len];
                    env.write_grid(agent, &mut whole);
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(kept), bits(&whole), "case {case}, t {}", env.t());
                }
            }
        }
        assert!(stays > 100 && goal_changes > 10, "stays {stays}, goal changes {goal_changes}");
    }

    #[test]
    fn row_copied_channels_equal_the_cellwise_ones_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(37);
        let mut compared = 0;
        for case in 0..120 {
            let fov = [3, 5, 7, 9, 11, 13][case % 6];
            let (w, h) = (rng.random_range(1..=40), rng.random_range(1..=40));
            let density = rng.random_range(0.0..0.4);
            let n = rng.random_range(1..=(w * h / 4).clamp(1, 30) as usize);
            let instance = random_instance(&mut rng, w, h, density, n);
            let task = [Task::PathFinding, Task::Formation, Task::Meta][case % 3];
            let config = EnvConfig { fov, task, step_limit: Some(60), ..EnvConfig::default() };
            let mut env = Env::new(config).unwrap();
            // Two resets on one map: the second keeps the searched maps.
            for _ in 0..2 {
                env.reset(&instance).unwrap();
                let len = CHANNELS * (fov * fov) as usize;
                let (mut fast, mut slow) = (vec![0.0; len], vec![0.0; len]);
                loop {
                    for agent in 0..n {
                        env.write_grid(agent, &mut fast);
                        write_grid_cellwise(&env, agent, &mut slow);
                        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                        assert_eq!(
                            bits(&fast),
                            bits(&slow),
                            "case {case}, t {}, agent {agent}",
                            env.t()
                        );
                        compared += 1;
                    }
                    if env.is_done() {
                        break;
                    }
                    // Mostly towards the goal, so that agents park on their goals.
                    let actions: Vec<Action> = (0..n)
                        .map(|i| {
                            let here = env.positions()[i];
                            let towards = Action::MOVES.into_iter().find(|a| {
                                env.distance(i, a.apply(here))
                                    .is_some_and(|d| d < env.cost_to_go(i))
                            });
                            match towards {
                                Some(a) if rng.random_bool(0.7) => a,
                                _ => Action::ALL[rng.random_range(0..5)],
                            }
                        })
                        .collect();
                    env.step(&actions);
                }
            }
        }
        assert!(compared > 10_000, "{compared} windows compared");
    }
}
