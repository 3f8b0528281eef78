//! The one space-time search core under space-time A*, CBS and ECBS: paths of cell ids over
//! time, one type of constraints ([`Constraints`], built from [`Constraint`]s), one conflict
//! type and its detection ([`Conflict`], [`conflicts`]), one conflict-avoidance table
//! ([`ConflictTable`]), one MDD ([`Mdd`]) and one low-level search ([`LowLevel`]) generic
//! over how its open list is ordered: plain A* ([`AStarOrder`]) or focal search
//! ([`FocalOrder`]). Every search reads the [`crate::BudgetClock`] of its run.
//!
//! A path is one [`CellId`] per time step, ending on the agent's goal, where it stays: an
//! agent following `path` is at `path[min(t, len - 1)]` ([`at`]), and the path's cost is its
//! arrival time for good ([`path_cost`]), as in `phalanx_core::PlanMetrics::sum_of_costs`.

mod conflict;
mod constraints;
mod low;
mod mdd;

pub(crate) use conflict::{Conflict, ConflictKind, ConflictTable, conflicts};
pub(crate) use constraints::{Constraint, Constraints};
pub(crate) use low::{AStarOrder, FocalOrder, LowLevel, LowResult, Query, successors};
pub(crate) use mdd::{Mdd, MddQuery, MddScratch};

use phalanx_core::{AgentId, Cell, CellId, DistanceMap, Grid, Instance, Plan};

#[cfg(test)]
use std::rc::Rc;

/// One agent's path: a cell per time step, ending on its goal.
pub(crate) type Path = Vec<CellId>;

/// The cell an agent following `path` occupies at `t` (it stays at the last cell).
#[inline]
pub(crate) fn at(path: &[CellId], t: u32) -> CellId {
    path[(t as usize).min(path.len() - 1)]
}

/// Cost of a path: its arrival time at the goal for good.
#[inline]
pub(crate) fn path_cost(path: &[CellId]) -> u32 {
    path.len() as u32 - 1
}

/// Converts per-agent paths (each ending at its goal) into a padded [`Plan`].
pub(crate) fn paths_to_plan(grid: &Grid, paths: &[impl AsRef<[CellId]>]) -> Plan {
    let cells: Vec<Vec<Cell>> =
        paths.iter().map(|path| path.as_ref().iter().map(|&id| grid.cell(id)).collect()).collect();
    Plan::from_paths(&cells)
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

/// What every search needs of each agent: its start and goal cells and the BFS distances to
/// its goal (computed once, reused by every low-level search of the agent).
pub(crate) struct Agents {
    /// Start cells.
    pub(crate) starts: Vec<CellId>,
    /// Goal cells.
    pub(crate) goals: Vec<CellId>,
    /// BFS distances to each goal.
    pub(crate) dists: Vec<DistanceMap>,
    /// The bound on arrival times ([`joint_horizon_bound`]).
    pub(crate) max_time: u32,
}

impl Agents {
    /// The agents of `instance`.
    pub(crate) fn of(instance: &Instance) -> Agents {
        let grid = instance.grid();
        Agents {
            starts: instance.starts().iter().map(|&c| grid.id(c)).collect(),
            goals: instance.goals().iter().map(|&c| grid.id(c)).collect(),
            dists: instance.goals().iter().map(|&g| DistanceMap::bfs(grid, g)).collect(),
            max_time: joint_horizon_bound(instance),
        }
    }

    /// The low-level query of `agent` under `constraints` (no node limit).
    pub(crate) fn query<'a>(
        &'a self,
        agent: AgentId,
        constraints: &'a Constraints,
        cat: Option<&'a ConflictTable>,
    ) -> Query<'a> {
        let a = agent.index();
        Query {
            start: self.starts[a],
            goal: self.goals[a],
            dist: self.dists[a].as_slice(),
            constraints,
            cat,
            max_time: self.max_time,
            node_limit: None,
        }
    }
}

#[cfg(test)]
mod tests;
