//! Constraints on one agent's path: forbidden cells at times, forbidden moves, cells
//! forbidden from a time on, and the earliest time it may finish.

use phalanx_core::CellId;
use rustc_hash::{FxHashMap, FxHashSet};

use super::path_cost;

/// One constraint, as a constraint-tree node adds it to an agent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Constraint {
    /// Not at `cell` at `t`.
    Vertex {
        /// The cell.
        cell: CellId,
        /// The time.
        t: u32,
    },
    /// Not the move `from -> to` arriving at `t`.
    Edge {
        /// Where the move starts.
        from: CellId,
        /// Where it ends.
        to: CellId,
        /// The arrival time.
        t: u32,
    },
    /// Not at `cell` at `t` or later (target reasoning).
    BlockedFrom {
        /// The cell.
        cell: CellId,
        /// The first forbidden time.
        t: u32,
    },
    /// Arrival at the goal for good at `t` or later (target reasoning).
    FinishNotBefore {
        /// The earliest finishing time.
        t: u32,
    },
}

/// The constraints of one agent.
#[derive(Debug, Clone, Default)]
pub(crate) struct Constraints {
    /// Forbidden `(cell, t)` pairs.
    vertex: FxHashSet<(CellId, u32)>,
    /// Forbidden moves `(from, to, t)`, arriving at `t`.
    edge: FxHashSet<(CellId, CellId, u32)>,
    /// Cells forbidden from a time on (agents parked at their goals in prioritised planning).
    blocked_from: FxHashMap<CellId, u32>,
    /// The latest time of any constraint (the problem is static afterwards).
    latest: u32,
    /// The agent may finish (arrive at its goal for good) only at this time or later
    /// (target reasoning: "the path is longer than `t`").
    min_finish: u32,
}

impl Constraints {
    /// The constraints `constraints` together.
    pub(crate) fn of<'c>(constraints: impl IntoIterator<Item = &'c Constraint>) -> Constraints {
        let mut res = Constraints::default();
        for &c in constraints {
            res.add(c);
        }
        res
    }

    /// Adds `constraint`.
    pub(crate) fn add(&mut self, constraint: Constraint) {
        match constraint {
            Constraint::Vertex { cell, t } => {
                self.vertex.insert((cell, t));
                self.latest = self.latest.max(t);
            }
            Constraint::Edge { from, to, t } => {
                self.edge.insert((from, to, t));
                self.latest = self.latest.max(t);
            }
            Constraint::BlockedFrom { cell, t } => {
                let since = self.blocked_from.entry(cell).or_insert(t);
                *since = (*since).min(t);
                self.latest = self.latest.max(t);
            }
            Constraint::FinishNotBefore { t } => {
                self.min_finish = self.min_finish.max(t);
                self.latest = self.latest.max(t);
            }
        }
    }

    /// The latest time of any constraint: from the next one on, the problem is static.
    pub(crate) fn latest(&self) -> u32 {
        self.latest
    }

    /// The earliest time the agent may finish at `goal`: after every vertex constraint on
    /// the goal (goal hold) and not before its finishing constraint.
    pub(crate) fn earliest_finish(&self, goal: CellId) -> u32 {
        self.goal_latest(goal).map_or(0, |t| t + 1).max(self.min_finish)
    }

    /// Reserves `path` of another agent: its cells, its moves (no swaps) and its goal for
    /// good from its arrival on (prioritised planning).
    pub(crate) fn reserve_path(&mut self, path: &[CellId]) {
        for (t, &cell) in path.iter().enumerate() {
            self.add(Constraint::Vertex { cell, t: t as u32 });
            if t > 0 {
                self.add(Constraint::Edge { from: cell, to: path[t - 1], t: t as u32 });
            }
        }
        let arrival = path_cost(path);
        self.blocked_from.insert(path[path.len() - 1], arrival);
        self.latest = self.latest.max(arrival);
    }

    /// The latest time the goal `goal` is forbidden at (`None` when never): the agent may
    /// finish only later.
    fn goal_latest(&self, goal: CellId) -> Option<u32> {
        let mut res = None;
        for &(cell, t) in &self.vertex {
            if cell == goal && res.is_none_or(|r| t > r) {
                res = Some(t);
            }
        }
        res
    }

    /// Whether the move `from -> to` arriving at `t` (a wait when `from == to`) is allowed.
    #[inline]
    pub(crate) fn allows(&self, from: CellId, to: CellId, t: u32) -> bool {
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
