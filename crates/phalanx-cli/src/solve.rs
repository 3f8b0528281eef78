//! `phalanx solve`: plans an instance with one of the classical planners of `phalanx-plan` or
//! a learned policy (`hrl`, the hierarchy; `pathfinding`, the path-finding policy alone;
//! `imitation`, the student of the centralised expert),
//! writes the plan in the libMultiRobotPlanning format and prints the outcome, the runtime and
//! the validator's metrics (text, or JSON with `--json`).
//!
//! A learned policy plays the instance `--rollouts` times (the first greedy, the others with
//! random actions at `--random-prob`) and keeps the best rollout (solved first, then the
//! shortest, then the lowest formation loss); `runtime_s` covers the distance maps and every
//! rollout. When no rollout reaches the goals within `3 × side` steps the outcome is
//! `step_limit` and no plan is written.
//!
//! Exit codes: 0 a valid plan came back, 1 no plan (unsolvable, timeout, node limit, step
//! limit) or an invalid one, 4 an incomplete planner (prioritised A*) found none, which
//! proves nothing; bad input is an error (`main` maps it to 2).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use phalanx_eval::{Method, Settings, Solver};
use phalanx_io::PlanStats;
use phalanx_plan::joint_astar::{JointAStarConfig, Objective};
use phalanx_plan::planner::Outcome;
use phalanx_plan::swarm::SwarmConfig;
use phalanx_plan::{Budget, PlannerChoice, SolveSummary, astar, cbs, ecbs, run_planner};

use phalanx_rl::models;

use crate::{meta, render, util};

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
    /// The learned hierarchy: the meta policy over the path-finding and formation policies.
    Hrl,
    /// The learned path-finding policy alone.
    #[value(name = "pathfinding")]
    PathFinding,
    /// The learned low level under the scripted leader–follower meta rule (--wait-above,
    /// --patience).
    Leader,
    /// The imitation student: one decentralised policy that learned from the centralised
    /// expert (docs/imitation.md).
    Imitation,
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
    #[arg(long, value_parser = util::non_negative)]
    weight: Option<f64>,
    /// Wall-clock limit in seconds (classical planners).
    #[arg(long, default_value_t = 300.0, value_parser = util::seconds)]
    time_limit: f64,
    #[command(flatten)]
    rollouts: meta::RolloutArgs,
    #[command(flatten)]
    acting: meta::ActingArgs,
    /// Learned policies: the weights directory (hrl: the meta policy's; default: the
    /// shipped models/meta or models/pathfinding).
    #[arg(long, value_name = "DIR")]
    weights: Option<PathBuf>,
    #[command(flatten)]
    leader: meta::LeaderArgs,
    /// Seed of the rollouts' random actions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Where to write the plan (libMultiRobotPlanning YAML).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Learned policies: write the best rollout with -o even when it does not reach the goals
    /// (to look at a failure; such a plan breaks the validator's last rule, goal not reached).
    #[arg(long)]
    partial: bool,
    /// Draw the plan (learned policies: the best rollout, also when it stops short) to FILE:
    /// .svg or .gif animated, .png of the last step.
    #[arg(long, value_name = "FILE")]
    render: Option<PathBuf>,
    #[command(flatten)]
    picture: render::PictureArgs,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(cmd: SolveCmd) -> anyhow::Result<ExitCode> {
    if let Some(path) = &cmd.render {
        render::format_of(path)?;
    }
    anyhow::ensure!(
        cmd.weight.is_none() || matches!(cmd.planner, PlannerName::Ecbs | PlannerName::Jsa),
        "--weight is a flag of the planners ecbs (its suboptimality bound) and jsa (its \
         formation-loss weight) only, not of {}",
        planner_name(cmd.planner)
    );
    let named = util::read_instance(&cmd.instance, cmd.agents)?;
    let instance = &named.instance;
    if matches!(
        cmd.planner,
        PlannerName::Hrl | PlannerName::PathFinding | PlannerName::Leader | PlannerName::Imitation
    ) {
        return learned(&cmd, &named);
    }
    let choice = match cmd.planner {
        PlannerName::Astar => PlannerChoice::SpaceTimeAStar(astar::AStarConfig::default()),
        PlannerName::Cbs => PlannerChoice::Cbs(cbs::CbsConfig::default()),
        PlannerName::Ecbs => PlannerChoice::Ecbs(
            ecbs::EcbsConfig::new(cmd.weight.unwrap_or(1.2))
                .map_err(|err| anyhow::anyhow!("--weight: {err}"))?,
        ),
        PlannerName::Jsa => PlannerChoice::JointAStar(JointAStarConfig::with_objective(
            Objective::Weighted(cmd.weight.unwrap_or(1.0)),
        )),
        PlannerName::Swarm => PlannerChoice::Swarm(SwarmConfig::default()),
        PlannerName::Hrl
        | PlannerName::PathFinding
        | PlannerName::Leader
        | PlannerName::Imitation => {
            unreachable!("learned planners return above")
        }
    };
    let budget = Budget { time_limit: Some(util::duration(cmd.time_limit)), node_limit: None };
    let report = run_planner(instance, &choice, &budget);
    let summary = SolveSummary::new(instance, &choice, &report);
    if let (Some(path), Ok(plan)) = (&cmd.output, &report.result) {
        let stats = PlanStats {
            high_level_expanded: report.stats.high_level_expanded,
            low_level_expanded: report.stats.low_level_expanded,
            ..PlanStats::of(plan, report.stats.runtime_s)
        };
        util::written(phalanx_io::write_plan_named(path, plan, &named.names, &stats), path)?;
    }
    if let (Some(path), Ok(plan)) = (&cmd.render, &report.result) {
        let title = format!("{} {}", summary.planner, render::file_name(&cmd.instance));
        render::episode(path, instance, plan, None, &title, &cmd.picture)?;
    }
    report_summary(&summary, cmd.json)
}

/// The planner's name as `--planner` spells it.
fn planner_name(planner: PlannerName) -> String {
    use clap::ValueEnum as _;
    planner.to_possible_value().map_or_else(String::new, |v| v.get_name().to_owned())
}

/// Prints the summary; the exit code of its outcome.
fn report_summary(summary: &SolveSummary, json: bool) -> anyhow::Result<ExitCode> {
    if json {
        util::print_json(&serde_json::to_value(summary)?)?;
    } else {
        util::print(&format!("{}\n", summary.to_text()))?;
    }
    Ok(match summary.outcome {
        Outcome::Solved => ExitCode::SUCCESS,
        Outcome::Incomplete => ExitCode::from(util::EXIT_INCOMPLETE),
        _ => ExitCode::from(1),
    })
}

/// Solves with a learned policy (see the module docs).
fn learned(cmd: &SolveCmd, named: &phalanx_io::NamedInstance) -> anyhow::Result<ExitCode> {
    let instance = &named.instance;
    let hrl = cmd.planner == PlannerName::Hrl;
    let scripted = cmd.planner == PlannerName::Leader;
    let rule = cmd.leader.rule(scripted)?;
    let name = match cmd.planner {
        PlannerName::Hrl => "meta",
        PlannerName::Imitation => "imitation",
        _ => "pathfinding",
    };
    let (mut policy, header, file) = models::load_with_header(cmd.weights.as_deref(), name)?;
    cmd.acting.apply(&mut policy);
    let solver = if hrl {
        let hierarchy = models::hierarchy(policy, &header, &file, None, None)?;
        Solver::Hierarchy(Box::new(hierarchy))
    } else if scripted {
        let low = models::low_level_of(policy, None)?;
        Solver::Hierarchy(Box::new(phalanx_rl::Hierarchy::scripted(rule, low)))
    } else if cmd.planner == PlannerName::Imitation {
        Solver::EndToEnd(Box::new(policy))
    } else {
        Solver::PathFinding(Box::new(policy))
    };
    let planner = match cmd.planner {
        PlannerName::Hrl => "hrl",
        PlannerName::Leader => "leader",
        PlannerName::Imitation => "imitation",
        _ => "pathfinding",
    };
    let rollouts = cmd.rollouts.rollouts(cmd.seed, usize::MAX);
    let settings = Settings { time_limit_s: cmd.time_limit, rollouts };
    let mut method = Method::new(planner, solver);
    method.fits(instance).map_err(|why| anyhow::anyhow!("{}: {why}", cmd.instance.display()))?;
    let run = method
        .run(instance, &settings)
        .with_context(|| format!("running the {name} policy on {}", cmd.instance.display()))?;
    let summary = &run.summary;
    let solved = summary.outcome == Outcome::Solved;
    if let (Some(path), Some(plan), true) = (&cmd.output, &run.plan, solved || cmd.partial) {
        let stats = PlanStats::of(plan, summary.runtime_s);
        util::written(phalanx_io::write_plan_named(path, plan, &named.names, &stats), path)?;
    }
    if let (Some(path), Some(plan)) = (&cmd.render, &run.plan) {
        let title = format!("{planner} {}", render::file_name(&cmd.instance));
        render::episode(path, instance, plan, run.choices.as_deref(), &title, &cmd.picture)?;
    }
    report_summary(summary, cmd.json)
}
