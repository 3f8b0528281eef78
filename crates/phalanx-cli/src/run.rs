//! `phalanx run`: a decentralised run of the path-finding policy. The world and every agent
//! are threads of one process that exchange only the paper's messages (observations, actions,
//! the end) over the in-process bus of phalanx-runtime (docs/runtime.md); the trajectory is
//! scored by the one validator and printed as `phalanx solve` prints a plan. Its plan is the
//! plan of `phalanx solve --planner pathfinding --rollouts 1`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use burn::tensor::Device;
use phalanx_env::EnvConfig;
use phalanx_io::PlanStats;
use phalanx_msg::EndReason;
use phalanx_plan::SolveSummary;
use phalanx_plan::planner::Outcome;
use phalanx_rl::policy_file::load_policy_any;
use phalanx_rl::{AgentPolicy, models};
use phalanx_runtime::{Agent, World, inproc, run_agent, run_world};

use crate::util;

/// Arguments of `phalanx run`.
#[derive(Debug, clap::Args)]
pub(crate) struct RunCmd {
    /// Instance file (.yaml/.yml or .scen).
    instance: PathBuf,
    /// Agents of a .scen file: its first N (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    /// The path-finding policy's directory or file (default: the shipped one).
    #[arg(long, value_name = "DIR")]
    weights: Option<PathBuf>,
    /// How long the world waits for an action before the first agent not in waits this
    /// step, milliseconds.
    #[arg(long, default_value_t = 2000, value_name = "MS")]
    step_timeout: u64,
    /// Write the trajectory as a libMultiRobotPlanning plan (when it reaches the goals).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Print one JSON object instead of `key: value` lines.
    #[arg(long)]
    json: bool,
}

/// Runs `phalanx run`.
pub(crate) fn run(cmd: RunCmd) -> anyhow::Result<ExitCode> {
    let named = util::read_instance(&cmd.instance, cmd.agents)?;
    let instance = &named.instance;
    let file = models::weights_file(cmd.weights.as_deref(), "pathfinding")?;
    let (policy, header) =
        load_policy_any(&file, &Device::flex()).context("loading the pathfinding policy")?;
    let n = instance.n_agents();
    let slots = header.net_config.n_agents_max;
    anyhow::ensure!(
        n <= slots,
        "{}: {n} agents, the policy takes at most {slots}",
        cmd.instance.display()
    );
    anyhow::ensure!(cmd.step_timeout > 0, "--step-timeout must be positive");
    let config = EnvConfig {
        fov: header.net_config.fov as u32,
        step_limit: Some(3 * instance.grid().side()),
        ..EnvConfig::default()
    };
    let mut world = World::new(instance, config, 0)
        .with_context(|| format!("{}: the world refuses the instance", cmd.instance.display()))?;
    let (mut world_end, agent_ends) = inproc::bus(n as u16);
    let step_timeout = Duration::from_millis(cmd.step_timeout);
    let started = Instant::now();
    let end = std::thread::scope(|scope| {
        let agents: Vec<_> = agent_ends
            .into_iter()
            .enumerate()
            .map(|(id, mut end)| {
                let decider = AgentPolicy::new(policy.clone(), id);
                scope.spawn(move || -> anyhow::Result<()> {
                    let mut agent = Agent::new(id as u16, decider?);
                    run_agent(&mut agent, &mut end, 10 * step_timeout)
                        .with_context(|| format!("agent {id}"))?;
                    Ok(())
                })
            })
            .collect();
        let end = run_world(&mut world, &mut world_end, step_timeout).context("the world");
        drop(world_end);
        for agent in agents {
            agent.join().map_err(|_| anyhow::anyhow!("an agent thread panicked"))??;
        }
        end
    })?;
    let runtime_s = started.elapsed().as_secs_f64();
    let plan = world.plan();
    let result = match end.reason {
        EndReason::Done => Ok(plan),
        EndReason::StepLimit | EndReason::Stopped => Err(Outcome::StepLimit),
    };
    let summary = SolveSummary::of(instance, "pathfinding (decentralised)", result, runtime_s);
    if let (Some(path), Outcome::Solved) = (&cmd.output, summary.outcome) {
        let stats = PlanStats::of(plan, runtime_s);
        util::written(phalanx_io::write_plan_named(path, plan, &named.names, &stats), path)?;
    }
    if cmd.json {
        let mut value = serde_json::to_value(&summary)?;
        value["missed_actions"] = world.missed().into();
        value["stale_actions"] = world.stale().into();
        util::print_json(&value)?;
    } else {
        util::print(&format!(
            "{}\nmissed_actions: {}\nstale_actions: {}\n",
            summary.to_text(),
            world.missed(),
            world.stale()
        ))?;
    }
    Ok(if summary.outcome == Outcome::Solved { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
