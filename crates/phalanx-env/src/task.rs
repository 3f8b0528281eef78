//! The simulator with a task's rewards, clipping and leader order writing [`ObsBuffers`]
//! ([`TaskEnv`]), and the [`MarlEnv`] the low-level policies are trained in ([`PoolEnv`]: the
//! path-finding and formation-training environments of docs/spec.md §5, §6, one type for every task).
//!
//! Each reset draws a map from the training pool ([`TrainPool`], generated once) and a fresh
//! instance from a `ChaCha8Rng` seeded with the reset's seed: for [`Task::Formation`] a
//! random placement with a random target formation ([`TrainPool::sample_formation`]), for the
//! other tasks the generator's start and goal regions ([`TrainPool::sample`]).
//! Observations are written into [`ObsBuffers`]: the four grid channels, the goal vector, the
//! mask of the task's clipping and the leader order of the task's rule.

use phalanx_core::{Action, Instance};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::marl::{MarlEnv, ObsBuffers, ObsShape, StepOut};
use crate::{Env, EnvConfig, EnvError, LeaderRule, PoolConfig, Task, TrainPool};

/// Formation placements tried on fresh maps before a reset gives up (each try already makes
/// [`crate::MAX_PLACEMENT_ATTEMPTS`] placements on its map).
const FORMATION_MAP_TRIES: usize = 16;

/// The simulator with a task's rewards, clipping and leader rule, writing [`ObsBuffers`]:
/// an episode starts from a given instance ([`TaskEnv::reset_to`]). [`PoolEnv`] adds the
/// training pool's instance draw; evaluation resets it to fresh instances.
#[derive(Debug, Clone)]
pub struct TaskEnv {
    env: Env,
    task: Task,
    n_agents: usize,
    rule: LeaderRule,
    actions: Vec<Action>,
}

impl TaskEnv {
    /// An environment of `task` for `n_agents` agents with the field of view and step limit
    /// of `env` (its task is replaced by `task`).
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn new(task: Task, env: EnvConfig, n_agents: usize) -> Result<TaskEnv, EnvError> {
        assert!(n_agents > 0, "an environment needs agents");
        Ok(TaskEnv {
            env: Env::new(EnvConfig { task, ..env })?,
            task,
            n_agents,
            rule: task.leader_rule(),
            actions: vec![Action::Wait; n_agents],
        })
    }

    /// The simulator (positions, goals, time of the running episode).
    pub fn env(&self) -> &Env {
        &self.env
    }

    /// The task.
    pub fn task(&self) -> Task {
        self.task
    }

    /// Start an episode on `instance` and write its first observation.
    ///
    /// # Errors
    /// If the instance has another agent count or the simulator refuses it.
    pub fn reset_to(&mut self, instance: &Instance, obs: &mut ObsBuffers) -> Result<(), EnvError> {
        if instance.n_agents() != self.n_agents {
            return Err(EnvError::AgentCount {
                expected: self.n_agents,
                found: instance.n_agents(),
            });
        }
        self.env.reset(instance)?;
        self.observe(obs);
        Ok(())
    }

    /// Agents per episode.
    pub fn n_agents(&self) -> usize {
        self.n_agents
    }

    /// Sizes of one agent's observation.
    pub fn obs_shape(&self) -> ObsShape {
        self.env.obs_shape()
    }

    /// Writes every agent's channels, goal vector and mask, then the leader order.
    fn observe(&mut self, obs: &mut ObsBuffers) {
        assert_eq!(obs.n_agents, self.n_agents, "buffers of another agent count");
        assert_eq!(obs.shape, self.obs_shape(), "buffers of another shape");
        self.env.observe(obs);
        let order = self.env.begin_turns(self.rule);
        obs.order.clear();
        obs.order.extend(order.iter().map(|&agent| usize::from(agent)));
    }

    /// Apply the joint action and write the next observation.
    pub fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        let out = self.env.step_indices(actions, &mut self.actions);
        self.observe(obs);
        out
    }
}

/// A training environment on the pool: a [`TaskEnv`] whose resets draw the task's instances
/// from the training pool.
#[derive(Debug, Clone)]
pub struct PoolEnv {
    inner: TaskEnv,
    pool: TrainPool,
    shaping: Option<Shaping>,
    reward_scale: f32,
}

/// Reward shaping towards the goals, a training aid: each step adds
/// `weight · (γ Φ(s') − Φ(s))` to the team reward, with `Φ(s) = −Σ_i d_i(s)` (the agents'
/// BFS distances to their goals).
///
/// - `gamma` = the learner's γ, with `Φ = 0` in a terminal state: potential-based shaping
///   (Ng, Harada and Russell 1999), which leaves the optimal policies unchanged; it only helps
///   where the task's own reward already favours the goals, and pays `weight (1 − γ) Σ d` for
///   waiting far from them.
/// - `gamma` = 1: a goal-progress bonus, `weight` per unit of distance an agent gains (and the
///   same taken for each unit lost), nothing for waiting: it biases the policy towards the
///   goals (in formation training the goals are a placement of the target formation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shaping {
    /// Scale of the shaping term.
    pub weight: f32,
    /// The learner's discount γ (the shaping must use the same one).
    pub gamma: f32,
}

impl PoolEnv {
    /// Generates the pool of `pool` once; episodes of `task` have `n_agents` agents and the
    /// field of view and step limit of `env` (its task is replaced by `task`).
    ///
    /// # Panics
    /// If `n_agents` is 0 or the pool has no maps.
    pub fn new(
        task: Task,
        pool: &PoolConfig,
        env: EnvConfig,
        n_agents: usize,
    ) -> Result<PoolEnv, EnvError> {
        let inner = TaskEnv::new(task, env, n_agents)?;
        let pool = TrainPool::new(pool)?;
        assert!(!pool.is_empty(), "the training pool has no maps");
        Ok(PoolEnv { inner, pool, shaping: None, reward_scale: 1.0 })
    }

    /// Multiply the team reward (shaping included) by `scale`, a training aid for tasks whose
    /// rewards are large (formation: `−k·L_f` every step); greedy policies do not change.
    pub fn with_reward_scale(mut self, scale: f32) -> PoolEnv {
        self.reward_scale = scale;
        self
    }

    /// Add potential-based reward shaping to the team reward (see [`Shaping`]).
    pub fn with_shaping(mut self, shaping: Option<Shaping>) -> PoolEnv {
        self.shaping = shaping;
        self
    }

    /// `Φ(s) = −Σ_i d_i(s)` of the running episode.
    fn potential(&self) -> f32 {
        let env = self.inner.env();
        -(0..self.inner.n_agents).map(|agent| env.cost_to_go(agent) as f32).sum::<f32>()
    }

    /// The same pool and task for teams of `n_agents` (the pool is shared, not regenerated).
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn with_agents(&self, n_agents: usize) -> Result<PoolEnv, EnvError> {
        let inner = TaskEnv::new(self.inner.task, self.inner.env.config().clone(), n_agents)?;
        let (shaping, reward_scale) = (self.shaping, self.reward_scale);
        Ok(PoolEnv { inner, pool: self.pool.clone(), shaping, reward_scale })
    }

    /// The simulator (positions, goals, time of the running episode).
    pub fn env(&self) -> &Env {
        self.inner.env()
    }

    /// Weigh `L_f` by `formation_weight` in the meta task's reward (the end-to-end
    /// baselines; the other tasks do not use it).
    pub fn with_formation_weight(mut self, formation_weight: f64) -> PoolEnv {
        self.inner.env.set_formation_weight(formation_weight);
        self
    }
}

impl MarlEnv for PoolEnv {
    fn n_agents(&self) -> usize {
        self.inner.n_agents
    }

    fn obs_shape(&self) -> ObsShape {
        self.inner.obs_shape()
    }

    /// # Panics
    /// For [`Task::Formation`], if no placement comes out on `FORMATION_MAP_TRIES` (16) drawn
    /// maps (too many agents for the pool's maps).
    fn reset(&mut self, seed: u64, obs: &mut ObsBuffers) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n_agents = self.inner.n_agents;
        let instance = match self.inner.task {
            Task::Formation => (0..FORMATION_MAP_TRIES)
                .find_map(|_| self.pool.sample_formation(n_agents, &mut rng).ok())
                .unwrap_or_else(|| panic!("no formation placement of {n_agents} agents")),
            Task::PathFinding | Task::Meta => self.pool.sample(n_agents, &mut rng),
        };
        self.inner.reset_to(&instance, obs).expect("pool instances fit the environment");
    }

    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        let before = self.shaping.map(|_| self.potential());
        let mut out = self.inner.step(actions, obs);
        if let (Some(Shaping { weight, gamma }), Some(before)) = (self.shaping, before) {
            let potential_based = gamma < 1.0;
            let after = if out.terminated && potential_based { 0.0 } else { self.potential() };
            out.team_reward += weight * (gamma * after - before);
        }
        out.team_reward *= self.reward_scale;
        out
    }
}
