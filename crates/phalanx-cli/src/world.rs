//! `phalanx world`: the world of a decentralised run as a process of its own (docs/runtime.md).
//! It owns the instance and the true state, listens on a Zenoh endpoint, waits until every
//! agent process of the team is ready, then each step publishes each agent's observation and
//! rank, collects the joint action (an agent that does not answer within the step timeout, or
//! whose process is gone, waits), steps, and at the end prints the one validator's metrics
//! and writes the trajectory as a plan. With `--policy hrl` the team is the hierarchy's: each
//! step the world collects the agents' choices of low-level policy first, then hands out the
//! formation frames (docs/runtime.md); the agents must run the same policy.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use phalanx_runtime::run_world_paced;
use phalanx_zenoh::{DEFAULT_PREFIX, DEFAULT_WORLD_ENDPOINT, Endpoints, Role, ZenohTransport};

use crate::run::{self, TeamPolicy, Vectors};
use crate::util;

/// Arguments of `phalanx world`.
#[derive(Debug, clap::Args)]
pub(crate) struct WorldCmd {
    /// Instance file (.yaml/.yml or .scen).
    instance: PathBuf,
    /// Agents of a .scen file: its first N (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    /// The Zenoh endpoint to listen on, which the agents connect to.
    #[arg(long, default_value = DEFAULT_WORLD_ENDPOINT, value_name = "ENDPOINT", value_parser = util::listen_endpoint)]
    listen: String,
    /// The run's key prefix (runs with different prefixes on one network do not mix).
    #[arg(long, default_value = DEFAULT_PREFIX)]
    prefix: String,
    /// The policy the agents run: the world serves its phases (the agents' --policy).
    #[arg(long, value_enum, default_value = "pathfinding")]
    policy: TeamPolicy,
    /// The agents' field of view (their policy's).
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_FOV)]
    fov: u32,
    /// With `--policy imitation`: what the agents' vectors hold after the goal vector, as the
    /// student's network reads them (`phalanx run` reads it off the network; docs/imitation.md).
    #[arg(long, value_enum, default_value = "team")]
    vectors: Vectors,
    /// With `--policy imitation`: the team vector's dead band in cells, the one the
    /// student acts with (`phalanx run` reads it off the policy file; the shipped student's
    /// 0.6; docs/imitation.md).
    #[arg(long, default_value_t = phalanx_env::obs::TEAM_DEADBAND, value_name = "CELLS", value_parser = util::team_deadband)]
    team_deadband: f64,
    /// How long to wait for an action before the first agent not in waits this step,
    /// milliseconds.
    #[arg(long, default_value_t = 2000, value_name = "MS")]
    step_timeout: u64,
    /// The control period: a step starts at least this long after the one before,
    /// milliseconds (0: as fast as the agents answer).
    #[arg(long, default_value_t = 0, value_name = "MS")]
    step_period: u64,
    /// How long to wait for every agent to join, seconds.
    #[arg(long, default_value_t = 60.0, value_parser = util::seconds, value_name = "S")]
    join_timeout: f64,
    /// Write the trajectory as a libMultiRobotPlanning plan (when it reaches the goals).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the trajectory with -o also when it stops short of the goals.
    #[arg(long, requires = "output")]
    partial: bool,
    /// Print one JSON object instead of `key: value` lines.
    #[arg(long)]
    json: bool,
}

/// Runs `phalanx world`.
pub(crate) fn run(cmd: WorldCmd) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(cmd.step_timeout > 0, "--step-timeout must be positive");
    let named = util::read_instance(&cmd.instance, cmd.agents)?;
    let mut world = run::world_for(
        &named,
        &cmd.instance,
        cmd.policy,
        cmd.fov,
        (cmd.vectors, cmd.team_deadband),
    )?;
    let n = u16::try_from(named.instance.n_agents()).context("too many agents")?;
    let mut endpoints = Endpoints::world(&cmd.listen);
    endpoints.prefix = cmd.prefix.clone();
    let mut transport =
        ZenohTransport::open(Role::World(n), &endpoints).context("opening the world's endpoint")?;
    transport
        .wait_ready(util::duration(cmd.join_timeout))
        .map_err(|err| util::PeerGone(err.to_string()))?;
    util::warn(&format!("world: {n} agents ready under {:?}, the episode starts", cmd.prefix));
    let started = Instant::now();
    let (timeout, period) =
        (Duration::from_millis(cmd.step_timeout), Duration::from_millis(cmd.step_period));
    let end = run_world_paced(&mut world, &mut transport, timeout, period).context("the world")?;
    let runtime_s = started.elapsed().as_secs_f64();
    // The agents leave once they hear the end; the world stays until they have (bounded), so
    // that the end reaches them before its session closes. Those that stay are not waited for.
    transport.wait_agents_left(Duration::from_secs(2));
    let output = run::PlanOut { path: cmd.output.as_deref(), partial: cmd.partial };
    run::report(&named, cmd.policy, &world, end, runtime_s, &output, cmd.json)
}
