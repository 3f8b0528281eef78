//! Episode replay: whole recorded episodes, sampled as padded episodes or as fixed-length
//! windows with burn-in.
//!
//! An [`Episode`] of `T` steps stores `T + 1` observations (the last one is the observation
//! after the final step, needed to bootstrap a truncated episode), `T` joint actions and team
//! rewards, and whether it ended by termination.
//! A [`Batch`] is a set of aligned sequences of `len + 1` observations and `len` transitions with
//! a `filled` mask: padding and burn-in transitions carry no loss.

use std::collections::VecDeque;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use phalanx_env::{MarlEnv, ObsBuffers, ObsShape};

pub use crate::hyper::SequenceMode;

/// One recorded episode.
#[derive(Clone, Debug, Default)]
pub struct Episode {
    /// Agents `N`.
    pub n_agents: usize,
    /// Number of steps `T`.
    pub len: usize,
    /// Grid observations, `[T + 1, N, C, F, F]`.
    pub grid: Vec<f32>,
    /// Vector observations, `[T + 1, N, env_vec]`.
    pub vec: Vec<f32>,
    /// Allowed actions, `[T + 1, N, A]`.
    pub action_mask: Vec<bool>,
    /// Acting order, `[T + 1, N]` (ranks to agents).
    pub order: Vec<usize>,
    /// Joint actions, `[T, N]`.
    pub actions: Vec<u8>,
    /// Team rewards, `[T]`.
    pub rewards: Vec<f32>,
    /// Whether the last step terminated the episode (otherwise it was truncated).
    pub terminated: bool,
    /// The seed its environment was reset with, when known: with the actions, all a
    /// checkpoint needs to rebuild the episode ([`Episode::replay`]).
    pub seed: Option<u64>,
}

/// Why joint actions are not an episode of an environment ([`Episode::replay`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplayError {
    /// The actions do not divide into joint actions of the team.
    #[error("{actions} actions do not make joint actions of {agents}")]
    Ragged {
        /// Number of actions.
        actions: usize,
        /// Team size.
        agents: usize,
    },
    /// The episode ended before the actions did.
    #[error("the episode ended at step {step} of {steps}")]
    EndedEarly {
        /// The step after the end.
        step: usize,
        /// Steps in the actions.
        steps: usize,
    },
    /// An action the environment's mask forbids.
    #[error("step {step}: agent {agent}'s action {action} is not allowed")]
    Masked {
        /// The step.
        step: usize,
        /// The agent.
        agent: usize,
        /// Its action.
        action: u8,
    },
    /// An episode said to have ended that was still running.
    #[error("the episode did not end after {steps} steps")]
    NotEnded {
        /// Steps played.
        steps: usize,
    },
    /// An episode said to be running that had ended.
    #[error("the episode ended at step {steps}")]
    Ended {
        /// Steps played.
        steps: usize,
    },
}

impl Episode {
    /// Start an episode at its first observation.
    pub fn start(obs: &ObsBuffers) -> Self {
        let mut res = Self { n_agents: obs.n_agents, ..Self::default() };
        res.push_obs(obs);
        res
    }

    /// Reset `env` with `seed` and start recording the episode it begins (remembering the
    /// seed, see [`Episode::seed`]).
    pub fn begin<E: MarlEnv>(env: &mut E, seed: u64, obs: &mut ObsBuffers) -> Self {
        env.reset(seed, obs);
        Self { seed: Some(seed), ..Self::start(obs) }
    }

    /// Rebuild an episode from its seed and joint actions (`[T, N]`) by playing them again in
    /// `env` (environments are deterministic), leaving `env` and `obs` where the episode left
    /// them. `ended` says whether the episode finished (it then ended at its last step:
    /// terminated, truncated, or cut at `max_steps`) or is still running.
    ///
    /// # Errors
    /// When the actions do not fit the environment: a masked action, an end before the last
    /// step, or an episode said to have ended that did not (so not this environment's episode).
    pub fn replay<E: MarlEnv>(
        env: &mut E,
        obs: &mut ObsBuffers,
        seed: u64,
        actions: &[u8],
        ended: bool,
        max_steps: usize,
    ) -> Result<Episode, ReplayError> {
        let n = env.n_agents();
        if !actions.len().is_multiple_of(n) {
            return Err(ReplayError::Ragged { actions: actions.len(), agents: n });
        }
        let mut episode = Episode::begin(env, seed, obs);
        let steps = actions.len() / n;
        let mut end = None;
        for (t, joint) in actions.chunks(n).enumerate() {
            if end.is_some() {
                return Err(ReplayError::EndedEarly { step: t, steps });
            }
            let masked = joint.iter().enumerate().position(|(agent, &a)| {
                !obs.mask_of(agent).get(usize::from(a)).copied().unwrap_or(false)
            });
            if let Some(agent) = masked {
                return Err(ReplayError::Masked { step: t, agent, action: joint[agent] });
            }
            let out = env.step(joint, obs);
            episode.push_step(joint, out.team_reward, obs);
            if out.terminated || out.truncated || episode.len >= max_steps {
                end = Some(out.terminated);
            }
        }
        match (ended, end) {
            (true, Some(terminated)) => episode.terminated = terminated,
            (false, None) => {}
            (true, None) => return Err(ReplayError::NotEnded { steps }),
            (false, Some(_)) => return Err(ReplayError::Ended { steps }),
        }
        Ok(episode)
    }

    /// Record one step: the joint action, its reward, and the observation it led to.
    pub fn push_step(&mut self, actions: &[u8], reward: f32, next_obs: &ObsBuffers) {
        self.actions.extend_from_slice(actions);
        self.rewards.push(reward);
        self.len += 1;
        self.push_obs(next_obs);
    }

    fn push_obs(&mut self, obs: &ObsBuffers) {
        self.grid.extend_from_slice(&obs.grid);
        self.vec.extend_from_slice(&obs.vec);
        self.action_mask.extend_from_slice(&obs.action_mask);
        self.order.extend_from_slice(&obs.order);
    }

    /// Sum of the team rewards.
    pub fn team_return(&self) -> f32 {
        self.rewards.iter().sum()
    }
}

/// A batch of aligned sequences, laid out agent-major so that `[B, N, ...]` reshapes to the
/// network's `[B * N, time, ...]`.
#[derive(Clone, Debug)]
pub struct Batch {
    /// Sequences `B`.
    pub batch: usize,
    /// Agents `N`.
    pub n_agents: usize,
    /// Transitions per sequence `L` (observations per sequence: `L + 1`).
    pub len: usize,
    /// Observation sizes.
    pub shape: ObsShape,
    /// `[B, N, L + 1, C, F, F]`.
    pub grid: Vec<f32>,
    /// `[B, N, L + 1, env_vec]` (the agent-slot one-hot is added by the learner).
    pub vec: Vec<f32>,
    /// `[B, N, L + 1, A]`; padding allows every action.
    pub action_mask: Vec<bool>,
    /// `[B, L + 1, N]`; padding is the identity order.
    pub order: Vec<usize>,
    /// `[B, N, L]`; padding 0.
    pub actions: Vec<u8>,
    /// `[B, L]`.
    pub rewards: Vec<f32>,
    /// `[B, L]`: 1 where the transition ends the episode by termination (no bootstrap).
    pub terminated: Vec<f32>,
    /// `[B, L]`: 1 where the transition is real and trained (not padding, not burn-in).
    pub filled: Vec<f32>,
}

impl Batch {
    fn empty(batch: usize, n_agents: usize, len: usize, shape: ObsShape) -> Self {
        let n_obs = batch * n_agents * (len + 1);
        Self {
            batch,
            n_agents,
            len,
            shape,
            grid: vec![0.0; n_obs * shape.grid_len()],
            vec: vec![0.0; n_obs * shape.env_vec],
            action_mask: vec![true; n_obs * shape.n_actions],
            order: (0..batch * (len + 1)).flat_map(|_| 0..n_agents).collect(),
            actions: vec![0; batch * n_agents * len],
            rewards: vec![0.0; batch * len],
            terminated: vec![0.0; batch * len],
            filled: vec![0.0; batch * len],
        }
    }

    /// The whole episodes `episodes` (of `n_agents` agents and observations of `shape`) as
    /// one batch, in their order, padded to the longest.
    ///
    /// # Panics
    /// If an episode has another team size.
    pub fn of_episodes(episodes: &[&Episode], n_agents: usize, shape: ObsShape) -> Batch {
        let len = episodes.iter().map(|ep| ep.len).max().unwrap_or(1);
        let mut res = Batch::empty(episodes.len(), n_agents, len, shape);
        for (b, ep) in episodes.iter().enumerate() {
            assert_eq!(ep.n_agents, n_agents, "an episode of another team size");
            res.copy_from(b, ep, 0, ep.len + 1, 0);
        }
        res
    }

    /// Copy episode `ep`'s observations `from..from + n_obs` and transitions
    /// `from..from + n_obs - 1` into sequence `b`; transitions from `train_from` on are filled.
    fn copy_from(&mut self, b: usize, ep: &Episode, from: usize, n_obs: usize, train_from: usize) {
        let (n_agents, len, shape) = (self.n_agents, self.len, self.shape);
        let (grid_len, vec_len, n_actions) = (shape.grid_len(), shape.env_vec, shape.n_actions);
        for t in 0..n_obs {
            let src_t = from + t;
            for agent_idx in 0..n_agents {
                let dst = (b * n_agents + agent_idx) * (len + 1) + t;
                let src = src_t * n_agents + agent_idx;
                self.grid[dst * grid_len..(dst + 1) * grid_len]
                    .copy_from_slice(&ep.grid[src * grid_len..(src + 1) * grid_len]);
                self.vec[dst * vec_len..(dst + 1) * vec_len]
                    .copy_from_slice(&ep.vec[src * vec_len..(src + 1) * vec_len]);
                self.action_mask[dst * n_actions..(dst + 1) * n_actions]
                    .copy_from_slice(&ep.action_mask[src * n_actions..(src + 1) * n_actions]);
            }
            let dst = (b * (len + 1) + t) * n_agents;
            self.order[dst..dst + n_agents]
                .copy_from_slice(&ep.order[src_t * n_agents..(src_t + 1) * n_agents]);
            if t + 1 < n_obs {
                for agent_idx in 0..n_agents {
                    self.actions[(b * n_agents + agent_idx) * len + t] =
                        ep.actions[src_t * n_agents + agent_idx];
                }
                self.rewards[b * len + t] = ep.rewards[src_t];
                let last = src_t + 1 == ep.len;
                self.terminated[b * len + t] = if last && ep.terminated { 1.0 } else { 0.0 };
                self.filled[b * len + t] = if t >= train_from { 1.0 } else { 0.0 };
            }
        }
    }
}

/// A bounded FIFO of episodes (capacity in episodes).
#[derive(Clone, Debug)]
pub struct Replay {
    capacity: usize,
    n_agents: usize,
    shape: ObsShape,
    episodes: VecDeque<Episode>,
}

impl Replay {
    /// An empty buffer holding at most `capacity` episodes of `n_agents` agents.
    pub fn new(capacity: usize, n_agents: usize, shape: ObsShape) -> Self {
        assert!(capacity > 0, "replay capacity must be positive");
        // It grows as it fills: a checkpoint naming many team sizes reserves little up front.
        Self { capacity, n_agents, shape, episodes: VecDeque::with_capacity(capacity.min(64)) }
    }

    /// Agents per stored episode.
    pub fn n_agents(&self) -> usize {
        self.n_agents
    }

    /// Number of stored episodes.
    pub fn len(&self) -> usize {
        self.episodes.len()
    }

    /// The stored episodes, oldest first.
    pub fn episodes(&self) -> impl Iterator<Item = &Episode> {
        self.episodes.iter()
    }

    /// Whether no episode is stored.
    pub fn is_empty(&self) -> bool {
        self.episodes.is_empty()
    }

    /// Store an episode (of at least one step), evicting the oldest when full.
    pub fn push(&mut self, episode: Episode) {
        assert!(episode.len > 0, "an episode needs at least one step");
        assert_eq!(episode.n_agents, self.n_agents, "agent count mismatch");
        assert_eq!(episode.actions.len(), episode.len * self.n_agents, "agent count mismatch");
        assert_eq!(
            episode.grid.len(),
            (episode.len + 1) * self.n_agents * self.shape.grid_len(),
            "observation size mismatch"
        );
        if self.episodes.len() == self.capacity {
            self.episodes.pop_front();
        }
        self.episodes.push_back(episode);
    }

    /// Drop every episode.
    pub fn clear(&mut self) {
        self.episodes.clear();
    }

    /// Sample `batch` sequences uniformly over episodes (windows: uniform start within the
    /// episode). Panics if the buffer is empty.
    pub fn sample(&self, batch: usize, mode: SequenceMode, rng: &mut ChaCha8Rng) -> Batch {
        assert!(!self.episodes.is_empty(), "sampling from an empty replay buffer");
        let picks: Vec<usize> =
            (0..batch).map(|_| rng.random_range(0..self.episodes.len())).collect();
        let (n_agents, shape) = (self.n_agents, self.shape);
        match mode {
            SequenceMode::Episodes => {
                let picked: Vec<&Episode> = picks.iter().map(|&idx| &self.episodes[idx]).collect();
                Batch::of_episodes(&picked, n_agents, shape)
            }
            SequenceMode::Windows { len: window, burn_in } => {
                assert!(window > 0, "window length must be positive");
                let mut res = Batch::empty(batch, n_agents, window + burn_in, shape);
                for (b, &idx) in picks.iter().enumerate() {
                    let ep = &self.episodes[idx];
                    let start = rng.random_range(0..ep.len);
                    let from = start.saturating_sub(burn_in);
                    let end = (start + window).min(ep.len);
                    res.copy_from(b, ep, from, end - from + 1, start - from);
                }
                res
            }
        }
    }
}
