//! Many independent episodes stepped together, their observations written into one set of
//! flat buffers ([`ObsBuf`]) that a learner turns into tensors without per-agent copies.
//!
//! Episodes are stepped in parallel with rayon, in chunks of at least
//! [`BatchEnv::MIN_CHUNK`] episodes; every episode writes only its own slices, so the result
//! is the same on any thread count. A step allocates nothing once the episodes are reset.

use phalanx_core::{Action, Instance};
use rayon::prelude::*;

use crate::obs::{ObsBuf, ObsLayout, ObsSlices};
use crate::{Env, EnvConfig, EnvError, LeaderRule};

/// The scalar outcome of one episode's last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Outcome {
    /// Sum of the agents' rewards.
    pub team_reward: f32,
    /// The task is done.
    pub terminated: bool,
    /// The step limit was reached.
    pub truncated: bool,
    /// Cancelled moves (collisions) this step.
    pub n_cancelled: u32,
    /// `L_f` after the step.
    pub formation_loss: f64,
}

/// `n_envs` episodes with `n_agents` agents each, one field of view.
#[derive(Debug, Clone)]
pub struct BatchEnv {
    envs: Vec<Env>,
    layout: ObsLayout,
    obs: ObsBuf,
    rewards: Vec<f32>,
    outcomes: Vec<Outcome>,
    /// Episodes whose messages were written since they were last cleared.
    messages_written: Vec<bool>,
}

impl BatchEnv {
    /// Episodes per rayon task: below this, splitting costs more than it gains.
    pub const MIN_CHUNK: usize = 8;

    /// A batch of `n_envs` episodes (not yet reset).
    pub fn new(config: EnvConfig, n_envs: usize, n_agents: usize) -> Result<BatchEnv, EnvError> {
        if n_agents > crate::MAX_AGENTS {
            return Err(EnvError::TooManyAgents(n_agents));
        }
        let env = Env::new(config.clone())?;
        let layout = ObsLayout { n_agents, fov: config.fov as usize };
        Ok(BatchEnv {
            envs: vec![env; n_envs],
            layout,
            obs: ObsBuf::new(layout, n_envs),
            rewards: vec![0.0; n_envs * n_agents],
            outcomes: vec![Outcome::default(); n_envs],
            messages_written: vec![false; n_envs],
        })
    }

    /// Number of episodes.
    #[inline]
    pub fn n_envs(&self) -> usize {
        self.envs.len()
    }

    /// Observation sizes of one episode.
    #[inline]
    pub fn layout(&self) -> ObsLayout {
        self.layout
    }

    /// Episode `env`.
    #[inline]
    pub fn env(&self, env: usize) -> &Env {
        &self.envs[env]
    }

    /// The observations of every episode.
    #[inline]
    pub fn obs(&self) -> &ObsBuf {
        &self.obs
    }

    /// Rewards of the last step, `[n_envs, n_agents]`.
    #[inline]
    pub fn rewards(&self) -> &[f32] {
        &self.rewards
    }

    /// Outcomes of the last step, one per episode.
    #[inline]
    pub fn outcomes(&self) -> &[Outcome] {
        &self.outcomes
    }

    /// Starts episode `env` on `instance` and writes its observation.
    pub fn reset(&mut self, env: usize, instance: &Instance) -> Result<(), EnvError> {
        if instance.n_agents() != self.layout.n_agents {
            return Err(EnvError::AgentCount {
                expected: self.layout.n_agents,
                found: instance.n_agents(),
            });
        }
        self.envs[env].reset(instance)?;
        let mut obs = self.obs.env_mut(env);
        self.envs[env].observe(&mut obs);
        obs.message.fill(0.0);
        self.messages_written[env] = false;
        self.rewards[env * self.layout.n_agents..(env + 1) * self.layout.n_agents].fill(0.0);
        self.outcomes[env] = Outcome::default();
        Ok(())
    }

    /// Starts every episode, episode `i` on `instances[i]`, in parallel.
    ///
    /// # Panics
    /// If there is not one instance per episode.
    pub fn reset_all(&mut self, instances: &[Instance]) -> Result<(), EnvError> {
        assert_eq!(instances.len(), self.envs.len(), "one instance per episode");
        if let Some(bad) = instances.iter().find(|it| it.n_agents() != self.layout.n_agents) {
            return Err(EnvError::AgentCount {
                expected: self.layout.n_agents,
                found: bad.n_agents(),
            });
        }
        let results: Vec<Result<(), EnvError>> =
            self.envs.par_iter_mut().zip(instances).map(|(env, inst)| env.reset(inst)).collect();
        results.into_iter().collect::<Result<(), EnvError>>()?;
        self.rewards.fill(0.0);
        self.outcomes.fill(Outcome::default());
        self.obs.message.fill(0.0);
        self.messages_written.fill(false);
        self.for_each_env(|_, env, obs, _, _| env.observe(obs));
        Ok(())
    }

    /// Resets every ended episode (and every episode never reset) on `sample(index)`,
    /// in index order, so a seeded sampler gives the same episodes on any thread count;
    /// returns how many were reset.
    pub fn reset_done(
        &mut self,
        mut sample: impl FnMut(usize) -> Instance,
    ) -> Result<usize, EnvError> {
        let mut n_reset = 0;
        for i in 0..self.envs.len() {
            if self.envs[i].is_done() {
                self.reset(i, &sample(i))?;
                n_reset += 1;
            }
        }
        Ok(n_reset)
    }

    /// Steps every running episode with its agents' actions (`[n_envs, n_agents]`, agent
    /// order) and writes the observations. An ended episode is left as it is (zero
    /// rewards, its last outcome kept) until it is reset.
    ///
    /// # Panics
    /// If `actions` has another length than `n_envs · n_agents`.
    pub fn step(&mut self, actions: &[Action]) {
        let n = self.layout.n_agents;
        assert_eq!(actions.len(), self.envs.len() * n, "one action per agent per episode");
        self.clear_messages();
        self.for_each_env(|i, env, obs, rewards, outcome| {
            if env.is_done() {
                rewards.fill(0.0);
                return;
            }
            record(env.step(&actions[i * n..(i + 1) * n]), rewards, outcome);
            env.observe(obs);
        });
    }

    /// Starts sequential acting in every running episode (SPEC §6): computes each
    /// episode's order under `rule`. Messages are zero until agents choose.
    pub fn begin_turns(&mut self, rule: LeaderRule) {
        self.clear_messages();
        self.for_each_env(|_, env, _, _, _| {
            if !env.is_done() {
                env.begin_turns(rule);
            }
        });
    }

    /// The agent that acts `k`-th in episode `env` this step.
    #[inline]
    pub fn turn_agent(&self, env: usize, k: usize) -> usize {
        self.envs[env].turn_order()[k] as usize
    }

    /// Records the action of the agent whose turn it is in every running episode (one
    /// action per episode; ended episodes ignore theirs) and writes the next agent's
    /// message into the message buffer.
    ///
    /// # Panics
    /// If `actions` has another length than `n_envs`, or an episode's agents have all
    /// chosen already.
    pub fn choose(&mut self, actions: &[Action]) {
        assert_eq!(actions.len(), self.envs.len(), "one action per episode");
        let len = self.layout.agent_message_len();
        for (i, (env, &action)) in self.envs.iter_mut().zip(actions).enumerate() {
            if env.is_done() {
                continue;
            }
            if let Some(next) = env.choose(action) {
                let at = (i * self.layout.n_agents + next) * len;
                env.write_message(next, &mut self.obs.message[at..at + len]);
                self.messages_written[i] = true;
            }
        }
    }

    /// Steps every running episode with the actions chosen in turn, as [`BatchEnv::step`].
    ///
    /// # Panics
    /// If some agent of a running episode has not chosen.
    pub fn step_chosen(&mut self) {
        self.clear_messages();
        self.for_each_env(|_, env, obs, rewards, outcome| {
            if env.is_done() {
                rewards.fill(0.0);
                return;
            }
            record(env.step_chosen(), rewards, outcome);
            env.observe(obs);
        });
    }

    /// Zeroes the messages of the episodes that wrote some.
    fn clear_messages(&mut self) {
        let len = self.layout.message_len();
        for (i, written) in self.messages_written.iter_mut().enumerate() {
            if std::mem::take(written) {
                self.obs.message[i * len..(i + 1) * len].fill(0.0);
            }
        }
    }

    /// Runs `f` on every episode with its index, observation slices, reward slice and
    /// outcome: in parallel chunks, or on the calling thread when rayon has one thread or
    /// the batch is too small to split (handing work to the pool then only adds two
    /// context switches per step).
    fn for_each_env(
        &mut self,
        f: impl Fn(usize, &mut Env, &mut ObsSlices<'_>, &mut [f32], &mut Outcome) + Sync,
    ) {
        let l = self.layout;
        if rayon::current_num_threads() == 1 || self.envs.len() < 2 * Self::MIN_CHUNK {
            let parts = self
                .envs
                .iter_mut()
                .zip(self.obs.grid.chunks_exact_mut(l.grid_len()))
                .zip(self.obs.vector.chunks_exact_mut(l.vector_len()))
                .zip(self.obs.message.chunks_exact_mut(l.message_len()))
                .zip(self.obs.mask.chunks_exact_mut(l.mask_len()))
                .zip(self.rewards.chunks_exact_mut(l.n_agents))
                .zip(self.outcomes.iter_mut())
                .enumerate();
            for (i, ((((((env, grid), vector), message), mask), rewards), outcome)) in parts {
                let mut obs = ObsSlices { grid, vector, message, mask };
                f(i, env, &mut obs, rewards, outcome);
            }
            return;
        }
        self.envs
            .par_iter_mut()
            .zip(self.obs.grid.par_chunks_mut(l.grid_len()))
            .zip(self.obs.vector.par_chunks_mut(l.vector_len()))
            .zip(self.obs.message.par_chunks_mut(l.message_len()))
            .zip(self.obs.mask.par_chunks_mut(l.mask_len()))
            .zip(self.rewards.par_chunks_mut(l.n_agents))
            .zip(self.outcomes.par_iter_mut())
            .enumerate()
            .with_min_len(Self::MIN_CHUNK)
            .for_each(|(i, ((((((env, grid), vector), message), mask), rewards), outcome))| {
                let mut obs = ObsSlices { grid, vector, message, mask };
                f(i, env, &mut obs, rewards, outcome);
            });
    }
}

/// Copies one episode's step result into the batch's reward row and outcome.
fn record(step: crate::Step<'_>, rewards: &mut [f32], outcome: &mut Outcome) {
    rewards.copy_from_slice(step.rewards);
    *outcome = Outcome {
        team_reward: step.team_reward,
        terminated: step.terminated,
        truncated: step.truncated,
        n_cancelled: step.info.n_cancelled,
        formation_loss: step.info.formation_loss,
    };
}
