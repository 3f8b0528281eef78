//! Behaviour cloning and DAgger (`docs/imitation.md`, *The student*): the settings of a
//! run, its schedule of rounds, and the expert data turned into the learner's episodes.
//!
//! A run trains one network of the end-to-end kind (five moves on the meta task, agents in
//! leader order with the action messages) on the expert's labels:
//! - round 0 clones the expert on the data of [`ImitationConfig::data`] for
//!   [`ImitationConfig::updates`] updates;
//! - each DAgger round `k` (1 to [`ImitationConfig::rounds`]) lets the student play
//!   [`ImitationConfig::round_episodes`] fresh episodes of the training pool as it acts at
//!   test time, has the expert label every state it reaches ([`super::generate_with`]), adds
//!   them to what it has, and trains [`ImitationConfig::round_updates`] updates more on all of it.
//!
//! The schedule is a function of the update count alone, so a run resumed from a
//! checkpoint knows which round it is in and which data files it needs.

use std::path::PathBuf;

use phalanx_env::obs::VECTOR_LEN;
use phalanx_env::{EnvConfig, LeaderRule, MapKind, ObsBuffers, PoolConfig, Task, TaskEnv};
use serde::{Deserialize, Serialize};

use super::finetune::{CloningData, FinetuneConfig};
use super::{DataConfig, DataError, Dataset, ExpertChoice, ExpertEpisode, StudentRollouts};
use crate::learner::{Learner, LearnerConfig};
use crate::net::QNetConfig;
use crate::replay::{Episode, SequenceMode};

/// Settings of an imitation run (`phalanx train imitation`; a settings file may give any
/// subset of the fields).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImitationConfig {
    /// The cloning data: expert episodes on the training pool (teams of 3 to 8 by default).
    pub data: DataConfig,
    /// More expert data cloned beside `data` from round 0 on, each set its own file
    /// (`data-0-K.bin`, K from 1): episodes of other pools (mazes, rooms, the user's maps)
    /// labelled by the expert that suits them. An object in a settings file is read over
    /// `data`, field by field (`{"pool": {"kind": "maze"}, "expert": "cbs", "seed": 7}`
    /// keeps `data`'s environment and team sizes). Batches take the team sizes in turn and,
    /// within one, episodes uniformly: a set's share of the batches is its share of the
    /// episodes of its team sizes. Default: the shipped student's [`corridor_sets`] over
    /// `data`; `[]` for none.
    pub more_data: Vec<DataConfig>,
    /// The student's network (five actions, the goal and place vectors, 8 agent slots).
    pub net: QNetConfig,
    /// Adam's learning rate.
    pub lr: f64,
    /// Sequences per update.
    pub batch_size: usize,
    /// How sequences are cut (default whole episodes: the recurrent state as at test time).
    pub sequence: SequenceMode,
    /// Clip the global gradient norm to this value; `None`: no clip.
    pub grad_clip_norm: Option<f32>,
    /// Updates of round 0 (cloning); default 1250.
    pub updates: u64,
    /// DAgger rounds after cloning; default 0: with the team vector no round was chosen on
    /// the validation stream over the cloning alone (docs/imitation.md).
    pub rounds: u32,
    /// Student episodes relabelled per DAgger round.
    pub round_episodes: u64,
    /// The training pool of the DAgger rounds' episodes (`None`: the cloning data's,
    /// `data.pool`); larger maps than cloning's let the student meet long routes.
    pub round_pool: Option<PoolConfig>,
    /// The expert that labels the DAgger rounds' states (`None`: the cloning data's,
    /// `data.expert`). The student leaves the expert's plan at most steps, so the expert
    /// re-plans at most steps: `swarm` costs 10–100× less per plan than `swarm-jsa`
    /// (docs/imitation.md, *The expert alone*).
    pub round_expert: Option<ExpertChoice>,
    /// Updates after each DAgger round's data.
    pub round_updates: u64,
    /// The student's random-action rate in its DAgger rollouts.
    pub round_epsilon: f64,
    /// A DAgger rollout ends when the team reaches one joint state this many times (it
    /// stands still or oscillates; 0: never). The stall's states are labelled once or twice
    /// each; without the cut, a stuck student costs the expert a re-plan at every step up to
    /// the step limit (measured: 26–48 minutes per 150 episodes on 64² maps).
    pub round_stall_visits: u32,
    /// A checkpoint every this many updates (and at the end of every round).
    pub checkpoint_every: u64,
    /// Start from this checkpoint's or policy file's network.
    pub init_from: Option<PathBuf>,
    /// Validation after every round: this many instances of every Table II row.
    pub validation_maps: u64,
    /// Validation also every this many updates within a round (`None`: at the end of every
    /// round only, as the shipped student). A student's closed-loop figures swing between
    /// snapshots of one cloning run (docs/experiments.md, 2026-12-05 night): validating
    /// more often lets `policy.bin` be the best of them. Not written when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validate_every: Option<u64>,
    /// The seed of the validation stream (the benchmark's test stream is seed 11).
    pub validation_seed: u64,
    /// Validate on the rows of maps at most this side only (`None`: every row).
    pub validation_max_side: Option<u32>,
    /// Fine-tuning on the meta reward after cloning and the rounds, one update per
    /// iteration ([`super::finetune`]; `null`: none).
    pub finetune: Option<FinetuneConfig>,
}

/// The shipped student's corridor sets over `data` (docs/imitation.md, *Corridors*): 900
/// episodes of generated 32² mazes and 600 of 64² rooms, labelled by CBS, with `data`'s
/// environment, noise and node limit and its team sizes among 3, 4 and 5 (none when it has
/// none of them).
pub fn corridor_sets(data: &DataConfig) -> Vec<DataConfig> {
    let agents: Vec<usize> = data.agents.iter().copied().filter(|n| (3..=5).contains(n)).collect();
    if agents.is_empty() {
        return Vec::new();
    }
    let set = |kind, size, episodes, seed| DataConfig {
        pool: PoolConfig { kind, size, ..PoolConfig::default() },
        expert: ExpertChoice::Cbs,
        agents: agents.clone(),
        episodes,
        seed,
        student: None,
        ..data.clone()
    };
    vec![set(MapKind::Maze, 32, 900, 10), set(MapKind::Rooms, 64, 600, 11)]
}

impl Default for ImitationConfig {
    fn default() -> ImitationConfig {
        let data =
            DataConfig { agents: vec![3, 4, 5, 6, 7, 8], episodes: 1500, ..DataConfig::default() };
        ImitationConfig {
            more_data: corridor_sets(&data),
            data,
            net: QNetConfig { env_vec: 3 * VECTOR_LEN, ..QNetConfig::default() },
            lr: 1e-3,
            batch_size: 16,
            sequence: SequenceMode::Episodes,
            grad_clip_norm: Some(10.0),
            updates: 1250,
            rounds: 0,
            round_episodes: 300,
            round_pool: None,
            round_expert: None,
            round_updates: 1500,
            round_epsilon: 0.0,
            round_stall_visits: 3,
            checkpoint_every: 250,
            init_from: None,
            validation_maps: 10,
            validate_every: None,
            validation_seed: 1,
            validation_max_side: None,
            finetune: Some(FinetuneConfig::default()),
        }
    }
}

impl ImitationConfig {
    /// Parses a settings file's JSON over the defaults. A `data` object given in part is
    /// read over the student's default data (teams of 3 to 8, 1500 episodes), field by
    /// field, not over the data settings' own defaults: `{"data": {"seed": 1}}` changes the
    /// seed only.
    ///
    /// # Errors
    /// When the JSON does not parse (naming the line) or a value is out of range.
    pub fn from_json(text: &str) -> Result<ImitationConfig, String> {
        // Parsed as it is first, so that a syntax error or an unknown field names its line.
        let mut config: ImitationConfig =
            serde_json::from_str(text).map_err(|err| format!("{err}"))?;
        let given: serde_json::Value =
            serde_json::from_str(text).map_err(|err| format!("{err}"))?;
        let over = |base: &DataConfig, fields: &serde_json::Map<String, serde_json::Value>| {
            let mut data = serde_json::to_value(base).map_err(|err| format!("{err}"))?;
            for (key, value) in fields {
                data[key] = value.clone();
            }
            serde_json::from_value::<DataConfig>(data).map_err(|err| format!("{err}"))
        };
        if let Some(fields) = given.get("data").and_then(|it| it.as_object()) {
            config.data = over(&ImitationConfig::default().data, fields)
                .map_err(|err| format!("data: {err}"))?;
        }
        // The default sets follow the data given; the sets given are read over it (parsed
        // above, so every one is an object).
        if given.get("more_data").is_none() {
            config.more_data = corridor_sets(&config.data);
        }
        let sets = given.get("more_data").and_then(|it| it.as_array()).into_iter().flatten();
        for (k, (set, given)) in config.more_data.iter_mut().zip(sets).enumerate() {
            if let Some(fields) = given.as_object() {
                *set =
                    over(&config.data, fields).map_err(|err| format!("more_data[{k}]: {err}"))?;
            }
        }
        config.check()?;
        Ok(config)
    }

    /// Refuses values a run cannot follow, naming the field and its value.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn check(&self) -> Result<(), String> {
        self.net.check().map_err(|err| format!("net: {err}"))?;
        let net = &self.net;
        let env = &self.data.env;
        env.check().map_err(|err| format!("data.env: {err}"))?;
        let vector = env.vector_len();
        if net.n_actions != phalanx_core::Action::COUNT || net.env_vec != vector || net.centralised
        {
            return Err(format!(
                "net: the student is a decentralised network of 5 actions and a vector of \
                 {vector} (data.env.place_vector {}, team_vector {}; n_actions {}, env_vec {}, \
                 centralised {})",
                env.place_vector, env.team_vector, net.n_actions, net.env_vec, net.centralised
            ));
        }
        if env.place_vector && env.task != Task::Meta {
            return Err("data.env.place_vector: the place vector is the meta task's".into());
        }
        if self.data.env.fov as usize != net.fov {
            return Err(format!("net.fov {} is not data.env.fov {}", net.fov, self.data.env.fov));
        }
        if let Some(&n) = self.data.agents.iter().find(|&&n| n == 0 || n > net.n_agents_max) {
            return Err(format!("data.agents: {n} agents do not fit {} slots", net.n_agents_max));
        }
        for (k, more) in self.more_data.iter().enumerate() {
            if more.env != self.data.env || more.leader_rule != self.data.leader_rule {
                return Err(format!(
                    "more_data[{k}]: its env and leader_rule must be data's (the student reads \
                     one kind of observation)"
                ));
            }
            if more.student.is_some() || more.episodes == 0 {
                return Err(format!(
                    "more_data[{k}]: expert data of at least one episode (no student)"
                ));
            }
            if let Some(n) = more.agents.iter().find(|n| !self.data.agents.contains(n)) {
                return Err(format!(
                    "more_data[{k}].agents: the student trains teams of {:?} (data.agents), \
                     not {n}",
                    self.data.agents
                ));
            }
        }
        if self.data.leader_rule != self.data.env.task.leader_rule() {
            return Err(format!(
                "data.leader_rule: {:?} is not the order the {:?} task acts in",
                self.data.leader_rule, self.data.env.task
            ));
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(format!("lr: {} is not a positive number", self.lr));
        }
        if self.batch_size == 0 || self.checkpoint_every == 0 || self.validate_every == Some(0) {
            return Err("batch_size, checkpoint_every and validate_every must be at least 1".into());
        }
        if let SequenceMode::Windows { len: 0, .. } = self.sequence {
            return Err("sequence: windows of 0 transitions".into());
        }
        if self.data.episodes == 0 || (self.rounds > 0 && self.round_episodes == 0) {
            return Err("data.episodes and round_episodes must be at least 1".into());
        }
        if !(0.0..=1.0).contains(&self.round_epsilon) {
            return Err(format!("round_epsilon: {} is not a probability", self.round_epsilon));
        }
        if self.grad_clip_norm.is_some_and(|it| !(it.is_finite() && it > 0.0)) {
            return Err(format!("grad_clip_norm: {:?} is not positive", self.grad_clip_norm));
        }
        if let Some(finetune) = &self.finetune {
            finetune.check()?;
            if let Some(&n) = finetune.agents.iter().find(|&&n| n == 0 || n > net.n_agents_max) {
                return Err(format!(
                    "finetune.agents: {n} agents do not fit {} slots",
                    net.n_agents_max
                ));
            }
        }
        self.total_updates().map(|_| ()).ok_or_else(|| "the updates overflow".to_owned())
    }

    /// Whether the run's expert data is its `more_data` sets alone: no cloning update or
    /// round, and a fine-tuning whose cloning term draws on those sets only (the paper's data
    /// is then neither made nor read).
    pub fn clones_more_only(&self) -> bool {
        self.round_end(self.rounds) == 0
            && self.finetune.as_ref().is_some_and(|it| it.cloning_data == CloningData::More)
    }

    /// Whether the fine-tuning has a cloning term with data to draw on: a `cloning` weight
    /// above 0, and `more_data` sets or `cloning_data` `all`.
    pub fn cloning_term(&self) -> bool {
        self.finetune.as_ref().is_some_and(|it| {
            it.cloning > 0.0 && (it.cloning_data == CloningData::All || !self.more_data.is_empty())
        })
    }

    /// The learner's settings: Adam at `lr`, batches of `batch_size` sequences cut by
    /// `sequence`, every episode kept (no replay eviction), an update as soon as one team
    /// size has data.
    pub fn learner_config(&self) -> LearnerConfig {
        LearnerConfig {
            lr: self.lr,
            batch_size: self.batch_size,
            replay_capacity: usize::MAX / 2,
            sequence: self.sequence,
            grad_clip_norm: self.grad_clip_norm,
            learning_starts: 1,
            target_update_interval: self.checkpoint_every,
            ..LearnerConfig::default()
        }
    }

    /// Updates of the whole run (`None` on overflow).
    pub fn total_updates(&self) -> Option<u64> {
        let finetune = self.finetune.as_ref().map_or(0, |it| it.iterations);
        self.round_end_checked(self.rounds)?.checked_add(finetune)
    }

    /// [`ImitationConfig::round_end`], `None` on overflow.
    fn round_end_checked(&self, round: u32) -> Option<u64> {
        self.round_updates.checked_mul(u64::from(round))?.checked_add(self.updates)
    }

    /// The update count at which `round` ends (round 0 is cloning).
    pub fn round_end(&self, round: u32) -> u64 {
        self.updates + self.round_updates * u64::from(round)
    }

    /// The data settings of DAgger round `round` (1 on): `round_episodes` episodes of
    /// `round_pool` from their own seed, moved by the student whose network has the CRC-32
    /// `network`.
    pub fn round_data(&self, round: u32, network: u32) -> DataConfig {
        DataConfig {
            pool: self.round_pool.clone().unwrap_or_else(|| self.data.pool.clone()),
            expert: self.round_expert.unwrap_or(self.data.expert),
            episodes: self.round_episodes,
            seed: round_seed(self.data.seed, round),
            student: Some(StudentRollouts {
                round,
                network,
                epsilon: self.round_epsilon,
                stall_visits: self.round_stall_visits,
            }),
            ..self.data.clone()
        }
    }
}

/// The seed of DAgger round `round`'s episodes: far from the cloning data's stream (episode
/// `i` of round `k` draws from stream `i` of this seed).
fn round_seed(seed: u64, round: u32) -> u64 {
    seed.wrapping_add(u64::from(round).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// The learner's episode of an expert episode: every step's observations in `env`
/// (replayed with the actions taken), the acting order of `rule` and, as the actions, the
/// expert's labels. `None` for an episode without steps.
///
/// # Errors
/// If the environment refuses the instance or the replay leaves the recorded positions or
/// order.
pub fn learner_episode(
    episode: &ExpertEpisode,
    env: &EnvConfig,
    rule: LeaderRule,
) -> Result<Option<Episode>, DataError> {
    if episode.steps.is_empty() {
        return Ok(None);
    }
    let index = episode.index;
    if rule != env.task.leader_rule() {
        return Err(DataError::Replay { episode: index, step: 0, what: "acting order" });
    }
    let n = episode.instance.n_agents();
    let mut sim =
        TaskEnv::new(env.task, env.clone(), n).map_err(|err| DataError::Env(index, err))?;
    let mut obs = ObsBuffers::new(n, sim.obs_shape());
    sim.reset_to(&episode.instance, &mut obs).map_err(|err| DataError::Env(index, err))?;
    let mut out = Episode::start(&obs);
    let n_actions = obs.shape.n_actions;
    let mut labels = vec![0_u8; n];
    let mut taken = vec![0_u8; n];
    for (t, step) in episode.steps.iter().enumerate() {
        if sim.env().positions() != step.positions.as_slice() {
            return Err(DataError::Replay { episode: index, step: t, what: "positions" });
        }
        let order = obs.order.iter().map(|&agent| agent as u16);
        if !order.eq(step.order.iter().copied()) {
            return Err(DataError::Replay { episode: index, step: t, what: "acting order" });
        }
        for agent in 0..n {
            labels[agent] = step.expert[agent].index() as u8;
            taken[agent] = step.taken[agent].index() as u8;
            // The label is always an allowed action (the expert moves into free cells).
            let row = (out.len * n + agent) * n_actions;
            out.action_mask[row + usize::from(labels[agent])] = true;
        }
        let done = sim.step(&taken, &mut obs);
        out.push_step(&labels, 0.0, &obs);
        out.terminated = done.terminated;
    }
    Ok(Some(out))
}

/// Adds every episode of `data` to `learner`'s buffers (as [`learner_episode`] makes them);
/// returns the samples added (agents × steps).
///
/// # Errors
/// As [`learner_episode`]; also for a team size the learner does not train.
pub fn add_to_learner(learner: &mut Learner, data: &Dataset) -> Result<u64, DataError> {
    let (env, rule) = (&data.config.env, data.config.leader_rule);
    let mut samples = 0;
    for episode in &data.episodes {
        let n = episode.instance.n_agents();
        if !learner.agent_counts().contains(&n) {
            return Err(DataError::Settings(format!(
                "episode {}: a team of {n}; the student trains teams of {:?}",
                episode.index,
                learner.agent_counts()
            )));
        }
        if let Some(it) = learner_episode(episode, env, rule)? {
            samples += (it.len * it.n_agents) as u64;
            learner.store(it);
        }
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use burn::tensor::Device;
    use phalanx_env::PoolConfig;

    use super::super::{ExpertChoice, for_each_sample, generate, generate_with};
    use super::*;

    /// A small run's settings: a few 16² pool maps, teams of 3 and 4, the fast expert.
    fn small() -> ImitationConfig {
        ImitationConfig {
            data: DataConfig {
                pool: PoolConfig { n_maps: 3, size: 16, ..PoolConfig::default() },
                agents: vec![3, 4],
                episodes: 6,
                seed: 3,
                noise: 0.1,
                expert: ExpertChoice::Swarm,
                ..DataConfig::default()
            },
            batch_size: 4,
            ..ImitationConfig::default()
        }
    }

    #[test]
    fn the_learner_sees_what_the_samples_hold() {
        let config = small();
        let data = generate(&config.data, &|_| {}).unwrap().0;
        for episode in &data.episodes {
            let rule = config.data.leader_rule;
            let it = learner_episode(episode, &config.data.env, rule).unwrap().unwrap();
            let n = it.n_agents;
            assert_eq!((it.len, n), (episode.steps.len(), episode.instance.n_agents()));
            let grid = it.grid.len() / ((it.len + 1) * n);
            let mut count = 0;
            for_each_sample(episode, &config.data.env, rule, |s| {
                let row = s.t * n + s.agent;
                assert_eq!(&it.grid[row * grid..(row + 1) * grid], s.grid);
                let width = s.vector.len();
                assert_eq!(width, 9, "the student reads the goal, place and team vectors");
                assert_eq!(&it.vec[row * width..(row + 1) * width], s.vector);
                assert_eq!(&it.action_mask[row * 5..row * 5 + 5], s.mask);
                assert_eq!(it.order[s.t * n + s.rank], s.agent);
                assert_eq!(usize::from(it.actions[row]), s.target.index());
                count += 1;
            })
            .unwrap();
            assert_eq!(count, it.len * n);
        }
    }

    #[test]
    fn cloning_fits_the_labels_and_the_student_can_be_relabelled() {
        let config = small();
        let device = Device::flex().autodiff();
        let mut learner =
            Learner::new(config.net.clone(), config.learner_config(), &[3, 4], 1, &device);
        let data = generate(&config.data, &|_| {}).unwrap().0;
        let samples = add_to_learner(&mut learner, &data).unwrap();
        assert_eq!(samples, data.n_samples());
        let first = learner.imitation_update().unwrap();
        let mut last = first;
        for _ in 0..60 {
            last = learner.imitation_update().unwrap();
        }
        assert!(first.loss.is_finite() && last.loss < 0.7 * first.loss, "{first:?} -> {last:?}");
        assert!(last.accuracy > first.accuracy, "{first:?} -> {last:?}");

        // A DAgger round: the student moves the team, the expert labels every state.
        let policy = learner.policy();
        let round = ImitationConfig { round_episodes: 3, ..config.clone() }.round_data(1, 0);
        let relabelled = generate_with(&round, Some(&policy), &|_| {}).unwrap().0;
        assert_eq!(relabelled.episodes.len(), 3);
        assert!(relabelled.episodes.iter().all(|e| !e.steps.is_empty()));
        add_to_learner(&mut learner, &relabelled).unwrap();
        // The same round again is the same data (the student is greedy, the seed fixed).
        assert_eq!(generate_with(&round, Some(&policy), &|_| {}).unwrap().0, relabelled);
        // The settings and the student go together.
        assert!(generate_with(&round, None, &|_| {}).is_err());
        assert!(generate_with(&config.data, Some(&policy), &|_| {}).is_err());
    }

    #[test]
    fn the_schedule_follows_the_update_count() {
        let config = ImitationConfig {
            updates: 100,
            rounds: 3,
            round_updates: 40,
            finetune: None,
            ..Default::default()
        };
        assert_eq!(config.total_updates(), Some(220));
        let finetune = ImitationConfig {
            finetune: Some(FinetuneConfig { iterations: 30, ..FinetuneConfig::default() }),
            ..config.clone()
        };
        assert_eq!(finetune.total_updates(), Some(250));
        assert_eq!(finetune.round_end(3), 220, "the fine-tuning follows the rounds");
        assert_eq!(
            (config.round_end(0), config.round_end(1), config.round_end(3)),
            (100, 140, 220)
        );
        let round = config.round_data(2, 7);
        assert_eq!(round.episodes, config.round_episodes);
        assert_ne!(round.seed, config.data.seed);
        assert_ne!(round.seed, config.round_data(1, 7).seed);
        assert_eq!(round.student.unwrap().round, 2);
        assert_eq!(round.expert, config.data.expert);
        let swarm = ImitationConfig { round_expert: Some(ExpertChoice::Swarm), ..config.clone() };
        assert_eq!(swarm.round_data(2, 7).expert, ExpertChoice::Swarm);
        assert_eq!(swarm.round_data(2, 7).student.unwrap().stall_visits, 3);
        config.check().unwrap();
    }

    #[test]
    fn a_partial_data_object_keeps_the_students_defaults() {
        let config = ImitationConfig::from_json(r#"{"data": {"seed": 7}}"#).unwrap();
        let parsed = ImitationConfig::from_json(r#"{"round_expert": "swarm"}"#).unwrap();
        assert_eq!(parsed.round_expert, Some(ExpertChoice::Swarm));
        let default = ImitationConfig::default();
        assert_eq!(config.data, DataConfig { seed: 7, ..default.data.clone() });
        assert_eq!(config.data.agents, [3, 4, 5, 6, 7, 8]);
        let given = r#"{"data": {"agents": [3], "episodes": 9}}"#;
        let config = ImitationConfig::from_json(given).unwrap();
        assert_eq!((config.data.agents, config.data.episodes), (vec![3], 9));
        assert_eq!(config.data.env, default.data.env);
        assert!(ImitationConfig::from_json(r#"{"data": {"sed": 7}}"#).unwrap_err().contains("sed"));
    }

    #[test]
    fn more_data_is_read_over_the_data_and_checked() {
        let given = r#"{"data": {"agents": [3, 4], "seed": 5},
                        "more_data": [{"pool": {"kind": "maze"}, "expert": "cbs", "seed": 9}]}"#;
        let config = ImitationConfig::from_json(given).unwrap();
        let [maze] = config.more_data.as_slice() else { panic!("one set") };
        let pool = PoolConfig { kind: phalanx_env::MapKind::Maze, ..PoolConfig::default() };
        let expected =
            DataConfig { pool, expert: ExpertChoice::Cbs, seed: 9, ..config.data.clone() };
        assert_eq!(maze, &expected, "the fields not given are data's");
        let round_trip = serde_json::to_string(&config).unwrap();
        assert_eq!(ImitationConfig::from_json(&round_trip).unwrap(), config);
        let none = ImitationConfig::from_json(r#"{"more_data": []}"#).unwrap();
        let written = serde_json::to_string(&none).unwrap();
        assert_eq!(ImitationConfig::from_json(&written).unwrap().more_data, []);
        // By default, the corridor sets over the data given.
        let default = ImitationConfig::default();
        let kinds: Vec<_> = default.more_data.iter().map(|it| (it.pool.kind, it.expert)).collect();
        assert_eq!(
            kinds,
            [(MapKind::Maze, ExpertChoice::Cbs), (MapKind::Rooms, ExpertChoice::Cbs)]
        );
        assert!(default.more_data.iter().all(|it| it.agents == [3, 4, 5]));
        let threes = ImitationConfig::from_json(r#"{"data": {"agents": [3, 8], "seed": 4}}"#);
        let threes = threes.unwrap();
        assert_eq!(threes.more_data, corridor_sets(&threes.data));
        assert!(threes.more_data.iter().all(|it| it.agents == [3] && it.seed != 4));
        let eights = ImitationConfig::from_json(r#"{"data": {"agents": [8]}}"#).unwrap();
        assert!(eights.more_data.is_empty() && !eights.cloning_term());
        assert!(default.cloning_term() && !none.cloning_term());
        let all = r#"{"more_data": [], "finetune": {"cloning_data": "all"}}"#;
        assert!(ImitationConfig::from_json(all).unwrap().cloning_term());
        let bad = |text: &str| ImitationConfig::from_json(text).unwrap_err();
        assert!(bad(r#"{"more_data": [3]}"#).contains("expected struct DataConfig at line 1"));
        assert!(bad(r#"{"more_data": [{"sed": 1}]}"#).contains("unknown field `sed`"));
        let wider = bad(r#"{"data": {"agents": [3]}, "more_data": [{"agents": [3, 4]}]}"#);
        assert!(wider.starts_with("more_data[0].agents: the student trains teams of [3]"));
        let env = bad(r#"{"more_data": [{}, {"env": {"fov": 7}}]}"#);
        assert!(env.starts_with("more_data[1]: its env"), "{env}");
        assert!(bad(r#"{"more_data": [{"episodes": 0}]}"#).contains("at least one episode"));
    }

    #[test]
    fn bad_settings_name_the_field() {
        let bad = |text: &str| ImitationConfig::from_json(text).unwrap_err();
        assert!(bad(r#"{"lr": -1}"#).contains("lr"));
        assert!(bad(r#"{"validate_every": 0}"#).contains("validate_every"));
        assert!(bad(r#"{"round_epsilon": 2}"#).contains("round_epsilon"));
        assert!(bad(r#"{"net": {"n_actions": 2}}"#).contains("5 actions"));
        assert!(bad(r#"{"data": {"agents": [9]}}"#).contains("data.agents"));
        let team_alone = bad(r#"{"data": {"env": {"place_vector": false, "team_vector": true}}}"#);
        assert!(team_alone.starts_with("data.env: the team vector needs"), "{team_alone}");
        assert!(bad(r#"{"data": {"env": {"fov": 8}}}"#).contains("data.env: field of view 8"));
        assert!(bad("{\n \"rounds\": \"x\"}").contains("line 2"));
        assert!(bad(r#"{"updates": 18446744073709551615, "rounds": 1}"#).contains("overflow"));
        assert!(bad(r#"{"finetune": {"rollouts": 1}}"#).contains("2 rollouts"));
        assert!(bad(r#"{"finetune": {"agents": [9]}}"#).contains("finetune.agents"));
        assert!(bad(r#"{"finetune": {"lr": 0}}"#).contains("finetune.lr"));
        assert!(bad(r#"{"finetune": {"cloning": -1}}"#).contains("cloning"));
        let none = ImitationConfig::from_json(r#"{"finetune": null}"#).unwrap();
        assert_eq!(none.total_updates(), Some(none.updates));
    }
}
