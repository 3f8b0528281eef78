//! One agent's side of a policy, for an agent that decides alone (a process of its own,
//! docs/runtime.md): its own recurrent state, its own observation, and the actions of the
//! agents ranked before it this step as its message. The network is the same as
//! [`Policy`]'s; an [`AgentPolicy`] per agent gives, step by step, the actions the batched
//! [`Policy::act`] gives the team (greedy, or with the policy's stall escape, whose draws
//! are the agent's own; tested in `tests/it/agent.rs`).
//!
//! [`AgentHierarchy`] is one agent's side of the whole hierarchy ([`Hierarchy`]): the meta
//! policy and both low-level policies, each an [`AgentPolicy`] with its own recurrent state;
//! an agent per team member, driven through the phases of the hierarchy's step, gives the
//! trajectory of the batched hierarchy (tested over the in-process bus in phalanx-runtime).

use phalanx_env::Choice;
use phalanx_env::obs::VECTOR_LEN;

use crate::escape::Stuck;
use crate::hierarchy::{Hierarchy, MetaPolicy};
use crate::net::masked_argmax;
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
    /// A scripted meta policy reads the whole team's state: it does not decide per agent.
    #[error("a scripted meta policy does not run as one agent's policy")]
    Scripted,
    /// A head asked for before the recurrent pass of the step it reads.
    #[error("no {0} observation this step")]
    NotObserved(&'static str),
}

/// One agent of a team acting with a policy's network.
#[derive(Clone, Debug)]
pub struct AgentPolicy {
    policy: Policy,
    agent: usize,
    /// Its side of the policy's stall escape, when the policy has one.
    stuck: Stuck,
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
        Ok(AgentPolicy { policy, agent, stuck: Stuck::new(agent) })
    }

    /// The agent.
    pub fn agent(&self) -> usize {
        self.agent
    }

    /// Starts a new episode (the recurrent state back to zeros).
    pub fn reset(&mut self) {
        self.policy.reset();
        self.stuck = Stuck::new(self.agent);
    }

    /// The greedy action for this step's observation (`grid` `[C, F, F]`, `vector`, `mask`)
    /// after the agents of `earlier` (`(agent, action)`, those ranked before it) chose theirs,
    /// or the policy's stall escape's random one ([`Policy::set_escape`]). Advances the
    /// recurrent state: [`AgentPolicy::observe`], then [`AgentPolicy::choose`].
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
        let greedy = self.head(&features, mask, message);
        let escaped = self.policy.escape().and_then(|rule| {
            let stalled = self.stuck.visit(&rule, vector);
            stalled.then(|| self.stuck.step_out(&rule, mask)).flatten()
        });
        Ok(escaped.map_or(greedy, |action| action as u8))
    }

    /// This step's recurrent pass on the agent's observation (`grid` `[C, F, F]`, `vector`):
    /// advances the recurrent state and returns what the head reads. Apart from
    /// [`AgentPolicy::choose`] so that a policy's state can follow every step of an episode
    /// while another policy acts (the hierarchy's low level, docs/hierarchy.md).
    ///
    /// # Errors
    /// Inputs of other sizes than the network's.
    pub fn observe(&mut self, grid: &[f32], vector: &[f32]) -> Result<Features, AgentError> {
        self.check_inputs(grid, vector)?;
        let cfg = self.policy.config().clone();
        let mut vec = vec![0.0_f32; cfg.vec_dim()];
        vec[..cfg.env_vec].copy_from_slice(vector);
        vec[cfg.env_vec + self.agent] = 1.0;
        Ok(Features(self.policy.recurrent_rows(grid, &vec)))
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
        let q = self.policy.head(&features.0, &message);
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

    /// Refuses a grid or vector of another size than the network's.
    fn check_inputs(&self, grid: &[f32], vector: &[f32]) -> Result<(), AgentError> {
        let cfg = self.policy.config();
        let grid_len = cfg.channels * cfg.fov * cfg.fov;
        for (what, found, expected) in
            [("grid", grid.len(), grid_len), ("vector", vector.len(), cfg.env_vec)]
        {
            if found != expected {
                return Err(AgentError::Size { what, found, expected });
            }
        }
        Ok(())
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
pub struct Features(Vec<f32>);

/// One agent of a team acting with the hierarchy: its meta policy and the two low-level
/// policies, each with its own recurrent state. A step goes:
/// [`AgentHierarchy::observe`] (the path-finding observation, which the meta policy reads
/// too), [`AgentHierarchy::choose`] once the agents ranked before it in the meta order chose,
/// [`AgentHierarchy::observe_frame`] (the formation frame) and [`AgentHierarchy::act`] once
/// the agents ranked before it in the low-level order acted (a leader that chose path
/// finding acts before the frame, on the features of [`AgentHierarchy::observe`]). Both
/// recurrent passes run every step, whichever policy acts, as in [`crate::LowLevel`].
#[derive(Clone, Debug)]
pub struct AgentHierarchy {
    meta: AgentPolicy,
    pathfinding: AgentPolicy,
    formation: AgentPolicy,
    /// Whether the meta observation ends with the vector towards the agent's place.
    place_input: bool,
    /// This step's meta and path-finding features.
    observed: Option<(Features, Features)>,
    /// This step's formation features.
    framed: Option<Features>,
}

impl AgentHierarchy {
    /// Agent `agent` of a team acting with `hierarchy` (a learned meta policy).
    ///
    /// # Errors
    /// A scripted meta policy, or networks without a slot `agent`.
    pub fn new(hierarchy: &Hierarchy, agent: usize) -> Result<AgentHierarchy, AgentError> {
        let MetaPolicy::Learned(meta) = &hierarchy.meta else {
            return Err(AgentError::Scripted);
        };
        let low = &hierarchy.low;
        Ok(AgentHierarchy {
            meta: AgentPolicy::new(meta.as_ref().clone(), agent)?,
            pathfinding: AgentPolicy::new(low.pathfinding().clone(), agent)?,
            formation: AgentPolicy::new(low.formation().clone(), agent)?,
            place_input: hierarchy.place_input,
            observed: None,
            framed: None,
        })
    }

    /// The agent.
    pub fn agent(&self) -> usize {
        self.meta.agent()
    }

    /// Starts a new episode (every recurrent state back to zeros).
    pub fn reset(&mut self) {
        for policy in [&mut self.meta, &mut self.pathfinding, &mut self.formation] {
            policy.reset();
        }
        (self.observed, self.framed) = (None, None);
    }

    /// This step's path-finding observation (`grid` `[C, F, F]`, `vector`: the goal vector,
    /// then the vector towards the agent's place, `phalanx_env::Env::write_place_vector`):
    /// the path-finding and meta recurrent passes. The path-finding policy reads the goal
    /// vector; the meta policy reads the same grid and the goal vector, with the place
    /// vector when it reads it.
    ///
    /// # Errors
    /// Inputs of other sizes than the networks'.
    pub fn observe(&mut self, grid: &[f32], vector: &[f32]) -> Result<(), AgentError> {
        let (goal, place) = vector.split_at(VECTOR_LEN.min(vector.len()));
        let mut meta_vector = goal.to_vec();
        if self.place_input {
            meta_vector.extend_from_slice(place);
        }
        // Both inputs are checked before either recurrent state moves.
        self.meta.check_inputs(grid, &meta_vector)?;
        self.pathfinding.check_inputs(grid, goal)?;
        let meta = self.meta.observe(grid, &meta_vector)?;
        let pathfinding = self.pathfinding.observe(grid, goal)?;
        (self.observed, self.framed) = (Some((meta, pathfinding)), None);
        Ok(())
    }

    /// The meta choice after the agents of `earlier` (`(agent, choice)`, those ranked before
    /// it in the meta order) chose theirs: greedy, either choice allowed.
    ///
    /// # Errors
    /// No observation this step, or a message outside the network's slots or choices.
    pub fn choose(&self, earlier: &[(usize, u8)]) -> Result<Choice, AgentError> {
        let (meta, _) = self.observed.as_ref().ok_or(AgentError::NotObserved("path-finding"))?;
        let choice = self.meta.choose(meta, &[true; Choice::COUNT], earlier)?;
        Ok(Choice::from_index(choice).expect("the meta network has two actions"))
    }

    /// This step's formation-frame observation (`grid` `[C, F, F]`, `vector`): the formation
    /// recurrent pass.
    ///
    /// # Errors
    /// Inputs of other sizes than the network's.
    pub fn observe_frame(&mut self, grid: &[f32], vector: &[f32]) -> Result<(), AgentError> {
        self.framed = Some(self.formation.observe(grid, vector)?);
        Ok(())
    }

    /// The greedy action of the low-level policy `choice` under `mask` (that policy's
    /// observation's, clipped by the earlier actions) after the agents of `earlier` (`(agent,
    /// action)`, those ranked before it in the low-level order) acted.
    ///
    /// # Errors
    /// No observation of that policy this step, a mask that does not fit or allows nothing,
    /// a message outside the network's slots or actions.
    pub fn act(
        &self,
        choice: Choice,
        mask: &[bool],
        earlier: &[(usize, u8)],
    ) -> Result<u8, AgentError> {
        match choice {
            Choice::PathFinding => {
                let (_, features) =
                    self.observed.as_ref().ok_or(AgentError::NotObserved("path-finding"))?;
                self.pathfinding.choose(features, mask, earlier)
            }
            Choice::Formation => {
                let features = self.framed.as_ref().ok_or(AgentError::NotObserved("formation"))?;
                self.formation.choose(features, mask, earlier)
            }
        }
    }
}
