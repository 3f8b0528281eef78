//! Imitation data: expert rollouts on the training pool, the expert's joint action factored
//! into per-agent labels in the acting order, and the file they are kept in
//! (`docs/imitation.md`).
//!
//! - [`rollout`] plays one episode in the environment with the expert of
//!   `phalanx_plan::expert` (re-planned whenever the team is off its plan), optionally with
//!   random actions mixed in, and records every step's joint positions, acting order, the
//!   expert's joint action (the labels) and the joint action taken.
//! - [`generate`] makes a whole data set from a [`DataConfig`]: episodes on the
//!   training pool only (`phalanx_env::TrainPool`, never an evaluation stream), in parallel
//!   with rayon, each from its own seeded stream, so the result is the same on any thread
//!   count.
//! - [`for_each_sample`] replays an episode in the environment and hands out one
//!   [`Sample`] per agent and step in the acting order: the agent's own observation (its
//!   `[4, F, F]` channels, goal vector and mask), the message of the expert's actions of the
//!   agents ranked before it, and the expert's action for it as the target.
//! - [`file`](mod@file) is the on-disk format (a versioned, checksummed header and episodes).
//! - [`generate_with`] makes a DAgger round's data: the student moves the team, the expert
//!   labels every state it reaches; [`learn`] trains the student on the data (cloning, then
//!   DAgger rounds).

use std::collections::BTreeMap;

use phalanx_core::{Action, Cell, Instance};
use phalanx_env::{Env, EnvConfig, EnvError, LeaderRule, ObsBuffers, PoolConfig, Task, TrainPool};
use phalanx_plan::expert::{Expert, ExpertConfig, ExpertPlanner, ExpertStats};
use phalanx_plan::swarm::SubSolver;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::policy::Policy;

pub mod file;
pub mod finetune;
pub mod learn;

pub use file::{DataError, Dataset};

/// Number of actions, the width of a message row.
const N_ACTIONS: usize = Action::COUNT;

/// Which expert labels the data (serialised in the file's header).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum ExpertChoice {
    /// SWARM-MAPF-R with its default settings.
    #[default]
    Swarm,
    /// Joint-state A\* on `T + w·Σ L_f`, SWARM-MAPF-R when it runs out of nodes.
    #[serde(rename = "jsa")]
    JointAStar {
        /// The loss weight `w`.
        w: f64,
    },
    /// SWARM-MAPF-R whose local MAPF instances are solved by joint-state A\* on
    /// `T + w·Σ L_f` first (`SubSolver::JointAStar`), CBS when that runs out of nodes.
    #[serde(rename = "swarm-jsa")]
    SwarmJointAStar {
        /// The loss weight `w`.
        w: f64,
    },
    /// CBS, SWARM-MAPF-R when it runs out of nodes: formation ignored, the expert of mazes
    /// and rooms (`ExpertPlanner::Cbs`).
    Cbs,
}

impl ExpertChoice {
    /// The expert's settings: this planner, `node_limit` per call.
    pub fn config(self, node_limit: u64) -> ExpertConfig {
        let mut config = ExpertConfig { node_limit, ..ExpertConfig::default() };
        match self {
            ExpertChoice::Swarm => {}
            ExpertChoice::JointAStar { w } => config.planner = ExpertPlanner::JointAStar { w },
            ExpertChoice::Cbs => config.planner = ExpertPlanner::Cbs,
            ExpertChoice::SwarmJointAStar { w } => {
                config.swarm.sub_solver = SubSolver::JointAStar { w };
                config.swarm.jsa_node_limit = node_limit;
            }
        }
        config
    }
}

/// Settings of a data set; the file's header holds them, so a file says how it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DataConfig {
    /// The training pool the episodes are drawn from (never the evaluation stream).
    pub pool: PoolConfig,
    /// The environment the episodes run in (field of view, step limit, clipping of the
    /// masks, the place and team vectors). Default: the meta task's (formation clipping) with
    /// the place and team vectors, otherwise the paper's.
    pub env: EnvConfig,
    /// The acting order of the labels; default path finding (the agent in front leads, the
    /// hierarchy's low-level order before its frame).
    pub leader_rule: LeaderRule,
    /// Team sizes, one drawn uniformly per episode; default 3, 4, 5.
    pub agents: Vec<usize>,
    /// Number of episodes; default 1000.
    pub episodes: u64,
    /// Seed: episode `i` draws from stream `i` of `ChaCha8Rng::seed_from_u64(seed)`.
    pub seed: u64,
    /// Share of episodes whose team is wide (`TrainPool::sample_episode`); default 0.5.
    pub wide_share: f64,
    /// Probability, per agent and step, that the agent takes a uniformly random action
    /// instead of the expert's, so the data visits states off the expert's plan (the label
    /// stays the expert's); default 0.05.
    pub noise: f64,
    /// The expert; default SWARM-MAPF-R with joint-state A\* (`w = 1`) on its local
    /// instances (`docs/imitation.md`, *Decision*).
    pub expert: ExpertChoice,
    /// Node limit of one expert call (of each local joint-state A\* search); default 20 000.
    pub node_limit: u64,
    /// When given, the team is moved by a student policy instead of the noisy expert (a
    /// DAgger round, [`generate_with`]); `noise` is then unused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub student: Option<StudentRollouts>,
}

/// What a DAgger round's data file records of the student that moved the team.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudentRollouts {
    /// The DAgger round (1 is the first after cloning).
    pub round: u32,
    /// The CRC-32 of the student's network (`phalanx_rl::policy_file::network_checksum`).
    pub network: u32,
    /// Probability, per agent and step, of a uniformly random action instead of the
    /// student's greedy one.
    pub epsilon: f64,
    /// The rollout ends ([`EpisodeEnd::Stalled`]) when the team reaches one joint state this
    /// many times; 0: never (the data files written before 2026-12-05).
    #[serde(default)]
    pub stall_visits: u32,
}

impl Default for DataConfig {
    fn default() -> DataConfig {
        DataConfig {
            pool: PoolConfig::default(),
            env: EnvConfig {
                task: Task::Meta,
                place_vector: true,
                team_vector: true,
                ..EnvConfig::default()
            },
            leader_rule: LeaderRule::PathFinding,
            agents: vec![3, 4, 5],
            episodes: 1000,
            seed: 0,
            wide_share: 0.5,
            noise: 0.05,
            expert: ExpertChoice::SwarmJointAStar { w: 1.0 },
            node_limit: 20_000,
            student: None,
        }
    }
}

impl DataConfig {
    /// Whether data made with `self` holds the episodes data made with `other` holds: the
    /// same settings but for what only the observations read (the place and team vectors
    /// and the team vector's dead band), which the replay computes ([`for_each_sample`]) and
    /// no expert episode depends on. A
    /// student's rollouts depend on what the student reads, so a round's data (with
    /// `student`) must match exactly.
    pub fn same_episodes(&self, other: &DataConfig) -> bool {
        let bare = |config: &DataConfig| {
            let env = EnvConfig {
                place_vector: false,
                team_vector: false,
                team_deadband: phalanx_env::obs::TEAM_DEADBAND,
                ..config.env.clone()
            };
            DataConfig { env, ..config.clone() }
        };
        if self.student.is_some() || other.student.is_some() {
            return self == other;
        }
        bare(self) == bare(other)
    }
}

/// One step of an expert episode.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExpertStep {
    /// Every agent's cell before the step.
    pub positions: Vec<Cell>,
    /// The acting order (agent at each rank, leader first) as the environment computes it
    /// at these positions.
    pub order: Vec<u16>,
    /// The expert's joint action at these positions: the labels.
    pub expert: Vec<Action>,
    /// The joint action taken (the expert's, or a random action for some agents).
    pub taken: Vec<Action>,
}

/// How an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EpisodeEnd {
    /// Every agent stands on its goal.
    Reached,
    /// The step limit came first.
    Truncated,
    /// The expert had no plan from the last state (the state has no step recorded).
    ExpertFailed,
    /// A student's rollout came back to one joint state [`StudentRollouts::stall_visits`]
    /// times (the team stood still or oscillated): the states of a stall are labelled, its
    /// repetitions are not (each would cost a re-plan and teach nothing new).
    Stalled,
}

/// One expert episode: the instance and its steps.
#[derive(Debug, Clone, PartialEq)]
pub struct ExpertEpisode {
    /// The episode's index in its data set.
    pub index: u64,
    /// The map, starts and goals.
    pub instance: Instance,
    /// The steps, in time order.
    pub steps: Vec<ExpertStep>,
    /// How it ended.
    pub end: EpisodeEnd,
    /// Every agent's cell after the last step (the starts when there is no step).
    pub last: Vec<Cell>,
    /// Expert calls that planned (the first one included).
    pub replans: u32,
}

impl ExpertEpisode {
    /// The joint positions of every step and the final ones (`steps + 1` rows): the
    /// episode as a plan.
    pub fn plan(&self) -> phalanx_core::Plan {
        let mut plan = phalanx_core::Plan::new(self.instance.n_agents());
        for step in &self.steps {
            plan.push(&step.positions);
        }
        plan.push(&self.last);
        plan
    }

    /// Samples of the episode: one per agent and step.
    pub fn n_samples(&self) -> u64 {
        (self.steps.len() * self.instance.n_agents()) as u64
    }
}

/// Plays one episode of `instance` in `env` with `expert`'s actions, each agent taking a
/// uniformly random action instead with probability `noise` (drawn from `rng`); records
/// every step in the acting order of `rule`. Ends when every agent is on its goal, at the
/// step limit, or when the expert has no plan. Returns the episode and what its expert did.
///
/// # Errors
/// If the environment refuses the instance.
pub fn rollout(
    env: &mut Env,
    instance: &Instance,
    expert: &ExpertConfig,
    rule: LeaderRule,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Result<(ExpertEpisode, ExpertStats), EnvError> {
    rollout_with(env, instance, expert, rule, 0, &mut |_env, _order, labels, taken| {
        taken.copy_from_slice(labels);
        if noise > 0.0 {
            for a in taken.iter_mut() {
                if rng.random_bool(noise) {
                    *a = Action::ALL[rng.random_range(0..N_ACTIONS)];
                }
            }
        }
    })
}

/// Who moves the team in [`rollout_with`]: called at every step with the environment, the
/// acting order, the expert's joint action (the labels) and the joint action to write.
pub type Actor<'a> = dyn FnMut(&Env, &[u16], &[Action], &mut [Action]) + 'a;

/// Plays one episode of `instance` in `env`, the joint action at each step chosen by `act`,
/// the expert's answer at every state reached recorded as the labels; the acting order is
/// `rule`'s. Ends as [`rollout`] does, and also ([`EpisodeEnd::Stalled`]) when the team
/// reaches one joint state the `stall_visits`-th time (0: never).
///
/// # Errors
/// If the environment refuses the instance.
pub fn rollout_with(
    env: &mut Env,
    instance: &Instance,
    expert: &ExpertConfig,
    rule: LeaderRule,
    stall_visits: u32,
    act: &mut Actor<'_>,
) -> Result<(ExpertEpisode, ExpertStats), EnvError> {
    env.reset(instance)?;
    let n = instance.n_agents();
    let mut expert = Expert::new(instance, expert);
    let mut steps = Vec::new();
    let mut labels = vec![Action::Wait; n];
    // Visits of each joint state.
    let mut visits: BTreeMap<Vec<Cell>, u32> = BTreeMap::new();
    let end = loop {
        let positions = env.positions().to_vec();
        if positions == instance.goals() {
            break EpisodeEnd::Reached;
        }
        if stall_visits > 0 {
            let seen = visits.entry(positions.clone()).or_insert(0);
            *seen += 1;
            if *seen >= stall_visits {
                break EpisodeEnd::Stalled;
            }
        }
        if expert.act(&positions, &mut labels).is_err() {
            break EpisodeEnd::ExpertFailed;
        }
        let order = env.begin_turns(rule).to_vec();
        let mut taken = labels.clone();
        act(env, &order, &labels, &mut taken);
        let step = env.step(&taken);
        let (terminated, truncated) = (step.terminated, step.truncated);
        steps.push(ExpertStep { positions, order, expert: labels.clone(), taken });
        if terminated || env.positions() == instance.goals() {
            break EpisodeEnd::Reached;
        }
        if truncated {
            break EpisodeEnd::Truncated;
        }
    };
    let stats = *expert.stats();
    let last = env.positions().to_vec();
    let replans = stats.replans as u32;
    Ok((ExpertEpisode { index: 0, instance: instance.clone(), steps, end, last, replans }, stats))
}

/// What [`generate`] measured besides the episodes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GenerateStats {
    /// The experts' counts, summed over episodes.
    pub expert: ExpertStats,
}

/// Episode `index`'s random stream: stream `index` of `seed`.
fn episode_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// Episodes generated in parallel at a time (the rest wait their turn, so memory stays that
/// of the episodes themselves).
const CHUNK: u64 = 256;

/// Generates the data set of `config`: episode `i` draws its team size, its instance from
/// the training pool, and its noise from stream `i` of the seed, and is played by a fresh
/// expert; episodes run in parallel with rayon and come back in index order, so the data set
/// is the same on any thread count. `progress` is called with 1 after each episode (from
/// any thread).
///
/// # Errors
/// If the settings are out of range (no team size, a team that does not fit the pool's
/// start region, a noise outside `0..=1`), the pool cannot be generated or the environment
/// refuses the settings.
pub fn generate(
    config: &DataConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Dataset, GenerateStats), DataError> {
    generate_with(config, None, progress)
}

/// [`generate`], the team moved by `student` (greedy, random actions at the rate of
/// `config.student`) instead of the noisy expert when given: a DAgger round's data, every
/// state the student reaches labelled by the expert.
///
/// # Errors
/// As [`generate`]; also when `student` and `config.student` are not both given or both
/// absent, or the student's network does not read this environment's observations.
pub fn generate_with(
    config: &DataConfig,
    student: Option<&Policy>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Dataset, GenerateStats), DataError> {
    check_config(config)?;
    let pool = TrainPool::new(&config.pool).map_err(DataError::Pool)?;
    let probe = Env::new(config.env.clone()).map_err(DataError::Pool)?;
    // The student's random-action rate and stall cut, when a student moves the team.
    let rollouts = match (student, &config.student) {
        (None, None) => None,
        (Some(policy), Some(rollouts)) => {
            let net = policy.config();
            let shape = probe.obs_shape();
            let fits = (net.channels, net.fov, net.env_vec, net.n_actions)
                == (shape.channels, shape.fov, shape.env_vec, shape.n_actions);
            if !fits || config.agents.iter().any(|&n| n > net.n_agents_max) {
                return Err(DataError::Settings(format!(
                    "student: a network of {} channels, field of view {}, vector {}, {} \
                     actions and {} agent slots does not act in this environment",
                    net.channels, net.fov, net.env_vec, net.n_actions, net.n_agents_max
                )));
            }
            Some((rollouts.epsilon, rollouts.stall_visits))
        }
        _ => return Err(DataError::Settings("student: rollouts need the student's policy".into())),
    };
    let expert = config.expert.config(config.node_limit);
    let mut episodes = Vec::with_capacity(config.episodes as usize);
    let mut stats = GenerateStats::default();
    let mut start = 0;
    while start < config.episodes {
        let end = (start + CHUNK).min(config.episodes);
        let chunk: Vec<(ExpertEpisode, ExpertStats)> = (start..end)
            .into_par_iter()
            .map(|index| {
                let mut rng = episode_rng(config.seed, index);
                let n_agents = config.agents[rng.random_range(0..config.agents.len())];
                let instance = pool.sample_episode(n_agents, config.wide_share, &mut rng);
                let mut env = Env::new(config.env.clone()).expect("checked above");
                let rule = config.leader_rule;
                let played = match (student, rollouts) {
                    (Some(policy), Some((epsilon, stall))) => {
                        let mut policy = policy.clone();
                        policy.reset();
                        let mut obs = ObsBuffers::new(n_agents, env.obs_shape());
                        let mut chosen = vec![0_u8; n_agents];
                        let mut act =
                            |env: &Env, order: &[u16], _: &[Action], taken: &mut [Action]| {
                                env.observe(&mut obs);
                                obs.order.clear();
                                obs.order.extend(order.iter().map(|&agent| usize::from(agent)));
                                policy.act(&obs, epsilon, &mut rng, &mut chosen);
                                for (a, &c) in taken.iter_mut().zip(&chosen) {
                                    *a = Action::ALL[usize::from(c)];
                                }
                            };
                        rollout_with(&mut env, &instance, &expert, rule, stall, &mut act)
                    }
                    _ => rollout(&mut env, &instance, &expert, rule, config.noise, &mut rng),
                };
                let (mut episode, counts) = played.expect("pool instances fit the environment");
                episode.index = index;
                progress(1);
                (episode, counts)
            })
            .collect();
        for (episode, counts) in chunk {
            stats.expert.add(&counts);
            episodes.push(episode);
        }
        start = end;
    }
    Ok((Dataset { config: config.clone(), episodes }, stats))
}

/// Refuses settings [`generate`] cannot follow, naming the field and its value.
fn check_config(config: &DataConfig) -> Result<(), DataError> {
    let bad = |what: String| Err(DataError::Settings(what));
    let room = phalanx_gen::region_side(config.pool.size).pow(2) as usize;
    if config.agents.is_empty() {
        return bad("agents: no team size given".into());
    }
    if let Some(&n) = config.agents.iter().find(|&&n| n == 0 || n > room.min(255)) {
        return bad(format!("agents: a team of {n} does not fit (1 to {})", room.min(255)));
    }
    if !(0.0..=1.0).contains(&config.noise) {
        return bad(format!("noise: {} is not a probability", config.noise));
    }
    if let Some(student) = &config.student
        && !(0.0..=1.0).contains(&student.epsilon)
    {
        return bad(format!("student.epsilon: {} is not a probability", student.epsilon));
    }
    if !(0.0..=1.0).contains(&config.wide_share) {
        return bad(format!("wide_share: {} is not a probability", config.wide_share));
    }
    if config.pool.n_maps == 0 {
        return bad("pool.n_maps: the pool has no maps".into());
    }
    if let ExpertChoice::JointAStar { w } | ExpertChoice::SwarmJointAStar { w } = config.expert
        && !(w.is_finite() && w >= 0.0)
    {
        return bad(format!("expert: the loss weight {w} is not a finite non-negative number"));
    }
    Ok(())
}

/// One agent's training example at one step, in the acting order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<'a> {
    /// The step (0 is the episode's first).
    pub t: usize,
    /// The agent.
    pub agent: usize,
    /// Its rank in the step's acting order (0 is the leader).
    pub rank: usize,
    /// Its channels, `[4, F, F]` (`docs/observation.md`).
    pub grid: &'a [f32],
    /// Its goal vector, then its place vector with `EnvConfig::place_vector`, `[3]` or `[6]`.
    pub vector: &'a [f32],
    /// Its action mask under the environment's clipping, `[5]`.
    pub mask: &'a [bool],
    /// The message: row `j` the one-hot of the expert's action for agent `j` if `j` acts
    /// before this agent in the step's order, zeros otherwise, `[n_agents, 5]`.
    pub message: &'a [f32],
    /// The expert's action for this agent: the label.
    pub target: Action,
}

/// Writes the message of the agent at `rank`: row `j` is the one-hot of `actions[j]` for
/// every agent `j` ranked before it in `order`, the other rows zero (`[n_agents, 5]`; what
/// `Env::write_message` writes when the earlier agents chose `actions`).
///
/// # Panics
/// If `out` is not `n_agents × 5` long.
pub fn write_message(order: &[u16], actions: &[Action], rank: usize, out: &mut [f32]) {
    assert_eq!(out.len(), order.len() * N_ACTIONS, "message of another size");
    out.fill(0.0);
    for &j in &order[..rank] {
        let j = usize::from(j);
        out[j * N_ACTIONS + actions[j].index()] = 1.0;
    }
}

/// Replays `episode` in a fresh environment of `env_config` and calls `f` with every
/// agent's [`Sample`] of every step, in time order and, within a step, in the acting order
/// of `rule`.
///
/// # Errors
/// If the environment refuses the instance, or the replay leaves the recorded positions
/// or acting order (a file made by another version of the environment).
pub fn for_each_sample(
    episode: &ExpertEpisode,
    env_config: &EnvConfig,
    rule: LeaderRule,
    mut f: impl FnMut(&Sample<'_>),
) -> Result<(), DataError> {
    let index = episode.index;
    let mut env = Env::new(env_config.clone()).map_err(|e| DataError::Env(index, e))?;
    env.reset(&episode.instance).map_err(|e| DataError::Env(index, e))?;
    let n = episode.instance.n_agents();
    let mut obs = ObsBuffers::new(n, env.obs_shape());
    let mut message = vec![0.0; n * N_ACTIONS];
    let clip = env_config.task.clip();
    for (t, step) in episode.steps.iter().enumerate() {
        if env.positions() != step.positions.as_slice() {
            return Err(DataError::Replay { episode: index, step: t, what: "positions" });
        }
        if env.begin_turns(rule) != step.order.as_slice() {
            return Err(DataError::Replay { episode: index, step: t, what: "acting order" });
        }
        env.observe_clipped(&mut obs, clip);
        for (rank, &agent) in step.order.iter().enumerate() {
            let agent = usize::from(agent);
            write_message(&step.order, &step.expert, rank, &mut message);
            f(&Sample {
                t,
                agent,
                rank,
                grid: obs.grid_of(agent),
                vector: obs.vec_of(agent),
                mask: obs.mask_of(agent),
                message: &message,
                target: step.expert[agent],
            });
        }
        env.step(&step.taken);
    }
    Ok(())
}

#[cfg(test)]
mod tests;
