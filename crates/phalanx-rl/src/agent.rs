//! One agent's side of a policy, for an agent that decides alone (a process of its own,
//! docs/runtime.md): its own recurrent state, its own observation, and the actions of the
//! agents ranked before it this step as its message. The network is the same as
//! [`Policy`]'s; an [`AgentPolicy`] per agent gives, step by step, the actions the batched
//! [`Policy::act`] gives the team (greedy; tested in `tests/it/agent.rs`).

use burn::tensor::{Tensor, TensorData};

use crate::net::{masked_argmax, tensor3, to_vec};
use crate::policy::Policy;

/// Why an agent cannot act.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AgentError {
    /// The agent's slot is outside the network's.
    #[error("agent {agent}: the network has {slots} agent slots")]
    Slot {
        /// The agent.
        agent: usize,
        /// The network's slots.
        slots: usize,
    },
    /// An input of another size than the network's.
    #[error("{what} of {found} values, the network takes {expected}")]
    Size {
        /// Which input.
        what: &'static str,
        /// Its length.
        found: usize,
        /// The network's.
        expected: usize,
    },
    /// A message naming an agent or action outside the network's.
    #[error("message: agent {agent}'s action {action} is not one of the network's")]
    Message {
        /// The agent.
        agent: usize,
        /// Its action.
        action: u8,
    },
    /// No action is allowed.
    #[error("the mask allows no action")]
    NoAction,
}

/// One agent of a team acting with a policy's network.
#[derive(Clone, Debug)]
pub struct AgentPolicy {
    policy: Policy,
    agent: usize,
}

impl AgentPolicy {
    /// Agent `agent` (its slot in the network's one-hot and message) acting with `policy`.
    ///
    /// # Errors
    /// If the network has no slot `agent`.
    pub fn new(mut policy: Policy, agent: usize) -> Result<AgentPolicy, AgentError> {
        let slots = policy.config().n_agents_max;
        if agent >= slots {
            return Err(AgentError::Slot { agent, slots });
        }
        policy.reset();
        Ok(AgentPolicy { policy, agent })
    }

    /// The agent.
    pub fn agent(&self) -> usize {
        self.agent
    }

    /// Starts a new episode (the recurrent state back to zeros).
    pub fn reset(&mut self) {
        self.policy.reset();
    }

    /// The greedy action for this step's observation (`grid` `[C, F, F]`, `vector`, `mask`)
    /// after the agents of `earlier` (`(agent, action)`, those ranked before it) chose theirs.
    /// Advances the recurrent state.
    ///
    /// # Errors
    /// Inputs of other sizes than the network's, a message outside its slots or actions, a
    /// mask that allows nothing.
    pub fn act(
        &mut self,
        grid: &[f32],
        vector: &[f32],
        mask: &[bool],
        earlier: &[(usize, u8)],
    ) -> Result<u8, AgentError> {
        let cfg = self.policy.config().clone();
        let grid_len = cfg.channels * cfg.fov * cfg.fov;
        for (what, found, expected) in [
            ("grid", grid.len(), grid_len),
            ("vector", vector.len(), cfg.env_vec),
            ("mask", mask.len(), cfg.n_actions),
        ] {
            if found != expected {
                return Err(AgentError::Size { what, found, expected });
            }
        }
        if !mask.contains(&true) {
            return Err(AgentError::NoAction);
        }
        let mut message = vec![0.0_f32; cfg.message_dim()];
        for &(agent, action) in earlier {
            if agent >= cfg.n_agents_max || usize::from(action) >= cfg.n_actions {
                return Err(AgentError::Message { agent, action });
            }
            message[agent * cfg.n_actions + usize::from(action)] = 1.0;
        }
        let mut vec = vec![0.0_f32; cfg.vec_dim()];
        vec[..cfg.env_vec].copy_from_slice(vector);
        vec[cfg.env_vec + self.agent] = 1.0;
        let device = self.policy.device().clone();
        let grid = Tensor::<5>::from_data(
            TensorData::new(grid.to_vec(), [1, 1, cfg.channels, cfg.fov, cfg.fov]),
            &device,
        );
        let vec = tensor3(vec, [1, 1, cfg.vec_dim()], &device);
        let features = self.policy.recurrent_rows(grid, vec);
        let message = tensor3(message, [1, 1, cfg.message_dim()], &device);
        let q = to_vec(self.policy.head(features, message));
        Ok(masked_argmax(&q, mask) as u8)
    }
}
