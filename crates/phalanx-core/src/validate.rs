//! The one plan validator: the oracle for every planner and for the environment's replays.

use std::fmt;

use crate::{Cell, Instance, Plan};

/// The first rule a plan breaks, with where it breaks it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Violation {
    /// The time step (`0` is the start).
    pub step: usize,
    /// The agent (0-based), when the violation is about one.
    pub agent: Option<usize>,
    /// What is wrong.
    pub kind: ViolationKind,
}

/// The rules of a valid plan (docs/spec.md §1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ViolationKind {
    /// The plan is for another number of agents.
    AgentCount {
        /// Agents in the instance.
        expected: usize,
        /// Agents in the plan.
        found: usize,
    },
    /// The plan has no steps.
    Empty,
    /// An agent does not begin at its start.
    WrongStart {
        /// The instance's start.
        expected: Cell,
        /// The plan's first cell.
        found: Cell,
    },
    /// An agent is outside the grid.
    OutOfBounds {
        /// The cell.
        cell: Cell,
    },
    /// An agent is on an obstacle.
    Obstacle {
        /// The cell.
        cell: Cell,
    },
    /// An agent moves by more than one cell in one step.
    Jump {
        /// Cell at `step - 1`.
        from: Cell,
        /// Cell at `step`.
        to: Cell,
    },
    /// Two agents in one cell.
    VertexConflict {
        /// The other (lower-indexed) agent.
        other: usize,
        /// The shared cell.
        cell: Cell,
    },
    /// Two agents exchange cells.
    SwapConflict {
        /// The other (lower-indexed) agent.
        other: usize,
        /// This agent's cell at `step - 1`.
        from: Cell,
        /// This agent's cell at `step`.
        to: Cell,
    },
    /// An agent is not on its goal at the end of the plan.
    GoalNotReached {
        /// Its final cell.
        cell: Cell,
        /// Its goal.
        goal: Cell,
    },
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.agent {
            Some(agent) => write!(f, "step {}, agent {agent}: ", self.step)?,
            None => write!(f, "step {}: ", self.step)?,
        }
        match self.kind {
            ViolationKind::AgentCount { expected, found } => {
                write!(f, "the plan has {found} agents but the instance has {expected}")
            }
            ViolationKind::Empty => write!(f, "the plan has no steps"),
            ViolationKind::WrongStart { expected, found } => {
                write!(f, "starts at {found} instead of its start {expected}")
            }
            ViolationKind::OutOfBounds { cell } => write!(f, "{cell} is outside the map"),
            ViolationKind::Obstacle { cell } => write!(f, "{cell} is an obstacle"),
            ViolationKind::Jump { from, to } => write!(f, "jumps from {from} to {to}"),
            ViolationKind::VertexConflict { other, cell } => {
                write!(f, "vertex conflict with agent {other} at {cell}")
            }
            ViolationKind::SwapConflict { other, from, to } => {
                write!(f, "swap conflict with agent {other} moving {from} -> {to}")
            }
            ViolationKind::GoalNotReached { cell, goal } => {
                write!(f, "ends at {cell}, not on its goal {goal}")
            }
        }
    }
}

impl std::error::Error for Violation {}

/// Checks `plan` against `instance` and names the first violation: agent count, then step
/// by step (starts at step 0; then per step: bounds, obstacles, jumps for each agent in
/// index order, then vertex and swap conflicts by agent pair), then the goals at the end.
/// Following (entering a cell another agent leaves in the same step) is allowed.
pub fn validate(instance: &Instance, plan: &Plan) -> Result<(), Violation> {
    let violation = |step, agent, kind| Err(Violation { step, agent, kind });
    if plan.n_agents() != instance.n_agents() {
        let kind =
            ViolationKind::AgentCount { expected: instance.n_agents(), found: plan.n_agents() };
        return violation(0, None, kind);
    }
    if plan.is_empty() {
        return violation(0, None, ViolationKind::Empty);
    }
    let grid = instance.grid();
    for (agent, (&found, &expected)) in plan.at(0).iter().zip(instance.starts()).enumerate() {
        if found != expected {
            return violation(0, Some(agent), ViolationKind::WrongStart { expected, found });
        }
    }
    let mut order: Vec<(Cell, usize)> = Vec::new();
    for t in 1..plan.n_steps() {
        let (prev, cur) = (plan.at(t - 1), plan.at(t));
        for (agent, (&from, &to)) in prev.iter().zip(cur).enumerate() {
            if !grid.in_bounds(to) {
                return violation(t, Some(agent), ViolationKind::OutOfBounds { cell: to });
            }
            if grid.is_blocked(to) {
                return violation(t, Some(agent), ViolationKind::Obstacle { cell: to });
            }
            if from.manhattan(to) > 1 {
                return violation(t, Some(agent), ViolationKind::Jump { from, to });
            }
        }
        if let Some((other, agent)) = first_vertex_conflict(cur, &mut order) {
            return violation(
                t,
                Some(agent),
                ViolationKind::VertexConflict { other, cell: cur[agent] },
            );
        }
        for agent in 0..cur.len() {
            let (from, to) = (prev[agent], cur[agent]);
            if from == to {
                continue;
            }
            // A swap partner stood at `to` and now stands at `from`.
            if let Some(other) = (0..agent).find(|&o| prev[o] == to && cur[o] == from) {
                return violation(t, Some(agent), ViolationKind::SwapConflict { other, from, to });
            }
        }
    }
    let last = plan.horizon();
    for (agent, (&cell, &goal)) in plan.at(last).iter().zip(instance.goals()).enumerate() {
        if cell != goal {
            return violation(last, Some(agent), ViolationKind::GoalNotReached { cell, goal });
        }
    }
    Ok(())
}

/// The vertex conflict `(lower agent, higher agent)` with the smallest higher agent, if any.
fn first_vertex_conflict(cur: &[Cell], order: &mut Vec<(Cell, usize)>) -> Option<(usize, usize)> {
    if cur.len() <= 32 {
        return (1..cur.len()).find_map(|j| (0..j).find(|&i| cur[i] == cur[j]).map(|i| (i, j)));
    }
    order.clear();
    order.extend(cur.iter().copied().zip(0..));
    order.sort_unstable();
    order.windows(2).filter(|w| w[0].0 == w[1].0).map(|w| (w[0].1, w[1].1)).min_by_key(|&(_, j)| j)
}

#[cfg(test)]
mod tests;
