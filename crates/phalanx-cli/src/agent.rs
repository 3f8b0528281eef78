//! `phalanx agent`: one agent of a decentralised run as a process of its own
//! (docs/runtime.md). It loads its policy (the inference part only: the path-finding policy,
//! or the hierarchy's meta policy and both low-level policies), joins the world over Zenoh,
//! and each step waits for its observation and the actions of the agents ranked before it,
//! decides and publishes its action (an agent of the hierarchy first its choice, once the
//! agents before it in the meta order chose); nothing else leaves it. It ends with the
//! episode (exit 0), or when the world is gone or silent (exit 6).

use std::process::ExitCode;

use anyhow::Context as _;
use phalanx_runtime::RunError;
use phalanx_zenoh::{
    DEFAULT_AGENT_ENDPOINT, DEFAULT_PREFIX, DEFAULT_WORLD_ENDPOINT, Endpoints, Role, ZenohTransport,
};

use crate::run::TeamArgs;
use crate::util;

/// Arguments of `phalanx agent`.
#[derive(Debug, clap::Args)]
pub(crate) struct AgentCmd {
    /// This agent's index in the instance (0-based).
    #[arg(long)]
    id: u16,
    #[command(flatten)]
    team: TeamArgs,
    /// The world's Zenoh endpoint.
    #[arg(long, default_value = DEFAULT_WORLD_ENDPOINT, value_name = "ENDPOINT", value_parser = util::connect_endpoint)]
    connect: String,
    /// The Zenoh endpoint this agent listens on, for the other agents to connect to.
    #[arg(long, default_value = DEFAULT_AGENT_ENDPOINT, value_name = "ENDPOINT", value_parser = util::listen_endpoint)]
    listen: String,
    /// The run's key prefix (as the world's).
    #[arg(long, default_value = DEFAULT_PREFIX)]
    prefix: String,
    /// How long to wait for the world and the other agents to join, seconds.
    #[arg(long, default_value_t = 60.0, value_parser = util::seconds, value_name = "S")]
    join_timeout: f64,
    /// How long the world may be silent before the agent gives up, seconds.
    #[arg(long, default_value_t = 30.0, value_parser = util::seconds, value_name = "S")]
    silence: f64,
}

/// Runs `phalanx agent`.
pub(crate) fn run(cmd: AgentCmd) -> anyhow::Result<ExitCode> {
    let team =
        cmd.team.load(usize::from(cmd.id) + 1).with_context(|| format!("agent {}", cmd.id))?;
    let mut endpoints = Endpoints::agent(&cmd.listen, &cmd.connect);
    endpoints.prefix = cmd.prefix.clone();
    let mut transport = ZenohTransport::open(Role::Agent(cmd.id), &endpoints)
        .with_context(|| format!("agent {}: opening its endpoint", cmd.id))?;
    let n = transport.wait_ready(util::duration(cmd.join_timeout)).map_err(|err| match err {
        // A bad --id is bad input, not a peer gone.
        err @ phalanx_zenoh::NetError::NotInTeam { .. } => anyhow::Error::new(err),
        err => util::PeerGone(err.to_string()).into(),
    })?;
    anyhow::ensure!(
        cmd.id < n,
        "agent {}: the world's team has {n} agents (ids 0 to {})",
        cmd.id,
        n - 1
    );
    let silence = util::duration(cmd.silence);
    match team
        .run_agent(cmd.id, &mut transport, silence)
        .with_context(|| format!("agent {}", cmd.id))?
    {
        Ok(end) => {
            util::print(&format!(
                "agent {}: episode {} ended after {} steps ({:?})\n",
                cmd.id, end.episode, end.steps, end.reason
            ))?;
            Ok(ExitCode::SUCCESS)
        }
        Err(err @ (RunError::WorldGone | RunError::WorldSilent(_))) => {
            Err(util::PeerGone(format!("agent {}: {err}", cmd.id)).into())
        }
        Err(err) => Err(err).with_context(|| format!("agent {}", cmd.id)),
    }
}
