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
    /// The network reads the whole team's observations (the centralised baseline), so no
    /// agent can act with it alone.
    #[error("the network is centralised: it acts for whole teams only")]
    Centralised,
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
    /// If the network has no slot `agent` or is centralised.
    pub fn new(mut policy: Policy, agent: usize) -> Result<AgentPolicy, AgentError> {
        if policy.is_centralised() {
            return Err(AgentError::Centralised);
        }
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
    /// Advances the recurrent state: [`AgentPolicy::observe`], then [`AgentPolicy::choose`].
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
        // Every input is checked before the recurrent state moves.
        self.check_mask(mask)?;
        let message = self.message(earlier)?;
        let features = self.observe(grid, vector)?;
        Ok(self.head(&features, mask, message))
    }

    /// This step's recurrent pass on the agent's observation (`grid` `[C, F, F]`, `vector`):
    /// advances the recurrent state and returns what the head reads. Apart from
    /// [`AgentPolicy::choose`] so that a policy's state can follow every step of an episode
    /// while another policy acts (the hierarchy's low level, docs/hierarchy.md).
    ///
    /// # Errors
    /// Inputs of other sizes than the network's.
    pub fn observe(&mut self, grid: &[f32], vector: &[f32]) -> Result<Features, AgentError> {
        let cfg = self.policy.config().clone();
        let grid_len = cfg.channels * cfg.fov * cfg.fov;
        for (what, found, expected) in
            [("grid", grid.len(), grid_len), ("vector", vector.len(), cfg.env_vec)]
        {
            if found != expected {
                return Err(AgentError::Size { what, found, expected });
            }
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
        Ok(Features(self.policy.recurrent_rows(grid, vec)))
    }

    /// The greedy action the head gives `features` (this step's, from
    /// [`AgentPolicy::observe`]) under `mask`, after the agents of `earlier` chose theirs.
    ///
    /// # Errors
    /// A mask of another size than the network's or that allows nothing, a message outside
    /// its slots or actions.
    pub fn choose(
        &self,
        features: &Features,
        mask: &[bool],
        earlier: &[(usize, u8)],
    ) -> Result<u8, AgentError> {
        self.check_mask(mask)?;
        let message = self.message(earlier)?;
        Ok(self.head(features, mask, message))
    }

    /// The head's greedy action under a checked mask and message.
    fn head(&self, features: &Features, mask: &[bool], message: Vec<f32>) -> u8 {
        let len = message.len();
        let message = tensor3(message, [1, 1, len], self.policy.device());
        let q = to_vec(self.policy.head(features.0.clone(), message));
        masked_argmax(&q, mask) as u8
    }

    /// The message of the actions of `earlier`, refused when one names an agent or an action
    /// outside the network's.
    fn message(&self, earlier: &[(usize, u8)]) -> Result<Vec<f32>, AgentError> {
        let cfg = self.policy.config();
        let mut message = vec![0.0_f32; cfg.message_dim()];
        for &(agent, action) in earlier {
            if agent >= cfg.n_agents_max || usize::from(action) >= cfg.n_actions {
                return Err(AgentError::Message { agent, action });
            }
            message[agent * cfg.n_actions + usize::from(action)] = 1.0;
        }
        Ok(message)
    }

    /// Refuses a mask of another size than the network's actions, or one that allows nothing.
    fn check_mask(&self, mask: &[bool]) -> Result<(), AgentError> {
        let expected = self.policy.config().n_actions;
        if mask.len() != expected {
            return Err(AgentError::Size { what: "mask", found: mask.len(), expected });
        }
        if !mask.contains(&true) {
            return Err(AgentError::NoAction);
        }
        Ok(())
    }
}

/// One step's output of an agent's recurrent pass, which its head reads
/// ([`AgentPolicy::observe`], [`AgentPolicy::choose`]).
#[derive(Clone, Debug)]
pub struct Features(Tensor<3>);
