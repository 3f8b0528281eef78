//! A joint plan: the positions of every agent at every step, `X_0 = starts, …, X_T`.

use crate::Cell;

/// Positions per step per agent, stored flat (`n_agents` cells per step).
///
/// **Invariant:** at least one agent and every step has exactly `n_agents` cells. A plan is
/// not checked against an instance until it goes through [`crate::validate`].
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct Plan {
    n_agents: usize,
    cells: Vec<Cell>,
}

impl Plan {
    /// An empty plan (no steps yet) for `n_agents` agents.
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn new(n_agents: usize) -> Plan {
        assert!(n_agents > 0, "a plan needs at least one agent");
        Plan { n_agents, cells: Vec::new() }
    }

    /// A plan from per-step joint positions.
    ///
    /// # Panics
    /// If there are no steps, no agents, or the steps differ in length.
    pub fn from_steps(steps: &[Vec<Cell>]) -> Plan {
        let mut res = Plan::new(steps.first().map_or(0, Vec::len));
        for step in steps {
            res.push(step);
        }
        res
    }

    /// A plan from per-agent paths of any lengths; a path that ends early is padded with its
    /// last cell (the agent waits there), as in libMultiRobotPlanning schedules.
    ///
    /// # Panics
    /// If there are no paths or a path is empty.
    pub fn from_paths(paths: &[Vec<Cell>]) -> Plan {
        assert!(paths.iter().all(|p| !p.is_empty()), "empty path");
        let n_steps = paths.iter().map(Vec::len).max().unwrap_or(0);
        let mut res = Plan::new(paths.len());
        res.cells.reserve(n_steps * paths.len());
        for t in 0..n_steps {
            res.cells.extend(paths.iter().map(|p| p[t.min(p.len() - 1)]));
        }
        res
    }

    /// Appends one joint position.
    ///
    /// # Panics
    /// If `positions` has another length than the number of agents.
    pub fn push(&mut self, positions: &[Cell]) {
        assert_eq!(positions.len(), self.n_agents, "joint position of the wrong size");
        self.cells.extend_from_slice(positions);
    }

    /// Number of agents.
    #[inline]
    pub fn n_agents(&self) -> usize {
        self.n_agents
    }

    /// Number of joint positions, `T + 1` (0 for an empty plan).
    #[inline]
    pub fn n_steps(&self) -> usize {
        self.cells.len() / self.n_agents
    }

    /// Whether the plan has no steps at all.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The last time index `T` (`n_steps - 1`), 0 for an empty plan.
    #[inline]
    pub fn horizon(&self) -> usize {
        self.n_steps().saturating_sub(1)
    }

    /// Joint position at step `t`.
    ///
    /// # Panics
    /// If `t >= n_steps()`.
    #[inline]
    pub fn at(&self, t: usize) -> &[Cell] {
        &self.cells[t * self.n_agents..(t + 1) * self.n_agents]
    }

    /// Joint positions in time order.
    pub fn steps(&self) -> impl ExactSizeIterator<Item = &[Cell]> + '_ {
        self.cells.chunks_exact(self.n_agents)
    }

    /// Agent `agent`'s path, one cell per step.
    pub fn path(&self, agent: usize) -> impl ExactSizeIterator<Item = Cell> + '_ {
        assert!(agent < self.n_agents, "agent {agent} out of range");
        self.cells.iter().skip(agent).step_by(self.n_agents).copied()
    }

    /// Agent `agent`'s path without its trailing repeats of the last cell (how
    /// libMultiRobotPlanning writes schedules). At least one cell for a non-empty plan.
    pub fn trimmed_path(&self, agent: usize) -> Vec<Cell> {
        let mut path: Vec<Cell> = self.path(agent).collect();
        while path.len() > 1 && path[path.len() - 2] == path[path.len() - 1] {
            path.pop();
        }
        path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_padded_and_trimmed() {
        let a = vec![Cell::new(0, 0), Cell::new(1, 0)];
        let b = vec![Cell::new(5, 5), Cell::new(5, 4), Cell::new(5, 3), Cell::new(5, 3)];
        let plan = Plan::from_paths(&[a.clone(), b]);
        assert_eq!(plan.n_steps(), 4);
        assert_eq!(plan.horizon(), 3);
        assert_eq!(plan.at(3), &[Cell::new(1, 0), Cell::new(5, 3)]);
        assert_eq!(plan.trimmed_path(0), a);
        assert_eq!(plan.trimmed_path(1).len(), 3);
        assert_eq!(Plan::from_steps(&plan.steps().map(<[Cell]>::to_vec).collect::<Vec<_>>()), plan);
    }
}
