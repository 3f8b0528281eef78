//! `phalanx solve`: plans an instance with one of the classical planners of `phalanx-plan`,
//! writes the plan in the libMultiRobotPlanning format and prints the outcome, the runtime and
//! the validator's metrics (text, or JSON with `--json`).
//!
//! Exit codes: 0 a valid plan came back, 1 no plan (unsolvable, timeout, node limit) or an
//! invalid one; bad input is an error (`main` maps it to 2).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use phalanx_io::PlanStats;
use phalanx_plan::joint_astar::{JointAStarConfig, Objective};
use phalanx_plan::planner::Outcome;
use phalanx_plan::swarm::SwarmConfig;
use phalanx_plan::{Budget, PlannerChoice, SolveSummary, astar, cbs, ecbs, run_planner};

use crate::util;

/// The planners `phalanx solve` offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum PlannerName {
    /// Prioritised space-time A*: agents planned one after another.
    Astar,
    /// Conflict-based search (sum-of-costs optimal).
    Cbs,
    /// Enhanced CBS with suboptimality bound `--weight` (default 1.2).
    Ecbs,
    /// Joint-state A* minimising `makespan + w · Σ L_f` (`--weight`, default 1).
    Jsa,
    /// SWARM-MAPF-R (leader path, rigid translation, local MAPF).
    Swarm,
}

/// Plans an instance and reports the plan's metrics.
#[derive(Debug, clap::Args)]
pub(crate) struct SolveCmd {
    /// The instance: libMultiRobotPlanning `.yaml` or MovingAI `.scen`.
    instance: PathBuf,
    /// Use only the first N agents of the instance file.
    #[arg(long)]
    agents: Option<usize>,
    /// The planner.
    #[arg(long, value_enum, default_value = "cbs")]
    planner: PlannerName,
    /// The weight: jsa's formation-loss weight `w`, ecbs's suboptimality bound.
    #[arg(long)]
    weight: Option<f64>,
    /// Wall-clock limit in seconds.
    #[arg(long, default_value_t = 300.0)]
    time_limit: f64,
    /// Where to write the plan (libMultiRobotPlanning YAML).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(cmd: SolveCmd) -> anyhow::Result<ExitCode> {
    if !(cmd.time_limit.is_finite() && cmd.time_limit > 0.0) {
        anyhow::bail!("--time-limit must be a positive number of seconds, not {}", cmd.time_limit);
    }
    let named = util::read_instance(&cmd.instance, cmd.agents)?;
    let instance = &named.instance;
    let choice = match cmd.planner {
        PlannerName::Astar => PlannerChoice::SpaceTimeAStar(astar::AStarConfig::default()),
        PlannerName::Cbs => PlannerChoice::Cbs(cbs::CbsConfig::default()),
        PlannerName::Ecbs => PlannerChoice::Ecbs(ecbs::EcbsConfig { w: cmd.weight.unwrap_or(1.2) }),
        PlannerName::Jsa => PlannerChoice::JointAStar(JointAStarConfig::with_objective(
            Objective::Weighted(cmd.weight.unwrap_or(1.0)),
        )),
        PlannerName::Swarm => PlannerChoice::Swarm(SwarmConfig::default()),
    };
    let budget =
        Budget { time_limit: Some(Duration::from_secs_f64(cmd.time_limit)), node_limit: None };
    let report = run_planner(instance, &choice, &budget);
    let summary = SolveSummary::new(instance, &choice, &report);
    if let (Some(path), Ok(plan)) = (&cmd.output, &report.result) {
        let stats = PlanStats {
            high_level_expanded: report.stats.high_level_expanded,
            low_level_expanded: report.stats.low_level_expanded,
            ..PlanStats::of(plan, report.stats.runtime_s)
        };
        phalanx_io::write_plan_named(path, plan, &named.names, &stats)
            .with_context(|| format!("writing plan {}", path.display()))?;
    }
    if cmd.json {
        util::print_json(&serde_json::to_value(&summary)?)?;
    } else {
        util::print(&format!("{}\n", summary.to_text()))?;
    }
    Ok(if summary.outcome == Outcome::Solved { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
