//! Joint-state A* for moving agents in formation (MAiF): A* over the k-tuple of the agents'
//! cells, the baseline "Joint-State A*" of Liu et al. (IROS 2021), after Felner et al.,
//! *Search-based optimal solvers for the multi-agent pathfinding problem: summary and
//! challenges* (SoCS 2017), with operator decomposition from Standley, *Finding optimal
//! solutions to cooperative pathfinding problems* (AAAI 2010); docs/planners.md
//! (*Joint-state A\**) has the decisions.
//!
//! - **State:** the ordered k-tuple of cells; no time component.
//! - **Step:** every agent picks one of the five actions; a joint move is discarded when an
//!   agent leaves the map or enters an obstacle, or two agents end in one cell (vertex) or
//!   exchange cells (swap). Following is allowed.
//! - **Cost** of a step into `X'`: `1 + w·L_f(X', G)` ([`Objective::Weighted`]), or one of the
//!   two lexicographic end points of the (makespan, ΣL_f) front
//!   ([`Objective::MakespanFirst`], [`Objective::FormationFirst`]). Costs are kept in fixed
//!   point ([`COST_SCALE`] units per step, losses rounded to `1/COST_SCALE`), so sums are
//!   exact and ties are ties.
//! - **Heuristic:** `max_i D_i(p_i)` steps, `D_i` the BFS distance to agent `i`'s goal;
//!   admissible and consistent (no lower bound on the future loss is used).
//! - **Tie-breaking:** smaller `f`, then larger `g`, then the node generated last (LIFO).
//! - **Duplicate detection:** a best-`g` table keyed by the packed joint state; a node is
//!   expanded at most once, so the finite state space is exhausted and an unsolvable
//!   instance (the two-cell swap) ends as [`PlanFailure::Unsolvable`].
//! - **Operator decomposition** (default for `k >= 4`): intermediate nodes assign one agent's
//!   move at a time, checking conflicts as moves are assigned; the step cost is charged with
//!   the k-th move. Intermediate nodes are not deduplicated.
//!
//! Statistics: `high_level_expanded` counts expanded full joint states and
//! `low_level_expanded` expanded intermediate (operator-decomposition) nodes.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::hash::Hash;
use std::time::Instant;

use phalanx_core::{
    Action, Cell, DistanceMap, Grid, Instance, Plan, PlanMetrics, formation_loss,
    formation_loss_squared,
};
use rustc_hash::FxHashMap;

use crate::{Budget, PlanFailure, PlanReport, SearchStats};

/// Fixed-point units of one step (and of one unit of formation loss) in the search's costs.
pub const COST_SCALE: f64 = (1u64 << 30) as f64;

/// Which per-step formation loss the cost charges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StepLoss {
    /// The root loss `L_f` of the authors' environment (the Table II quantity).
    #[default]
    Root,
    /// The squared loss `L_f²` of the paper's Eq. 1.
    Squared,
}

/// What the search minimises over plans `X_0 … X_T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    /// `T + w · Σ_{t=1..T} loss(X_t)`; `w = 0` is a makespan-optimal MAPF.
    Weighted(f64),
    /// Lexicographic `(T, Σ loss)`: the makespan-first end point of the front.
    MakespanFirst,
    /// Lexicographic `(Σ loss, T)`: the formation-first end point of the front.
    FormationFirst,
    /// Lexicographic `(Σ loss, T)` among plans with makespan at most the given bound: the
    /// ε-constraint step of the exact front. The search state then includes the time step.
    FormationFirstWithin(u32),
}

/// When to use operator decomposition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Decomposition {
    /// For four agents or more (baselines.md §4).
    #[default]
    Auto,
    /// Always.
    Always,
    /// Never: every node generates all joint moves at once.
    Never,
}

/// Settings of joint-state A*.
#[derive(Debug, Clone, PartialEq)]
pub struct JointAStarConfig {
    /// The objective; default `Weighted(1.0)` (baselines.md §4 reports `w = 1`).
    pub objective: Objective,
    /// The per-step loss the objective charges; default the root loss.
    pub loss: StepLoss,
    /// Operator decomposition; default [`Decomposition::Auto`].
    pub decomposition: Decomposition,
    /// Memory guard: at most this many search nodes are stored (full and intermediate);
    /// beyond it the search stops with [`PlanFailure::NodeLimit`]. Default 20 million
    /// (a few GiB for five agents). The budget's node limit, if smaller, applies too.
    pub max_stored_nodes: u64,
}

impl Default for JointAStarConfig {
    fn default() -> JointAStarConfig {
        JointAStarConfig {
            objective: Objective::Weighted(1.0),
            loss: StepLoss::Root,
            decomposition: Decomposition::Auto,
            max_stored_nodes: 20_000_000,
        }
    }
}

impl JointAStarConfig {
    /// The default settings with another objective.
    pub fn with_objective(objective: Objective) -> JointAStarConfig {
        JointAStarConfig { objective, ..JointAStarConfig::default() }
    }
}

/// Finds a plan minimising `config.objective`; see the module documentation.
///
/// The budget's node limit counts expanded nodes (full and intermediate). Never panics on
/// unsolvable instances or exhausted budgets: those are [`PlanFailure`] outcomes.
pub fn solve(instance: &Instance, config: &JointAStarConfig, budget: &Budget) -> PlanReport {
    let started = Instant::now();
    let bits = bits_per_cell(instance.grid());
    let time_bits =
        if matches!(config.objective, Objective::FormationFirstWithin(_)) { 32 } else { 0 };
    let (result, mut stats) = if bits * instance.n_agents() as u32 + time_bits <= 128 {
        Search::<u128>::new(instance, config, budget, started, bits).run()
    } else {
        Search::<Box<[u32]>>::new(instance, config, budget, started, bits).run()
    };
    stats.runtime_s = started.elapsed().as_secs_f64();
    PlanReport { result, stats }
}

/// One point of a (makespan, formation loss) front.
#[derive(Debug, Clone, PartialEq)]
pub struct ParetoPoint {
    /// The objective whose optimum this is.
    pub objective: Objective,
    /// The plan's makespan `T`.
    pub makespan: usize,
    /// The Table II formation loss `Σ_{t=1..T} L_f / side`.
    pub formation_loss: f64,
    /// `Σ_{t=1..T} L_f` (root loss).
    pub sum_loss: f64,
}

/// Settings of [`pareto_front`].
#[derive(Debug, Clone, PartialEq)]
pub struct ParetoConfig {
    /// Weights of the weighted sweep; default `{0, 0.01, 0.03, 0.1, 0.3, 1, 3, 10, 100}`.
    pub weights: Vec<f64>,
    /// Also solve the two lexicographic end points; default true.
    pub endpoints: bool,
    /// Search settings shared by every run (their objective is replaced).
    pub search: JointAStarConfig,
}

impl Default for ParetoConfig {
    fn default() -> ParetoConfig {
        ParetoConfig {
            weights: vec![0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0],
            endpoints: true,
            search: JointAStarConfig::default(),
        }
    }
}

/// The outcome of [`pareto_front`].
#[derive(Debug, Clone, PartialEq)]
pub struct ParetoFront {
    /// Non-dominated points, by increasing makespan (then loss); duplicates removed.
    pub points: Vec<ParetoPoint>,
    /// Every run in order (makespan-first end point, the weights, formation-first end point)
    /// with its outcome.
    pub runs: Vec<(Objective, Result<ParetoPoint, PlanFailure>)>,
    /// Statistics summed over the runs.
    pub stats: SearchStats,
}

/// The supported (convex-hull) points of the (makespan, ΣL_f) front: a weighted sweep plus
/// the two lexicographic end points (baselines.md §4 (a)). The budget's time limit is
/// shared: each run gets what the earlier runs left.
pub fn pareto_front(instance: &Instance, config: &ParetoConfig, budget: &Budget) -> ParetoFront {
    let started = Instant::now();
    let mut objectives = Vec::new();
    if config.endpoints {
        objectives.push(Objective::MakespanFirst);
    }
    objectives.extend(config.weights.iter().map(|&w| Objective::Weighted(w)));
    if config.endpoints {
        objectives.push(Objective::FormationFirst);
    }
    let mut runs = Vec::with_capacity(objectives.len());
    let mut stats = SearchStats::default();
    for objective in objectives {
        let point = front_point(instance, objective, &config.search, budget, started, &mut stats);
        runs.push((objective, point));
    }
    stats.runtime_s = started.elapsed().as_secs_f64();
    ParetoFront { points: non_dominated(&runs), runs, stats }
}

/// The exact (makespan, ΣL_f) front by the ε-constraint method (baselines.md §4 (b)): the
/// makespan-first end point `T₀`, the formation-first end point, and for every bound
/// `T = T₀ + 1, T₀ + 2, …` the least loss of a plan with makespan at most `T`, until that
/// loss reaches the formation-first optimum or the time limit runs out. Every
/// [`ParetoFront::runs`] entry is in that order except that the formation-first run comes
/// second. Meant for small instances: each bound is a search over (joint state, time).
pub fn exact_front(instance: &Instance, config: &JointAStarConfig, budget: &Budget) -> ParetoFront {
    let started = Instant::now();
    let mut stats = SearchStats::default();
    let mut runs = Vec::new();
    for objective in [Objective::MakespanFirst, Objective::FormationFirst] {
        let point = front_point(instance, objective, config, budget, started, &mut stats);
        runs.push((objective, point));
    }
    if let (Ok(first), Ok(last)) = (&runs[0].1, &runs[1].1) {
        let (first_makespan, last_makespan) = (first.makespan as u32, last.makespan as u32);
        let least_loss = last.sum_loss;
        for horizon in first_makespan + 1..last_makespan {
            let objective = Objective::FormationFirstWithin(horizon);
            let point = front_point(instance, objective, config, budget, started, &mut stats);
            let done = match &point {
                Ok(point) => point.sum_loss <= least_loss + 1e-9,
                Err(_) => true,
            };
            runs.push((objective, point));
            if done {
                break;
            }
        }
    }
    stats.runtime_s = started.elapsed().as_secs_f64();
    ParetoFront { points: non_dominated(&runs), runs, stats }
}

/// Solves one objective with what remains of the budget and scores the plan.
fn front_point(
    instance: &Instance,
    objective: Objective,
    search: &JointAStarConfig,
    budget: &Budget,
    started: Instant,
    stats: &mut SearchStats,
) -> Result<ParetoPoint, PlanFailure> {
    let remaining = budget.time_limit.map(|t| t.saturating_sub(started.elapsed()));
    let run_budget = Budget { time_limit: remaining, ..*budget };
    let report = solve(instance, &JointAStarConfig { objective, ..search.clone() }, &run_budget);
    stats.high_level_expanded += report.stats.high_level_expanded;
    stats.low_level_expanded += report.stats.low_level_expanded;
    report.result.map(|plan| {
        let metrics = PlanMetrics::of(instance, &plan);
        let sum_loss = metrics.formation_loss_per_step.iter().skip(1).sum();
        ParetoPoint {
            objective,
            makespan: metrics.makespan,
            formation_loss: metrics.formation_loss,
            sum_loss,
        }
    })
}

/// The non-dominated points of the successful runs, by increasing makespan, duplicates removed.
fn non_dominated(runs: &[(Objective, Result<ParetoPoint, PlanFailure>)]) -> Vec<ParetoPoint> {
    let mut points: Vec<ParetoPoint> =
        runs.iter().filter_map(|(_, it)| it.as_ref().ok().cloned()).collect();
    points.sort_by(|a, b| a.makespan.cmp(&b.makespan).then(a.sum_loss.total_cmp(&b.sum_loss)));
    let mut front: Vec<ParetoPoint> = Vec::new();
    for point in points {
        // Sorted by makespan: a point is dominated iff an earlier kept point has no more loss.
        if front.iter().all(|kept| point.sum_loss < kept.sum_loss - 1e-9) {
            front.push(point);
        }
    }
    front
}

/// Bits needed for a dense cell id of `grid`.
fn bits_per_cell(grid: &Grid) -> u32 {
    let n = grid.n_cells().max(2) as u64;
    64 - (n - 1).leading_zeros()
}

/// A search cost, compared lexicographically: `(primary, secondary)` in fixed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
struct Cost(i64, i64);

impl Cost {
    fn add(self, other: Cost) -> Cost {
        Cost(self.0.saturating_add(other.0), self.1.saturating_add(other.1))
    }
}

/// A loss or a weighted loss in fixed point.
fn fixed(value: f64) -> i64 {
    let scaled = (value * COST_SCALE).round();
    if scaled.is_finite() { scaled.clamp(0.0, 1e18) as i64 } else { 1e18 as i64 }
}

/// Packed joint states, the keys of the best-`g` table.
/// With `time`, the key also holds the time step (for [`Objective::FormationFirstWithin`]).
trait StateKey: Hash + Eq {
    fn pack(grid: &Grid, cells: &[Cell], bits: u32, time: Option<u32>) -> Self;
}

impl StateKey for u128 {
    #[inline]
    fn pack(grid: &Grid, cells: &[Cell], bits: u32, time: Option<u32>) -> u128 {
        let key = cells.iter().fold(0u128, |acc, &c| acc << bits | u128::from(grid.id(c).0));
        match time {
            Some(t) => key << 32 | u128::from(t),
            None => key,
        }
    }
}

impl StateKey for Box<[u32]> {
    fn pack(grid: &Grid, cells: &[Cell], _bits: u32, time: Option<u32>) -> Box<[u32]> {
        cells.iter().map(|&c| grid.id(c).0).chain(time).collect()
    }
}

/// A stored search node. Its cells live in `Search::cells[idx * k..(idx + 1) * k]`: for an
/// intermediate node, agents `< next_agent` already hold their new cells.
struct Node {
    /// The parent node (`u32::MAX` for the root); for a full node, the previous full node.
    parent: u32,
    /// For an intermediate node, the full node whose step it assigns; else itself.
    base: u32,
    g: Cost,
    /// 0 for a full joint state, `j` for an intermediate node that moved agents `< j`.
    next_agent: u32,
    /// The time step of the full state (of the base, for an intermediate node).
    t: u32,
}

/// An entry of the open list: smaller `f` first, then larger `g`, then the newer node.
#[derive(PartialEq, Eq)]
struct OpenEntry {
    f: Cost,
    g: Cost,
    node: u32,
}

impl Ord for OpenEntry {
    fn cmp(&self, other: &Self) -> Ordering {
        // BinaryHeap pops the greatest entry.
        other.f.cmp(&self.f).then(self.g.cmp(&other.g)).then(self.node.cmp(&other.node))
    }
}

impl PartialOrd for OpenEntry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Best known `g` of a full joint state, and whether it has been expanded.
struct Seen {
    g: Cost,
    node: u32,
    closed: bool,
}

struct Search<'a, K> {
    instance: &'a Instance,
    grid: &'a Grid,
    config: &'a JointAStarConfig,
    budget: &'a Budget,
    started: Instant,
    bits: u32,
    n_agents: usize,
    decompose: bool,
    /// The makespan bound of [`Objective::FormationFirstWithin`].
    horizon: Option<u32>,
    dist: Vec<DistanceMap>,
    nodes: Vec<Node>,
    cells: Vec<Cell>,
    open: BinaryHeap<OpenEntry>,
    seen: FxHashMap<K, Seen>,
    stats: SearchStats,
    /// Scratch: the joint move being assigned (used without decomposition).
    scratch: Vec<Cell>,
}

impl<'a, K: StateKey> Search<'a, K> {
    fn new(
        instance: &'a Instance,
        config: &'a JointAStarConfig,
        budget: &'a Budget,
        started: Instant,
        bits: u32,
    ) -> Search<'a, K> {
        let n_agents = instance.n_agents();
        let decompose = match config.decomposition {
            Decomposition::Auto => n_agents >= 4,
            Decomposition::Always => true,
            Decomposition::Never => false,
        };
        Search {
            instance,
            grid: instance.grid(),
            config,
            budget,
            started,
            bits,
            n_agents,
            decompose,
            horizon: match config.objective {
                Objective::FormationFirstWithin(horizon) => Some(horizon),
                _ => None,
            },
            dist: Vec::new(),
            nodes: Vec::new(),
            cells: Vec::new(),
            open: BinaryHeap::new(),
            seen: FxHashMap::default(),
            stats: SearchStats::default(),
            scratch: Vec::with_capacity(n_agents),
        }
    }

    fn run(mut self) -> (Result<Plan, PlanFailure>, SearchStats) {
        let res = self.search();
        (res, self.stats)
    }

    /// The time part of a key: only with a makespan bound.
    fn time_key(&self, t: u32) -> Option<u32> {
        self.horizon.map(|_| t)
    }

    fn node_cells(&self, node: u32) -> &[Cell] {
        let k = self.n_agents;
        &self.cells[node as usize * k..(node as usize + 1) * k]
    }

    /// The heuristic of a full state, in steps.
    fn h_full(&self, cells: &[Cell]) -> u32 {
        cells.iter().zip(&self.dist).map(|(&c, d)| d.raw(c)).max().unwrap_or(0)
    }

    fn h_cost(&self, steps: u32) -> Cost {
        let steps = i64::from(steps) * COST_SCALE as i64;
        match self.config.objective {
            Objective::Weighted(_) | Objective::MakespanFirst => Cost(steps, 0),
            Objective::FormationFirst | Objective::FormationFirstWithin(_) => Cost(0, steps),
        }
    }

    fn step_cost(&self, cells: &[Cell]) -> Cost {
        let goals = self.instance.goals();
        let one = COST_SCALE as i64;
        let loss = |cells: &[Cell]| match self.config.loss {
            StepLoss::Root => formation_loss(cells, goals),
            StepLoss::Squared => formation_loss_squared(cells, goals),
        };
        match self.config.objective {
            Objective::Weighted(0.0) => Cost(one, 0),
            Objective::Weighted(w) => Cost(one.saturating_add(fixed(w * loss(cells))), 0),
            Objective::MakespanFirst => Cost(one, fixed(loss(cells))),
            Objective::FormationFirst | Objective::FormationFirstWithin(_) => {
                Cost(fixed(loss(cells)), one)
            }
        }
    }

    fn node_limit_hit(&self) -> bool {
        let expanded = self.stats.high_level_expanded + self.stats.low_level_expanded;
        self.budget.node_limit.is_some_and(|limit| expanded >= limit)
            || self.nodes.len() as u64 >= self.config.max_stored_nodes
    }

    fn time_up(&self) -> bool {
        self.budget.time_limit.is_some_and(|limit| self.started.elapsed() >= limit)
    }

    /// Stores a node and puts it on the open list.
    fn push_node(&mut self, parent: u32, base: u32, g: Cost, next_agent: u32, h: Cost) -> u32 {
        let idx = self.nodes.len() as u32;
        let t = match self.nodes.get(base as usize) {
            Some(base_node) if next_agent != 0 => base_node.t,
            _ => self.nodes.get(parent as usize).map_or(0, |p| p.t + 1),
        };
        self.nodes.push(Node { parent, base, g, next_agent, t });
        self.open.push(OpenEntry { f: g.add(h), g, node: idx });
        idx
    }

    /// Offers the full joint state in `self.scratch`, reached from full node `parent`.
    fn offer_full(&mut self, parent: u32) {
        let t = self.nodes[parent as usize].t + 1;
        let h_steps = self.h_full(&self.scratch);
        if self
            .horizon
            .is_some_and(|horizon| u64::from(t) + u64::from(h_steps) > u64::from(horizon))
        {
            return;
        }
        let g = self.nodes[parent as usize].g.add(self.step_cost(&self.scratch));
        let key = K::pack(self.grid, &self.scratch, self.bits, self.time_key(t));
        let idx = self.nodes.len() as u32;
        match self.seen.get_mut(&key) {
            Some(seen) if seen.closed || seen.g <= g => return,
            Some(seen) => {
                seen.g = g;
                seen.node = idx;
            }
            None => {
                self.seen.insert(key, Seen { g, node: idx, closed: false });
            }
        }
        let h = self.h_cost(h_steps);
        let cells = std::mem::take(&mut self.scratch);
        self.cells.extend_from_slice(&cells);
        self.scratch = cells;
        self.push_node(parent, idx, g, 0, h);
    }

    fn search(&mut self) -> Result<Plan, PlanFailure> {
        let instance = self.instance;
        self.dist = instance.goals().iter().map(|&g| DistanceMap::bfs(self.grid, g)).collect();
        let starts = instance.starts();
        if self.h_full(starts) == DistanceMap::UNREACHABLE {
            return Err(PlanFailure::Unsolvable);
        }
        // The root.
        self.cells.extend_from_slice(starts);
        if self.horizon.is_some_and(|horizon| self.h_full(starts) > horizon) {
            return Err(PlanFailure::Unsolvable);
        }
        let key = K::pack(self.grid, starts, self.bits, self.time_key(0));
        self.seen.insert(key, Seen { g: Cost::default(), node: 0, closed: false });
        let h = self.h_cost(self.h_full(starts));
        self.push_node(u32::MAX, 0, Cost::default(), 0, h);

        let mut pops: u64 = 0;
        while let Some(OpenEntry { node, g, .. }) = self.open.pop() {
            pops += 1;
            if pops.is_multiple_of(1024) && self.time_up() {
                return Err(PlanFailure::Timeout);
            }
            if self.node_limit_hit() {
                return Err(PlanFailure::NodeLimit);
            }
            let next_agent = self.nodes[node as usize].next_agent;
            if next_agent == 0 {
                let time = self.time_key(self.nodes[node as usize].t);
                let key = K::pack(self.grid, self.node_cells(node), self.bits, time);
                let Some(seen) = self.seen.get_mut(&key) else { continue };
                if seen.closed || seen.node != node || seen.g != g {
                    continue; // a stale entry
                }
                seen.closed = true;
                if self.node_cells(node) == instance.goals() {
                    return Ok(self.plan_to(node));
                }
                self.stats.high_level_expanded += 1;
                if self.decompose {
                    self.expand_agent(node);
                } else {
                    self.expand_all(node);
                }
            } else {
                self.stats.low_level_expanded += 1;
                self.expand_agent(node);
            }
        }
        Err(PlanFailure::Unsolvable)
    }

    /// Whether agent `agent` may move from `from` to `to` given the agents `< agent`, which
    /// moved from `old[i]` to `new[i]`.
    fn move_ok(&self, old: &[Cell], new: &[Cell], agent: usize, from: Cell, to: Cell) -> bool {
        if self.grid.is_blocked(to) {
            return false;
        }
        (0..agent).all(|i| new[i] != to && !(new[i] == from && old[i] == to))
    }

    /// Without decomposition: every valid joint move of full node `node`, by depth-first
    /// assignment in agent order and action order.
    fn expand_all(&mut self, node: u32) {
        let old: Vec<Cell> = self.node_cells(node).to_vec();
        self.scratch.clear();
        self.assign(node, &old, 0);
    }

    fn assign(&mut self, node: u32, old: &[Cell], agent: usize) {
        if agent == self.n_agents {
            self.offer_full(node);
            return;
        }
        for action in Action::ALL {
            let to = action.apply(old[agent]);
            if !self.move_ok(old, &self.scratch, agent, old[agent], to) {
                continue;
            }
            self.scratch.push(to);
            self.assign(node, old, agent + 1);
            self.scratch.pop();
        }
    }

    /// With decomposition: the moves of the next agent of `node` (full or intermediate).
    fn expand_agent(&mut self, node: u32) {
        let k = self.n_agents;
        let Node { base, g, next_agent, .. } = self.nodes[node as usize];
        let agent = next_agent as usize;
        let old: Vec<Cell> = self.node_cells(base).to_vec();
        let current: Vec<Cell> = self.node_cells(node).to_vec();
        for action in Action::ALL {
            let to = action.apply(old[agent]);
            if !self.move_ok(&old, &current, agent, old[agent], to) {
                continue;
            }
            if agent + 1 == k {
                self.scratch.clear();
                self.scratch.extend_from_slice(&current[..agent]);
                self.scratch.push(to);
                self.offer_full(base);
            } else {
                let moved = current[..agent]
                    .iter()
                    .chain(std::iter::once(&to))
                    .zip(&self.dist)
                    .map(|(&c, d)| d.raw(c))
                    .max()
                    .unwrap_or(0);
                let unmoved = old[agent + 1..]
                    .iter()
                    .zip(&self.dist[agent + 1..])
                    .map(|(&c, d)| d.raw(c))
                    .max()
                    .unwrap_or(0);
                if moved == DistanceMap::UNREACHABLE {
                    continue;
                }
                let h_steps = (moved + 1).max(unmoved);
                let t = self.nodes[base as usize].t;
                if self.horizon.is_some_and(|hz| u64::from(t) + u64::from(h_steps) > u64::from(hz))
                {
                    continue;
                }
                let h = self.h_cost(h_steps);
                self.cells.extend_from_slice(&current[..agent]);
                self.cells.push(to);
                self.cells.extend_from_slice(&old[agent + 1..]);
                self.push_node(node, base, g, next_agent + 1, h);
            }
        }
    }

    /// The plan ending at full node `node`.
    fn plan_to(&self, node: u32) -> Plan {
        let mut chain = Vec::new();
        let mut cur = node;
        while cur != u32::MAX {
            chain.push(cur);
            cur = self.nodes[cur as usize].parent;
            // Intermediate nodes are never the parent of a full node.
            debug_assert!(cur == u32::MAX || self.nodes[cur as usize].next_agent == 0);
        }
        let mut plan = Plan::new(self.n_agents);
        for &idx in chain.iter().rev() {
            plan.push(self.node_cells(idx));
        }
        plan
    }
}

#[cfg(test)]
mod tests;
