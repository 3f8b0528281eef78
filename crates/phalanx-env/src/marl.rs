//! The interface training and evaluation step: a cooperative multi-agent environment with
//! one team reward per step, its flat observation buffers, and the lockstep step of many
//! such environments at once.
//!
//! A [`MarlEnv`] is a cooperative multi-agent environment with one team reward per step.
//! Observations travel in flat `f32` buffers ([`ObsBuffers`]) that the environment overwrites in
//! place on `reset` and `step`, so a batched simulator can fill them without allocating.
//! Besides the observations the environment supplies, per agent, the action mask (docs/spec.md §5
//! action clipping: a masked action is never chosen and never bootstrapped from) and the
//! leader order in which agents act within the step (docs/spec.md §6: the leader first).
//! Acting is sequential: the agent at rank `k` sees the actions chosen by ranks `0..k` as its
//! message, but the environment receives the joint action at once.

use rayon::prelude::*;

/// Sizes of one agent's observation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObsShape {
    /// Grid channels `C`.
    pub channels: usize,
    /// Field of view `F` (the grid part is `C × F × F`).
    pub fov: usize,
    /// Length of the vector part (goal vector: 3).
    pub env_vec: usize,
    /// Number of actions `A`.
    pub n_actions: usize,
}

impl ObsShape {
    /// Floats in one agent's grid observation, `C * F * F`.
    pub fn grid_len(&self) -> usize {
        self.channels * self.fov * self.fov
    }
}

/// Observation buffers for all agents of one environment, overwritten in place.
#[derive(Clone, Debug, PartialEq)]
pub struct ObsBuffers {
    /// Number of agents `N`.
    pub n_agents: usize,
    /// Sizes of one agent's observation.
    pub shape: ObsShape,
    /// Grid observations, `[N, C, F, F]` row-major.
    pub grid: Vec<f32>,
    /// Vector observations, `[N, env_vec]`.
    pub vec: Vec<f32>,
    /// Allowed actions, `[N, A]`; at least one `true` per agent.
    pub action_mask: Vec<bool>,
    /// Acting order: `order[rank]` is the agent acting at `rank` (a permutation of `0..N`).
    pub order: Vec<usize>,
}

impl ObsBuffers {
    /// Zeroed buffers (all actions allowed, identity order).
    pub fn new(n_agents: usize, shape: ObsShape) -> Self {
        Self {
            n_agents,
            shape,
            grid: vec![0.0; n_agents * shape.grid_len()],
            vec: vec![0.0; n_agents * shape.env_vec],
            action_mask: vec![true; n_agents * shape.n_actions],
            order: (0..n_agents).collect(),
        }
    }

    /// Agent `agent_idx`'s grid observation, `[C, F, F]`.
    pub fn grid_of(&self, agent_idx: usize) -> &[f32] {
        let len = self.shape.grid_len();
        &self.grid[agent_idx * len..(agent_idx + 1) * len]
    }

    /// Agent `agent_idx`'s vector observation.
    pub fn vec_of(&self, agent_idx: usize) -> &[f32] {
        let len = self.shape.env_vec;
        &self.vec[agent_idx * len..(agent_idx + 1) * len]
    }

    /// Agent `agent_idx`'s allowed actions.
    pub fn mask_of(&self, agent_idx: usize) -> &[bool] {
        let n_actions = self.shape.n_actions;
        &self.action_mask[agent_idx * n_actions..(agent_idx + 1) * n_actions]
    }

    /// Panics with a message if the buffers break their documented invariants.
    pub fn check(&self) {
        assert_eq!(self.grid.len(), self.n_agents * self.shape.grid_len(), "grid buffer size");
        assert_eq!(self.vec.len(), self.n_agents * self.shape.env_vec, "vector buffer size");
        assert_eq!(self.action_mask.len(), self.n_agents * self.shape.n_actions, "mask size");
        let mut seen = vec![false; self.n_agents];
        for &agent_idx in &self.order {
            assert!(!std::mem::replace(&mut seen[agent_idx], true), "order is not a permutation");
        }
        assert_eq!(self.order.len(), self.n_agents, "order is not a permutation");
        for agent_idx in 0..self.n_agents {
            assert!(self.mask_of(agent_idx).contains(&true), "agent {agent_idx} has no action");
        }
    }
}

/// What one step returns.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepOut {
    /// Team reward (sum of the agents' rewards, docs/spec.md §5).
    pub team_reward: f32,
    /// The episode ended in an absorbing state (goal or formation reached): no bootstrap.
    pub terminated: bool,
    /// The episode was cut by the step limit: the learner bootstraps from the last observation.
    pub truncated: bool,
    /// Moves cancelled by collisions this step (information only).
    pub collisions: u32,
    /// `L_f` of the positions after the step (information only; 0 for an environment that
    /// has no formation).
    pub formation_loss: f64,
}

/// A cooperative multi-agent environment with a team reward.
///
/// [`crate::PoolEnv`] is the one for the low-level tasks; learners train on any.
pub trait MarlEnv {
    /// Number of agents; fixed for the environment's lifetime.
    fn n_agents(&self) -> usize;
    /// Sizes of one agent's observation.
    fn obs_shape(&self) -> ObsShape;
    /// Start a new episode drawn from `seed` and write its first observation.
    fn reset(&mut self, seed: u64, obs: &mut ObsBuffers);
    /// Apply the joint action (`actions[agent_idx]`, all allowed by the last mask) and write the
    /// next observation (also after the last step: the learner bootstraps from it on truncation).
    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut;
}

/// Steps every environment with its slice of `actions` (`[Σ N_e]`, environment after
/// environment, agent order within one; `offsets[e]` is where environment `e`'s agents
/// start) and writes its observation into `obs[e]` and its outcome into `outs[e]`.
///
/// This is the step of training's collector. Environments run in parallel on the rayon pool
/// (each writes only its own buffers, so the result is the same on any thread count) or on
/// the calling thread when the pool has one thread; nothing is allocated.
///
/// # Panics
/// If the slices disagree in length.
pub fn step_lockstep<E: MarlEnv + Send>(
    envs: &mut [E],
    obs: &mut [ObsBuffers],
    actions: &[u8],
    offsets: &[usize],
    outs: &mut [StepOut],
) {
    let n = envs.len();
    assert!(obs.len() == n && offsets.len() == n && outs.len() == n, "one buffer per environment");
    let step = |((env, obs), (&at, out)): ((&mut E, &mut ObsBuffers), (&usize, &mut StepOut))| {
        *out = env.step(&actions[at..at + obs.n_agents], obs);
    };
    if rayon::current_num_threads() == 1 {
        envs.iter_mut().zip(obs.iter_mut()).zip(offsets.iter().zip(outs.iter_mut())).for_each(step);
    } else {
        envs.par_iter_mut()
            .zip(obs.par_iter_mut())
            .zip(offsets.par_iter().zip(outs.par_iter_mut()))
            .for_each(step);
    }
}
