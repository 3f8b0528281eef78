//! One agent's machine: it holds its observation and the actions it heard, and acts once it
//! has heard every agent ranked before it this step.

use std::collections::BTreeMap;

use phalanx_msg::{Action, Message, Observation};
use phalanx_rl::AgentPolicy;

/// A policy that decides one agent's action.
pub trait Decide {
    /// A new episode starts.
    fn reset(&mut self);

    /// The action for `obs` after the agents of `earlier` (`(agent, action)`) chose theirs.
    ///
    /// # Errors
    /// When the observation does not fit the policy.
    fn decide(&mut self, obs: &Observation, earlier: &[(usize, u8)]) -> Result<u8, AgentFault>;
}

impl Decide for AgentPolicy {
    fn reset(&mut self) {
        AgentPolicy::reset(self);
    }

    fn decide(&mut self, obs: &Observation, earlier: &[(usize, u8)]) -> Result<u8, AgentFault> {
        Ok(self.act(&obs.grid, &obs.vector, &obs.mask, earlier)?)
    }
}

/// Why an agent cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum AgentFault {
    /// An observation for another agent.
    #[error("agent {me} got the observation of agent {other}")]
    NotMine {
        /// This agent.
        me: u16,
        /// The observation's.
        other: u16,
    },
    /// The policy refused the observation.
    #[error(transparent)]
    Policy(#[from] phalanx_rl::AgentError),
}

/// An action heard: `(rank, agent, action)`.
type Heard = (u16, u16, u8);

/// One agent of a decentralised run.
#[derive(Debug)]
pub struct Agent<D> {
    id: u16,
    policy: D,
    episode: Option<u32>,
    /// This step's observation, until the agent acts on it.
    current: Option<Observation>,
    /// Actions heard, by `(episode, step)`, each `(rank, agent, action)`.
    heard: BTreeMap<(u32, u32), Vec<Heard>>,
}

impl<D: Decide> Agent<D> {
    /// Agent `id` deciding with `policy`.
    pub fn new(id: u16, policy: D) -> Agent<D> {
        Agent { id, policy, episode: None, current: None, heard: BTreeMap::new() }
    }

    /// The agent's id.
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The episode `episode` ended: forget it.
    pub fn end(&mut self, episode: u32) {
        self.heard.retain(|&(e, _), _| e != episode);
        if self.current.as_ref().is_some_and(|o| o.episode == episode) {
            self.current = None;
        }
    }

    /// Handles one message; returns the action to publish when the agent acted.
    ///
    /// # Errors
    /// An observation for another agent, or one the policy refuses.
    pub fn handle(&mut self, message: Message) -> Result<Option<Action>, AgentFault> {
        match message {
            Message::Observation(obs) => {
                if obs.agent != self.id {
                    return Err(AgentFault::NotMine { me: self.id, other: obs.agent });
                }
                if self.episode != Some(obs.episode) {
                    self.episode = Some(obs.episode);
                    self.policy.reset();
                }
                // Actions of earlier steps can no longer matter.
                let (episode, step) = (obs.episode, obs.step);
                self.heard.retain(|&(e, s), _| e != episode || s >= step);
                self.current = Some(obs);
            }
            Message::Action(action) if action.agent != self.id => {
                let heard = self.heard.entry((action.episode, action.step)).or_default();
                if !heard.iter().any(|&(_, agent, _)| agent == action.agent) {
                    heard.push((action.rank, action.agent, action.action));
                }
            }
            Message::Action(_) | Message::End(_) => {}
        }
        self.try_act()
    }

    /// Acts when this step's observation and the actions of every agent before it are in.
    fn try_act(&mut self) -> Result<Option<Action>, AgentFault> {
        let Some(obs) = &self.current else { return Ok(None) };
        let heard = self.heard.get(&(obs.episode, obs.step));
        let mut earlier: Vec<Heard> = heard
            .map(|it| it.iter().copied().filter(|&(rank, _, _)| rank < obs.rank).collect())
            .unwrap_or_default();
        if earlier.len() < usize::from(obs.rank) {
            return Ok(None);
        }
        // In rank order, as the team's message is built.
        earlier.sort_unstable();
        let message: Vec<(usize, u8)> =
            earlier.iter().map(|&(_, agent, action)| (usize::from(agent), action)).collect();
        let action = self.policy.decide(obs, &message)?;
        let out =
            Action { episode: obs.episode, step: obs.step, agent: self.id, rank: obs.rank, action };
        self.current = None;
        Ok(Some(out))
    }
}
