//! The hierarchy's environment (docs/spec.md §6, the paper's Algorithm 1): the meta task's episode with
//! the three observations the hierarchy reads each step.
//!
//! Each step:
//! 1. the meta policy observes ([`HierEnv::observe`] writes the meta buffers): the episode's
//!    four channels and goal vector, optionally followed by the vector towards the agent's
//!    place ([`MetaInputs`]), a mask allowing both choices, and the path-finding
//!    leader order (the agent in front decides first; later agents see the earlier choices as
//!    their message);
//! 2. every agent chooses a low-level policy ([`Choice`]); [`HierEnv::set_choices`] fixes the
//!    step's acting order for the low level: the path finders first, front first, then the
//!    formation followers, nearest the team's centroid first;
//! 3. the low-level policies act in that order, each agent through the policy it chose, with
//!    the message of the actions taken before it whichever policy took them, and its mask
//!    clipped by those actions ([`HierEnv::clip_claimed`]). The path-finding
//!    policy reads the episode's observation with path-finding clipping
//!    ([`HierEnv::pathfinding_obs`]); the formation policy reads the formation frame (the goal
//!    layout placed on the team, `env/frame.rs`) with formation clipping
//!    ([`HierEnv::formation_obs`]). The frame is anchored at the leader (the first in the
//!    order): once the leader has acted, [`HierEnv::place_frame`] puts the leader's slot on
//!    the cell its action leads to (its own cell when its move is blocked), so that
//!    formation followers move with it; when every agent chose formation, the front agent's
//!    slot is its own cell (the team closes up on its front). Both buffers are written every
//!    step, so both policies' recurrent states can advance every step whichever runs;
//! 4. [`HierEnv::step`] applies the joint action; the reward is the meta task's (Table I:
//!    collision −50, +1 a move towards the goal, −`w_f · L_f` per agent).

use phalanx_core::{Action, Cell, Instance};

use crate::env::frame::Frame;
use crate::marl::{ObsBuffers, ObsShape, StepOut};
use crate::obs::{N_ACTIONS, VECTOR_LEN};
use crate::{Clip, Env, EnvConfig, EnvError, LeaderRule, Task};

/// Which low-level policy an agent runs this step: the meta policy's action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Choice {
    /// The path-finding policy (meta action 0).
    PathFinding = 0,
    /// The formation policy (meta action 1).
    Formation = 1,
}

impl Choice {
    /// Number of meta actions.
    pub const COUNT: usize = 2;

    /// The choice of meta action `index`, `None` above 1.
    pub fn from_index(index: u8) -> Option<Choice> {
        match index {
            0 => Some(Choice::PathFinding),
            1 => Some(Choice::Formation),
            _ => None,
        }
    }
}

/// Message-aware clipping for an agent on cell `here` ([`HierEnv::clip_claimed`]): removes
/// from `mask` the moves into a cell that an earlier agent's move `(cell, action index)` of
/// `earlier` leads to, or into the cell of an earlier agent that moves into `here`. Waiting
/// stays as it was. Only the differences between cells matter, so an agent that knows where
/// its team mates stand relative to it clips on relative cells (`here` the origin) exactly
/// as on the grid's; a team mate further than two cells (Manhattan) cannot take a cell from
/// it.
///
/// # Panics
/// If an action index is above 4 or the mask is not five long.
pub fn clip_claimed(
    here: Cell,
    earlier: impl Iterator<Item = (Cell, u8)> + Clone,
    mask: &mut [bool],
) {
    assert_eq!(mask.len(), N_ACTIONS, "one flag per action");
    let next = |cell: Cell, action: u8| {
        Action::from_index(usize::from(action)).expect("action index below 5").apply(cell)
    };
    for (index, allowed) in mask.iter_mut().enumerate() {
        let action = Action::from_index(index).expect("five actions");
        if !*allowed || action == Action::Wait {
            continue;
        }
        let target = action.apply(here);
        *allowed = !earlier.clone().any(|(cell, action)| {
            let to = next(cell, action);
            to == target || (to == here && cell == target)
        });
    }
}

/// What a meta observation's vector holds after the path-finding goal vector: the goal
/// vector towards the agent's place in the layout placed on the front agent
/// ([`Env::write_place_vector`]), or nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MetaInputs {
    /// The vector towards the agent's place.
    pub place: bool,
}

impl MetaInputs {
    /// Length of the meta observation's vector: the one place it is computed.
    pub fn vector_len(self) -> usize {
        VECTOR_LEN + if self.place { VECTOR_LEN } else { 0 }
    }
}

/// One episode of the meta task with the meta, path-finding and formation observations.
#[derive(Debug, Clone)]
pub struct HierEnv {
    env: Env,
    n_agents: usize,
    inputs: MetaInputs,
    pathfinding: ObsBuffers,
    formation: ObsBuffers,
    actions: Vec<Action>,
    /// The agent in front this step (the path-finding leader rule).
    front: usize,
    /// How many agents chose path finding this step (the head of the order).
    path_finders: usize,
    /// The followers still to be ordered (scratch of [`HierEnv::place_frame`]).
    unordered: Vec<usize>,
    /// The formation frame of the current step.
    frame: Frame,
}

impl HierEnv {
    /// An environment for teams of `n_agents` with the field of view and step limit of
    /// `config` (its task becomes [`Task::Meta`]), whose meta observation's vector holds
    /// `inputs`.
    ///
    /// # Panics
    /// If `n_agents` is 0.
    pub fn new(config: EnvConfig, n_agents: usize, inputs: MetaInputs) -> Result<Self, EnvError> {
        assert!(n_agents > 0, "an environment needs agents");
        // The low-level observations are the path-finding and formation policies' own: the
        // place vector is the meta observation's ([`MetaInputs::place`]).
        let env = Env::new(EnvConfig {
            task: Task::Meta,
            place_vector: false,
            team_vector: false,
            ..config
        })?;
        let low = env.obs_shape();
        Ok(HierEnv {
            env,
            n_agents,
            inputs,
            pathfinding: ObsBuffers::new(n_agents, low),
            formation: ObsBuffers::new(n_agents, low),
            actions: vec![Action::Wait; n_agents],
            front: 0,
            path_finders: 0,
            unordered: Vec::with_capacity(n_agents),
            frame: Frame::default(),
        })
    }

    /// Sizes of one agent's meta observation: the four channels, the vector of
    /// [`MetaInputs::vector_len`], two actions.
    pub fn meta_shape(&self) -> ObsShape {
        ObsShape {
            env_vec: self.inputs.vector_len(),
            n_actions: Choice::COUNT,
            ..self.env.obs_shape()
        }
    }

    /// What the meta observation's vector holds.
    pub fn meta_inputs(&self) -> MetaInputs {
        self.inputs
    }

    /// Agents per episode.
    pub fn n_agents(&self) -> usize {
        self.n_agents
    }

    /// The simulator (positions, goals, time, `L_f` of the running episode).
    pub fn env(&self) -> &Env {
        &self.env
    }

    /// The formation frame's goals of the current step (valid after
    /// [`HierEnv::place_frame`]): each agent's cell of the goal layout placed on the team.
    pub fn frame_goals(&self) -> &[Cell] {
        self.frame.goals()
    }

    /// The path-finding policy's observation of the current step (valid after
    /// [`HierEnv::set_choices`], which writes its order).
    pub fn pathfinding_obs(&self) -> &ObsBuffers {
        &self.pathfinding
    }

    /// The formation policy's observation (the formation frame) of the current step, in the
    /// order of [`HierEnv::set_choices`] (valid after [`HierEnv::place_frame`]).
    pub fn formation_obs(&self) -> &ObsBuffers {
        &self.formation
    }

    /// Starts an episode on `instance` whose meta reward weighs `L_f` by `formation_weight`
    /// per agent; writes the meta observation.
    ///
    /// # Errors
    /// If the instance has another agent count or the simulator refuses it.
    pub fn reset_to(
        &mut self,
        instance: &Instance,
        formation_weight: f64,
        meta: &mut ObsBuffers,
    ) -> Result<(), EnvError> {
        if instance.n_agents() != self.n_agents {
            return Err(EnvError::AgentCount {
                expected: self.n_agents,
                found: instance.n_agents(),
            });
        }
        self.env.set_formation_weight(formation_weight);
        self.env.reset(instance)?;
        self.observe(meta);
        Ok(())
    }

    /// The leader of the current step (the first in [`HierEnv::set_choices`]' order).
    pub fn leader(&self) -> usize {
        self.pathfinding.order[0]
    }

    /// Anchors the formation frame and writes the formation policy's observation. With
    /// `leader_action` (the leader chose path finding), the leader's slot is the cell that
    /// action leads to (its own cell when the move is blocked); with `None` (every agent chose
    /// formation), the slot of the agent in front (the path-finding leader) is its own cell, so
    /// that a team closing up gathers where its front stands instead of where its centre
    /// does (anchored at the centre agent, the whole team drifted back while closing up).
    ///
    /// # Panics
    /// If `leader_action` is not an action index.
    pub fn place_frame(&mut self, leader_action: Option<u8>) {
        let leader = if leader_action.is_some() { self.leader() } else { self.front };
        let here = self.env.positions()[leader];
        let next = leader_action
            .map(|a| Action::from_index(usize::from(a)).expect("action index below 5").apply(here))
            .filter(|&cell| self.env.distance(leader, cell).is_some())
            .unwrap_or(here);
        self.frame.update(&self.env, leader, next);
        self.chain_order();
        let (env, frame) = (&self.env, &self.frame);
        let shape = self.formation.shape;
        let grids = self.formation.grid.chunks_exact_mut(shape.grid_len());
        let vectors = self.formation.vec.chunks_exact_mut(VECTOR_LEN);
        let masks = self.formation.action_mask.chunks_exact_mut(N_ACTIONS);
        for (agent, ((grid, vector), mask)) in grids.zip(vectors).zip(masks).enumerate() {
            frame.write_grid(env, agent, grid);
            frame.write_vector(env, agent, vector);
            env.write_mask(agent, Clip::Formation, mask);
        }
    }

    /// Reorders the agents that chose formation (the tail of the order) so that an agent
    /// whose frame goal another of them stands on acts after that one (a team translating
    /// moves front first, each follower into the cell the one before it leaves); otherwise
    /// the order stays the formation rule's.
    fn chain_order(&mut self) {
        let order = &mut self.pathfinding.order;
        let first = self.path_finders;
        let positions = self.env.positions();
        let goals = self.frame.goals();
        let tail = &mut self.unordered;
        tail.clear();
        tail.extend_from_slice(&order[first..]);
        let mut placed = first;
        while !tail.is_empty() {
            let free = |a: usize, rest: &[usize]| {
                !rest.iter().any(|&b| b != a && positions[b] == goals[a])
            };
            let pick = tail.iter().position(|&a| free(a, tail)).unwrap_or(0);
            order[placed] = tail.remove(pick);
            placed += 1;
        }
        self.formation.order.clone_from(order);
    }

    /// Message-aware clipping: removes from `mask` (agent `agent`'s allowed actions) the moves
    /// that the actions already chosen this step rule out, `actions[i]` for the agents `i` of
    /// `earlier`: a move into the cell an earlier agent's action leads to (a vertex conflict)
    /// or into the cell of an earlier agent that moves into this agent's cell (a swap). Such
    /// a move would be cancelled by the step; an agent knows it from the message (the
    /// earlier actions) and its view (their cells lie within two cells of its own). Waiting
    /// stays as it was.
    ///
    /// # Panics
    /// If an action index is above 4 or the mask is not five long.
    pub fn clip_claimed(&self, agent: usize, earlier: &[usize], actions: &[u8], mask: &mut [bool]) {
        let positions = self.env.positions();
        let moves = earlier.iter().map(|&i| (positions[i], actions[i]));
        clip_claimed(positions[agent], moves, mask);
    }

    /// Writes the meta observation of the current state and the path-finding observation.
    fn observe(&mut self, meta: &mut ObsBuffers) {
        assert_eq!(meta.n_agents, self.n_agents, "buffers of another agent count");
        assert_eq!(meta.shape, self.meta_shape(), "buffers of another shape");
        self.env.observe_clipped(&mut self.pathfinding, Clip::PathFinding);
        meta.grid.copy_from_slice(&self.pathfinding.grid);
        let width = meta.shape.env_vec;
        let order = self.env.begin_turns(LeaderRule::PathFinding);
        meta.order.clear();
        meta.order.extend(order.iter().map(|&agent| usize::from(agent)));
        let front = meta.order[0];
        // The layout of `MetaInputs`: the goal vector, then the place vector.
        for (agent, out) in meta.vec.chunks_exact_mut(width).enumerate() {
            let (goal, place) = out.split_at_mut(VECTOR_LEN);
            goal.copy_from_slice(self.pathfinding.vec_of(agent));
            if self.inputs.place {
                self.env.write_place_vector(agent, front, place);
            }
        }
        meta.action_mask.fill(true);
    }

    /// Records the agents' choices (`choices[agent]`, meta action indices) and writes the
    /// low level's acting order of this step into both low-level observations: the agents
    /// that chose path finding first, front first (the path-finding rule), then those that
    /// chose formation, nearest the team's centroid first (the formation rule); ties by agent
    /// index. The leader is thus the front path finder, or with formation only, the agent at
    /// the centre.
    ///
    /// # Panics
    /// If there is not one choice per agent or a choice is not 0 or 1.
    pub fn set_choices(&mut self, choices: &[u8]) {
        assert_eq!(choices.len(), self.n_agents, "one choice per agent");
        let chose = |agent: usize, choice: Choice| {
            Choice::from_index(choices[agent]).expect("a meta action is 0 or 1") == choice
        };
        let mut order = std::mem::take(&mut self.pathfinding.order);
        order.clear();
        let front = self.env.begin_turns(LeaderRule::PathFinding);
        self.front = usize::from(front[0]);
        order.extend(
            front.iter().map(|&a| usize::from(a)).filter(|&a| chose(a, Choice::PathFinding)),
        );
        self.path_finders = order.len();
        let centre = self.env.begin_turns(LeaderRule::Formation);
        order.extend(
            centre.iter().map(|&a| usize::from(a)).filter(|&a| chose(a, Choice::Formation)),
        );
        self.formation.order.clone_from(&order);
        self.pathfinding.order = order;
    }

    /// Applies the low-level joint action (`actions[agent]`, action indices) and writes the
    /// next meta observation.
    ///
    /// # Panics
    /// If there is not one action per agent, an action index is above 4, or the episode has
    /// ended.
    pub fn step(&mut self, actions: &[u8], meta: &mut ObsBuffers) -> StepOut {
        let out = self.env.step_indices(actions, &mut self.actions);
        self.observe(meta);
        out
    }
}
