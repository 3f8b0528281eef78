//! Settings of the environment (the reward task, the field of view, the formation weight and
//! the step limit) and its typed errors.

use phalanx_gen::GenError;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Most agents in one episode: two `u16` values are reserved in the occupancy grid.
pub const MAX_AGENTS: usize = u16::MAX as usize - 1;

/// The largest footprint penalty: costs stay far below `u32`'s sentinels on a 4096² map, and
/// the search's ring of buckets (`λ + 2`) stays short.
pub const MAX_FOOTPRINT_PENALTY: u32 = 100;

/// Which reward of docs/spec.md §5 (the paper's Table I) the environment pays, which action mask it
/// writes and when an episode is terminated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Task {
    /// Path finding: reach the goals. Terminated when every agent stands on its goal.
    #[default]
    PathFinding,
    /// Formation keeping: reach the goals' layout anywhere. Terminated when `L_f = 0`.
    Formation,
    /// The meta task: reach the goals with `−w_f · L_f` per step. Terminated when every
    /// agent stands on its goal.
    Meta,
}

/// Which moves an agent may choose (docs/spec.md §5 action clipping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Clip {
    /// Moves that do not increase the agent's BFS distance to its goal, and `Wait`.
    PathFinding,
    /// Moves into a free cell, and `Wait`.
    Formation,
    /// Every action.
    None,
}

impl Task {
    /// The action clipping of the task: path finding for [`Task::PathFinding`], formation
    /// for [`Task::Formation`] and [`Task::Meta`] (the end-to-end baselines clip as the
    /// formation policy does, docs/spec.md §7; the hierarchy writes its low-level policies' masks).
    pub fn clip(self) -> Clip {
        match self {
            Task::PathFinding => Clip::PathFinding,
            Task::Formation | Task::Meta => Clip::Formation,
        }
    }

    /// The leader ordering of the task's policy (docs/spec.md §6); the meta task's caller picks
    /// the rule of the low-level policy that runs.
    pub fn leader_rule(self) -> LeaderRule {
        match self {
            Task::Formation => LeaderRule::Formation,
            Task::PathFinding | Task::Meta => LeaderRule::PathFinding,
        }
    }
}

/// The order in which agents act within a step (docs/spec.md §6). Ties are broken by agent index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LeaderRule {
    /// Smallest BFS distance to the own goal first (the agent in front leads).
    PathFinding,
    /// Nearest the centroid of the current positions first (Euclidean, compared exactly in
    /// integers).
    Formation,
}

/// Environment settings. Defaults are the paper's values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EnvConfig {
    /// Side `F` of the square field of view, odd and at least 3. Paper: 9.
    pub fov: u32,
    /// The reward task. Default: path finding.
    pub task: Task,
    /// The meta task's formation weight `w_f` (docs/spec.md §6, Eq. 14); unused by the other tasks.
    /// Default 1.
    pub formation_weight: f64,
    /// Steps after which an episode is truncated; `None` means `3 × map side` (the paper).
    pub step_limit: Option<u32>,
    /// The meta task's idle cost `c`: each step, an agent off its goal that is idle (see
    /// `idle_scope`) loses `c`; unused by the other tasks. Default 0 (Table I). Not written
    /// when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub idle_cost: f64,
    /// What counts as idle for `idle_cost`. Default: each agent. Not written when the default.
    #[serde(skip_serializing_if = "IdleScope::is_agent")]
    pub idle_scope: IdleScope,
    /// The footprint penalty `λ` of the path-finding cost channel and mask: with `Some(λ)`,
    /// each agent's cost map charges `1 + λ` for each cell on the way where the goal layout placed
    /// with the agent there covers a blocked cell (a team cost map, `docs/hierarchy.md`);
    /// `None` (the default, the paper's) is the BFS distance. At most 100. Not written when
    /// `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub footprint_penalty: Option<u32>,
}

/// What the meta task's idle cost charges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum IdleScope {
    /// Each agent off its goal that did not get closer pays, whatever the others did (the
    /// default: the shipped meta policy's).
    #[default]
    Agent,
    /// A step in which no agent of the team got closer to its goal: every agent off its goal
    /// pays (a team that stands, in formation or not).
    Team,
}

impl IdleScope {
    fn is_agent(&self) -> bool {
        *self == IdleScope::Agent
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl Default for EnvConfig {
    fn default() -> EnvConfig {
        EnvConfig {
            fov: 9,
            task: Task::PathFinding,
            formation_weight: 1.0,
            step_limit: None,
            idle_cost: 0.0,
            idle_scope: IdleScope::Agent,
            footprint_penalty: None,
        }
    }
}

/// Why the environment cannot be built or reset.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EnvError {
    /// The field of view is even or below 3.
    #[error("field of view {0} must be odd and at least 3")]
    Fov(u32),
    /// The footprint penalty is above its largest value.
    #[error("footprint penalty {0} is above the largest, {max}", max = MAX_FOOTPRINT_PENALTY)]
    FootprintPenalty(u32),
    /// The instance has more agents than the occupancy grid can name.
    #[error("too many agents: {0} (at most {max})", max = MAX_AGENTS)]
    TooManyAgents(usize),
    /// A batch mixes instances with different numbers of agents.
    #[error("the batch has {expected} agents per episode but the instance has {found}")]
    AgentCount {
        /// Agents per episode of the batch.
        expected: usize,
        /// Agents of the instance.
        found: usize,
    },
    /// The generator refused the settings.
    #[error(transparent)]
    Gen(#[from] GenError),
    /// No valid formation-training placement came out.
    #[error("no formation-training placement of {n_agents} agents after {attempts} attempts")]
    Placement {
        /// Agents to place.
        n_agents: usize,
        /// Attempts made.
        attempts: u32,
    },
}
