//! Conflicts between agents' paths, and the conflict-avoidance table that steers a
//! low-level search away from them.

use std::rc::Rc;

use phalanx_core::{AgentId, CellId};
use rustc_hash::FxHashMap;

use super::{Constraint, Path, at, path_cost};

/// Kinds of conflicts between two agents' paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum ConflictKind {
    /// Both at `cell` at `t`.
    Vertex {
        /// The shared cell.
        cell: CellId,
    },
    /// `a1` moves `from -> to` arriving at `t` while `a2` moves `to -> from`.
    Edge {
        /// Where `a1`'s move starts.
        from: CellId,
        /// Where it ends.
        to: CellId,
    },
}

/// A conflict of agents `a1 < a2` at time `t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Conflict {
    /// The first agent.
    pub(crate) a1: AgentId,
    /// The second agent.
    pub(crate) a2: AgentId,
    /// When (the arrival time of the moves).
    pub(crate) t: u32,
    /// Where.
    pub(crate) kind: ConflictKind,
}

impl Conflict {
    /// The order "earliest first": time, then the agent pair, then the kind.
    pub(crate) fn earliest_key(&self) -> (u32, AgentId, AgentId, ConflictKind) {
        (self.t, self.a1, self.a2, self.kind)
    }

    /// The earliest of `conflicts`.
    pub(crate) fn earliest(conflicts: &[Conflict]) -> Option<Conflict> {
        conflicts.iter().min_by_key(|c| c.earliest_key()).copied()
    }

    /// The standard split (Sharon et al. 2015): each agent in turn is forbidden its part of
    /// the conflict.
    pub(crate) fn split(&self) -> [(AgentId, Constraint); 2] {
        let t = self.t;
        match self.kind {
            ConflictKind::Vertex { cell } => [
                (self.a1, Constraint::Vertex { cell, t }),
                (self.a2, Constraint::Vertex { cell, t }),
            ],
            ConflictKind::Edge { from, to } => [
                (self.a1, Constraint::Edge { from, to, t }),
                (self.a2, Constraint::Edge { from: to, to: from, t }),
            ],
        }
    }
}

/// Every conflict between every pair of paths: pairs in order, each pair's in time order (a
/// vertex conflict hides a swap at the same time).
pub(crate) fn conflicts(paths: &[Rc<Path>]) -> Vec<Conflict> {
    let mut res = Vec::new();
    for i in 0..paths.len() {
        for j in i + 1..paths.len() {
            let (a1, a2) = (AgentId(i as u16), AgentId(j as u16));
            let (p1, p2) = (&paths[i], &paths[j]);
            for t in 1..p1.len().max(p2.len()) as u32 {
                let (u1, v1) = (at(p1, t - 1), at(p1, t));
                let (u2, v2) = (at(p2, t - 1), at(p2, t));
                if v1 == v2 {
                    res.push(Conflict { a1, a2, t, kind: ConflictKind::Vertex { cell: v1 } });
                } else if u1 == v2 && u2 == v1 {
                    res.push(Conflict { a1, a2, t, kind: ConflictKind::Edge { from: u1, to: v1 } });
                }
            }
        }
    }
    res
}

/// Conflict-avoidance table: the other agents' paths, to break ties towards fewer conflicts.
#[derive(Debug, Clone, Default)]
pub(crate) struct ConflictTable {
    vertex: FxHashMap<(CellId, u32), u16>,
    edge: FxHashMap<(CellId, CellId, u32), u16>,
    parked: FxHashMap<CellId, u32>,
    /// The latest arrival of a path in the table: the table is static afterwards.
    pub(crate) horizon: u32,
}

impl ConflictTable {
    /// The table of the paths of every agent but `agent` (agents not planned yet have
    /// empty paths and are left out).
    pub(crate) fn of_others(paths: &[Rc<Path>], agent: AgentId) -> ConflictTable {
        let mut res = ConflictTable::default();
        for (a, path) in paths.iter().enumerate() {
            if a != agent.index() && !path.is_empty() {
                res.add(path);
            }
        }
        res
    }

    fn add(&mut self, path: &[CellId]) {
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
    pub(crate) fn count(&self, from: CellId, to: CellId, t: u32) -> u32 {
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
