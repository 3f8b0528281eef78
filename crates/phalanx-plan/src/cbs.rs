//! Conflict-Based Search (Sharon et al. 2015) with the ICBS improvements (Boyarski et al. 2015).

use phalanx_core::Instance;

use crate::{Budget, PlanFailure, PlanReport, SearchStats};

/// Settings of CBS; the defaults enable every improvement.
#[derive(Debug, Clone, PartialEq)]
pub struct CbsConfig {
    /// Classify conflicts as cardinal / semi-cardinal / non-cardinal with MDDs and split on
    /// the most important first (ICBS). Default `true`.
    pub prioritize_conflicts: bool,
    /// Adopt a child's paths without branching when it removes a conflict at no cost
    /// (bypassing, ICBS). Default `true`.
    pub bypass: bool,
    /// Rectangle (symmetry) reasoning with barrier constraints (Li et al. 2019). Default `true`.
    pub rectangle_reasoning: bool,
    /// Admissible high-level heuristic from the weighted pairwise dependency graph (WDG,
    /// Li et al. 2019). Default `true`.
    pub wdg_heuristic: bool,
    /// Low-level tie-breaking towards fewer conflicts with other agents' paths (conflict
    /// avoidance table). Default `true`.
    pub conflict_avoidance: bool,
}

impl Default for CbsConfig {
    fn default() -> CbsConfig {
        CbsConfig {
            prioritize_conflicts: true,
            bypass: true,
            rectangle_reasoning: true,
            wdg_heuristic: true,
            conflict_avoidance: true,
        }
    }
}

/// CBS, optimal for the sum of costs. Nodes counted against the budget: high-level nodes.
pub fn solve(instance: &Instance, config: &CbsConfig, budget: &Budget) -> PlanReport {
    let _ = (instance, config, budget);
    PlanReport::failure(PlanFailure::Unsolvable, SearchStats::default())
}
