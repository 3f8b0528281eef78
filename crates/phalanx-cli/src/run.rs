//! `phalanx run`: a decentralised run of the path-finding policy, of the hierarchy
//! (`--policy hrl`) or of the imitation student (`--policy imitation`). The world and every
//! agent exchange only the paper's messages (observations, actions, the end, and for the
//! hierarchy the choices and the formation frames; docs/runtime.md): as threads of one process over the in-process bus of
//! phalanx-runtime, or with `--processes` as processes of their own (`phalanx world` and one
//! `phalanx agent` each) over Zenoh on loopback. The trajectory is scored by the one validator
//! and printed as `phalanx solve` prints a plan; either way it is the plan of `phalanx solve
//! --planner pathfinding --rollouts 1` (or `--planner hrl`, `--planner imitation`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use phalanx_env::{EnvConfig, Task};
use phalanx_io::{NamedInstance, PlanStats};
use phalanx_msg::{End, EndReason};
use phalanx_plan::SolveSummary;
use phalanx_plan::planner::Outcome;
use phalanx_rl::{AgentHierarchy, AgentPolicy, Hierarchy, Policy, models};
use phalanx_runtime::{Agent, HierAgent, Machine, World, inproc, run_agent, run_world};

use crate::util;

/// The policies a decentralised team can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TeamPolicy {
    /// The path-finding policy.
    Pathfinding,
    /// The hierarchy: the meta policy choosing each agent's low-level policy every step.
    Hrl,
    /// The imitation student: the five moves on the meta task, learned from the
    /// centralised expert.
    Imitation,
}

impl TeamPolicy {
    /// Its name on the command line.
    pub(crate) fn name(self) -> &'static str {
        match self {
            TeamPolicy::Pathfinding => "pathfinding",
            TeamPolicy::Hrl => "hrl",
            TeamPolicy::Imitation => "imitation",
        }
    }

    /// Its name under `models/`.
    fn model(self) -> &'static str {
        match self {
            TeamPolicy::Pathfinding => "pathfinding",
            TeamPolicy::Hrl => "meta",
            TeamPolicy::Imitation => "imitation",
        }
    }
}

/// What the imitation student's vector holds after its goal vector (docs/imitation.md, *The
/// exact input*): the world must write what the network reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Vectors {
    /// The goal vector alone (3 values).
    Goal,
    /// Then the vector towards the agent's place on the agent in front (6).
    Place,
    /// Then the team vector of the agent in front (9): the shipped student.
    Team,
}

impl Vectors {
    /// What an environment of `config` writes.
    fn of(config: &EnvConfig) -> Vectors {
        match (config.place_vector, config.team_vector) {
            (_, true) => Vectors::Team,
            (true, false) => Vectors::Place,
            (false, false) => Vectors::Goal,
        }
    }

    /// `config` writing these vectors.
    fn apply(self, config: EnvConfig) -> EnvConfig {
        let (place_vector, team_vector) = match self {
            Vectors::Goal => (false, false),
            Vectors::Place => (true, false),
            Vectors::Team => (true, true),
        };
        EnvConfig { place_vector, team_vector, ..config }
    }

    /// Its name on the command line (clap's, the one spelling).
    fn name(self) -> String {
        use clap::ValueEnum as _;
        self.to_possible_value().expect("every choice is named").get_name().to_owned()
    }
}

/// What an agent decides with: one flat policy (path finding or the imitation student), or
/// the hierarchy (its meta policy and both low-level policies).
#[derive(Debug, Clone)]
pub(crate) enum Team {
    /// A flat policy of the five moves.
    Flat(Box<Policy>),
    /// The hierarchy.
    Hierarchy(Box<Hierarchy>),
}

impl Team {
    /// The policy `policy` of `weights` (the meta policy's, for the hierarchy; default: the
    /// shipped one), for a team of `n` agents.
    pub(crate) fn load(
        policy: TeamPolicy,
        weights: Option<&Path>,
        n: usize,
    ) -> anyhow::Result<Team> {
        match policy {
            TeamPolicy::Pathfinding | TeamPolicy::Imitation => {
                Ok(Team::Flat(Box::new(policy_for(weights, policy.model(), n)?)))
            }
            TeamPolicy::Hrl => {
                let hierarchy = models::load_hierarchy(weights)
                    .context("loading the hierarchy (the meta policy and its low level)")?;
                let slots = hierarchy.n_agents_max();
                anyhow::ensure!(
                    n <= slots,
                    "a team of {n} agents, the hierarchy takes at most {slots}"
                );
                Ok(Team::Hierarchy(Box::new(hierarchy)))
            }
        }
    }

    /// The field of view its policies read.
    pub(crate) fn fov(&self) -> u32 {
        match self {
            Team::Flat(policy) => policy.config().fov as u32,
            Team::Hierarchy(hierarchy) => hierarchy.fov() as u32,
        }
    }

    /// The vectors its policy reads (the place and team vectors: a student of the planners).
    pub(crate) fn vectors(&self) -> Vectors {
        match self {
            Team::Flat(policy) => Vectors::of(&policy.env_config(Task::Meta)),
            Team::Hierarchy(_) => Vectors::Goal,
        }
    }

    /// The team vector's dead band its policy acts with (the flat policy's own, which a
    /// student's file records; the default for the hierarchy, which reads no team vector).
    pub(crate) fn team_deadband(&self) -> f64 {
        match self {
            Team::Flat(policy) => policy.team_deadband(),
            Team::Hierarchy(_) => phalanx_env::obs::TEAM_DEADBAND,
        }
    }

    /// Runs agent `id` over `transport` until the episode ends (see
    /// [`phalanx_runtime::run_agent`]).
    pub(crate) fn run_agent(
        &self,
        id: u16,
        transport: &mut impl phalanx_runtime::Transport,
        silence: Duration,
    ) -> anyhow::Result<Result<End, phalanx_runtime::RunError>> {
        fn go(
            agent: &mut impl Machine,
            transport: &mut impl phalanx_runtime::Transport,
            silence: Duration,
        ) -> Result<End, phalanx_runtime::RunError> {
            run_agent(agent, transport, silence)
        }
        let slot = usize::from(id);
        Ok(match self {
            Team::Flat(policy) => {
                let decider = AgentPolicy::new(policy.as_ref().clone(), slot)?;
                go(&mut Agent::new(id, decider), transport, silence)
            }
            Team::Hierarchy(hierarchy) => {
                let decider = AgentHierarchy::new(hierarchy, slot)?;
                go(&mut HierAgent::new(id, decider), transport, silence)
            }
        })
    }
}

/// The policy a team runs, as `phalanx run` and `phalanx agent` take it.
#[derive(Debug, clap::Args)]
pub(crate) struct TeamArgs {
    /// The policy the agents run (the world's --policy).
    #[arg(long, value_enum, default_value = "pathfinding")]
    pub(crate) policy: TeamPolicy,
    /// The policy's directory or file (hrl: the meta policy's; default: the shipped
    /// models/pathfinding, models/meta or models/imitation).
    #[arg(long, value_name = "DIR")]
    pub(crate) weights: Option<PathBuf>,
}

impl TeamArgs {
    /// The team's policy, loaded for a team of `n` agents.
    pub(crate) fn load(&self, n: usize) -> anyhow::Result<Team> {
        Team::load(self.policy, self.weights.as_deref(), n)
    }
}

/// Arguments of `phalanx run`.
#[derive(Debug, clap::Args)]
pub(crate) struct RunCmd {
    /// Instance file (.yaml/.yml or .scen).
    instance: PathBuf,
    /// Agents of a .scen file: its first N (default all).
    #[arg(long, value_name = "N")]
    agents: Option<usize>,
    #[command(flatten)]
    team: TeamArgs,
    /// How long the world waits for an action before the first agent not in waits this
    /// step, milliseconds.
    #[arg(long, default_value_t = 2000, value_name = "MS")]
    step_timeout: u64,
    /// The world and every agent as processes of their own (`phalanx world`, `phalanx
    /// agent`) over Zenoh, instead of threads of this one.
    #[arg(long)]
    processes: bool,
    /// With --processes: the Zenoh endpoint the world listens on (default: a free port on
    /// loopback).
    #[arg(long, value_name = "ENDPOINT", requires = "processes")]
    listen: Option<String>,
    /// Write the trajectory as a libMultiRobotPlanning plan (when it reaches the goals).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the trajectory with -o also when it stops short of the goals (to look at a
    /// failure; such a plan breaks the validator's last rule, goal not reached).
    #[arg(long, requires = "output")]
    partial: bool,
    /// Print one JSON object instead of `key: value` lines.
    #[arg(long)]
    json: bool,
}

/// Where `phalanx run` and `phalanx world` write the trajectory.
pub(crate) struct PlanOut<'a> {
    /// The plan file, if any.
    pub(crate) path: Option<&'a Path>,
    /// Also when the team stopped short of the goals.
    pub(crate) partial: bool,
}

/// The flat policy `name` of `weights` (or the shipped one) for a team of `n` agents.
pub(crate) fn policy_for(weights: Option<&Path>, name: &str, n: usize) -> anyhow::Result<Policy> {
    let (policy, header, file) = models::load_with_header(weights, name)
        .with_context(|| format!("loading the {name} policy"))?;
    let slots = header.net_config.n_agents_max;
    anyhow::ensure!(
        n <= slots,
        "{}: a team of {n} agents, the policy takes at most {slots}",
        file.display()
    );
    Ok(policy)
}

/// The world of `instance` for a team of `policy` of field of view `fov` (the student's
/// observations with `vectors`, its team vector with the dead band `team_deadband` it acts
/// with), with the instance's step limit (docs/spec.md §3, `Instance::step_limit`).
pub(crate) fn world_for(
    named: &NamedInstance,
    path: &Path,
    policy: TeamPolicy,
    fov: u32,
    (vectors, team_deadband): (Vectors, f64),
) -> anyhow::Result<World> {
    let instance = &named.instance;
    let config = EnvConfig { fov, ..EnvConfig::default() };
    match policy {
        TeamPolicy::Pathfinding => World::new(instance, config, 0),
        TeamPolicy::Imitation => {
            let meta = EnvConfig { task: Task::Meta, team_deadband, ..config };
            World::new(instance, vectors.apply(meta), 0)
        }
        TeamPolicy::Hrl => World::hierarchy(instance, config, 0),
    }
    .with_context(|| format!("{}: the world refuses the instance", path.display()))
}

/// Scores the world's trajectory with the one validator and prints it as `phalanx solve`
/// does, with the actions missed and stale (and for the hierarchy the choices missed); writes the plan to `output` when it reached the
/// goals. Exit 0 when it did, 1 otherwise.
pub(crate) fn report(
    named: &NamedInstance,
    policy: TeamPolicy,
    world: &World,
    end: End,
    runtime_s: f64,
    output: &PlanOut<'_>,
    json: bool,
) -> anyhow::Result<ExitCode> {
    let instance = &named.instance;
    let plan = world.plan();
    let result = match end.reason {
        EndReason::Done => Ok(plan),
        EndReason::StepLimit | EndReason::Stopped => Err(Outcome::StepLimit),
    };
    let planner = format!("{} (decentralised)", policy.name());
    let summary = SolveSummary::of(instance, &planner, result, runtime_s);
    let solved = summary.outcome == Outcome::Solved;
    if let (Some(path), true) = (output.path, solved || output.partial) {
        let stats = PlanStats::of(plan, runtime_s);
        util::written(phalanx_io::write_plan_named(path, plan, &named.names, &stats), path)?;
    }
    if json {
        let mut value = serde_json::to_value(&summary)?;
        value["missed_actions"] = world.missed().into();
        value["missed_by_agent"] = world.missed_by_agent().into();
        value["stale_actions"] = world.stale().into();
        if world.is_hierarchy() {
            value["missed_choices"] = world.missed_choices().into();
            value["missed_choices_by_agent"] = world.missed_choices_by_agent().into();
        }
        util::print_json(&value)?;
    } else {
        let mut text = format!(
            "{}\nmissed_actions: {}\nmissed_by_agent: {:?}\nstale_actions: {}\n",
            summary.to_text(),
            world.missed(),
            world.missed_by_agent(),
            world.stale()
        );
        if world.is_hierarchy() {
            text += &format!(
                "missed_choices: {}\nmissed_choices_by_agent: {:?}\n",
                world.missed_choices(),
                world.missed_choices_by_agent()
            );
        }
        util::print(&text)?;
    }
    Ok(if summary.outcome == Outcome::Solved { ExitCode::SUCCESS } else { ExitCode::from(1) })
}

/// Runs `phalanx run`.
pub(crate) fn run(cmd: RunCmd) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(cmd.step_timeout > 0, "--step-timeout must be positive");
    let named = util::read_instance(&cmd.instance, cmd.agents)?;
    let n = named.instance.n_agents();
    let team = cmd.team.load(n)?;
    if cmd.processes {
        return processes(&cmd, n, &team);
    }
    let reads = (team.vectors(), team.team_deadband());
    let mut world = world_for(&named, &cmd.instance, cmd.team.policy, team.fov(), reads)?;
    let (mut world_end, agent_ends) = inproc::bus(n as u16);
    let step_timeout = Duration::from_millis(cmd.step_timeout);
    let started = Instant::now();
    let end = std::thread::scope(|scope| {
        let agents: Vec<_> = agent_ends
            .into_iter()
            .enumerate()
            .map(|(id, mut end)| {
                let team = &team;
                scope.spawn(move || -> anyhow::Result<()> {
                    team.run_agent(id as u16, &mut end, 10 * step_timeout)?
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
    let output = PlanOut { path: cmd.output.as_deref(), partial: cmd.partial };
    report(&named, cmd.team.policy, &world, end, runtime_s, &output, cmd.json)
}

/// `phalanx run --processes`: starts `phalanx world` and one `phalanx agent` per agent (this
/// same binary), all on loopback under a key prefix of this run's own, and waits for them.
/// The world prints the result; its exit code is the run's, unless an agent failed.
fn processes(cmd: &RunCmd, n: usize, team: &Team) -> anyhow::Result<ExitCode> {
    let fov = team.fov();
    let exe = std::env::current_exe().context("finding the phalanx binary")?;
    let endpoint = match &cmd.listen {
        Some(endpoint) => endpoint.clone(),
        None => format!("tcp/127.0.0.1:{}", free_port()?),
    };
    let prefix = format!("phalanx/run-{}", std::process::id());
    let mut world = Command::new(&exe);
    world.arg("world").arg(&cmd.instance).args(["--listen", &endpoint, "--prefix", &prefix]);
    world.args(["--fov", &fov.to_string(), "--step-timeout", &cmd.step_timeout.to_string()]);
    world.args(["--policy", cmd.team.policy.name()]);
    if cmd.team.policy == TeamPolicy::Imitation {
        world.args(["--vectors", &team.vectors().name()]);
        world.args(["--team-deadband", &team.team_deadband().to_string()]);
    }
    if let Some(agents) = cmd.agents {
        world.args(["--agents", &agents.to_string()]);
    }
    if let Some(output) = &cmd.output {
        world.arg("--output").arg(output);
    }
    if cmd.partial {
        world.arg("--partial");
    }
    if cmd.json {
        world.arg("--json");
    }
    let mut world = world.stdin(Stdio::null()).spawn().context("starting the world process")?;
    let mut agents: Vec<Child> = Vec::with_capacity(n);
    for id in 0..n {
        let mut agent = Command::new(&exe);
        agent.args(["agent", "--id", &id.to_string(), "--connect", &endpoint, "--prefix", &prefix]);
        agent.args(["--policy", cmd.team.policy.name()]);
        if let Some(weights) = &cmd.team.weights {
            agent.arg("--weights").arg(weights);
        }
        let spawned = agent.stdin(Stdio::null()).stdout(Stdio::null()).spawn();
        match spawned {
            Ok(child) => agents.push(child),
            Err(err) => {
                for child in agents.iter_mut().chain([&mut world]) {
                    let _ = child.kill();
                    let _ = child.wait();
                }
                return Err(err).context(format!("starting agent {id}'s process"));
            }
        }
    }
    let status = world.wait().context("waiting for the world process")?;
    // The agents end with the episode; one still running after a grace period is stopped.
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut failed = Vec::new();
    for (id, agent) in agents.iter_mut().enumerate() {
        let code = loop {
            match agent.try_wait().context("waiting for an agent process")? {
                Some(status) => break status.code(),
                None if Instant::now() >= deadline => {
                    let _ = agent.kill();
                    let _ = agent.wait();
                    break None;
                }
                None => std::thread::sleep(Duration::from_millis(10)),
            }
        };
        if code != Some(0) {
            failed.push(format!("agent {id} ended with {code:?}"));
        }
    }
    let code = status.code().and_then(|c| u8::try_from(c).ok()).unwrap_or(util::EXIT_PEER_GONE);
    if !failed.is_empty() {
        util::warn(&format!("warning: {}", failed.join("; ")));
        if code == 0 {
            return Ok(ExitCode::from(util::EXIT_PEER_GONE));
        }
    }
    Ok(ExitCode::from(code))
}

/// A TCP port free on loopback now (the system's choice).
fn free_port() -> anyhow::Result<u16> {
    let listener =
        std::net::TcpListener::bind("127.0.0.1:0").context("finding a free loopback port")?;
    Ok(listener.local_addr().context("finding a free loopback port")?.port())
}
