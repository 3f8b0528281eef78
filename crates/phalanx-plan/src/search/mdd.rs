//! Multi-valued decision diagrams (Sharon et al. 2013): the cells an agent may occupy at each
//! time on some path of a given cost, to classify conflicts as cardinal or not.

use phalanx_core::{CellId, DistanceMap, Grid};

use super::{Constraints, successors};
use crate::BudgetClock;

/// For each time `t <= cost`, the cells an agent may occupy at `t` on some path of exactly
/// `cost` that satisfies its constraints.
#[derive(Debug, Clone)]
pub(crate) struct Mdd {
    /// `layers[t]`: sorted cell ids.
    pub(crate) layers: Vec<Vec<CellId>>,
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

/// What an MDD is built of: one agent's path ends, its optimal cost and its constraints.
pub(crate) struct MddQuery<'a> {
    /// The start.
    pub(crate) start: CellId,
    /// The goal.
    pub(crate) goal: CellId,
    /// The agent's optimal cost under `constraints` (so the goal-hold rule holds at it).
    pub(crate) cost: u32,
    /// BFS distances to `goal`.
    pub(crate) dist: &'a [u32],
    /// The agent's constraints.
    pub(crate) constraints: &'a Constraints,
}

impl Mdd {
    /// Builds the MDD of the paths of `query` arriving at exactly its cost and staying.
    /// Returns `None` on a timeout.
    pub(crate) fn build(
        grid: &Grid,
        query: &MddQuery<'_>,
        clock: &BudgetClock,
        scratch: &mut MddScratch,
    ) -> Option<Mdd> {
        let MddQuery { start, goal, cost, dist, constraints } = *query;
        scratch.ensure(grid.n_cells());
        let mut layers: Vec<Vec<CellId>> = Vec::with_capacity(cost as usize + 1);
        layers.push(vec![start]);
        for t in 1..=cost {
            if t % 64 == 0 && clock.timed_out() {
                return None;
            }
            let mark = scratch.fresh();
            let mut next_layer = Vec::new();
            for &cell in &layers[t as usize - 1] {
                let (succ, n) = successors(grid, cell);
                for &next in &succ[..n] {
                    let d = dist[next.index()];
                    if d == DistanceMap::UNREACHABLE || t + d > cost {
                        continue;
                    }
                    if scratch.stamp[next.index()] == mark || !constraints.allows(cell, next, t) {
                        continue;
                    }
                    scratch.stamp[next.index()] = mark;
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
                scratch.stamp[cell.index()] = mark;
            }
            let step = t as u32 + 1;
            let stamp = &scratch.stamp;
            layers[t].retain(|&cell| {
                let (succ, n) = successors(grid, cell);
                succ[..n].iter().any(|&next| {
                    stamp[next.index()] == mark && constraints.allows(cell, next, step)
                })
            });
        }
        for layer in &mut layers {
            layer.sort_unstable();
        }
        Some(Mdd { layers })
    }

    /// Whether every path of the MDD is at `cell` at `t` (`t` past the end: at the goal).
    pub(crate) fn is_singleton(&self, cell: CellId, t: u32) -> bool {
        let layer = &self.layers[(t as usize).min(self.layers.len() - 1)];
        layer.len() == 1 && layer[0] == cell
    }
}
