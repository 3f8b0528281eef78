//! `phalanx train pathfinding|formation`: trains a low-level policy (VDN + double DQN, SPEC §6)
//! on the training pool, with a progress bar on stderr, metrics appended as JSON lines to
//! `DIR/metrics.jsonl` (one `{"name", "step", "value"}` object per value, names of
//! `phalanx_rl::metrics`), an atomic checkpoint `DIR/checkpoint` with the policy file
//! `DIR/policy.bin` beside it every N updates and at the end, and the training curves
//! `DIR/curves.svg` redrawn at each checkpoint. `--resume` continues from `DIR/checkpoint`
//! exactly as the run would have gone on: the checkpoint carries the replay buffers and the
//! running episodes (`Learner::save_with_collection`).
//!
//! The run's settings (`--config FILE`, JSON, every field optional) are written to
//! `DIR/config.json`; a resumed run without `--config` reads them back from there.

use std::collections::VecDeque;
use std::fs;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use burn::tensor::Device;
use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use phalanx_env::{EnvConfig, PoolConfig, PoolEnv, Shaping, Task};
use phalanx_rl::{Collector, Learner, LearnerConfig, QNetConfig, metrics};
use serde::{Deserialize, Serialize};

use crate::{plot, util};

/// The policy file (online network only, what `phalanx eval` and `models/` use) written
/// beside each checkpoint.
const POLICY: &str = "policy.bin";

/// The training-curve plot written beside the metrics.
const CURVES: &str = "curves.svg";

/// Episodes in the progress bar's recent success rate.
const SUCCESS_WINDOW: usize = 100;

/// The low-level policies `phalanx train` trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TaskName {
    /// Path finding: reach the goals across a pool map.
    #[value(name = "pathfinding")]
    PathFinding,
    /// Formation: reach a random target formation from a random placement.
    Formation,
}

impl TaskName {
    /// The name on the command line and under `models/`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            TaskName::PathFinding => "pathfinding",
            TaskName::Formation => "formation",
        }
    }

    /// The environment's task.
    pub(crate) fn task(self) -> Task {
        match self {
            TaskName::PathFinding => Task::PathFinding,
            TaskName::Formation => Task::Formation,
        }
    }
}

/// Trains a path-finding or formation policy.
#[derive(Debug, clap::Args)]
pub(crate) struct TrainCmd {
    /// The policy to train.
    #[arg(value_enum)]
    task: TaskName,
    /// Settings (JSON, every field optional): agent_counts, n_envs, steps, checkpoint_every,
    /// net, learner, env, pool, shaping, reward_scale, init_from (docs/learning.md).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Output directory: metrics.jsonl, checkpoint, config.json.
    #[arg(long, value_name = "DIR", default_value = "run")]
    out: PathBuf,
    /// Continue from DIR/checkpoint.
    #[arg(long)]
    resume: bool,
    /// Seed of the learner (network, exploration, episode draws).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Total environment steps of the run (a resumed run counts the steps already taken);
    /// overrides the config's `steps`.
    #[arg(long, value_name = "N")]
    steps: Option<u64>,
}

/// Settings of a training run. Defaults: teams of 3, 16 environments in lockstep, 200 000
/// steps, a checkpoint every 1000 updates, the default network and learner, the paper's
/// environment and pool; formation training defaults to teams of 3, 4 and 5, 15 environments
/// and a step limit of 64 (the shipped formation policy's settings, see
/// [`TrainConfig::with_task_defaults`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct TrainConfig {
    /// Team sizes trained (one shared network; environments take the sizes in turn).
    agent_counts: Vec<usize>,
    /// Environments played in lockstep (batched inference).
    n_envs: usize,
    /// Total environment steps.
    steps: u64,
    /// Gradient updates between checkpoints.
    checkpoint_every: u64,
    /// Network sizes (ignored on resume: the checkpoint's).
    net: QNetConfig,
    /// Learner hyper-parameters (ignored on resume: the checkpoint's).
    learner: LearnerConfig,
    /// Field of view and step limit (the task is the command's).
    env: EnvConfig,
    /// The training pool.
    pool: PoolConfig,
    /// Weight of the goal-progress bonus (`phalanx_rl::Shaping` with γ = 1: `weight` per unit
    /// of BFS distance an agent gains towards its goal, the same taken for each unit lost):
    /// default 20 for formation, 0 for path finding (whose Table I reward already pays each
    /// step towards the goal).
    shaping: Option<f32>,
    /// Factor on the team reward seen by the learner (shaping included): default 0.05 for
    /// formation (its `−k·L_f` per step is large), 1 for path finding.
    reward_scale: Option<f32>,
    /// Warm start: initial weights from this checkpoint or policy file (same network), e.g.
    /// the path-finding policy for formation training; ignored on resume.
    init_from: Option<PathBuf>,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            agent_counts: vec![3],
            n_envs: 16,
            steps: 200_000,
            checkpoint_every: 1000,
            net: QNetConfig::default(),
            learner: LearnerConfig::default(),
            env: EnvConfig::default(),
            pool: PoolConfig::default(),
            shaping: None,
            reward_scale: None,
            init_from: None,
        }
    }
}

impl TrainConfig {
    /// Fills the team and episode settings whose default depends on the task, where `given`
    /// (the config file's JSON, `Null` without one) leaves them out: formation trains teams
    /// of 3, 4 and 5 in 15 environments (five of each) with episodes of at most 64 steps.
    /// The task's `shaping` and `reward_scale` stay `None` here; [`run`] applies their
    /// defaults where it builds the environments.
    fn with_task_defaults(mut self, task: Task, given: &serde_json::Value) -> TrainConfig {
        if task == Task::Formation {
            if given.get("agent_counts").is_none() {
                self.agent_counts = vec![3, 4, 5];
            }
            if given.get("n_envs").is_none() {
                self.n_envs = 15;
            }
            if given.get("env").and_then(|env| env.get("step_limit")).is_none() {
                self.env.step_limit = Some(64);
            }
        }
        self
    }
}

/// Runs `phalanx train`.
pub(crate) fn run(cmd: TrainCmd) -> anyhow::Result<ExitCode> {
    let dir = &cmd.out;
    let saved_config = dir.join("config.json");
    let task = cmd.task.task();
    let mut config = match (&cmd.config, cmd.resume) {
        (Some(path), _) => read_config(path, task)?,
        (None, true) if saved_config.exists() => read_config(&saved_config, task)?,
        (None, _) => TrainConfig::default().with_task_defaults(task, &serde_json::Value::Null),
    };
    if let Some(steps) = cmd.steps {
        config.steps = steps;
    }
    let device = Device::flex().autodiff();
    let checkpoint = dir.join("checkpoint");
    let mut learner = if cmd.resume {
        Learner::load(&checkpoint, &device).context("resuming")?
    } else {
        let max = config.net.n_agents_max;
        anyhow::ensure!(!config.agent_counts.is_empty(), "agent_counts must not be empty");
        for &n in &config.agent_counts {
            anyhow::ensure!(
                (1..=max).contains(&n),
                "agent count {n} must be between 1 and the network's n_agents_max {max}"
            );
        }
        let mut learner = Learner::new(
            config.net.clone(),
            config.learner.clone(),
            &config.agent_counts,
            cmd.seed,
            &device,
        );
        if let Some(path) = &config.init_from {
            learner.init_from(path).context("warm start (init_from)")?;
        }
        learner
    };
    if learner.agent_counts() != config.agent_counts {
        util::warn(&format!(
            "the checkpoint trains teams of {:?}; config agent_counts {:?} ignored",
            learner.agent_counts(),
            config.agent_counts
        ));
        config.agent_counts = learner.agent_counts().to_vec();
    }
    anyhow::ensure!(config.n_envs > 0, "n_envs must be positive");
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let json = serde_json::to_string_pretty(&config).expect("the config serialises");
    fs::write(&saved_config, json + "\n")
        .with_context(|| format!("writing {}", saved_config.display()))?;

    let weight = config.shaping.unwrap_or(match task {
        Task::Formation => 20.0,
        Task::PathFinding | Task::Meta => 0.0,
    });
    let shaping = (weight != 0.0).then_some(Shaping { weight, gamma: 1.0 });
    let first = PoolEnv::new(task, &config.pool, config.env.clone(), config.agent_counts[0])
        .with_context(|| format!("building the {:?} environment", cmd.task))?
        .with_shaping(shaping)
        .with_reward_scale(config.reward_scale.unwrap_or(match task {
            Task::Formation => 0.05,
            Task::PathFinding | Task::Meta => 1.0,
        }));
    let counts = &config.agent_counts;
    let envs = (0..config.n_envs)
        .map(|e| first.with_agents(counts[e % counts.len()]))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("building the {:?} environment", cmd.task))?;
    let step_limit = config.env.step_limit.unwrap_or(3 * config.pool.size) as usize;
    let mut collector = Collector::new(envs, step_limit);

    if cmd.resume && !learner.restore_collection(&checkpoint, &mut collector).context("resuming")? {
        util::warn(&format!(
            "warning: {} has no collection state (an older or hand-made checkpoint): the replay \
             buffers refill before training goes on",
            checkpoint.display()
        ));
    }
    train(collector, learner, &config, dir, cmd.resume)
}

/// Reads a config file; the fields it leaves out take their defaults for `task`.
fn read_config(path: &Path, task: Task) -> anyhow::Result<TrainConfig> {
    let text =
        fs::read_to_string(path).with_context(|| format!("reading config {}", path.display()))?;
    let parse_error = || format!("parsing config {}", path.display());
    // Typed first, so that errors name the line and the field.
    let config: TrainConfig = serde_json::from_str(&text).with_context(parse_error)?;
    let given: serde_json::Value = serde_json::from_str(&text).with_context(parse_error)?;
    Ok(config.with_task_defaults(task, &given))
}

/// The collect/update loop with the progress bar, the metrics file and the checkpoints.
/// `Learner::train` runs in chunks of `checkpoint_every × train_every` environment steps
/// (about `checkpoint_every` updates once learning has started); a checkpoint is written after
/// each chunk that crossed a multiple of `checkpoint_every` updates.
fn train(
    mut collector: Collector<PoolEnv>,
    mut learner: Learner,
    config: &TrainConfig,
    dir: &Path,
    resume: bool,
) -> anyhow::Result<ExitCode> {
    let metrics_path = dir.join("metrics.jsonl");
    let checkpoint = dir.join("checkpoint");
    let file = fs::OpenOptions::new()
        .create(true)
        .append(resume)
        .write(true)
        .truncate(!resume)
        .open(&metrics_path)
        .with_context(|| format!("opening {}", metrics_path.display()))?;

    let start = learner.counters();
    let bar = ProgressBar::new(config.steps);
    let style = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:30}] {pos}/{len} steps, {sps} steps/s, eta {eta} {msg}",
    )
    .expect("a valid template")
    .with_key("sps", |state: &ProgressState, out: &mut dyn std::fmt::Write| {
        let _ = write!(out, "{:.0}", state.per_sec());
    })
    .progress_chars("=> ");
    bar.set_style(style);
    bar.set_position(start.env_steps.min(config.steps));
    bar.reset_eta();
    bar.enable_steady_tick(Duration::from_millis(500));
    let mut sink = Sink {
        out: BufWriter::new(file),
        err: None,
        recent: VecDeque::new(),
        bar: bar.clone(),
        total: config.steps,
        episodes: start.episodes,
        updates: 0,
        started: Instant::now(),
    };
    let started = Instant::now();
    let every = config.checkpoint_every.max(1);
    let chunk = every.saturating_mul(learner.config().train_every.max(1));
    let mut last_saved = start.updates / every;
    while learner.counters().env_steps < config.steps {
        let todo = (config.steps - learner.counters().env_steps).min(chunk);
        learner.train(&mut collector, todo, &mut sink);
        if let Some(err) = sink.err.take() {
            return Err(err).with_context(|| format!("writing {}", metrics_path.display()));
        }
        let updates = learner.counters().updates;
        if updates / every > last_saved {
            last_saved = updates / every;
            sink.out.flush().with_context(|| format!("writing {}", metrics_path.display()))?;
            learner.save_with_collection(&checkpoint, &collector)?;
            learner.save_policy(&dir.join(POLICY))?;
            plot_curves(dir);
        }
    }
    bar.finish_and_clear();
    sink.out.flush().with_context(|| format!("writing {}", metrics_path.display()))?;
    learner.save_with_collection(&checkpoint, &collector)?;
    learner.save_policy(&dir.join(POLICY))?;
    plot_curves(dir);

    let counters = learner.counters();
    let secs = started.elapsed().as_secs_f64().max(1e-9);
    let sps = (counters.env_steps - start.env_steps) as f64 / secs;
    util::print(&util::table(&[
        ("env steps", counters.env_steps.to_string()),
        ("episodes", counters.episodes.to_string()),
        ("updates", counters.updates.to_string()),
        ("steps/s", format!("{sps:.1}")),
        ("success", format!("{:.2} (last {SUCCESS_WINDOW} episodes)", sink.success_rate())),
        ("checkpoint", checkpoint.display().to_string()),
        ("curves", dir.join(CURVES).display().to_string()),
    ]))?;
    Ok(ExitCode::SUCCESS)
}

/// Redraws `DIR/curves.svg` from `DIR/metrics.jsonl`; a failure is reported, not fatal (the
/// checkpoint and the metrics are what a run must not lose).
fn plot_curves(dir: &Path) {
    let metrics = dir.join("metrics.jsonl");
    match plot::training_curves(&metrics, &dir.join(CURVES)) {
        Ok(None) => {}
        Ok(Some(line)) => util::warn(&format!(
            "warning: {}:{line}: skipped lines that are not metrics in the curves",
            metrics.display()
        )),
        Err(err) => util::warn(&format!("warning: no training curves: {err:#}")),
    }
}

/// Writes metrics as JSON lines and drives the progress bar: steps and episodes, ε and the
/// success rate of the last [`SUCCESS_WINDOW`] episodes.
struct Sink {
    out: BufWriter<fs::File>,
    /// The first write error (the learner's sink cannot fail; the loop checks after each call).
    err: Option<std::io::Error>,
    recent: VecDeque<bool>,
    bar: ProgressBar,
    total: u64,
    episodes: u64,
    /// Updates in this process, and when it started (for updates/s).
    updates: u64,
    started: Instant,
}

impl Sink {
    fn success_rate(&self) -> f64 {
        let n = self.recent.len().max(1) as f64;
        self.recent.iter().filter(|&&it| it).count() as f64 / n
    }
}

impl phalanx_rl::MetricSink for Sink {
    fn record(&mut self, name: &'static str, env_step: u64, value: f64) {
        match name {
            metrics::SUCCESS => {
                if self.recent.len() == SUCCESS_WINDOW {
                    self.recent.pop_front();
                }
                self.recent.push_back(value > 0.5);
            }
            metrics::TD_LOSS => self.updates += 1,
            metrics::EPSILON => {
                self.episodes += 1;
                let ups = self.updates as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
                self.bar.set_position(env_step.min(self.total));
                self.bar.set_message(format!(
                    "| {} episodes, {ups:.1} updates/s, eps {value:.3}, success {:.2}",
                    self.episodes,
                    self.success_rate()
                ));
            }
            _ => {}
        }
        if self.err.is_some() {
            return;
        }
        let line = serde_json::json!({ "name": name, "step": env_step, "value": value });
        if let Err(err) = writeln!(self.out, "{line}") {
            self.err = Some(err);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formation_defaults_fill_only_what_the_file_leaves_out() {
        let none = serde_json::Value::Null;
        let formation = TrainConfig::default().with_task_defaults(Task::Formation, &none);
        assert_eq!(formation.agent_counts, [3, 4, 5]);
        assert_eq!((formation.n_envs, formation.env.step_limit), (15, Some(64)));
        let path = TrainConfig::default().with_task_defaults(Task::PathFinding, &none);
        assert_eq!(path, TrainConfig::default());

        let text = r#"{"n_envs": 6, "env": {"step_limit": null}}"#;
        let given: serde_json::Value = serde_json::from_str(text).unwrap();
        let config: TrainConfig = serde_json::from_str(text).unwrap();
        let config = config.with_task_defaults(Task::Formation, &given);
        assert_eq!(config.agent_counts, [3, 4, 5]);
        assert_eq!((config.n_envs, config.env.step_limit), (6, None));
    }
}
