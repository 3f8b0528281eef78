//! One agent of a team of the hierarchy (docs/runtime.md): each step it chooses its low-level
//! policy once the agents ranked before it in the meta order chose, then acts through that
//! policy once the agents ranked before it in the low-level order acted.

use phalanx_core::Cell;
use phalanx_env::Choice;
use phalanx_msg::{Action, Frame, Message, Observation};
use phalanx_rl::AgentHierarchy;

use crate::agent::{AgentFault, Heard, Machine};

/// The hierarchy as one agent runs it: the meta policy and the two low-level policies, each
/// with its own recurrent state.
pub trait DecideHier {
    /// A new episode starts.
    fn reset(&mut self);

    /// This step's path-finding observation (which the meta policy reads too): the recurrent
    /// passes.
    ///
    /// # Errors
    /// When the observation does not fit the policies.
    fn observe(&mut self, obs: &Observation) -> Result<(), AgentFault>;

    /// The meta choice after the agents of `earlier` (`(agent, choice)`) chose theirs.
    ///
    /// # Errors
    /// When the message does not fit the meta policy.
    fn choose(&mut self, earlier: &[(usize, u8)]) -> Result<Choice, AgentFault>;

    /// This step's formation-frame observation: the formation recurrent pass.
    ///
    /// # Errors
    /// When the observation does not fit the formation policy.
    fn observe_frame(&mut self, obs: &Observation) -> Result<(), AgentFault>;

    /// The action of the low-level policy `choice` under `mask` after the agents of
    /// `earlier` (`(agent, action)`) acted.
    ///
    /// # Errors
    /// When the mask or the message does not fit the policy.
    fn act(
        &mut self,
        choice: Choice,
        mask: &[bool],
        earlier: &[(usize, u8)],
    ) -> Result<u8, AgentFault>;
}

impl DecideHier for AgentHierarchy {
    fn reset(&mut self) {
        AgentHierarchy::reset(self);
    }

    fn observe(&mut self, obs: &Observation) -> Result<(), AgentFault> {
        Ok(AgentHierarchy::observe(self, &obs.grid, &obs.vector)?)
    }

    fn choose(&mut self, earlier: &[(usize, u8)]) -> Result<Choice, AgentFault> {
        Ok(AgentHierarchy::choose(self, earlier)?)
    }

    fn observe_frame(&mut self, obs: &Observation) -> Result<(), AgentFault> {
        Ok(AgentHierarchy::observe_frame(self, &obs.grid, &obs.vector)?)
    }

    fn act(
        &mut self,
        choice: Choice,
        mask: &[bool],
        earlier: &[(usize, u8)],
    ) -> Result<u8, AgentFault> {
        Ok(AgentHierarchy::act(self, choice, mask, earlier)?)
    }
}

/// Where one agent is in its step.
#[derive(Debug)]
struct Step {
    /// The step's path-finding observation (its rank the meta order's), kept for its mask.
    meta: Observation,
    /// Its choice, once made (or the world's stand-in for it).
    chosen: Option<Choice>,
    /// Whether it acted (as the path-finding leader, or at its turn in the frame).
    acted: bool,
    /// The step's frame, once in.
    frame: Option<Frame>,
}

/// One agent of a decentralised run of the hierarchy.
#[derive(Debug)]
pub struct HierAgent<H> {
    id: u16,
    policy: H,
    episode: Option<u32>,
    step: Option<Step>,
    choices: Heard,
    actions: Heard,
}

impl<H: DecideHier> HierAgent<H> {
    /// Agent `id` deciding with `policy`.
    pub fn new(id: u16, policy: H) -> HierAgent<H> {
        HierAgent {
            id,
            policy,
            episode: None,
            step: None,
            choices: Heard::default(),
            actions: Heard::default(),
        }
    }

    /// The agent's id.
    pub fn id(&self) -> u16 {
        self.id
    }

    /// Handles one message; returns what to publish: its choice, its action, or both (a
    /// leader that chose path finding acts at once).
    ///
    /// # Errors
    /// A message for another agent, one the policies refuse, or a path-finding team's
    /// observation.
    pub fn handle(&mut self, message: Message) -> Result<Vec<Message>, AgentFault> {
        match message {
            Message::Meta(obs) => {
                self.check(&obs)?;
                if self.episode != Some(obs.episode) {
                    self.episode = Some(obs.episode);
                    self.policy.reset();
                }
                self.choices.forget_before(obs.episode, obs.step);
                self.actions.forget_before(obs.episode, obs.step);
                self.policy.observe(&obs)?;
                self.step = Some(Step { meta: obs, chosen: None, acted: false, frame: None });
            }
            Message::Frame(frame) => {
                self.check(&frame.observation)?;
                Choice::from_index(frame.choice).ok_or(AgentFault::Choice(frame.choice))?;
                let obs = &frame.observation;
                // A frame of a step whose observation did not come is no use.
                if let Some(step) = self.step.as_mut()
                    && (step.meta.episode, step.meta.step) == (obs.episode, obs.step)
                    && step.frame.is_none()
                {
                    self.policy.observe_frame(obs)?;
                    step.frame = Some(frame);
                }
            }
            // Its own choice heard is the world's stand-in, when its own came late.
            Message::Choice(choice) => self.choices.note(&choice),
            Message::Action(action) if action.agent != self.id => self.actions.note(&action),
            Message::Observation(_) => {
                let sent = "path-finding observation";
                return Err(AgentFault::OtherTeam { runs: "the hierarchy", sent });
            }
            Message::Action(_) | Message::End(_) => {}
        }
        self.try_go()
    }

    /// Refuses an observation for another agent.
    fn check(&self, obs: &Observation) -> Result<(), AgentFault> {
        if obs.agent != self.id {
            return Err(AgentFault::NotMine { me: self.id, other: obs.agent });
        }
        Ok(())
    }

    /// Chooses when the earlier meta ranks chose (and leads at once when it is the first path
    /// finder), acts when its frame and the earlier low-level ranks' actions are in.
    fn try_go(&mut self) -> Result<Vec<Message>, AgentFault> {
        let mut out = Vec::new();
        let Some(step) = self.step.as_mut() else { return Ok(out) };
        let (episode, at) = (step.meta.episode, step.meta.step);
        let action = |rank, action| Action { episode, step: at, agent: self.id, rank, action };
        let earlier = self.choices.before(episode, at, step.meta.rank);
        let stand_in = self.choices.of(episode, at, self.id).and_then(Choice::from_index);
        if let Some(earlier) = &earlier {
            match (step.chosen, stand_in) {
                (None, None) => {
                    let choice = self.policy.choose(earlier)?;
                    out.push(Message::Choice(action(step.meta.rank, choice as u8)));
                    step.chosen = Some(choice);
                }
                // The world ran out of time for its choice: it runs what the world said.
                (_, Some(stand_in)) => step.chosen = Some(stand_in),
                (Some(_), None) => {}
            }
            // The path finders act first, front first: the first one leads, with no message,
            // before the frame is anchored at its next cell.
            let formation = Choice::Formation as u8;
            if step.chosen == Some(Choice::PathFinding)
                && !step.acted
                && step.frame.is_none()
                && earlier.iter().all(|&(_, c)| c == formation)
            {
                let led = self.policy.act(Choice::PathFinding, &step.meta.mask, &[])?;
                step.acted = true;
                out.push(Message::Action(action(0, led)));
            }
        }
        if let Some(frame) = &step.frame
            && !step.acted
        {
            let obs = &frame.observation;
            let choice =
                Choice::from_index(frame.choice).ok_or(AgentFault::Choice(frame.choice))?;
            if obs.rank == 0 && choice == Choice::PathFinding {
                // The world took it as the path-finding leader without its action (its choice
                // came late) and has moved on: nothing to do this step.
                step.acted = true;
            } else if let Some(earlier) = self.actions.before(episode, at, obs.rank) {
                let mut mask = match choice {
                    Choice::PathFinding => step.meta.mask.clone(),
                    Choice::Formation => obs.mask.clone(),
                };
                clip_by_near(frame, &earlier, &mut mask);
                let acted = self.policy.act(choice, &mask, &earlier)?;
                step.acted = true;
                out.push(Message::Action(action(obs.rank, acted)));
            }
        }
        Ok(out)
    }
}

/// Clips `mask` by the earlier actions of the team mates near the agent
/// ([`phalanx_env::clip_claimed`] on cells relative to the agent's; a team mate further away
/// cannot take a cell from it). A mask that is not one flag per move is left to the policy
/// to refuse.
fn clip_by_near(frame: &Frame, earlier: &[(usize, u8)], mask: &mut [bool]) {
    if mask.len() != phalanx_env::obs::N_ACTIONS {
        return;
    }
    let moves = earlier.iter().filter_map(|&(agent, action)| {
        let near = frame.near.iter().find(|near| usize::from(near.agent) == agent)?;
        let valid = usize::from(action) < phalanx_env::obs::N_ACTIONS;
        valid.then(|| (Cell::new(i32::from(near.dx), i32::from(near.dy)), action))
    });
    phalanx_env::clip_claimed(Cell::new(0, 0), moves, mask);
}

impl<H: DecideHier> Machine for HierAgent<H> {
    fn handle_message(&mut self, message: Message) -> Result<Vec<Message>, AgentFault> {
        self.handle(message)
    }

    fn end(&mut self, episode: u32) {
        self.choices.forget(episode);
        self.actions.forget(episode);
        if self.step.as_ref().is_some_and(|s| s.meta.episode == episode) {
            self.step = None;
        }
    }
}
