//! Space-time A* (Silver 2005, "Cooperative Pathfinding", AIIDE) over `(cell, t)`: the low
//! level of CBS and ECBS, and prioritised planning on top of it.
//!
//! The search honours vertex constraints `(cell, t)`, edge constraints `(from, to, t)` (the
//! move `from -> to` arriving at `t`), cells blocked from a time on (prioritised planning:
//! agents parked at their goals) and the goal-hold rule: an agent finishes only at a time
//! later than every constraint on its goal cell, since it stays there for good. The cost of a
//! path is its arrival time at the goal (trailing waits are free), as in
//! `phalanx_core::PlanMetrics::sum_of_costs`.
//!
//! Heuristic: the BFS distance to the goal (a [`DistanceMap`] computed once per agent and
//! reused by every search), raised to the earliest admissible finishing time. Both parts are
//! consistent, so no state is expanded twice.
//!
//! Tie-breaking, explicit and deterministic: smaller `f`, then fewer conflicts with the
//! conflict-avoidance table (when one is given), then larger `g` (dive towards the goal), then
//! the earlier-generated node. Successors are generated in the order Wait, Up, Down, Left,
//! Right.
//!
//! Finiteness: once `t` passes every constraint and every path in the conflict-avoidance
//! table, the problem is static; all later times share one layer ("time collapse"), so one
//! search visits at most `(horizon + 2) * cells` states and ends with `Infeasible` when the
//! constraints admit no path. A hard bound `max_time` on the arrival time is also honoured.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use phalanx_core::{Cell, CellId, DistanceMap, Grid, Instance, Plan};
use rustc_hash::{FxHashMap, FxHashSet};

use crate::{Budget, BudgetClock, PlanFailure, PlanReport, SearchStats};

/// Settings of prioritised space-time A*.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AStarConfig {
    /// The planning order (agent indices); `None` plans agents in index order.
    pub order: Option<Vec<usize>>,
}

/// Prioritised planning (Silver 2005): agents plan one after another in `config.order`, each
/// with space-time A* avoiding the paths of the agents before it (they stay at their goals
/// afterwards). Incomplete: when an agent after the first finds no path, the order failed and
/// the report says [`PlanFailure::Incomplete`]; only the first agent's failure (no path even
/// alone) is [`PlanFailure::Unsolvable`]. For one agent it is plain optimal space-time A*. Nodes counted against the budget: low-level expansions.
pub fn solve(instance: &Instance, config: &AStarConfig, budget: &Budget) -> PlanReport {
    let clock = budget.start();
    let mut stats = SearchStats::default();
    let n_agents = instance.n_agents();
    let order: Vec<usize> = config.order.clone().unwrap_or_else(|| (0..n_agents).collect());
    assert!(
        order.len() == n_agents && {
            let mut sorted = order.clone();
            sorted.sort_unstable();
            sorted.iter().enumerate().all(|(i, &a)| i == a)
        },
        "order must be a permutation of the agents"
    );
    let grid = instance.grid();
    let mut low = LowLevel::new(grid);
    let mut reserved = Constraints::default();
    let mut paths: Vec<Vec<u32>> = vec![Vec::new(); n_agents];
    let max_time = joint_horizon_bound(instance);
    for (rank, &agent) in order.iter().enumerate() {
        let start = grid.id(instance.starts()[agent]).0;
        let goal = grid.id(instance.goals()[agent]).0;
        let dist = DistanceMap::bfs(grid, instance.goals()[agent]);
        let query = Query {
            start,
            goal,
            dist: dist.as_slice(),
            constraints: &reserved,
            cat: None,
            max_time,
            node_limit: budget.node_limit.map(|it| it.saturating_sub(stats.low_level_expanded)),
        };
        let res = low.search(&query, &clock, &mut stats.low_level_expanded);
        let path = match res {
            LowResult::Found(path) => path,
            LowResult::Infeasible => {
                stats.runtime_s = clock.elapsed_s();
                let failure =
                    if rank == 0 { PlanFailure::Unsolvable } else { PlanFailure::Incomplete };
                return PlanReport::failure(failure, stats);
            }
            LowResult::Timeout => {
                stats.runtime_s = clock.elapsed_s();
                return PlanReport::failure(PlanFailure::Timeout, stats);
            }
            LowResult::NodeLimit => {
                stats.runtime_s = clock.elapsed_s();
                return PlanReport::failure(PlanFailure::NodeLimit, stats);
            }
        };
        reserved.reserve_path(&path);
        paths[agent] = path;
    }
    stats.runtime_s = clock.elapsed_s();
    PlanReport { result: Ok(paths_to_plan(grid, &paths)), stats }
}

/// An upper bound on the makespan some sum-of-costs-optimal plan needs, when it is small:
/// a plan never needs to repeat a joint placement, so it has fewer steps than there are
/// placements of the agents on the free cells (`free! / (free - k)!`). Saturates at
/// `u32::MAX / 2` (no bound in practice); it matters on tiny maps, where it makes CBS finite.
pub(crate) fn joint_horizon_bound(instance: &Instance) -> u32 {
    let free = (instance.grid().n_cells() - instance.grid().n_blocked()) as u64;
    let cap = u64::from(u32::MAX / 2);
    let mut placements: u64 = 1;
    for i in 0..instance.n_agents() as u64 {
        placements = placements.saturating_mul(free.saturating_sub(i).max(1));
        if placements >= cap {
            return cap as u32;
        }
    }
    placements.saturating_sub(1) as u32
}

/// Converts per-agent paths of cell ids (each ending at its goal) into a padded [`Plan`].
pub(crate) fn paths_to_plan(grid: &Grid, paths: &[Vec<u32>]) -> Plan {
    let cells: Vec<Vec<Cell>> =
        paths.iter().map(|path| path.iter().map(|&id| grid.cell(CellId(id))).collect()).collect();
    Plan::from_paths(&cells)
}

/// The cell an agent following `path` occupies at `t` (it stays at the last cell).
#[inline]
pub(crate) fn at(path: &[u32], t: u32) -> u32 {
    path[(t as usize).min(path.len() - 1)]
}

/// Cost of a path: its arrival time at the goal for good.
#[inline]
pub(crate) fn path_cost(path: &[u32]) -> u32 {
    path.len() as u32 - 1
}

/// The constraints of one agent.
#[derive(Debug, Clone, Default)]
pub(crate) struct Constraints {
    /// Forbidden `(cell, t)` pairs.
    pub(crate) vertex: FxHashSet<(u32, u32)>,
    /// Forbidden moves `(from, to, t)`, arriving at `t`.
    pub(crate) edge: FxHashSet<(u32, u32, u32)>,
    /// Cells forbidden from a time on (agents parked at their goals in prioritised planning).
    pub(crate) blocked_from: FxHashMap<u32, u32>,
    /// The latest time of any constraint (the problem is static afterwards).
    pub(crate) latest: u32,
    /// The agent may finish (arrive at its goal for good) only at this time or later
    /// (target reasoning: "the path is longer than `t`").
    pub(crate) min_finish: u32,
    /// The agent must finish by this time.
    pub(crate) finish_by: Option<u32>,
}

impl Constraints {
    pub(crate) fn add_vertex(&mut self, cell: u32, t: u32) {
        self.vertex.insert((cell, t));
        self.latest = self.latest.max(t);
    }

    pub(crate) fn add_edge(&mut self, from: u32, to: u32, t: u32) {
        self.edge.insert((from, to, t));
        self.latest = self.latest.max(t);
    }

    /// Forbids `cell` from `t` on.
    pub(crate) fn block_from(&mut self, cell: u32, t: u32) {
        let since = self.blocked_from.entry(cell).or_insert(t);
        *since = (*since).min(t);
        self.latest = self.latest.max(t);
    }

    /// Requires finishing at `t` or later.
    pub(crate) fn finish_not_before(&mut self, t: u32) {
        self.min_finish = self.min_finish.max(t);
        self.latest = self.latest.max(t);
    }

    /// The earliest time the agent may finish at `goal`: after every vertex constraint on
    /// the goal (goal hold) and not before `min_finish`.
    pub(crate) fn earliest_finish(&self, goal: u32) -> u32 {
        self.goal_latest(goal).map_or(0, |t| t + 1).max(self.min_finish)
    }

    /// Reserves `path` of another agent: its cells, its moves (no swaps) and its goal for
    /// good from its arrival on.
    pub(crate) fn reserve_path(&mut self, path: &[u32]) {
        for (t, &cell) in path.iter().enumerate() {
            self.add_vertex(cell, t as u32);
            if t > 0 {
                self.add_edge(cell, path[t - 1], t as u32);
            }
        }
        let arrival = path_cost(path);
        self.blocked_from.insert(path[path.len() - 1], arrival);
        self.latest = self.latest.max(arrival);
    }

    /// The latest time the goal `goal` is forbidden at (`None` when never): the agent may
    /// finish only later.
    pub(crate) fn goal_latest(&self, goal: u32) -> Option<u32> {
        let mut res = None;
        if self.vertex.is_empty() {
            return res;
        }
        for &(cell, t) in &self.vertex {
            if cell == goal && res.is_none_or(|r| t > r) {
                res = Some(t);
            }
        }
        res
    }

    #[inline]
    pub(crate) fn allows(&self, from: u32, to: u32, t: u32) -> bool {
        if !self.vertex.is_empty() && self.vertex.contains(&(to, t)) {
            return false;
        }
        if !self.edge.is_empty() && from != to && self.edge.contains(&(from, to, t)) {
            return false;
        }
        if let Some(&since) = self.blocked_from.get(&to)
            && t >= since
        {
            return false;
        }
        true
    }
}

/// Conflict-avoidance table: the other agents' paths, to break ties towards fewer conflicts.
#[derive(Debug, Clone, Default)]
pub(crate) struct ConflictTable {
    vertex: FxHashMap<(u32, u32), u16>,
    edge: FxHashMap<(u32, u32, u32), u16>,
    parked: FxHashMap<u32, u32>,
    pub(crate) horizon: u32,
}

impl ConflictTable {
    /// The table of `paths`.
    pub(crate) fn of_paths<'p>(paths: impl IntoIterator<Item = &'p [u32]>) -> ConflictTable {
        let mut res = ConflictTable::default();
        for path in paths {
            res.add(path);
        }
        res
    }

    fn add(&mut self, path: &[u32]) {
        let arrival = path_cost(path);
        for (t, &cell) in path.iter().enumerate().take(path.len() - 1) {
            *self.vertex.entry((cell, t as u32)).or_default() += 1;
            if t > 0 {
                *self.edge.entry((path[t - 1], cell, t as u32)).or_default() += 1;
            }
        }
        if arrival > 0 {
            *self.edge.entry((path[path.len() - 2], path[path.len() - 1], arrival)).or_default() +=
                1;
        }
        self.parked.insert(path[path.len() - 1], arrival);
        self.horizon = self.horizon.max(arrival);
    }

    /// Conflicts caused by the move `from -> to` arriving at `t`.
    #[inline]
    pub(crate) fn count(&self, from: u32, to: u32, t: u32) -> u32 {
        let mut res = u32::from(self.vertex.get(&(to, t)).copied().unwrap_or(0));
        if let Some(&since) = self.parked.get(&to)
            && t >= since
        {
            res += 1;
        }
        if from != to {
            res += u32::from(self.edge.get(&(to, from, t)).copied().unwrap_or(0));
        }
        res
    }
}

/// One low-level query.
pub(crate) struct Query<'a> {
    pub(crate) start: u32,
    pub(crate) goal: u32,
    /// BFS distances to `goal`, [`DistanceMap::UNREACHABLE`] where unreachable.
    pub(crate) dist: &'a [u32],
    pub(crate) constraints: &'a Constraints,
    pub(crate) cat: Option<&'a ConflictTable>,
    /// Hard bound on the arrival time.
    pub(crate) max_time: u32,
    /// Bound on the expansions of this search.
    pub(crate) node_limit: Option<u64>,
}

/// The answer of one low-level search.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum LowResult {
    /// The path, one cell id per time step, ending on the goal.
    Found(Vec<u32>),
    /// The constraints admit no path.
    Infeasible,
    /// The budget's deadline passed.
    Timeout,
    /// The query's node limit was reached.
    NodeLimit,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    cell: u32,
    g: u32,
    conflicts: u32,
    parent: u32,
    closed: bool,
}

/// Reusable space-time A* on one grid (buffers live across searches).
pub(crate) struct LowLevel<'g> {
    grid: &'g Grid,
    nodes: Vec<Node>,
    index: FxHashMap<(u32, u32), u32>,
    open: BinaryHeap<Reverse<OpenKey>>,
}

/// `(f, conflicts, Reverse(g), node)`: the order of expansion.
type OpenKey = (u32, u32, Reverse<u32>, u32);

/// How often (in expansions) the low level reads the clock.
const CLOCK_EVERY: u64 = 1024;

impl<'g> LowLevel<'g> {
    pub(crate) fn new(grid: &'g Grid) -> LowLevel<'g> {
        LowLevel { grid, nodes: Vec::new(), index: FxHashMap::default(), open: BinaryHeap::new() }
    }

    /// The free 4-neighbours of `cell` followed by `cell` itself (wait first), in the fixed
    /// order Wait, Up, Down, Left, Right.
    #[inline]
    pub(crate) fn successors(grid: &Grid, cell: u32) -> ([u32; 5], usize) {
        let width = grid.width();
        let (x, y) = (cell % width, cell / width);
        let mut res = [cell; 5];
        let mut n = 1;
        let mut push = |c: u32| {
            if !grid.is_blocked_id(CellId(c)) {
                res[n] = c;
                n += 1;
            }
        };
        if y + 1 < grid.height() {
            push(cell + width);
        }
        if y > 0 {
            push(cell - width);
        }
        if x > 0 {
            push(cell - 1);
        }
        if x + 1 < width {
            push(cell + 1);
        }
        (res, n)
    }

    /// Runs one search; adds its expansions to `expanded`.
    pub(crate) fn search(
        &mut self,
        query: &Query<'_>,
        clock: &BudgetClock,
        expanded: &mut u64,
    ) -> LowResult {
        self.nodes.clear();
        self.index.clear();
        self.open.clear();
        let grid = self.grid;
        let h0 = query.dist[query.start as usize];
        if h0 == DistanceMap::UNREACHABLE {
            return LowResult::Infeasible;
        }
        let cons = query.constraints;
        // The earliest finishing time the goal-hold rule allows.
        let earliest_finish = cons.earliest_finish(query.goal);
        let max_time = query.max_time.min(cons.finish_by.unwrap_or(u32::MAX));
        if earliest_finish.max(h0) > max_time {
            return LowResult::Infeasible;
        }
        let cat_horizon = query.cat.map_or(0, |cat| cat.horizon);
        let cons_latest = cons.latest.max(cons.blocked_from.values().copied().max().unwrap_or(0));
        // Every time after `collapse` shares the layer `collapse`.
        let collapse = cons_latest.max(cat_horizon) + 1;
        let heuristic = |cell: u32, t: u32| -> u32 {
            let d = query.dist[cell as usize];
            d.max(earliest_finish.saturating_sub(t))
        };
        let mut local_expanded = 0u64;
        self.nodes.push(Node {
            cell: query.start,
            g: 0,
            conflicts: 0,
            parent: u32::MAX,
            closed: false,
        });
        self.index.insert((query.start, 0), 0);
        self.open.push(Reverse((heuristic(query.start, 0), 0, Reverse(0), 0)));
        while let Some(Reverse((_, conflicts, Reverse(g), idx))) = self.open.pop() {
            let node = self.nodes[idx as usize];
            if node.closed || node.g != g || node.conflicts != conflicts {
                continue;
            }
            self.nodes[idx as usize].closed = true;
            if node.cell == query.goal && g >= earliest_finish {
                return LowResult::Found(self.extract(idx));
            }
            local_expanded += 1;
            *expanded += 1;
            if local_expanded.is_multiple_of(CLOCK_EVERY) {
                if clock.timed_out() {
                    return LowResult::Timeout;
                }
                if query.node_limit.is_some_and(|limit| local_expanded > limit) {
                    return LowResult::NodeLimit;
                }
            }
            let t = g + 1;
            if t > max_time {
                continue;
            }
            let layer = t.min(collapse);
            let (succ, n_succ) = Self::successors(grid, node.cell);
            for &next in &succ[..n_succ] {
                if next == node.cell && g >= collapse {
                    continue; // waiting in the static layer never helps
                }
                if !cons.allows(node.cell, next, t) {
                    continue;
                }
                let d = query.dist[next as usize];
                if d == DistanceMap::UNREACHABLE || t + d > max_time {
                    continue;
                }
                let c = conflicts + query.cat.map_or(0, |cat| cat.count(node.cell, next, t));
                let key = (next, layer);
                let child = Node { cell: next, g: t, conflicts: c, parent: idx, closed: false };
                let child_idx = match self.index.get(&key) {
                    Some(&old) => {
                        let o = &mut self.nodes[old as usize];
                        if o.closed || (o.g, o.conflicts) <= (t, c) {
                            continue;
                        }
                        *o = child;
                        old
                    }
                    None => {
                        let new = self.nodes.len() as u32;
                        self.nodes.push(child);
                        self.index.insert(key, new);
                        new
                    }
                };
                self.open.push(Reverse((t + heuristic(next, t), c, Reverse(t), child_idx)));
            }
        }
        LowResult::Infeasible
    }

    fn extract(&self, mut idx: u32) -> Vec<u32> {
        let mut res = Vec::with_capacity(self.nodes[idx as usize].g as usize + 1);
        while idx != u32::MAX {
            let node = self.nodes[idx as usize];
            res.push(node.cell);
            idx = node.parent;
        }
        res.reverse();
        res
    }
}

/// A multi-valued decision diagram (Sharon et al. 2013): for each time `t <= cost`, the cells
/// an agent may occupy at `t` on some path of exactly `cost` that satisfies its constraints.
#[derive(Debug, Clone)]
pub(crate) struct Mdd {
    /// `layers[t]`: sorted cell ids.
    pub(crate) layers: Vec<Vec<u32>>,
}

/// Reusable per-cell marks for MDD construction and queries (flat, indexed by cell id).
#[derive(Debug, Clone)]
pub(crate) struct MddScratch {
    stamp: Vec<u32>,
    mark: u32,
}

impl MddScratch {
    /// Scratch space, allocated on first use (one `u32` per cell of the grid).
    pub(crate) fn new() -> MddScratch {
        MddScratch { stamp: Vec::new(), mark: 0 }
    }

    fn ensure(&mut self, n_cells: usize) {
        if self.stamp.len() < n_cells {
            self.stamp.resize(n_cells, 0);
        }
    }

    /// A mark no cell carries yet.
    fn fresh(&mut self) -> u32 {
        if self.mark == u32::MAX {
            self.stamp.fill(0);
            self.mark = 0;
        }
        self.mark += 1;
        self.mark
    }
}

impl Mdd {
    /// Builds the MDD of paths from `start` to `goal` arriving at exactly `cost` (and staying:
    /// `cost` must be the agent's optimal cost under `constraints`, so the goal-hold rule
    /// holds at `cost`). Returns `None` on a timeout.
    #[expect(clippy::too_many_arguments, reason = "one call site; the inputs of one query")]
    pub(crate) fn build(
        grid: &Grid,
        start: u32,
        goal: u32,
        cost: u32,
        dist: &[u32],
        constraints: &Constraints,
        clock: &BudgetClock,
        scratch: &mut MddScratch,
    ) -> Option<Mdd> {
        scratch.ensure(grid.n_cells());
        let mut layers: Vec<Vec<u32>> = Vec::with_capacity(cost as usize + 1);
        layers.push(vec![start]);
        for t in 1..=cost {
            if t % 64 == 0 && clock.timed_out() {
                return None;
            }
            let mark = scratch.fresh();
            let mut next_layer = Vec::new();
            for &cell in &layers[t as usize - 1] {
                let (succ, n) = LowLevel::successors(grid, cell);
                for &next in &succ[..n] {
                    let d = dist[next as usize];
                    if d == DistanceMap::UNREACHABLE || t + d > cost {
                        continue;
                    }
                    if scratch.stamp[next as usize] == mark || !constraints.allows(cell, next, t) {
                        continue;
                    }
                    scratch.stamp[next as usize] = mark;
                    next_layer.push(next);
                }
            }
            layers.push(next_layer);
        }
        // Backward pass: keep the cells with a successor in the next (kept) layer.
        let last = layers.len() - 1;
        layers[last].retain(|&c| c == goal);
        for t in (0..last).rev() {
            let mark = scratch.fresh();
            for &cell in &layers[t + 1] {
                scratch.stamp[cell as usize] = mark;
            }
            let step = t as u32 + 1;
            let stamp = &scratch.stamp;
            layers[t].retain(|&cell| {
                let (succ, n) = LowLevel::successors(grid, cell);
                succ[..n].iter().any(|&next| {
                    stamp[next as usize] == mark && constraints.allows(cell, next, step)
                })
            });
        }
        for layer in &mut layers {
            layer.sort_unstable();
        }
        Some(Mdd { layers })
    }

    /// Whether every path of the MDD is at `cell` at `t` (`t` past the end: at the goal).
    pub(crate) fn is_singleton(&self, cell: u32, t: u32) -> bool {
        let layer = &self.layers[(t as usize).min(self.layers.len() - 1)];
        layer.len() == 1 && layer[0] == cell
    }
}

#[cfg(test)]
mod tests;
