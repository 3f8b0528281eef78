//! `phalanx train pathfinding|formation|meta|e2e|ctce`: trains a low-level policy (VDN + double
//! DQN, docs/spec.md §6) on the training pool, or the meta policy over the two frozen ones
//! (`phalanx_rl::MetaEnv`) or an end-to-end baseline (VDN or the centralised CTCE) on the meta
//! reward, with a progress bar on stderr, metrics appended as JSON lines to
//! `DIR/metrics.jsonl` (one `{"name", "step", "value"}` object per value, names of
//! `phalanx_rl::metrics`), an atomic checkpoint `DIR/checkpoint` with the policy file
//! `DIR/policy.bin` beside it every N updates and at the end, and the training curves
//! `DIR/curves.svg` redrawn at each checkpoint. `--resume` continues from `DIR/checkpoint`
//! exactly as the run would have gone on: the checkpoint carries the replay buffers and the
//! running episodes (`Learner::save_with_collection`).
//!
//! The run's settings (`phalanx_rl::TrainConfig`: `--config FILE`, JSON, every field optional,
//! over the task's defaults, then the flags) are written to `DIR/config.json`; a resumed run
//! without `--config` reads them back from there.

use std::collections::VecDeque;
use std::fs;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use burn::tensor::Device;
use indicatif::ProgressBar;
use phalanx_env::{MarlEnv, MetaInputs};
use phalanx_rl::{Collector, Learner, Multiples, TrainConfig, TrainTask, metrics};

use phalanx_rl::models;

use crate::{meta, plot, util};

/// The policy file (online network only, what `phalanx eval` and `models/` use) written
/// beside each checkpoint.
const POLICY: &str = "policy.bin";

/// The training-curve plot written beside the metrics.
const CURVES: &str = "curves.svg";

/// Episodes in the progress bar's recent success rate.
const SUCCESS_WINDOW: usize = 100;

/// The policies `phalanx train` trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TaskName {
    /// Path finding: reach the goals across a pool map.
    #[value(name = "pathfinding")]
    PathFinding,
    /// Formation: reach a random target formation from a random placement.
    Formation,
    /// The meta policy: choose path finding or formation per agent and step, over the frozen
    /// low-level policies, on the meta reward (Table I) weighted by w_f (Eq. 14).
    Meta,
    /// The end-to-end VDN baseline (docs/spec.md §7): the five moves on the meta reward with
    /// formation clipping and the same w_f, no hierarchy.
    E2e,
    /// The centralised (CTCE) baseline: the e2e task with one network that reads the whole
    /// team's observations and chooses the joint action agent after agent.
    Ctce,
    /// The imitation student: behaviour cloning of the centralised expert, then DAgger
    /// rounds (docs/imitation.md); `--steps` caps its updates.
    Imitation,
}

impl TaskName {
    /// The library's task.
    pub(crate) fn train_task(self) -> TrainTask {
        match self {
            TaskName::PathFinding => TrainTask::PathFinding,
            TaskName::Formation => TrainTask::Formation,
            TaskName::Meta => TrainTask::Meta,
            TaskName::E2e => TrainTask::EndToEnd,
            TaskName::Ctce => TrainTask::Centralised,
            TaskName::Imitation => unreachable!("imitation runs apart (imitate_train)"),
        }
    }
}

/// Trains a path-finding, formation or meta policy.
#[derive(Debug, clap::Args)]
pub(crate) struct TrainCmd {
    /// The policy to train.
    #[arg(value_enum)]
    task: TaskName,
    /// Settings (JSON, every field optional, over the task's defaults): agent_counts, n_envs,
    /// steps, checkpoint_every, net, learner, env, pool, shaping, reward_scale, init_from,
    /// meta (docs/learning.md, docs/hierarchy.md).
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
    /// Meta, e2e and ctce: train one policy at M times the base weight w_f (default: meta 0.1,
    /// e2e and ctce 1).
    #[arg(long, value_name = "M", conflicts_with = "formation_weight", value_parser = util::non_negative)]
    weight_multiple: Option<f64>,
    /// Meta, e2e and ctce: train one policy with the formation weight W for every team size.
    #[arg(long, value_name = "W", value_parser = util::non_negative)]
    formation_weight: Option<f64>,
    /// Meta, e2e and ctce: the idle cost C, lost per agent and step off its goal without
    /// getting closer (`env.idle_cost`; default: meta 1.5, e2e and ctce 0, Table I's reward).
    #[arg(long, value_name = "C", value_parser = util::non_negative)]
    idle_cost: Option<f64>,
    /// Train on your own maps instead of the generated pool (`pool.maps`): MovingAI .map
    /// files, instance files (.yaml, .scen: their map) or directories of .map files; every
    /// episode places a formation and its translated goals on one of them (docs/learning.md).
    #[arg(long, value_name = "PATH", num_args = 1..)]
    maps: Vec<PathBuf>,
    /// Meta: the share S of training episodes whose team starts in a formation as wide as
    /// Table II's large maps' (`meta.wide_share`; default 0.5).
    #[arg(long, value_name = "S", value_parser = util::fraction)]
    wide_share: Option<f64>,
    /// Imitation: a chain of runs as one command, each stage a run in its own folder under
    /// DIR started from an earlier stage's files (JSON `{"stages": [{"name", "seed",
    /// "config"}]}`; docs/imitation.md, *Recipes*; the shipped student's is
    /// models/imitation/recipe.json). `--resume` skips the finished stages.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["config", "steps", "maps"])]
    recipe: Option<PathBuf>,
}

/// Runs `phalanx train`.
pub(crate) fn run(cmd: TrainCmd) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        cmd.recipe.is_none() || cmd.task == TaskName::Imitation,
        "--recipe is for `phalanx train imitation`"
    );
    if cmd.task == TaskName::Imitation {
        for (flag, given) in [
            ("--weight-multiple", cmd.weight_multiple.is_some()),
            ("--formation-weight", cmd.formation_weight.is_some()),
            ("--idle-cost", cmd.idle_cost.is_some()),
            ("--wide-share", cmd.wide_share.is_some()),
        ] {
            anyhow::ensure!(!given, "{flag} is not a setting of `phalanx train imitation`");
        }
        if cmd.recipe.is_some()
            || (cmd.resume && cmd.out.join(crate::imitate_recipe::RECIPE).exists())
        {
            anyhow::ensure!(cmd.seed == 0, "--seed is a stage's setting in a recipe");
            return crate::imitate_recipe::run(cmd.recipe.as_deref(), &cmd.out, cmd.resume);
        }
        return crate::imitate_train::run(&crate::imitate_train::ImitationArgs {
            config: cmd.config,
            out: cmd.out,
            resume: cmd.resume,
            seed: cmd.seed,
            steps: cmd.steps,
            maps: cmd.maps,
        });
    }
    let dir = &cmd.out;
    let saved_config = dir.join("config.json");
    let task = cmd.task.train_task();
    let mut config = match (&cmd.config, cmd.resume) {
        (Some(path), _) => read_config(path, task)?,
        (None, true) if saved_config.exists() => read_config(&saved_config, task)?,
        (None, _) => TrainConfig::for_task(task),
    };
    if let Some(steps) = cmd.steps {
        config.steps = steps;
    }
    for (flag, value) in [
        ("--weight-multiple", cmd.weight_multiple),
        ("--formation-weight", cmd.formation_weight),
        ("--idle-cost", cmd.idle_cost),
    ] {
        if let Some(v) = value {
            anyhow::ensure!(
                task == TrainTask::Meta || task.is_end_to_end(),
                "{flag} {v} is for `phalanx train meta`, `e2e` and `ctce`"
            );
        }
    }
    if let Some(c) = cmd.idle_cost {
        config.env.idle_cost = c;
    }
    if let Some(multiple) = cmd.weight_multiple {
        config.meta.multiples = Multiples::Fixed { multiple };
    }
    if !cmd.maps.is_empty() {
        config.pool.maps.clone_from(&cmd.maps);
    }
    if let Some(share) = cmd.wide_share {
        anyhow::ensure!(task == TrainTask::Meta, "--wide-share is for `phalanx train meta`");
        config.meta.wide_share = share;
    }
    if let Some(w) = cmd.formation_weight {
        config.meta.multiples = Multiples::Fixed { multiple: 1.0 };
        config.meta.base_weight = Some(config.agent_counts.iter().map(|&k| (k, w)).collect());
    }
    if task == TrainTask::Meta {
        let inputs = MetaInputs { place: config.meta.place_input };
        config.net.env_vec = inputs.vector_len();
    }
    config.check().map_err(|err| anyhow::anyhow!("{err}"))?;
    let device = Device::flex().autodiff();
    let checkpoint = dir.join("checkpoint");
    let fresh = || {
        let (net, counts) = (config.net.clone(), &config.agent_counts);
        Learner::new(net, config.learner.clone(), counts, cmd.seed, &device)
    };
    let mut learner = util::learner(cmd.resume, &checkpoint, fresh, config.init_from.as_deref())?;
    if learner.agent_counts() != config.agent_counts {
        util::warn(&format!(
            "the checkpoint trains teams of {:?}; config agent_counts {:?} ignored",
            learner.agent_counts(),
            config.agent_counts
        ));
        config.agent_counts = learner.agent_counts().to_vec();
    }
    if !config.pool.maps.is_empty() {
        // One's own maps are read and checked before anything is written.
        phalanx_env::TrainPool::new(&config.pool).context("the training pool")?;
    }
    util::written(fs::create_dir_all(dir), dir)?;
    let building = || format!("building the {} environment", task.name());
    if task == TrainTask::Meta {
        let (low, meta) = meta::low_level(&config, &learner)?;
        config.meta.base_weight = Some(meta.weight.base.clone());
        learner.set_meta(meta.clone());
        write_config(&saved_config, &config)?;
        let mut collector = config.meta_collector(low, meta.weight.base).with_context(building)?;
        restore(&mut learner, &mut collector, &checkpoint, cmd.resume)?;
        return train(collector, learner, &config, dir, cmd.resume);
    }
    if task.is_end_to_end() {
        let (mut formation, _) = models::load(config.meta.formation.as_deref(), "formation")?;
        config.meta.base_weight = Some(meta::base_weights(&config, None, &mut formation)?);
    }
    write_config(&saved_config, &config)?;
    let mut collector = config.pool_collector(task).with_context(building)?;
    restore(&mut learner, &mut collector, &checkpoint, cmd.resume)?;
    train(collector, learner, &config, dir, cmd.resume)
}

/// Writes the run's settings to `DIR/config.json`.
fn write_config(path: &Path, config: &TrainConfig) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(config).expect("the config serialises");
    util::written(phalanx_io::write_text(path, &(json + "\n")), path)
}

/// On resume, restores the collection state of the checkpoint (warning when it has none).
fn restore<E: MarlEnv + Send>(
    learner: &mut Learner,
    collector: &mut Collector<E>,
    checkpoint: &Path,
    resume: bool,
) -> anyhow::Result<()> {
    if resume && !learner.restore_collection(checkpoint, collector).context("resuming")? {
        util::warn(&format!(
            "warning: {} has no collection state (an older or hand-made checkpoint): the replay \
             buffers refill before training goes on",
            checkpoint.display()
        ));
    }
    Ok(())
}

/// Reads a config file over `task`'s defaults.
fn read_config(path: &Path, task: TrainTask) -> anyhow::Result<TrainConfig> {
    let text =
        fs::read_to_string(path).with_context(|| format!("reading config {}", path.display()))?;
    TrainConfig::from_json(&text, task)
        .with_context(|| format!("parsing config {}", path.display()))
}

/// The collect/update loop with the progress bar, the metrics file and the checkpoints.
/// `Learner::train` runs in chunks of `checkpoint_every × train_every` environment steps
/// (about `checkpoint_every` updates once learning has started); a checkpoint is written after
/// each chunk that crossed a multiple of `checkpoint_every` updates.
fn train<E: MarlEnv + Send>(
    mut collector: Collector<E>,
    mut learner: Learner,
    config: &TrainConfig,
    dir: &Path,
    resume: bool,
) -> anyhow::Result<ExitCode> {
    let metrics_path = dir.join("metrics.jsonl");
    let checkpoint = dir.join("checkpoint");
    if resume {
        util::cut_metrics(&metrics_path, learner.counters().env_steps)?;
    }
    let file = fs::OpenOptions::new()
        .create(true)
        .append(resume)
        .write(true)
        .truncate(!resume)
        .open(&metrics_path)
        .with_context(|| format!("opening {}", metrics_path.display()))?;

    let start = learner.counters();
    let bar = util::rate_bar(config.steps, start.env_steps.min(config.steps), "steps");
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
            return util::written(Err(err), &metrics_path);
        }
        let updates = learner.counters().updates;
        if updates / every > last_saved {
            last_saved = updates / every;
            util::written(sink.out.flush(), &metrics_path)?;
            util::written(learner.save_with_collection(&checkpoint, &collector), &checkpoint)?;
            util::written(learner.save_policy(&dir.join(POLICY)), &dir.join(POLICY))?;
            plot_curves(dir);
        }
    }
    bar.finish_and_clear();
    util::written(sink.out.flush(), &metrics_path)?;
    util::written(learner.save_with_collection(&checkpoint, &collector), &checkpoint)?;
    util::written(learner.save_policy(&dir.join(POLICY)), &dir.join(POLICY))?;
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
    use phalanx_rl::{Multiples, TrainConfig, TrainTask};

    #[test]
    fn task_defaults_fill_only_what_the_file_leaves_out() {
        let formation = TrainConfig::for_task(TrainTask::Formation);
        assert_eq!(formation.agent_counts, [3, 4, 5]);
        assert_eq!((formation.n_envs, formation.env.step_limit), (15, Some(64)));
        assert_eq!(TrainConfig::for_task(TrainTask::PathFinding), TrainConfig::default());

        let text = r#"{"n_envs": 6, "env": {"step_limit": null}, "shaping": null}"#;
        let config = TrainConfig::from_json(text, TrainTask::Formation).unwrap();
        assert_eq!(config.agent_counts, [3, 4, 5]);
        assert_eq!((config.n_envs, config.env.step_limit), (6, None));
        assert_eq!(config.shaping_for(TrainTask::Formation), 20.0);
        assert_eq!(config.env.fov, 9);
        let err = TrainConfig::from_json("{\n  \"n_envs\": \"six\"\n}", TrainTask::Meta);
        assert!(err.unwrap_err().to_string().contains("line 2"));
        let err = TrainConfig::from_json(r#"{"agent_counts": [9]}"#, TrainTask::Meta);
        assert!(err.unwrap_err().to_string().contains("agent count 9"));
    }

    #[test]
    fn end_to_end_runs_weigh_each_team_size_by_its_base_weight() {
        let mut config = TrainConfig::for_task(TrainTask::EndToEnd);
        let meta = TrainConfig::for_task(TrainTask::Meta);
        assert_eq!((config.net.n_actions, config.steps), (5, 3 * meta.steps));
        assert_eq!(config.agent_counts, meta.agent_counts);
        assert_eq!(TrainTask::EndToEnd.env_task(), phalanx_env::Task::Meta);
        config.meta.base_weight = Some(vec![(3, 4.0), (5, 2.0)]);
        config.meta.multiples = Multiples::Fixed { multiple: 0.5 };
        assert_eq!(config.end_to_end_weight(3), 2.0);
        assert_eq!(config.end_to_end_weight(5), 1.0);
        // A size without a base weight falls back to the environment's weight.
        assert_eq!(config.end_to_end_weight(4), config.env.formation_weight);
        let collector = TrainConfig { n_envs: 2, ..config }.pool_collector(TrainTask::EndToEnd);
        assert!(collector.is_ok());
    }
}
