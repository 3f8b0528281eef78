//! Prioritised planning (Silver 2005, "Cooperative Pathfinding", AIIDE) on the space-time
//! A* of `crate::search`: agents plan one after another, each avoiding the paths of the
//! agents before it, who stay at their goals afterwards.

use phalanx_core::{AgentId, Instance};

use crate::search::{self, AStarOrder, Agents, Constraints, LowLevel, LowResult};
use crate::{Budget, PlanFailure, PlanReport, SearchStats};

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
/// alone) is [`PlanFailure::Unsolvable`]. For one agent it is plain optimal space-time A*.
/// Nodes counted against the budget: low-level expansions.
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
    let agents = Agents::of(instance);
    let mut low = LowLevel::new(grid, AStarOrder::default());
    let mut reserved = Constraints::default();
    let mut paths: Vec<search::Path> = vec![Vec::new(); n_agents];
    for (rank, &agent) in order.iter().enumerate() {
        let mut query = agents.query(AgentId(agent as u16), &reserved, None);
        query.node_limit = budget.node_limit.map(|it| it.saturating_sub(stats.low_level_expanded));
        let path = match low.search(&query, &clock, &mut stats.low_level_expanded) {
            LowResult::Found { path, .. } => path,
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
    PlanReport { result: Ok(search::paths_to_plan(grid, &paths)), stats }
}
