//! A training run's settings: the schema of `phalanx train --config FILE` and `DIR/config.json`,
//! the task defaults, and the environments they build.
//!
//! Layering, later over earlier: [`TrainConfig::default`] (the task-independent defaults),
//! the task's defaults ([`TrainConfig::for_task`]), the fields a file gives
//! ([`TrainConfig::from_json`], merged object by object), then what the caller's flags set.

use std::path::PathBuf;

use phalanx_env::{EnvConfig, EnvError, MarlEnv, PoolConfig, PoolEnv, Shaping, Task};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::hierarchy::{FormationWeight, LowLevel, Multiples};
use crate::hyper::LearnerConfig;
use crate::meta_env::{MetaEnv, MetaEnvConfig};
use crate::net::QNetConfig;
use crate::train::Collector;
use crate::weight::WeightConfig;

/// What a run trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrainTask {
    /// The path-finding policy ([`Task::PathFinding`] on the pool).
    PathFinding,
    /// The formation policy ([`Task::Formation`]: formation-training placements on the pool).
    Formation,
    /// The meta policy over the two frozen low-level policies ([`MetaEnv`]).
    Meta,
    /// The end-to-end VDN baseline (docs/spec.md §7): one network of the five moves on the meta
    /// reward ([`Task::Meta`] on the pool, formation clipping), no hierarchy.
    EndToEnd,
    /// The centralised (CTCE) baseline (docs/spec.md §7): the end-to-end task with a
    /// centralised network ([`QNetConfig::centralised`]): every agent's Q reads the whole
    /// team's observations and the actions chosen before it, so the network chooses the joint
    /// action, agent after agent in leader order, from the team's observations.
    Centralised,
}

impl TrainTask {
    /// The name on the command line and under `models/`.
    pub fn name(self) -> &'static str {
        match self {
            TrainTask::PathFinding => "pathfinding",
            TrainTask::Formation => "formation",
            TrainTask::Meta => "meta",
            TrainTask::EndToEnd => "e2e",
            TrainTask::Centralised => "ctce",
        }
    }

    /// Whether the task is one of the end-to-end baselines (the five moves on the meta
    /// reward with formation clipping, no hierarchy).
    pub fn is_end_to_end(self) -> bool {
        matches!(self, TrainTask::EndToEnd | TrainTask::Centralised)
    }

    /// The environment's reward task.
    pub fn env_task(self) -> Task {
        match self {
            TrainTask::PathFinding => Task::PathFinding,
            TrainTask::Formation => Task::Formation,
            TrainTask::Meta | TrainTask::EndToEnd | TrainTask::Centralised => Task::Meta,
        }
    }
}

/// Settings of a training run. Task-independent defaults: teams of 3, 16 environments in
/// lockstep, 200 000 steps, a checkpoint every 1000 updates, the default network and learner,
/// the paper's environment and pool, no shaping, reward scale 1. [`TrainConfig::for_task`]
/// layers each task's own on top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Team sizes trained (one shared network; environments take the sizes in turn).
    pub agent_counts: Vec<usize>,
    /// Environments played in lockstep (batched inference).
    pub n_envs: usize,
    /// Total environment steps.
    pub steps: u64,
    /// Gradient updates between checkpoints.
    pub checkpoint_every: u64,
    /// Network sizes (ignored on resume: the checkpoint's).
    pub net: QNetConfig,
    /// Learner hyper-parameters (ignored on resume: the checkpoint's).
    pub learner: LearnerConfig,
    /// Field of view and step limit (the task is the run's).
    pub env: EnvConfig,
    /// The training pool.
    pub pool: PoolConfig,
    /// Weight of the goal-progress bonus ([`Shaping`] with γ = 1: `weight` per unit of BFS
    /// distance an agent gains towards its goal, the same taken for each unit lost); 0: none;
    /// `null`: the task's default.
    pub shaping: Option<f32>,
    /// Factor on the team reward seen by the learner (shaping included); `null`: the task's
    /// default.
    pub reward_scale: Option<f32>,
    /// Warm start: initial weights from this checkpoint or policy file (same network);
    /// ignored on resume.
    pub init_from: Option<PathBuf>,
    /// The meta task's settings (used by [`TrainTask::Meta`] only).
    pub meta: MetaSettings,
}

/// The meta task's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MetaSettings {
    /// The frozen path-finding policy (a policy file or checkpoint); `None`: the shipped one.
    pub pathfinding: Option<PathBuf>,
    /// The frozen formation policy; `None`: the shipped one.
    pub formation: Option<PathBuf>,
    /// The base weights `w_f` per team size, `(size, w_f)`; `None`: estimated at the start of
    /// the run with [`MetaSettings::estimate`] (Eq. 14) and written into the run's config.
    pub base_weight: Option<Vec<(usize, f64)>>,
    /// The multiple of the base weight trained (default 0.1, the shipped meta policy's).
    pub multiples: Multiples,
    /// How the base weights are estimated when not given.
    pub estimate: WeightConfig,
    /// Whether the meta observation ends with the vector towards the agent's place in the
    /// goal layout placed on the front agent (`phalanx_env::MetaInputs::place`; default no).
    pub place_input: bool,
    /// Share of the training episodes whose team starts in a formation drawn from
    /// `phalanx_env::WIDE_SIDE` cells a side, as wide as Table II's large maps' (the pool's
    /// are half as wide; `TrainPool::sample_wide`); default 0.
    pub wide_share: f64,
}

impl Default for MetaSettings {
    fn default() -> Self {
        MetaSettings {
            pathfinding: None,
            formation: None,
            base_weight: None,
            multiples: Multiples::Fixed { multiple: 0.1 },
            estimate: WeightConfig::default(),
            place_input: false,
            wide_share: 0.0,
        }
    }
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
            shaping: Some(0.0),
            reward_scale: Some(1.0),
            init_from: None,
            meta: MetaSettings::default(),
        }
    }
}

/// Why a configuration file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// Not JSON of the schema (serde's message names the line, the column and the field).
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A value that parses but cannot be used.
    #[error("{0}")]
    Invalid(String),
}

impl TrainConfig {
    /// The defaults of `task`:
    /// - path finding: the task-independent defaults;
    /// - formation: teams of 3, 4 and 5 in 15 environments, episodes of at most 64 steps, the
    ///   goal-progress bonus 20 and reward scale 0.05 (the shipped formation policy's
    ///   settings);
    /// - meta: the shipped meta policy's settings (`models/meta`): teams of 3, 4 and 5 in 15
    ///   environments, full-length episodes (`3 × side`), a network of two actions reading
    ///   the place vector (`env_vec` 6, `meta.place_input`), `0.1 × w_f`, half the episodes'
    ///   teams drawn wide (`meta.wide_share` 0.5), the idle cost 1.5, reward scale 0.1,
    ///   300 000 steps;
    /// - e2e: the meta task's teams, episodes and reward scale with the five moves, one fixed
    ///   multiple (1) of the base weights, and 900 000 steps (three times the meta policy's,
    ///   docs/spec.md §7);
    /// - ctce: the e2e settings with a centralised network.
    pub fn for_task(task: TrainTask) -> TrainConfig {
        let base = TrainConfig::default();
        match task {
            TrainTask::PathFinding => base,
            TrainTask::Formation => TrainConfig {
                agent_counts: vec![3, 4, 5],
                n_envs: 15,
                env: EnvConfig { step_limit: Some(64), ..base.env.clone() },
                shaping: Some(20.0),
                reward_scale: Some(0.05),
                ..base
            },
            TrainTask::Meta => TrainConfig {
                agent_counts: vec![3, 4, 5],
                n_envs: 15,
                steps: 300_000,
                net: QNetConfig { n_actions: 2, env_vec: 6, ..QNetConfig::default() },
                env: EnvConfig { idle_cost: 1.5, ..base.env.clone() },
                reward_scale: Some(0.1),
                meta: MetaSettings {
                    place_input: true,
                    wide_share: 0.5,
                    ..MetaSettings::default()
                },
                ..base
            },
            TrainTask::EndToEnd => {
                let meta = TrainConfig::for_task(TrainTask::Meta);
                TrainConfig {
                    agent_counts: meta.agent_counts,
                    n_envs: meta.n_envs,
                    steps: 900_000,
                    reward_scale: meta.reward_scale,
                    meta: MetaSettings {
                        multiples: Multiples::Fixed { multiple: 1.0 },
                        ..MetaSettings::default()
                    },
                    ..base
                }
            }
            TrainTask::Centralised => {
                let e2e = TrainConfig::for_task(TrainTask::EndToEnd);
                TrainConfig { net: QNetConfig { centralised: true, ..e2e.net.clone() }, ..e2e }
            }
        }
    }

    /// The settings of a configuration file's JSON text: the fields it gives over `task`'s
    /// defaults (objects merged field by field, so `{"env": {"fov": 7}}` keeps the task's
    /// step limit).
    ///
    /// # Errors
    /// If the text is not JSON of the schema (the message names line and column) or its
    /// values cannot be used ([`TrainConfig::check`]).
    pub fn from_json(text: &str, task: TrainTask) -> Result<TrainConfig, SettingsError> {
        // Typed first, so that errors name the line and the field.
        let _: TrainConfig = serde_json::from_str(text)?;
        let given: Value = serde_json::from_str(text)?;
        let mut merged = serde_json::to_value(TrainConfig::for_task(task)).expect("serialises");
        merge(&mut merged, given);
        let config: TrainConfig = serde_json::from_value(merged)?;
        config.check()?;
        Ok(config)
    }

    /// Checks what the schema cannot: positive counts and sizes within the network's slots.
    ///
    /// # Errors
    /// Naming the field and its value.
    pub fn check(&self) -> Result<(), SettingsError> {
        let invalid = |msg: String| Err(SettingsError::Invalid(msg));
        self.net.check().map_err(|err| SettingsError::Invalid(format!("net: {err}")))?;
        let max = self.net.n_agents_max;
        if self.agent_counts.is_empty() {
            return invalid("agent_counts must not be empty".into());
        }
        if let Some(&n) = self.agent_counts.iter().find(|&&n| !(1..=max).contains(&n)) {
            return invalid(format!(
                "agent count {n} must be between 1 and the network's n_agents_max {max}"
            ));
        }
        if self.n_envs == 0 {
            return invalid("n_envs must be positive".into());
        }
        if let Some(scale) = self.reward_scale
            && !(scale.is_finite() && scale > 0.0)
        {
            return invalid(format!("reward_scale {scale} must be positive"));
        }
        if let Some(shaping) = self.shaping
            && !shaping.is_finite()
        {
            return invalid(format!("shaping {shaping} must be finite"));
        }
        let idle = self.env.idle_cost;
        if !(idle.is_finite() && idle >= 0.0) {
            return invalid(format!("env.idle_cost {idle} must be a non-negative number"));
        }
        let Multiples::Fixed { multiple } = self.meta.multiples;
        if !(multiple.is_finite() && multiple >= 0.0) {
            return invalid(format!("meta.multiples: multiple {multiple} is not a weight"));
        }
        let wide = self.meta.wide_share;
        if !(0.0..=1.0).contains(&wide) {
            return invalid(format!("meta.wide_share {wide} must be between 0 and 1"));
        }
        if let Some(base) = &self.meta.base_weight {
            if base.is_empty() {
                return invalid("meta.base_weight must name at least one team size".into());
            }
            if let Some(&(k, w)) = base.iter().find(|(_, w)| !(w.is_finite() && *w >= 0.0)) {
                return invalid(format!("meta.base_weight for {k} agents is {w}, not a weight"));
            }
        }
        Ok(())
    }

    /// The step limit of the training episodes: the configured one, else `3 × pool side`;
    /// on one's own maps (`pool.maps`) each episode's own `3 ×` its map's side, which the
    /// environment truncates at (the collector then only cuts at `3 × 8192`, past any map).
    pub fn step_limit(&self) -> usize {
        match self.env.step_limit {
            Some(limit) => limit as usize,
            None if !self.pool.maps.is_empty() => 3 * 8192,
            None => 3 * self.pool.size as usize,
        }
    }

    /// The goal-progress bonus's weight: the configured one, else `task`'s default.
    pub fn shaping_for(&self, task: TrainTask) -> f32 {
        self.shaping.or(TrainConfig::for_task(task).shaping).unwrap_or(0.0)
    }

    /// The reward scale: the configured one, else `task`'s default.
    pub fn reward_scale_for(&self, task: TrainTask) -> f32 {
        self.reward_scale.or(TrainConfig::for_task(task).reward_scale).unwrap_or(1.0)
    }

    /// The formation weight of the end-to-end task for teams of `n_agents`: the base weight
    /// `meta.base_weight` gives for the size times the fixed multiple, else the environment's
    /// `formation_weight`.
    pub fn end_to_end_weight(&self, n_agents: usize) -> f64 {
        let base = self
            .meta
            .base_weight
            .as_ref()
            .and_then(|base| base.iter().find(|&&(k, _)| k == n_agents).map(|&(_, w)| w));
        let Multiples::Fixed { multiple } = self.meta.multiples;
        base.map_or(self.env.formation_weight, |w| w * multiple)
    }

    /// The low-level and end-to-end tasks' collector: `n_envs` [`PoolEnv`]s of `task` taking
    /// the team sizes in turn, with the shaping and reward scale of the settings (and for the
    /// end-to-end task each size's [`TrainConfig::end_to_end_weight`]).
    ///
    /// # Errors
    /// If the environment or the pool cannot be built.
    pub fn pool_collector(&self, task: TrainTask) -> Result<Collector<PoolEnv>, EnvError> {
        let weight = self.shaping_for(task);
        let shaping = (weight != 0.0).then_some(Shaping { weight, gamma: 1.0 });
        let first =
            PoolEnv::new(task.env_task(), &self.pool, self.env.clone(), self.agent_counts[0])?
                .with_shaping(shaping)
                .with_reward_scale(self.reward_scale_for(task));
        self.collector_of(&first, |first, k| {
            let env = first.with_agents(k)?;
            Ok(if task.is_end_to_end() {
                env.with_formation_weight(self.end_to_end_weight(k))
            } else {
                env
            })
        })
    }

    /// The meta task's collector over `low` with the base weights `base` (`(size, w_f)`).
    ///
    /// # Errors
    /// If the environment or the pool cannot be built.
    pub fn meta_collector(
        &self,
        low: LowLevel,
        base: Vec<(usize, f64)>,
    ) -> Result<Collector<MetaEnv>, EnvError> {
        let config = MetaEnvConfig {
            weight: FormationWeight { base, multiples: self.meta.multiples },
            place_input: self.meta.place_input,
            pool: self.pool.clone(),
            env: self.env.clone(),
            reward_scale: self.reward_scale_for(TrainTask::Meta),
            wide_share: self.meta.wide_share,
        };
        let first = MetaEnv::new(low, config, self.agent_counts[0])?;
        self.collector_of(&first, MetaEnv::with_agents)
    }

    /// `n_envs` environments made from `first` by `with_agents`, taking the team sizes in
    /// turn, in a collector of the run's step limit.
    fn collector_of<E: MarlEnv + Send>(
        &self,
        first: &E,
        with_agents: impl Fn(&E, usize) -> Result<E, EnvError>,
    ) -> Result<Collector<E>, EnvError> {
        let counts = &self.agent_counts;
        let envs = (0..self.n_envs)
            .map(|e| with_agents(first, counts[e % counts.len()]))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Collector::new(envs, self.step_limit()))
    }
}

/// `over`'s fields written into `base`, objects merged recursively (anything else replaced).
fn merge(base: &mut Value, over: Value) {
    match (base, over) {
        (Value::Object(base), Value::Object(over)) => {
            for (key, value) in over {
                match base.get_mut(&key) {
                    Some(slot) => merge(slot, value),
                    None => {
                        base.insert(key, value);
                    }
                }
            }
        }
        (slot, value) => *slot = value,
    }
}
