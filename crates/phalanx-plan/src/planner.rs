//! One entry point over every planner of the crate, and the summary the command line prints:
//! a closed [`PlannerChoice`] (config-driven, no string registry), [`run_planner`], and the
//! serde-serialisable [`SolveSummary`] (outcome, runtime, search statistics, the validator's
//! verdict and the plan metrics of docs/spec.md §3).

use phalanx_core::{Instance, Plan, PlanMetrics, validate};

use crate::joint_astar::{self, JointAStarConfig};
use crate::swarm::{self, SwarmConfig};
use crate::{Budget, PlanFailure, PlanReport};
use crate::{astar, cbs, ecbs};

/// A planner with its settings (closed, config-driven).
#[derive(Debug, Clone)]
pub enum PlannerChoice {
    /// Prioritised space-time A*.
    SpaceTimeAStar(astar::AStarConfig),
    /// Conflict-based search (sum-of-costs optimal, ignores the formation).
    Cbs(cbs::CbsConfig),
    /// Enhanced CBS (bounded suboptimal).
    Ecbs(ecbs::EcbsConfig),
    /// Joint-state A* over makespan and formation loss.
    JointAStar(JointAStarConfig),
    /// SWARM-MAPF-R.
    Swarm(SwarmConfig),
}

impl PlannerChoice {
    /// The planner's short name, as on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            PlannerChoice::SpaceTimeAStar(_) => "astar",
            PlannerChoice::Cbs(_) => "cbs",
            PlannerChoice::Ecbs(_) => "ecbs",
            PlannerChoice::JointAStar(_) => "jsa",
            PlannerChoice::Swarm(_) => "swarm",
        }
    }
}

/// Runs the chosen planner.
pub fn run_planner(instance: &Instance, choice: &PlannerChoice, budget: &Budget) -> PlanReport {
    match choice {
        PlannerChoice::SpaceTimeAStar(config) => astar::solve(instance, config, budget),
        PlannerChoice::Cbs(config) => cbs::solve(instance, config, budget),
        PlannerChoice::Ecbs(config) => ecbs::solve(instance, config, budget),
        PlannerChoice::JointAStar(config) => joint_astar::solve(instance, config, budget),
        PlannerChoice::Swarm(config) => swarm::solve(instance, config, budget),
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// A plan came back and the validator accepts it.
    Solved,
    /// A plan came back but the validator rejects it (a planner bug).
    Invalid,
    /// The planner proved that no plan exists.
    Unsolvable,
    /// An incomplete planner (prioritised A*) found no plan; the instance may still be
    /// solvable.
    Incomplete,
    /// The time limit ran out.
    Timeout,
    /// The node limit ran out.
    NodeLimit,
    /// A learned policy's rollouts all ended at the step limit (`3 × side`) short of the
    /// goals.
    StepLimit,
}

impl std::fmt::Display for Outcome {
    /// The snake-case name, as in the JSON summaries (`solved`, `step_limit`, …).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Outcome::Solved => "solved",
            Outcome::Invalid => "invalid",
            Outcome::Unsolvable => "unsolvable",
            Outcome::Incomplete => "incomplete",
            Outcome::Timeout => "timeout",
            Outcome::NodeLimit => "node_limit",
            Outcome::StepLimit => "step_limit",
        })
    }
}

impl Outcome {
    /// The outcome of a failure.
    pub fn of_failure(failure: PlanFailure) -> Outcome {
        match failure {
            PlanFailure::Unsolvable => Outcome::Unsolvable,
            PlanFailure::Incomplete => Outcome::Incomplete,
            PlanFailure::Timeout => Outcome::Timeout,
            PlanFailure::NodeLimit => Outcome::NodeLimit,
        }
    }
}

/// The metrics of a returned plan (docs/spec.md §3) as every command and the Python package
/// print them: [`PlanMetrics`] less its per-step losses.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SummaryMetrics {
    /// Every agent reaches its goal.
    pub success: bool,
    /// First step at which all agents stand on their goals.
    pub makespan: usize,
    /// Sum of costs (trailing waits at the goal not counted).
    pub sum_of_costs: usize,
    /// Table II formation loss, `Σ_t L_f / side`.
    pub formation_loss: f64,
    /// Mean per-step `L_f`.
    pub formation_loss_mean: f64,
    /// Largest per-step `L_f` (absent from records written before it was added: 0).
    #[serde(default)]
    pub formation_loss_max: f64,
}

impl SummaryMetrics {
    /// The summary of a plan's metrics.
    pub fn of(m: &PlanMetrics) -> SummaryMetrics {
        SummaryMetrics {
            success: m.success,
            makespan: m.makespan,
            sum_of_costs: m.sum_of_costs,
            formation_loss: m.formation_loss,
            formation_loss_mean: m.formation_loss_mean,
            formation_loss_max: m.formation_loss_max,
        }
    }
}

/// What `phalanx solve` prints: one run of one planner on one instance.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SolveSummary {
    /// The planner's short name.
    pub planner: String,
    /// How the run ended.
    pub outcome: Outcome,
    /// Wall-clock seconds of the run.
    pub runtime_s: f64,
    /// High-level nodes expanded (planner-specific, see each planner's docs).
    pub high_level_expanded: u64,
    /// Low-level nodes expanded.
    pub low_level_expanded: u64,
    /// The validator's first violation, when a plan came back and is invalid.
    pub violation: Option<String>,
    /// The plan's metrics, when a plan came back.
    pub metrics: Option<SummaryMetrics>,
    /// For a learned policy, the agent decisions of every rollout.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decisions: Option<u64>,
    /// For a learned policy that did not reach the goals, how its best rollout ended:
    /// `standing` or `oscillating` (`phalanx_core::Stall`); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stall: Option<String>,
}

impl SolveSummary {
    /// Validates the report's plan and computes its metrics.
    pub fn new(instance: &Instance, choice: &PlannerChoice, report: &PlanReport) -> SolveSummary {
        let result = report.result.as_ref().map_err(|failure| Outcome::of_failure(*failure));
        let mut summary = SolveSummary::of(instance, choice.name(), result, report.stats.runtime_s);
        summary.high_level_expanded = report.stats.high_level_expanded;
        summary.low_level_expanded = report.stats.low_level_expanded;
        summary
    }

    /// The summary of a run of `planner` that returned `result` (a plan, or the outcome of
    /// its failure) in `runtime_s` seconds: the plan validated and measured; no search
    /// statistics.
    pub fn of(
        instance: &Instance,
        planner: &str,
        result: Result<&Plan, Outcome>,
        runtime_s: f64,
    ) -> SolveSummary {
        let (outcome, violation, metrics) = match result {
            Ok(plan) => {
                let violation = validate(instance, plan).err().map(|v| v.to_string());
                let metrics = SummaryMetrics::of(&PlanMetrics::of(instance, plan));
                let outcome = if violation.is_some() { Outcome::Invalid } else { Outcome::Solved };
                (outcome, violation, Some(metrics))
            }
            Err(outcome) => (outcome, None, None),
        };
        SolveSummary {
            planner: planner.to_owned(),
            outcome,
            runtime_s,
            high_level_expanded: 0,
            low_level_expanded: 0,
            violation,
            metrics,
            decisions: None,
            stall: None,
        }
    }

    /// One `key: value` line per field, in a fixed order (what `phalanx solve` prints).
    pub fn to_text(&self) -> String {
        let mut lines = vec![
            format!("planner: {}", self.planner),
            format!("outcome: {}", self.outcome),
            format!("runtime_s: {:.6}", self.runtime_s),
            format!("high_level_expanded: {}", self.high_level_expanded),
            format!("low_level_expanded: {}", self.low_level_expanded),
        ];
        if let Some(decisions) = self.decisions {
            lines.push(format!("decisions: {decisions}"));
        }
        if let Some(stall) = &self.stall {
            lines.push(format!("stall: {stall}"));
        }
        if let Some(violation) = &self.violation {
            lines.push(format!("violation: {violation}"));
        }
        if let Some(m) = &self.metrics {
            lines.push(format!("success: {}", m.success));
            lines.push(format!("makespan: {}", m.makespan));
            lines.push(format!("sum_of_costs: {}", m.sum_of_costs));
            lines.push(format!("formation_loss: {:.6}", m.formation_loss));
            lines.push(format!("formation_loss_mean: {:.6}", m.formation_loss_mean));
        }
        lines.join("\n")
    }
}

#[cfg(test)]
mod tests {
    use phalanx_core::{Cell, Grid, Instance};

    use super::*;

    #[test]
    fn every_planner_is_summarised() {
        let c = Cell::new;
        let inst =
            Instance::new(Grid::new(6, 6), vec![c(0, 0), c(1, 0)], vec![c(4, 5), c(5, 5)]).unwrap();
        let choices = [
            PlannerChoice::SpaceTimeAStar(astar::AStarConfig::default()),
            PlannerChoice::Cbs(cbs::CbsConfig::default()),
            PlannerChoice::Ecbs(ecbs::EcbsConfig::default()),
            PlannerChoice::JointAStar(JointAStarConfig::default()),
            PlannerChoice::Swarm(SwarmConfig::default()),
        ];
        for choice in &choices {
            let report = run_planner(&inst, choice, &Budget::seconds(10.0));
            let summary = SolveSummary::new(&inst, choice, &report);
            assert_eq!(summary.outcome, Outcome::Solved, "{}", choice.name());
            let metrics = summary.metrics.as_ref().unwrap();
            assert!(metrics.success);
            assert_eq!(metrics.makespan, 9, "{}", choice.name());
            assert!(summary.to_text().contains("outcome: solved"));
        }
        let swap =
            Instance::new(Grid::new(2, 1), vec![c(0, 0), c(1, 0)], vec![c(1, 0), c(0, 0)]).unwrap();
        let choice = PlannerChoice::JointAStar(JointAStarConfig::default());
        let report = run_planner(&swap, &choice, &Budget::seconds(10.0));
        let summary = SolveSummary::new(&swap, &choice, &report);
        assert_eq!((summary.outcome, summary.metrics), (Outcome::Unsolvable, None));
    }
}
