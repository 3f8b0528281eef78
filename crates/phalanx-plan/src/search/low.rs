//! Space-time A* (Silver 2005, "Cooperative Pathfinding", AIIDE) over `(cell, t)`: the low
//! level of CBS and ECBS, and prioritised planning on top of it, with its open list ordered
//! as plain A* ([`AStarOrder`], optimal) or as focal search ([`FocalOrder`], bounded
//! suboptimal, Barer et al. 2014).
//!
//! The search honours the agent's [`Constraints`] and the goal-hold rule: an agent finishes
//! only at a time later than every constraint on its goal cell, since it stays there for
//! good. The cost of a path is its arrival time at the goal (trailing waits are free).
//!
//! Heuristic: the BFS distance to the goal (a `DistanceMap` computed once per agent and
//! reused by every search), raised to the earliest admissible finishing time. Both parts are
//! consistent, so no state is expanded twice.
//!
//! Tie-breaking, explicit and deterministic. A*: smaller `f`, then fewer conflicts with the
//! conflict-avoidance table (when one is given), then larger `g` (dive towards the goal),
//! then the earlier-generated node. Focal: among the open nodes with `f <= w · f_min`, fewer
//! conflicts, then smaller `f`, then larger `g`, then the earlier node. Successors are
//! generated in the order Wait, Up, Down, Left, Right.
//!
//! Finiteness: once `t` passes every constraint and every path in the conflict-avoidance
//! table, the problem is static; all later times share one layer ("time collapse"), so one
//! search visits at most `(horizon + 2) * cells` states and ends with `Infeasible` when the
//! constraints admit no path. A hard bound `max_time` on the arrival time is also honoured.

use std::cmp::Reverse;
use std::collections::{BTreeSet, BinaryHeap};
use std::num::NonZeroU32;

use phalanx_core::{CellId, DistanceMap, Grid};
use rustc_hash::FxHashMap;

use super::{ConflictTable, Constraints, Path};
use crate::BudgetClock;

/// One low-level query.
pub(crate) struct Query<'a> {
    /// The agent's start.
    pub(crate) start: CellId,
    /// Its goal.
    pub(crate) goal: CellId,
    /// BFS distances to `goal`, [`DistanceMap::UNREACHABLE`] where unreachable.
    pub(crate) dist: &'a [u32],
    /// Its constraints.
    pub(crate) constraints: &'a Constraints,
    /// The other agents' paths, to break ties towards fewer conflicts with.
    pub(crate) cat: Option<&'a ConflictTable>,
    /// Hard bound on the arrival time.
    pub(crate) max_time: u32,
    /// Bound on the expansions of this search.
    pub(crate) node_limit: Option<u64>,
}

/// The answer of one low-level search.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum LowResult {
    /// A path, one cell per time step, ending on the goal; `lower_bound` is a lower bound on
    /// the agent's optimal cost under its constraints (the path's cost for A*).
    Found {
        /// The path.
        path: Path,
        /// The lower bound.
        lower_bound: u32,
    },
    /// The constraints admit no path.
    Infeasible,
    /// The budget's deadline passed.
    Timeout,
    /// The query's node limit was reached.
    NodeLimit,
}

/// A search node: the state `(cell, g)` and how it was reached.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Node {
    cell: CellId,
    g: u32,
    f: u32,
    conflicts: u32,
    /// The node it was reached from, as its index plus one (`None` at the start): a node
    /// is then 24 bytes, not 28, which the searches on large maps feel.
    parent: Option<NonZeroU32>,
    closed: bool,
}

const _: () = assert!(std::mem::size_of::<Node>() == 24, "a search node stays 24 bytes");

/// How the open list is ordered: which node a search expands next.
pub(crate) trait Order {
    /// Empties the list for a new search whose start node has `f0`.
    fn reset(&mut self, f0: u32);
    /// Adds node `idx`, new or improved (then `replaced` is what it was).
    fn push(&mut self, node: &Node, idx: u32, replaced: Option<&Node>);
    /// Removes and returns the next node to expand; `None` when the list is empty.
    fn pop(&mut self, nodes: &[Node]) -> Option<u32>;
    /// After a node's successors were pushed.
    fn settle(&mut self, nodes: &[Node]);
    /// A lower bound on the optimal cost when `goal`, just popped, ends the search.
    fn lower_bound(&self, goal: &Node) -> u32;
}

/// `(f, conflicts, Reverse(g), node)`: the order of expansion of plain A*.
type AStarKey = (u32, u32, Reverse<u32>, u32);

/// Plain A*: smallest `(f, conflicts, -g, node)` first; optimal.
#[derive(Debug, Default)]
pub(crate) struct AStarOrder {
    heap: BinaryHeap<Reverse<AStarKey>>,
}

impl Order for AStarOrder {
    fn reset(&mut self, _f0: u32) {
        self.heap.clear();
    }

    fn push(&mut self, node: &Node, idx: u32, _replaced: Option<&Node>) {
        // An improved node's old entry stays; `pop` skips it as stale.
        self.heap.push(Reverse((node.f, node.conflicts, Reverse(node.g), idx)));
    }

    fn pop(&mut self, nodes: &[Node]) -> Option<u32> {
        while let Some(Reverse((_, conflicts, Reverse(g), idx))) = self.heap.pop() {
            let node = &nodes[idx as usize];
            if !node.closed && node.g == g && node.conflicts == conflicts {
                return Some(idx);
            }
        }
        None
    }

    fn settle(&mut self, _nodes: &[Node]) {}

    fn lower_bound(&self, goal: &Node) -> u32 {
        goal.f
    }
}

/// Focal search: OPEN ordered by `f`; FOCAL, the OPEN nodes with `f <= w · f_min`, by
/// conflicts, then `f`, then `-g`, then node; the next node is FOCAL's first.
#[derive(Debug)]
pub(crate) struct FocalOrder {
    w: f64,
    open: BTreeSet<(u32, Reverse<u32>, u32)>,
    focal: BTreeSet<(u32, u32, Reverse<u32>, u32)>,
    f_min: u32,
}

impl FocalOrder {
    /// Focal search with suboptimality bound `w >= 1`.
    pub(crate) fn new(w: f64) -> FocalOrder {
        FocalOrder { w, open: BTreeSet::new(), focal: BTreeSet::new(), f_min: 0 }
    }

    /// `⌊w · f⌋`, with a little slack for exact products.
    pub(crate) fn bound(f: u32, w: f64) -> u32 {
        (f64::from(f) * w + 1e-9).floor() as u32
    }
}

impl Order for FocalOrder {
    fn reset(&mut self, f0: u32) {
        self.open.clear();
        self.focal.clear();
        self.f_min = f0;
    }

    fn push(&mut self, node: &Node, idx: u32, replaced: Option<&Node>) {
        if let Some(old) = replaced {
            self.open.remove(&(old.f, Reverse(old.g), idx));
            self.focal.remove(&(old.conflicts, old.f, Reverse(old.g), idx));
        }
        self.open.insert((node.f, Reverse(node.g), idx));
        if node.f <= Self::bound(self.f_min, self.w) {
            self.focal.insert((node.conflicts, node.f, Reverse(node.g), idx));
        }
    }

    fn pop(&mut self, nodes: &[Node]) -> Option<u32> {
        let &(_, _, _, idx) = self.focal.first()?;
        let node = &nodes[idx as usize];
        self.focal.remove(&(node.conflicts, node.f, Reverse(node.g), idx));
        self.open.remove(&(node.f, Reverse(node.g), idx));
        Some(idx)
    }

    /// Raises `f_min` to OPEN's least `f` and moves the newly admitted nodes into FOCAL.
    fn settle(&mut self, nodes: &[Node]) {
        let Some(&(new_min, _, _)) = self.open.first() else { return };
        if new_min <= self.f_min {
            return;
        }
        let (old_bound, new_bound) =
            (Self::bound(self.f_min, self.w), Self::bound(new_min, self.w));
        // A bound at u32::MAX (a huge `w`) has admitted every node already.
        if let Some(first) = old_bound.checked_add(1) {
            for &(f, g, i) in self.open.range((first, Reverse(u32::MAX), 0)..) {
                if f > new_bound {
                    break;
                }
                self.focal.insert((nodes[i as usize].conflicts, f, g, i));
            }
        }
        self.f_min = new_min;
    }

    fn lower_bound(&self, goal: &Node) -> u32 {
        self.open.first().map_or(goal.f, |&(f, _, _)| f.min(goal.f)).min(self.f_min)
    }
}

/// How often (in expansions) a search reads the clock.
const CLOCK_EVERY: u64 = 1024;

/// The free 4-neighbours of `cell` followed by `cell` itself (wait first), in the fixed
/// order Wait, Up, Down, Left, Right.
#[inline]
pub(crate) fn successors(grid: &Grid, cell: CellId) -> ([CellId; 5], usize) {
    let width = grid.width();
    let (x, y) = (cell.0 % width, cell.0 / width);
    let mut res = [cell; 5];
    let mut n = 1;
    let mut push = |c: u32| {
        if !grid.is_blocked_id(CellId(c)) {
            res[n] = CellId(c);
            n += 1;
        }
    };
    if y + 1 < grid.height() {
        push(cell.0 + width);
    }
    if y > 0 {
        push(cell.0 - width);
    }
    if x > 0 {
        push(cell.0 - 1);
    }
    if x + 1 < width {
        push(cell.0 + 1);
    }
    (res, n)
}

/// Reusable space-time search on one grid (its buffers live across searches), its open list
/// ordered by `O`.
pub(crate) struct LowLevel<'g, O> {
    grid: &'g Grid,
    nodes: Vec<Node>,
    index: FxHashMap<(CellId, u32), u32>,
    order: O,
}

impl<'g, O: Order> LowLevel<'g, O> {
    /// A search on `grid` ordered by `order`.
    pub(crate) fn new(grid: &'g Grid, order: O) -> LowLevel<'g, O> {
        LowLevel { grid, nodes: Vec::new(), index: FxHashMap::default(), order }
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
        let h0 = query.dist[query.start.index()];
        if h0 == DistanceMap::UNREACHABLE {
            return LowResult::Infeasible;
        }
        let cons = query.constraints;
        // The earliest finishing time the goal-hold rule allows.
        let earliest_finish = cons.earliest_finish(query.goal);
        let max_time = query.max_time;
        if earliest_finish.max(h0) > max_time {
            return LowResult::Infeasible;
        }
        let cat_horizon = query.cat.map_or(0, |cat| cat.horizon);
        // Every time after `collapse` shares the layer `collapse`.
        let collapse = cons.latest().max(cat_horizon) + 1;
        let heuristic = |cell: CellId, t: u32| -> u32 {
            query.dist[cell.index()].max(earliest_finish.saturating_sub(t))
        };
        let f0 = heuristic(query.start, 0);
        let start =
            Node { cell: query.start, g: 0, f: f0, conflicts: 0, parent: None, closed: false };
        self.nodes.push(start);
        self.index.insert((query.start, 0), 0);
        self.order.reset(f0);
        self.order.push(&start, 0, None);
        let mut local_expanded = 0u64;
        while let Some(idx) = self.order.pop(&self.nodes) {
            let node = self.nodes[idx as usize];
            self.nodes[idx as usize].closed = true;
            if node.cell == query.goal && node.g >= earliest_finish {
                let lower_bound = self.order.lower_bound(&node);
                return LowResult::Found { path: self.extract(idx), lower_bound };
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
            let t = node.g + 1;
            if t <= max_time {
                self.expand(query, &node, idx, t, collapse, &heuristic);
            }
            self.order.settle(&self.nodes);
        }
        LowResult::Infeasible
    }

    /// Pushes the successors of `node` (index `idx`), arriving at `t`.
    fn expand(
        &mut self,
        query: &Query<'_>,
        node: &Node,
        idx: u32,
        t: u32,
        collapse: u32,
        heuristic: &impl Fn(CellId, u32) -> u32,
    ) {
        let layer = t.min(collapse);
        let (succ, n_succ) = successors(self.grid, node.cell);
        for &next in &succ[..n_succ] {
            if next == node.cell && node.g >= collapse {
                continue; // waiting in the static layer never helps
            }
            if !query.constraints.allows(node.cell, next, t) {
                continue;
            }
            let d = query.dist[next.index()];
            if d == DistanceMap::UNREACHABLE || t + d > query.max_time {
                continue;
            }
            let c = node.conflicts + query.cat.map_or(0, |cat| cat.count(node.cell, next, t));
            let f = t + heuristic(next, t);
            let child = Node {
                cell: next,
                g: t,
                f,
                conflicts: c,
                parent: NonZeroU32::new(idx + 1),
                closed: false,
            };
            let key = (next, layer);
            let (child_idx, replaced) = match self.index.get(&key) {
                Some(&old) => {
                    let o = self.nodes[old as usize];
                    if o.closed || (o.g, o.conflicts) <= (t, c) {
                        continue;
                    }
                    self.nodes[old as usize] = child;
                    (old, Some(o))
                }
                None => {
                    let new = self.nodes.len() as u32;
                    self.nodes.push(child);
                    self.index.insert(key, new);
                    (new, None)
                }
            };
            self.order.push(&child, child_idx, replaced.as_ref());
        }
    }

    fn extract(&self, idx: u32) -> Path {
        let mut res = Vec::with_capacity(self.nodes[idx as usize].g as usize + 1);
        let mut next = Some(idx);
        while let Some(i) = next {
            let node = &self.nodes[i as usize];
            res.push(node.cell);
            next = node.parent.map(|p| p.get() - 1);
        }
        res.reverse();
        res
    }
}
