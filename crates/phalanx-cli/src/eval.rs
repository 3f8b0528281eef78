//! `phalanx eval`: run a trained low-level policy greedily on freshly generated instances
//! (the evaluation stream, never the training pool) and print success rate, makespan,
//! collisions and formation loss; the work is `phalanx_rl::evaluate`.
//!
//! Path finding runs on generated instances (docs/spec.md §2: start and goal regions in opposite
//! corners). Formation runs, by default, in the formation-training environment on fresh maps:
//! agents placed at random within each other's view, a random target formation, success when
//! `L_f = 0` within `--max-steps` (default 50).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use phalanx_core::Instance;
use phalanx_env::{EnvConfig, EvalMaps, GenConfig, Task};
use phalanx_rl::{EvalSummary, Hierarchy, Rollouts, evaluate, evaluate_hierarchy};
use serde::Serialize;

use phalanx_rl::models;

use crate::{meta, render, util};

/// The learned policies `phalanx eval` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum PolicyName {
    /// The path-finding policy alone.
    #[value(name = "pathfinding")]
    PathFinding,
    /// The formation policy in the formation-training environment.
    Formation,
    /// The hierarchy: the meta policy over the path-finding and formation policies.
    Hrl,
    /// The hierarchy with the scripted leader–follower meta rule (--wait-above,
    /// --patience) instead of a trained meta policy.
    Leader,
    /// The end-to-end VDN baseline: the five moves on the meta task (`phalanx train e2e`).
    E2e,
    /// The centralised (CTCE) baseline: one network over the team's observations choosing
    /// the joint action on the meta task (`phalanx train ctce`).
    Ctce,
    /// The imitation student: the five moves on the meta task, learned from the
    /// centralised expert (`phalanx train imitation`).
    Imitation,
}

impl PolicyName {
    /// The name on the command line and under `models/` (`meta` for the hierarchy).
    pub(crate) fn name(self) -> &'static str {
        match self {
            PolicyName::PathFinding => "pathfinding",
            PolicyName::Formation => "formation",
            PolicyName::Hrl => "meta",
            PolicyName::Leader => "leader",
            PolicyName::E2e => "e2e",
            PolicyName::Ctce => "ctce",
            PolicyName::Imitation => "imitation",
        }
    }

    /// The environment's task.
    pub(crate) fn task(self) -> Task {
        match self {
            PolicyName::PathFinding => Task::PathFinding,
            PolicyName::Formation => Task::Formation,
            PolicyName::Hrl
            | PolicyName::Leader
            | PolicyName::E2e
            | PolicyName::Ctce
            | PolicyName::Imitation => Task::Meta,
        }
    }
}

/// Episodes per lockstep batch (one batched policy call per step for all of them).
const BATCH: usize = 25;

/// Step limit of formation episodes unless `--max-steps` says otherwise (the quality target:
/// formation reached within 50 steps).
const FORMATION_STEPS: u32 = 50;

/// Evaluates a trained policy on fresh instances.
#[derive(Debug, clap::Args)]
pub(crate) struct EvalCmd {
    /// The policy to evaluate.
    #[arg(long, value_enum)]
    policy: PolicyName,
    /// Directory with policy.bin or checkpoint (default: the shipped `models/<policy>`;
    /// for hrl, the meta policy's, `models/meta`).
    #[arg(long, value_name = "DIR")]
    weights: Option<PathBuf>,
    /// Number of fresh maps (one episode each).
    #[arg(long, default_value_t = 100)]
    maps: usize,
    /// The evaluation stream (`--fov` must be the policy's).
    #[command(flatten)]
    map: util::MapArgs,
    /// Step limit (default: 3 × side for path finding, 50 for formation).
    #[arg(long, value_name = "N")]
    max_steps: Option<u32>,
    /// Test-time rollouts per instance (docs/spec.md §6): the first greedy, the others with random
    /// actions (--random-prob); the best one counts and the time covers all of them.
    #[arg(long, default_value_t = 1)]
    rollouts: usize,
    /// Probability of a random allowed action per agent and step in the extra rollouts.
    #[arg(long, default_value_t = 0.05, value_parser = util::fraction)]
    random_prob: f64,
    #[command(flatten)]
    pick: meta::PickArgs,
    #[command(flatten)]
    acting: meta::ActingArgs,
    #[command(flatten)]
    leader: meta::LeaderArgs,
    /// hrl, leader: the path-finding policy's directory or file (default: the one the meta
    /// policy was trained over, if it is the shipped one; for leader, the shipped one).
    #[arg(long, value_name = "DIR")]
    pathfinding_weights: Option<PathBuf>,
    /// hrl, leader: the formation policy's directory or file.
    #[arg(long, value_name = "DIR")]
    formation_weights: Option<PathBuf>,
    /// Draw the first episodes (`--render-episodes`) as animated SVGs into DIR
    /// (`episode-0.svg`, …).
    #[arg(long, value_name = "DIR")]
    render: Option<PathBuf>,
    /// How many episodes `--render` draws.
    #[arg(long, value_name = "N", default_value_t = 3)]
    render_episodes: usize,
    #[command(flatten)]
    picture: render::PictureArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// What `phalanx eval --json` prints.
#[derive(Debug, Serialize)]
struct Report<'a> {
    policy: &'a str,
    weights: String,
    size: u32,
    density: f64,
    agents: usize,
    seed: u64,
    max_steps: u32,
    rollouts: Rollouts,
    #[serde(flatten)]
    summary: EvalSummary,
    /// Wall seconds of the episodes (policy and environment).
    seconds: f64,
    /// Agent decisions per second (agents × steps of every rollout / seconds, batched
    /// inference).
    decisions_per_s: f64,
    /// Heap memory over the run (bytes held by the program's allocations).
    memory: Memory,
}

/// Heap memory of an evaluation: after its first batch of episodes and at its end (the
/// difference is the per-episode records the report keeps, plans included), and the peak.
#[derive(Debug, Serialize)]
struct Memory {
    after_first_batch: usize,
    at_end: usize,
    peak: usize,
}

/// Runs `phalanx eval`.
pub(crate) fn run(cmd: EvalCmd) -> anyhow::Result<ExitCode> {
    let name = cmd.policy.name();
    let scripted = cmd.policy == PolicyName::Leader;
    let file = if scripted {
        models::weights_file(cmd.pathfinding_weights.as_deref(), "pathfinding")?
    } else {
        models::weights_file(cmd.weights.as_deref(), name)?
    };
    let (mut policy, header, _) =
        models::load_with_header(Some(&file), if scripted { "pathfinding" } else { name })?;
    cmd.acting.apply(&mut policy);
    let fov = header.net_config.fov as u32;
    anyhow::ensure!(
        cmd.map.fov == fov,
        "--fov {}: the {name} policy sees {fov}×{fov} (its network's field of view)",
        cmd.map.fov
    );
    anyhow::ensure!(
        (1..=header.net_config.n_agents_max).contains(&cmd.map.agents()),
        "--agents {} must be between 1 and the network's {} agent slots",
        cmd.map.agents(),
        header.net_config.n_agents_max
    );
    let rule = cmd.leader.rule(scripted)?;
    let task = cmd.policy.task();
    let max_steps = cmd.max_steps.unwrap_or(match task {
        Task::Formation => FORMATION_STEPS,
        Task::PathFinding | Task::Meta => 3 * cmd.map.size,
    });
    anyhow::ensure!(max_steps > 0, "--max-steps must be positive");
    anyhow::ensure!(cmd.maps > 0, "--maps 0: there is nothing to evaluate");
    let env = EnvConfig { step_limit: Some(max_steps), ..policy.env_config(task) };
    let instances = instances(&cmd, task, fov)?;

    let bar = util::bar(instances.len() as u64, "episodes");
    let started = Instant::now();
    anyhow::ensure!(cmd.rollouts >= 1, "--rollouts must be at least 1");
    let rollouts = cmd.pick.rollouts(cmd.rollouts, cmd.random_prob, cmd.map.seed);
    let mut after_first_batch = None;
    let mut progress = |done: usize| {
        after_first_batch.get_or_insert_with(crate::memory::held);
        bar.set_position(done as u64);
    };
    let episodes = if scripted {
        let low = models::low_level_of(policy, cmd.formation_weights.as_deref())?;
        let mut hierarchy = Hierarchy::scripted(rule, low);
        evaluate_hierarchy(&mut hierarchy, &env, &instances, BATCH, rollouts, &mut progress)
    } else if cmd.policy == PolicyName::Hrl {
        let mut hierarchy = models::hierarchy(
            policy,
            &header,
            &file,
            cmd.pathfinding_weights.as_deref(),
            cmd.formation_weights.as_deref(),
        )?;
        evaluate_hierarchy(&mut hierarchy, &env, &instances, BATCH, rollouts, &mut progress)
    } else {
        evaluate(&mut policy, task, &env, &instances, BATCH, rollouts, &mut progress)
    }
    .context("evaluating")?;
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    if let Some(dir) = &cmd.render {
        util::written(std::fs::create_dir_all(dir), dir)?;
        for (k, (episode, instance)) in
            episodes.iter().zip(&instances).take(cmd.render_episodes).enumerate()
        {
            let path = dir.join(format!("episode-{k}.svg"));
            let title = format!("{name} episode {k}");
            let choices = episode.choices.as_deref();
            render::episode(&path, instance, &episode.plan, choices, &title, &cmd.picture)?;
        }
    }
    let decisions: u64 = episodes.iter().map(|it| it.decisions).sum();
    let report = Report {
        policy: name,
        weights: file.display().to_string(),
        size: cmd.map.size,
        density: cmd.map.density,
        agents: cmd.map.agents(),
        seed: cmd.map.seed,
        max_steps,
        rollouts,
        summary: EvalSummary::of(&episodes),
        seconds,
        decisions_per_s: decisions as f64 / seconds.max(1e-9),
        memory: Memory {
            after_first_batch: after_first_batch.unwrap_or_default(),
            at_end: crate::memory::held(),
            peak: crate::memory::peak(),
        },
    };
    if cmd.json {
        util::print_json(&serde_json::to_value(&report)?)?;
    } else {
        util::print(&text(&report))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The evaluation instances: `--maps` of them from the evaluation stream.
fn instances(cmd: &EvalCmd, task: Task, fov: u32) -> anyhow::Result<Vec<Instance>> {
    let agents = cmd.map.agents();
    let n_agents = if task == Task::Formation { 1 } else { agents };
    let maps = EvalMaps::new(GenConfig { n_agents, fov, ..cmd.map.config() });
    if task == Task::Formation {
        return maps
            .formation_instances(agents, cmd.maps)
            .with_context(|| format!("no room for a formation of {agents} agents"));
    }
    (0..cmd.maps as u64)
        .map(|index| maps.instance(index).context("generating an evaluation instance"))
        .collect()
}

/// Bytes in MiB.
fn mib(bytes: usize) -> f64 {
    bytes as f64 / f64::from(1 << 20)
}

/// The report as a table.
fn text(r: &Report<'_>) -> String {
    let s = &r.summary;
    util::table(&[
        ("policy", format!("{} ({})", r.policy, r.weights)),
        (
            "maps",
            format!("{} × {}², density {}, {} agents", s.episodes, r.size, r.density, r.agents),
        ),
        ("success_rate", format!("{:.3}", s.success_rate)),
        (
            "makespan",
            if s.makespan.is_nan() {
                "- (no episode solved)".to_owned()
            } else {
                format!(
                    "{:.2} (lower bound {:.2}, ratio {:.3}; solved episodes)",
                    s.makespan, s.lower_bound, s.makespan_ratio
                )
            },
        ),
        ("collisions", format!("{:.2} per episode", s.collisions)),
        ("formation_loss", format!("{:.4} (sum of L_f over steps / map side)", s.formation_loss)),
        ("final L_f", format!("{:.4}", s.final_formation_loss)),
        (
            "stalled",
            format!(
                "{} standing, {} oscillating (episodes short of the goals)",
                s.standing, s.oscillating
            ),
        ),
        ("rollouts", format!("{} (random action prob. {})", r.rollouts.count, r.rollouts.epsilon)),
        ("decisions/s", format!("{:.0} ({:.2} s)", r.decisions_per_s, r.seconds)),
        (
            "memory",
            format!(
                "{:.1} MiB after the first batch, {:.1} MiB at the end, peak {:.1} MiB",
                mib(r.memory.after_first_batch),
                mib(r.memory.at_end),
                mib(r.memory.peak)
            ),
        ),
    ])
}
