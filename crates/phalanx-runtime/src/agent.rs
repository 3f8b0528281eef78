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

/// An agent's machine as [`crate::run_agent`] drives it: messages in, messages to publish
/// (on [`crate::Topic::Actions`]) out.
pub trait Machine {
    /// Handles one message other than the end; returns what to publish.
    ///
    /// # Errors
    /// A message the machine refuses, or a policy that fails.
    fn handle_message(&mut self, message: Message) -> Result<Vec<Message>, AgentFault>;

    /// The episode `episode` ended: forget it.
    fn end(&mut self, episode: u32);
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
    /// A message of the other kind of team: the world runs another policy.
    #[error(
        "this agent runs {runs}, the world sent a {sent}: the world and the agents must run \
         the same policy (--policy)"
    )]
    OtherTeam {
        /// The team this agent belongs to.
        runs: &'static str,
        /// The message it got.
        sent: &'static str,
    },
    /// A frame naming a low-level policy that is none.
    #[error("a frame with choice {0}, not 0 (path finding) or 1 (formation)")]
    Choice(u8),
    /// The policy refused the observation.
    #[error(transparent)]
    Policy(#[from] phalanx_rl::AgentError),
}

/// A message heard: `(rank, agent, value)`.
type Said = (u16, u16, u8);

/// Messages heard from the other agents (actions, or choices), by `(episode, step)`: the
/// first of each agent.
#[derive(Debug, Default)]
pub(crate) struct Heard(BTreeMap<(u32, u32), Vec<Said>>);

impl Heard {
    /// Notes `message` (an action or a choice) unless its agent was heard at its step.
    pub(crate) fn note(&mut self, message: &Action) {
        let heard = self.0.entry((message.episode, message.step)).or_default();
        if !heard.iter().any(|&(_, agent, _)| agent == message.agent) {
            heard.push((message.rank, message.agent, message.action));
        }
    }

    /// What was heard of `agent` at `(episode, step)`.
    pub(crate) fn of(&self, episode: u32, step: u32, agent: u16) -> Option<u8> {
        let heard = self.0.get(&(episode, step))?;
        heard.iter().find(|&&(_, a, _)| a == agent).map(|&(_, _, value)| value)
    }

    /// Forgets the steps of `episode` before `step` (they can no longer matter).
    pub(crate) fn forget_before(&mut self, episode: u32, step: u32) {
        self.0.retain(|&(e, s), _| e != episode || s >= step);
    }

    /// Forgets `episode`.
    pub(crate) fn forget(&mut self, episode: u32) {
        self.0.retain(|&(e, _), _| e != episode);
    }

    /// The `(agent, value)` of every rank before `rank` at `(episode, step)`, in rank order
    /// (as the team's message is built); `None` until they are all in.
    pub(crate) fn before(&self, episode: u32, step: u32, rank: u16) -> Option<Vec<(usize, u8)>> {
        let heard = self.0.get(&(episode, step));
        let mut earlier: Vec<Said> = heard
            .map(|it| it.iter().copied().filter(|&(r, _, _)| r < rank).collect())
            .unwrap_or_default();
        if earlier.len() < usize::from(rank) {
            return None;
        }
        earlier.sort_unstable();
        Some(earlier.iter().map(|&(_, agent, value)| (usize::from(agent), value)).collect())
    }
}

/// One agent of a decentralised run.
#[derive(Debug)]
pub struct Agent<D> {
    id: u16,
    policy: D,
    episode: Option<u32>,
    /// This step's observation, until the agent acts on it.
    current: Option<Observation>,
    /// Actions heard.
    heard: Heard,
}

impl<D: Decide> Agent<D> {
    /// Agent `id` deciding with `policy`.
    pub fn new(id: u16, policy: D) -> Agent<D> {
        Agent { id, policy, episode: None, current: None, heard: Heard::default() }
    }

    /// The agent's id.
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The episode `episode` ended: forget it.
    pub fn end(&mut self, episode: u32) {
        self.heard.forget(episode);
        if self.current.as_ref().is_some_and(|o| o.episode == episode) {
            self.current = None;
        }
    }

    /// Handles one message; returns the action to publish when the agent acted.
    ///
    /// # Errors
    /// An observation for another agent, one the policy refuses, or a message of the
    /// hierarchy's phases.
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
                self.heard.forget_before(obs.episode, obs.step);
                self.current = Some(obs);
            }
            Message::Action(action) if action.agent != self.id => self.heard.note(&action),
            Message::Meta(_) | Message::Frame(_) => {
                let sent = "message of the hierarchy's phases";
                return Err(AgentFault::OtherTeam { runs: "the path-finding policy", sent });
            }
            Message::Action(_) | Message::Choice(_) | Message::End(_) => {}
        }
        self.try_act()
    }

    /// Acts when this step's observation and the actions of every agent before it are in.
    fn try_act(&mut self) -> Result<Option<Action>, AgentFault> {
        let Some(obs) = &self.current else { return Ok(None) };
        let Some(message) = self.heard.before(obs.episode, obs.step, obs.rank) else {
            return Ok(None);
        };
        let action = self.policy.decide(obs, &message)?;
        let out =
            Action { episode: obs.episode, step: obs.step, agent: self.id, rank: obs.rank, action };
        self.current = None;
        Ok(Some(out))
    }
}

impl<D: Decide> Machine for Agent<D> {
    fn handle_message(&mut self, message: Message) -> Result<Vec<Message>, AgentFault> {
        Ok(self.handle(message)?.map(Message::Action).into_iter().collect())
    }

    fn end(&mut self, episode: u32) {
        Agent::end(self, episode);
    }
}
