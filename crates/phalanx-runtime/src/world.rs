//! The world's machine: the instance, the true state, the observations it hands out and the
//! joint action it collects, for a team of the path-finding policy or of the hierarchy.

use phalanx_core::{Action as Move, Instance, Plan};
use phalanx_env::obs::N_ACTIONS;
use phalanx_env::{Choice, EnvConfig, EnvError, HierEnv, MetaInputs, ObsBuffers, TaskEnv};
use phalanx_msg::{Action, End, EndReason, Frame, Message, NEAR, Near, Observation};

use crate::Topic;

/// Why the world cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum WorldFault {
    /// The environment refused the instance.
    #[error(transparent)]
    Env(#[from] EnvError),
}

/// The team a world runs, and its environment.
#[derive(Debug)]
enum Team {
    /// The path-finding policy: one observation and one action per agent and step.
    PathFinding(Box<Single>),
    /// The hierarchy: choices, then actions, each step.
    Hierarchy(Box<Hier>),
}

/// The path-finding task's episode and its observations.
#[derive(Debug)]
struct Single {
    env: TaskEnv,
    obs: ObsBuffers,
}

/// Where the hierarchy's step is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// The meta observations are out; the choices come in.
    Choosing,
    /// The choices are in and the leader chose path finding: its action comes in.
    Leading,
    /// The frames are out; the actions come in.
    Acting,
}

/// The hierarchy's episode and step.
#[derive(Debug)]
struct Hier {
    env: HierEnv,
    /// The meta observation (its order is the meta order).
    meta: ObsBuffers,
    phase: Phase,
    /// This step's choices so far, by agent.
    choices: Vec<Option<u8>>,
    /// Choices that did not come in time (the agent ran path finding instead), by agent.
    missed_choices: Vec<u64>,
}

/// The world of one episode.
#[derive(Debug)]
pub struct World {
    team: Team,
    episode: u32,
    step: u32,
    n_agents: usize,
    /// This step's actions so far, by agent.
    actions: Vec<Option<u8>>,
    plan: Plan,
    /// Actions that did not come in time (the agent waited instead), by agent.
    missed: Vec<u64>,
    /// Actions or choices that came for another step or episode, twice, or not allowed.
    stale: u64,
    end: Option<End>,
    /// What to publish next.
    outbox: Vec<(Topic, Message)>,
}

impl World {
    /// Episode `episode` on `instance` for a team of one flat policy, with the field of view,
    /// step limit and task of `config`: the path-finding task for the path-finding policy,
    /// the meta task (formation clipping) for the imitation student.
    ///
    /// # Errors
    /// If the environment refuses the instance.
    pub fn new(instance: &Instance, config: EnvConfig, episode: u32) -> Result<World, WorldFault> {
        let n = instance.n_agents();
        let mut env = TaskEnv::new(config.task, config, n)?;
        let mut obs = ObsBuffers::new(n, env.obs_shape());
        env.reset_to(instance, &mut obs)?;
        let positions = env.env().positions().to_vec();
        Ok(World::start(
            Team::PathFinding(Box::new(Single { env, obs })),
            instance,
            &positions,
            episode,
        ))
    }

    /// Episode `episode` on `instance` for a team of the hierarchy, with the field of view
    /// and step limit of `config` (the meta task's episode, `phalanx_env::HierEnv`).
    ///
    /// # Errors
    /// If the environment refuses the instance.
    pub fn hierarchy(
        instance: &Instance,
        config: EnvConfig,
        episode: u32,
    ) -> Result<World, WorldFault> {
        let n = instance.n_agents();
        // The formation weight only weighs the meta reward: it is not the world's. The vector
        // towards each agent's place goes to every agent; a meta policy that does not read
        // it ignores it.
        let inputs = MetaInputs { place: true };
        let mut env = HierEnv::new(config, n, inputs)?;
        let mut meta = ObsBuffers::new(n, env.meta_shape());
        env.reset_to(instance, 0.0, &mut meta)?;
        let positions = env.env().positions().to_vec();
        let hier = Hier {
            env,
            meta,
            phase: Phase::Choosing,
            choices: vec![None; n],
            missed_choices: vec![0; n],
        };
        Ok(World::start(Team::Hierarchy(Box::new(hier)), instance, &positions, episode))
    }

    fn start(
        team: Team,
        instance: &Instance,
        starts: &[phalanx_core::Cell],
        episode: u32,
    ) -> World {
        let n = instance.n_agents();
        let mut plan = Plan::new(n);
        plan.push(starts);
        let mut world = World {
            team,
            episode,
            step: 0,
            n_agents: n,
            actions: vec![None; n],
            plan,
            missed: vec![0; n],
            stale: 0,
            end: None,
            outbox: Vec::new(),
        };
        world.send_observations();
        world
    }

    /// Whether the team is the hierarchy's.
    pub fn is_hierarchy(&self) -> bool {
        matches!(self.team, Team::Hierarchy(_))
    }

    /// What to publish now, in order: the step's observations (of the hierarchy: the meta
    /// observations, then, once the choices and the leader's action are in, the frames).
    pub fn outbox(&mut self) -> Vec<(Topic, Message)> {
        std::mem::take(&mut self.outbox)
    }

    /// Queues the step's first observations: every agent's, with its rank.
    fn send_observations(&mut self) {
        let (episode, step) = (self.episode, self.step);
        let messages: Vec<Message> = match &self.team {
            Team::PathFinding(single) => {
                let obs = &single.obs;
                observations(episode, step, obs, &obs.order).map(Message::Observation).collect()
            }
            Team::Hierarchy(hier) => {
                // The path-finding observation, its vector followed by the place vector.
                let obs = hier.env.pathfinding_obs();
                observations(episode, step, obs, &hier.meta.order)
                    .map(|mut o| {
                        o.vector = hier.meta.vec_of(usize::from(o.agent)).to_vec();
                        Message::Meta(o)
                    })
                    .collect()
            }
        };
        self.queue(messages);
    }

    fn queue(&mut self, messages: Vec<Message>) {
        for message in messages {
            let agent = match &message {
                Message::Observation(o) | Message::Meta(o) => o.agent,
                Message::Frame(f) => f.observation.agent,
                _ => unreachable!("the world queues observations only"),
            };
            self.outbox.push((Topic::Agent(agent), message));
        }
    }

    /// Takes an action or a choice when it is this step's and its agent's first, and the
    /// step is where it may come; counts it stale otherwise. Other messages are not the
    /// world's and are ignored.
    pub fn receive(&mut self, message: &Message) {
        match message {
            Message::Action(action) => self.receive_action(action),
            Message::Choice(choice) => self.receive_choice(choice),
            _ => {}
        }
    }

    fn receive_action(&mut self, action: &Action) {
        let agent = usize::from(action.agent);
        let fits = action.episode == self.episode
            && action.step == self.step
            && agent < self.n_agents
            && self.actions[agent].is_none()
            && self.may_take(agent, action.action);
        if fits {
            self.actions[agent] = Some(action.action);
            self.advance();
        } else {
            self.stale += 1;
        }
    }

    fn receive_choice(&mut self, choice: &Action) {
        let agent = usize::from(choice.agent);
        let fits = choice.episode == self.episode
            && choice.step == self.step
            && agent < self.n_agents
            && Choice::from_index(choice.action).is_some();
        match &mut self.team {
            Team::Hierarchy(hier) if fits && hier.phase == Phase::Choosing => {
                if hier.choices[agent].is_none() {
                    hier.choices[agent] = Some(choice.action);
                    self.advance();
                    return;
                }
                self.stale += 1;
            }
            _ => self.stale += 1,
        }
    }

    /// Whether `action` may be agent `agent`'s now: allowed by the mask of the policy it
    /// runs. Before the frame is anchored, a hierarchy agent's action (a path-finding
    /// leader's may come before the last choice) is kept and checked once it is known which
    /// mask is its ([`World::advance`]).
    fn may_take(&self, agent: usize, action: u8) -> bool {
        let allowed = |mask: &[bool]| mask.get(usize::from(action)).copied().unwrap_or(false);
        match &self.team {
            Team::PathFinding(single) => allowed(single.obs.mask_of(agent)),
            Team::Hierarchy(hier) => match hier.phase {
                Phase::Choosing | Phase::Leading => usize::from(action) < N_ACTIONS,
                Phase::Acting => allowed(hier.mask_of(agent)),
            },
        }
    }

    /// Moves the hierarchy's step on as far as what is in allows: with every choice in, fixes
    /// the low-level order; with the leader's action in (or no path-finding leader), anchors
    /// the frame and queues the frames.
    fn advance(&mut self) {
        let Team::Hierarchy(hier) = &mut self.team else { return };
        if hier.phase == Phase::Acting {
            return;
        }
        if hier.phase == Phase::Choosing {
            let Some(choices) = hier.choices.iter().copied().collect::<Option<Vec<u8>>>() else {
                return;
            };
            hier.env.set_choices(&choices);
            let leader = hier.env.leader();
            if choices[leader] == Choice::PathFinding as u8 {
                hier.phase = Phase::Leading;
                let pathfinding = hier.env.pathfinding_obs().mask_of(leader);
                if let Some(action) = self.actions[leader]
                    && !pathfinding[usize::from(action)]
                {
                    self.actions[leader] = None;
                    self.stale += 1;
                }
            } else {
                hier.env.place_frame(None);
                hier.phase = Phase::Acting;
            }
        }
        if hier.phase == Phase::Leading {
            let Some(action) = self.actions[hier.env.leader()] else { return };
            hier.env.place_frame(Some(action));
            hier.phase = Phase::Acting;
        }
        // Acting, the frame just anchored: the actions kept so far are checked against
        // their masks, and the frames go out.
        for agent in 0..self.n_agents {
            if let Some(action) = self.actions[agent]
                && !hier.mask_of(agent)[usize::from(action)]
            {
                self.actions[agent] = None;
                self.stale += 1;
            }
        }
        let frames = hier.frames(self.episode, self.step);
        let to = |frame: Frame| (Topic::Agent(frame.observation.agent), Message::Frame(frame));
        self.outbox.extend(frames.into_iter().map(to));
    }

    /// The first agent, in the order of what the world waits for (choices in the meta order,
    /// the leader's action, the actions in the low-level order), whose message is not in;
    /// `None` when every action is in.
    pub fn next_missing(&self) -> Option<u16> {
        let missing = |order: &[usize]| {
            order.iter().find(|&&agent| self.actions[agent].is_none()).map(|&a| a as u16)
        };
        match &self.team {
            Team::PathFinding(single) => missing(&single.obs.order),
            Team::Hierarchy(hier) => match hier.phase {
                Phase::Choosing => {
                    hier.meta.order.iter().find(|&&a| hier.choices[a].is_none()).map(|&a| a as u16)
                }
                Phase::Leading => Some(hier.env.leader() as u16),
                Phase::Acting => missing(&hier.env.pathfinding_obs().order),
            },
        }
    }

    /// Gives up on [`World::next_missing`]: a missing choice counts as path finding, a
    /// missing action as a wait (counted as missed). The returned message says so to the
    /// agents ranked after it, who wait for it. `None` when every action is in.
    pub fn give_up_on_next(&mut self) -> Option<Message> {
        let agent = usize::from(self.next_missing()?);
        let (episode, step) = (self.episode, self.step);
        let (rank, message) = match &mut self.team {
            Team::PathFinding(single) => (rank_in(&single.obs.order, agent), None),
            Team::Hierarchy(hier) => match hier.phase {
                Phase::Choosing => {
                    let choice = Choice::PathFinding as u8;
                    hier.choices[agent] = Some(choice);
                    hier.missed_choices[agent] += 1;
                    let rank = rank_in(&hier.meta.order, agent);
                    (
                        rank,
                        Some(Message::Choice(Action {
                            episode,
                            step,
                            agent: agent as u16,
                            rank,
                            action: choice,
                        })),
                    )
                }
                Phase::Leading | Phase::Acting => {
                    (rank_in(&hier.env.pathfinding_obs().order, agent), None)
                }
            },
        };
        let message = message.unwrap_or_else(|| {
            let wait = Move::Wait as u8;
            self.actions[agent] = Some(wait);
            self.missed[agent] += 1;
            Message::Action(Action { episode, step, agent: agent as u16, rank, action: wait })
        });
        self.advance();
        Some(message)
    }

    /// Whether every agent's action is in.
    pub fn ready(&self) -> bool {
        let acting = match &self.team {
            Team::PathFinding(_) => true,
            Team::Hierarchy(hier) => hier.phase == Phase::Acting,
        };
        acting && self.actions.iter().all(Option::is_some)
    }

    /// Steps with the actions in (an agent without one waits, one without a choice runs
    /// path finding); `Some` when the episode ended.
    pub fn step(&mut self) -> Option<End> {
        if let Some(end) = self.end {
            return Some(end);
        }
        while self.give_up_on_next().is_some() {}
        self.outbox.clear();
        let joint: Vec<u8> = self.actions.iter().map(|a| a.expect("every action is in")).collect();
        let out = match &mut self.team {
            Team::PathFinding(single) => single.env.step(&joint, &mut single.obs),
            Team::Hierarchy(hier) => {
                let out = hier.env.step(&joint, &mut hier.meta);
                hier.phase = Phase::Choosing;
                hier.choices.iter_mut().for_each(|c| *c = None);
                out
            }
        };
        self.step += 1;
        let positions = match &self.team {
            Team::PathFinding(single) => single.env.env().positions(),
            Team::Hierarchy(hier) => hier.env.env().positions(),
        };
        self.plan.push(positions);
        self.actions.iter_mut().for_each(|a| *a = None);
        let reason = if out.terminated {
            Some(EndReason::Done)
        } else if out.truncated {
            Some(EndReason::StepLimit)
        } else {
            None
        };
        self.end = reason.map(|reason| End { episode: self.episode, steps: self.step, reason });
        if self.end.is_none() {
            self.send_observations();
        }
        self.end
    }

    /// The trajectory so far, one joint position per step.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Actions that did not come in time (the agent waited).
    pub fn missed(&self) -> u64 {
        self.missed.iter().sum()
    }

    /// Actions that did not come in time, by agent.
    pub fn missed_by_agent(&self) -> &[u64] {
        &self.missed
    }

    /// Choices that did not come in time (the agent ran path finding), by agent; empty for
    /// a path-finding team.
    pub fn missed_choices_by_agent(&self) -> &[u64] {
        match &self.team {
            Team::PathFinding(_) => &[],
            Team::Hierarchy(hier) => &hier.missed_choices,
        }
    }

    /// Choices that did not come in time.
    pub fn missed_choices(&self) -> u64 {
        self.missed_choices_by_agent().iter().sum()
    }

    /// Actions or choices that came for another step, twice, or not allowed.
    pub fn stale(&self) -> u64 {
        self.stale
    }
}

impl Hier {
    /// The mask of the policy agent `agent` runs this step (valid once the frame is
    /// anchored).
    fn mask_of(&self, agent: usize) -> &[bool] {
        if self.choices[agent] == Some(Choice::Formation as u8) {
            self.env.formation_obs().mask_of(agent)
        } else {
            self.env.pathfinding_obs().mask_of(agent)
        }
    }

    /// Every agent's frame: its formation observation and low-level rank, its policy, and
    /// its team mates within [`NEAR`] cells.
    fn frames(&self, episode: u32, step: u32) -> Vec<Frame> {
        let order = &self.env.pathfinding_obs().order;
        let positions = self.env.env().positions();
        observations(episode, step, self.env.formation_obs(), order)
            .map(|observation| {
                let agent = usize::from(observation.agent);
                let here = positions[agent];
                let near = positions
                    .iter()
                    .enumerate()
                    .filter(|&(other, cell)| other != agent && here.manhattan(*cell) <= NEAR)
                    .map(|(other, cell)| Near {
                        agent: other as u16,
                        dx: (cell.x - here.x) as i8,
                        dy: (cell.y - here.y) as i8,
                    })
                    .collect();
                let choice = self.choices[agent].unwrap_or(Choice::PathFinding as u8);
                Frame { observation, choice, near }
            })
            .collect()
    }
}

/// The rank of `agent` in `order`.
fn rank_in(order: &[usize], agent: usize) -> u16 {
    order.iter().position(|&a| a == agent).expect("every agent has a rank") as u16
}

/// Every agent's observation of `obs` at `(episode, step)`, with its rank in `order`.
fn observations<'a>(
    episode: u32,
    step: u32,
    obs: &'a ObsBuffers,
    order: &[usize],
) -> impl Iterator<Item = Observation> + 'a {
    let n = obs.n_agents;
    let mut rank = vec![0_u16; n];
    for (r, &agent) in order.iter().enumerate() {
        rank[agent] = r as u16;
    }
    (0..n).map(move |agent| Observation {
        episode,
        step,
        agent: agent as u16,
        rank: rank[agent],
        n_agents: n as u16,
        grid: obs.grid_of(agent).to_vec(),
        vector: obs.vec_of(agent).to_vec(),
        mask: obs.mask_of(agent).to_vec(),
    })
}
