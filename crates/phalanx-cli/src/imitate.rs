//! `phalanx imitate`: the expert and the data of imitation learning (`docs/imitation.md`).
//!
//! - `imitate expert` measures the expert alone on the Table II rows (the evaluation
//!   stream's instances, as `phalanx bench table2`): success, makespan against CBS's, the
//!   Table II formation loss, time per call, and, with `--noise`, how it does when the team
//!   is pushed off its plan;
//! - `imitate data` writes expert rollouts on the training pool to a data file, in parallel
//!   (`RAYON_NUM_THREADS`), the same file for the same seed on any thread count;
//! - `imitate check` reads a data file, replays every episode into its samples, and
//!   summarises it.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use phalanx_core::{Action, PlanMetrics, validate};
use phalanx_env::{Env, EnvConfig, PoolConfig, Task};
use phalanx_eval::Case;
use phalanx_plan::Budget;
use phalanx_plan::cbs::{self, CbsConfig};
use phalanx_plan::expert::ExpertStats;
use phalanx_rl::imitation::{self, DataConfig, Dataset, EpisodeEnd, ExpertChoice};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::{generate, util};

/// The subcommands of `phalanx imitate`.
#[derive(Debug, Subcommand)]
pub(crate) enum ImitateCmd {
    /// Measure the expert alone on the Table II rows: success, makespan, loss, time per call.
    Expert(ExpertArgs),
    /// Write expert rollouts on the training pool to a data file.
    Data(DataArgs),
    /// Read a data file, replay its episodes into samples and summarise it.
    Check(CheckArgs),
}

/// `phalanx imitate expert`.
#[derive(Debug, Args)]
pub(crate) struct ExpertArgs {
    /// The expert: `swarm`, `cbs` (CBS, swarm when it fails), `jsa:W` (joint-state A* on
    /// T + W·ΣL_f, swarm when it fails) or `swarm-jsa:W` (swarm with joint-state A* on its
    /// local instances).
    #[arg(long, default_value = "swarm", value_parser = parse_expert)]
    expert: ExpertChoice,
    /// Instances per row (the evaluation stream's first ones).
    #[arg(long, default_value_t = 10)]
    maps: u64,
    /// Base seed of the evaluation stream (as `phalanx bench`).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Only the rows of maps at most this side.
    #[arg(long)]
    max_side: Option<u32>,
    /// Probability per agent and step of a random action instead of the expert's: the team
    /// is pushed off the plan and the expert re-plans from where it is.
    #[arg(long, default_value_t = 0.0, value_parser = util::fraction)]
    noise: f64,
    /// Node limit of one expert call.
    #[arg(long, default_value_t = 200_000)]
    node_limit: u64,
    /// Time limit of CBS, whose makespan is the reference, in seconds.
    #[arg(long, default_value_t = 30.0, value_parser = util::positive)]
    cbs_time_limit: f64,
}

/// `phalanx imitate data`.
#[derive(Debug, Args)]
pub(crate) struct DataArgs {
    /// The data file to write (atomically).
    #[arg(long)]
    out: PathBuf,
    /// Episodes.
    #[arg(long, default_value_t = 1000)]
    episodes: u64,
    /// Seed of the episodes' streams.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Team sizes, one drawn per episode.
    #[arg(long, value_delimiter = ',', default_value = "3,4,5")]
    agents: Vec<usize>,
    /// Probability per agent and step of a random action instead of the expert's.
    #[arg(long, default_value_t = 0.05, value_parser = util::fraction)]
    noise: f64,
    /// Share of episodes with a wide team (formations from a 10×10 square).
    #[arg(long, default_value_t = 0.5, value_parser = util::fraction)]
    wide_share: f64,
    /// The expert: `swarm`, `cbs`, `jsa:W` or `swarm-jsa:W` (as `imitate expert`).
    #[arg(long, default_value = "swarm-jsa:1", value_parser = parse_expert)]
    expert: ExpertChoice,
    /// Node limit of one expert call (of each local joint-state A* search).
    #[arg(long, default_value_t = DataConfig::default().node_limit)]
    node_limit: u64,
    /// Maps in the training pool.
    #[arg(long, default_value_t = PoolConfig::default().n_maps)]
    pool_maps: usize,
    /// Base seed of the training pool.
    #[arg(long, default_value_t = 0)]
    pool_seed: u64,
    /// Side of the training pool's maps.
    #[arg(long, default_value_t = PoolConfig::default().size)]
    pool_size: u32,
    /// What the training pool's maps look like: the paper's random walls, mazes of 2-cell
    /// corridors or rooms joined by one-cell doors (formations placed anywhere on them).
    #[arg(long, value_enum, default_value_t = generate::Kind::Random)]
    pool_kind: generate::Kind,
}

/// `phalanx imitate check`.
#[derive(Debug, Args)]
pub(crate) struct CheckArgs {
    /// The data file.
    file: PathBuf,
}

/// Runs `phalanx imitate`.
pub(crate) fn run(cmd: ImitateCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        ImitateCmd::Expert(args) => expert(&args),
        ImitateCmd::Data(args) => data(&args),
        ImitateCmd::Check(args) => check(&args),
    }
}

/// `swarm`, `cbs`, `jsa:W` or `swarm-jsa:W`.
fn parse_expert(text: &str) -> Result<ExpertChoice, String> {
    match text.split_once(':') {
        None if text == "swarm" => Ok(ExpertChoice::Swarm),
        None if text == "cbs" => Ok(ExpertChoice::Cbs),
        Some(("jsa", w)) => Ok(ExpertChoice::JointAStar { w: util::non_negative(w)? }),
        Some(("swarm-jsa", w)) => Ok(ExpertChoice::SwarmJointAStar { w: util::non_negative(w)? }),
        _ => Err(format!("{text:?} is not an expert (swarm, cbs, jsa:W or swarm-jsa:W)")),
    }
}

/// One row's figures.
#[derive(Default)]
struct RowFigures {
    runs: u64,
    solved: u64,
    invalid: u64,
    makespan: f64,
    loss: f64,
    /// CBS's makespans and the expert's on the instances both solved.
    cbs_makespan: f64,
    paired_makespan: f64,
    cbs_solved: u64,
    stats: ExpertStats,
    decide_s: f64,
}

fn expert(args: &ExpertArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.maps > 0, "--maps 0: there is nothing to measure");
    let cases: Vec<Case> = Case::table2(false)
        .into_iter()
        .filter(|c| args.max_side.is_none_or(|m| c.side <= m))
        .collect();
    anyhow::ensure!(
        !cases.is_empty(),
        "--max-side {:?}: no Table II row is that small",
        args.max_side
    );
    let config = args.expert.config(args.node_limit);
    let env_config = EnvConfig { task: Task::Meta, ..EnvConfig::default() };
    let bar = util::bar(cases.len() as u64 * args.maps, "instances");
    let mut rows = vec![vec![
        "row".to_owned(),
        "success".to_owned(),
        "makespan".to_owned(),
        "/ CBS".to_owned(),
        "loss (Table II)".to_owned(),
        "plans / episode".to_owned(),
        "ms / plan".to_owned(),
        "µs / decision".to_owned(),
    ]];
    let mut invalid = false;
    for case in &cases {
        let mut f = RowFigures::default();
        for index in 0..args.maps {
            let (instance, map_seed) = case.instance(args.seed, index)?;
            let mut env = Env::new(env_config.clone())?;
            let mut rng = ChaCha8Rng::seed_from_u64(map_seed);
            let started = Instant::now();
            let (episode, stats) = imitation::rollout(
                &mut env,
                &instance,
                &config,
                phalanx_env::LeaderRule::PathFinding,
                args.noise,
                &mut rng,
            )?;
            f.decide_s += started.elapsed().as_secs_f64();
            f.stats.add(&stats);
            f.runs += 1;
            let plan = episode.plan();
            if episode.end == EpisodeEnd::Reached {
                if validate(&instance, &plan).is_err() {
                    f.invalid += 1;
                } else {
                    let m = PlanMetrics::of(&instance, &plan);
                    f.solved += 1;
                    f.makespan += m.makespan as f64;
                    f.loss += m.formation_loss;
                    let budget = Budget::seconds(args.cbs_time_limit);
                    if let Ok(cbs_plan) =
                        cbs::solve(&instance, &CbsConfig::default(), &budget).result
                    {
                        f.cbs_solved += 1;
                        f.cbs_makespan += PlanMetrics::of(&instance, &cbs_plan).makespan as f64;
                        f.paired_makespan += m.makespan as f64;
                    }
                }
            }
            bar.inc(1);
        }
        if f.invalid > 0 {
            util::warn(&format!("{}: {} expert episodes are invalid plans", case.label, f.invalid));
            invalid = true;
        }
        let solved = f.solved.max(1) as f64;
        let ratio = if f.cbs_solved > 0 {
            format!("{:.3}", f.paired_makespan / f.cbs_makespan)
        } else {
            "–".to_owned()
        };
        rows.push(vec![
            case.label.clone(),
            format!("{:.2}", f.solved as f64 / f.runs as f64),
            format!("{:.1}", f.makespan / solved),
            ratio,
            format!("{:.3}", f.loss / solved),
            format!("{:.1}", f.stats.replans as f64 / f.runs as f64),
            format!("{:.2}", 1e3 * f.stats.plan_seconds / f.stats.replans.max(1) as f64),
            format!("{:.1}", 1e6 * f.decide_s / f.stats.calls.max(1) as f64),
        ]);
    }
    bar.finish_and_clear();
    util::print(&util::columns(&rows))?;
    Ok(if invalid { ExitCode::from(util::EXIT_INVALID) } else { ExitCode::SUCCESS })
}

fn data(args: &DataArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.episodes > 0, "--episodes 0: there is nothing to write");
    let config = DataConfig {
        pool: PoolConfig {
            n_maps: args.pool_maps,
            seed: args.pool_seed,
            size: args.pool_size,
            kind: args.pool_kind.map_kind(),
            ..PoolConfig::default()
        },
        agents: args.agents.clone(),
        episodes: args.episodes,
        seed: args.seed,
        noise: args.noise,
        wide_share: args.wide_share,
        expert: args.expert,
        node_limit: args.node_limit,
        ..DataConfig::default()
    };
    let bar = util::bar(args.episodes, "episodes");
    let started = Instant::now();
    let (data, stats) = imitation::generate(&config, &|n| bar.inc(n))?;
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let bytes = data.to_bytes();
    util::written(phalanx_io::write_bytes(&args.out, &bytes), &args.out)?;
    let count = |end: EpisodeEnd| data.episodes.iter().filter(|e| e.end == end).count();
    let samples = data.n_samples();
    let (mut makespan, mut loss, mut reached) = (0.0, 0.0, 0usize);
    for episode in data.episodes.iter().filter(|e| e.end == EpisodeEnd::Reached) {
        let m = PlanMetrics::of(&episode.instance, &episode.plan());
        makespan += m.makespan as f64;
        loss += m.formation_loss;
        reached += 1;
    }
    let per = |x: f64| format!("{:.3}", x / reached.max(1) as f64);
    util::print(&util::table(&[
        ("file", args.out.display().to_string()),
        ("episodes", data.episodes.len().to_string()),
        (
            "reached / truncated / expert failed",
            format!(
                "{} / {} / {}",
                count(EpisodeEnd::Reached),
                count(EpisodeEnd::Truncated),
                count(EpisodeEnd::ExpertFailed)
            ),
        ),
        ("makespan, Table II loss (reached)", format!("{} {}", per(makespan), per(loss))),
        ("steps", data.n_steps().to_string()),
        ("samples", samples.to_string()),
        ("expert plans", stats.expert.replans.to_string()),
        ("joint-state A* or CBS fallbacks to swarm", stats.expert.fallbacks.to_string()),
        ("expert seconds planning", format!("{:.1}", stats.expert.plan_seconds)),
        ("expert calls past the time limit", stats.expert.timeouts.to_string()),
        ("bytes", bytes.len().to_string()),
        ("seconds", format!("{seconds:.1}")),
        ("samples / s", format!("{:.0}", samples as f64 / seconds)),
        ("threads", rayon::current_num_threads().to_string()),
    ]))?;
    Ok(ExitCode::SUCCESS)
}

fn check(args: &CheckArgs) -> anyhow::Result<ExitCode> {
    let path = &args.file;
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let data =
        Dataset::from_bytes(&bytes).with_context(|| format!("reading {}", path.display()))?;
    let config = &data.config;
    let bar = util::bar(data.episodes.len() as u64, "episodes");
    let started = Instant::now();
    let mut labels = [0u64; Action::COUNT];
    let (mut samples, mut followers, mut copies) = (0u64, 0u64, 0u64);
    for episode in &data.episodes {
        imitation::for_each_sample(episode, &config.env, config.leader_rule, |s| {
            samples += 1;
            labels[s.target.index()] += 1;
            if s.rank > 0 {
                followers += 1;
                // The leader's action is in the message: does the follower copy it?
                let leader = usize::from(episode.steps[s.t].order[0]);
                if episode.steps[s.t].expert[leader] == s.target {
                    copies += 1;
                }
            }
        })
        .with_context(|| format!("replaying {}", path.display()))?;
        bar.inc(1);
    }
    let seconds = started.elapsed().as_secs_f64().max(1e-6);
    bar.finish_and_clear();
    let share = |k: u64, of: u64| format!("{:.3}", k as f64 / of.max(1) as f64);
    let histogram = Action::ALL
        .iter()
        .map(|a| format!("{a:?} {}", share(labels[a.index()], samples)))
        .collect::<Vec<_>>()
        .join(", ");
    util::print(&util::table(&[
        ("file", path.display().to_string()),
        ("episodes", data.episodes.len().to_string()),
        ("samples", samples.to_string()),
        ("labels", histogram),
        ("followers copying the leader", share(copies, followers)),
        ("replay samples / s", format!("{:.0}", samples as f64 / seconds)),
        ("settings", serde_json::to_string(config)?),
    ]))?;
    Ok(ExitCode::SUCCESS)
}
