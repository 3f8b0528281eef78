//! Settings of the environment (the reward task, the field of view, the formation weight and
//! the step limit) and its typed errors.

use phalanx_gen::GenError;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Most agents in one episode: two `u16` values are reserved in the occupancy grid.
pub const MAX_AGENTS: usize = u16::MAX as usize - 1;

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
    /// Steps after which an episode is truncated; `None` means the instance's own
    /// ([`phalanx_core::step_limit`]: `3 × map side`, the paper's, unless an agent's shortest
    /// route is longer than two sides).
    pub step_limit: Option<u32>,
    /// The meta task's idle cost `c`: each step, an agent off its goal that did not get
    /// closer to it loses `c`; unused by the other tasks. Default 0 (Table I). Not written
    /// when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub idle_cost: f64,
    /// Whether an agent's vector holds, after its goal vector, the vector towards its
    /// *place*: its cell of the goal layout placed on the agent in front (the path-finding
    /// leader), as [`crate::Env::write_place_vector`] writes it (`docs/observation.md`); the
    /// vector is then 6 long. The planners' student reads it (`docs/imitation.md`). Default
    /// false. Not written when false.
    #[serde(skip_serializing_if = "is_false")]
    pub place_vector: bool,
    /// Whether an agent's vector ends with the *team vector*: for the agent in front (the
    /// path-finding leader), the vector towards its place in the goal layout placed on the
    /// team's centre (the mean of the agents' cells), zeros within
    /// [`EnvConfig::team_deadband`] of it; zeros for the other agents
    /// ([`crate::Env::write_team_vector`]). It tells the agent in front, whose place vector is
    /// zeros, how far the others lag behind; it can compute it from the others' broadcast
    /// place vectors (`docs/observation.md`). Needs [`EnvConfig::place_vector`]; the vector is
    /// then 9 long. The shipped student reads it (`docs/imitation.md`). Default false. Not
    /// written when false.
    #[serde(skip_serializing_if = "is_false")]
    pub team_vector: bool,
    /// The team vector's dead band in cells: the team vector is zeros while it is shorter
    /// (a team that lags less is left to the followers' place vectors, and the agent in
    /// front does not wait for it). Default [`crate::obs::TEAM_DEADBAND`], 1.5, what the
    /// shipped student was trained with; narrower at test time, the team keeps its shape
    /// better and takes longer (`docs/imitation.md`, *The dead band at test time*). Not
    /// written when the default.
    #[serde(skip_serializing_if = "is_default_deadband")]
    pub team_deadband: f64,
}

fn is_default_deadband(x: &f64) -> bool {
    *x == crate::obs::TEAM_DEADBAND
}

fn is_false(x: &bool) -> bool {
    !*x
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl EnvConfig {
    /// Refuses settings no environment can follow: an even field of view or one below 3, the
    /// team vector without the place vector it follows, a dead band that is not a number
    /// of cells at or above 0 ([`crate::Env::new`] checks them).
    ///
    /// # Errors
    /// [`EnvError::Fov`], [`EnvError::TeamVector`] or [`EnvError::TeamDeadband`].
    pub fn check(&self) -> Result<(), EnvError> {
        if self.fov < 3 || self.fov.is_multiple_of(2) {
            return Err(EnvError::Fov(self.fov));
        }
        if self.team_vector && !self.place_vector {
            return Err(EnvError::TeamVector);
        }
        check_team_deadband(self.team_deadband)
    }

    /// The length of each agent's vector: the goal vector, then the place and team vectors
    /// when on ([`crate::obs::VECTOR_LEN`] values each).
    pub fn vector_len(&self) -> usize {
        let vectors = 1 + usize::from(self.place_vector) + usize::from(self.team_vector);
        vectors * crate::obs::VECTOR_LEN
    }
}

impl Default for EnvConfig {
    fn default() -> EnvConfig {
        EnvConfig {
            fov: phalanx_gen::DEFAULT_FOV,
            task: Task::PathFinding,
            formation_weight: 1.0,
            step_limit: None,
            idle_cost: 0.0,
            place_vector: false,
            team_vector: false,
            team_deadband: crate::obs::TEAM_DEADBAND,
        }
    }
}

/// Refuses a team-vector dead band that is not a finite number of cells at or above 0.
///
/// # Errors
/// [`EnvError::TeamDeadband`].
pub fn check_team_deadband(cells: f64) -> Result<(), EnvError> {
    if cells.is_finite() && cells >= 0.0 { Ok(()) } else { Err(EnvError::TeamDeadband(cells)) }
}

/// Why the environment cannot be built or reset.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EnvError {
    /// The field of view is even or below 3.
    #[error("field of view {0} must be odd and at least 3")]
    Fov(u32),
    /// The team vector without the place vector it follows.
    #[error("the team vector needs the place vector (team_vector without place_vector)")]
    TeamVector,
    /// The team vector's dead band is negative or not a number.
    #[error("team vector dead band {0}: a number of cells, 0 or more")]
    TeamDeadband(f64),
    /// A training map cannot be read or holds no formation (the reader's message names the
    /// file, and the line where one is at fault).
    #[error("training map: {0}")]
    Map(String),
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
