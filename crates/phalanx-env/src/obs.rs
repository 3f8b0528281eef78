//! The observation encoding (SPEC §4) and the flat buffers observations are written into.
//!
//! | part | shape | value |
//! |---|---|---|
//! | channel 0, obstacles | `F × F` | 1 for a blocked or outside cell, else 0 |
//! | channel 1, positions | `F × F` | agent `j` (this one included, at the centre) as `(j + 1) / n_agents`, 0 for no agent |
//! | channel 2, cost | `F × F` | `clamp(d(c) − d(own), −(F−1), F−1) / (F−1)` in `[−1, 1]`; [`COST_SENTINEL`] for blocked, outside or cut-off cells and for the cell of another agent standing on its own goal |
//! | channel 3, formation | `F × F` | agent `j`'s goal at `goal_j − goal_self` from the centre, as `(j + 1) / n_agents` (this agent's goal is the centre) |
//! | vector | `3` | `(dx / ‖d‖, dy / ‖d‖, ‖d‖ / (‖d‖ + F))` for `d = goal − position`, zeros on the goal |
//! | message | `n_agents × 5` | row `j` one-hot of the action agent `j` chose earlier in this step, zero rows for agents not yet acted |
//! | mask | `5` | action allowed by the task's clipping (in action index order) |
//!
//! Window cell `(row r, column c)` is the map cell `(x + c − R, y + r − R)` for the agent at
//! `(x, y)` and `R = F / 2`: row 0 is the *bottom* row (smallest `y`, `Up` increases the
//! row) and column 0 the left. `d` is the BFS distance to the agent's own goal. Every value
//! is bounded independently of the map side, so a policy trained on 32×32 maps reads
//! 1024×1024 maps unchanged.

/// The cost channel's value for blocked, outside or unreachable cells and for the cell of
/// another agent that stands on its own goal (the authors' environment used 1000 and 3000).
pub const COST_SENTINEL: f32 = 2.0;

/// Number of `F × F` channels.
pub const CHANNELS: usize = 4;

/// Length of the goal vector.
pub const VECTOR_LEN: usize = 3;

/// Number of actions, the width of a message row and of a mask.
pub const N_ACTIONS: usize = phalanx_core::Action::COUNT;

/// Sizes of one episode's observations: `n_agents` agents with an `fov × fov` view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObsLayout {
    /// Agents per episode.
    pub n_agents: usize,
    /// Field of view side `F`.
    pub fov: usize,
}

impl ObsLayout {
    /// Floats of one agent's channels, `4 · F · F`.
    #[inline]
    pub fn agent_grid_len(&self) -> usize {
        CHANNELS * self.fov * self.fov
    }

    /// Floats of one episode's channels, `n_agents · 4 · F · F`.
    #[inline]
    pub fn grid_len(&self) -> usize {
        self.n_agents * self.agent_grid_len()
    }

    /// Floats of one episode's goal vectors, `n_agents · 3`.
    #[inline]
    pub fn vector_len(&self) -> usize {
        self.n_agents * VECTOR_LEN
    }

    /// Floats of one agent's message, `n_agents · 5`.
    #[inline]
    pub fn agent_message_len(&self) -> usize {
        self.n_agents * N_ACTIONS
    }

    /// Floats of one episode's messages, `n_agents · n_agents · 5`.
    #[inline]
    pub fn message_len(&self) -> usize {
        self.n_agents * self.agent_message_len()
    }

    /// Flags of one episode's masks, `n_agents · 5`.
    #[inline]
    pub fn mask_len(&self) -> usize {
        self.n_agents * N_ACTIONS
    }
}

/// Observations of `n_envs` episodes in flat row-major buffers, ready to become tensors
/// without copies:
///
/// - `grid`: `[n_envs, n_agents, 4, F, F]`,
/// - `vector`: `[n_envs, n_agents, 3]`,
/// - `message`: `[n_envs, n_agents, n_agents, 5]`,
/// - `mask`: `[n_envs, n_agents, 5]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObsBuf {
    layout: ObsLayout,
    n_envs: usize,
    /// The four channels, `[n_envs, n_agents, 4, F, F]`.
    pub grid: Vec<f32>,
    /// Goal vectors, `[n_envs, n_agents, 3]`.
    pub vector: Vec<f32>,
    /// Action messages, `[n_envs, n_agents, n_agents, 5]`.
    pub message: Vec<f32>,
    /// Action masks, `[n_envs, n_agents, 5]`.
    pub mask: Vec<bool>,
}

impl ObsBuf {
    /// Zeroed buffers for `n_envs` episodes of this layout.
    pub fn new(layout: ObsLayout, n_envs: usize) -> ObsBuf {
        ObsBuf {
            layout,
            n_envs,
            grid: vec![0.0; n_envs * layout.grid_len()],
            vector: vec![0.0; n_envs * layout.vector_len()],
            message: vec![0.0; n_envs * layout.message_len()],
            mask: vec![false; n_envs * layout.mask_len()],
        }
    }

    /// The layout of one episode.
    #[inline]
    pub fn layout(&self) -> ObsLayout {
        self.layout
    }

    /// Number of episodes.
    #[inline]
    pub fn n_envs(&self) -> usize {
        self.n_envs
    }

    /// Agent `agent`'s channels in episode `env`, `[4, F, F]`.
    pub fn agent_grid(&self, env: usize, agent: usize) -> &[f32] {
        let len = self.layout.agent_grid_len();
        let at = (env * self.layout.n_agents + agent) * len;
        &self.grid[at..at + len]
    }

    /// One value: channel `channel`, window row `row`, column `col` of `agent` in `env`.
    pub fn at(&self, env: usize, agent: usize, channel: usize, row: usize, col: usize) -> f32 {
        let f = self.layout.fov;
        self.agent_grid(env, agent)[(channel * f + row) * f + col]
    }

    /// Agent `agent`'s goal vector in episode `env`.
    pub fn agent_vector(&self, env: usize, agent: usize) -> &[f32] {
        let at = (env * self.layout.n_agents + agent) * VECTOR_LEN;
        &self.vector[at..at + VECTOR_LEN]
    }

    /// Agent `agent`'s message in episode `env`, `[n_agents, 5]`.
    pub fn agent_message(&self, env: usize, agent: usize) -> &[f32] {
        let len = self.layout.agent_message_len();
        let at = (env * self.layout.n_agents + agent) * len;
        &self.message[at..at + len]
    }

    /// Agent `agent`'s action mask in episode `env`, in action index order.
    pub fn agent_mask(&self, env: usize, agent: usize) -> &[bool] {
        let at = (env * self.layout.n_agents + agent) * N_ACTIONS;
        &self.mask[at..at + N_ACTIONS]
    }

    /// Mutable views of episode `env`'s parts.
    pub fn env_mut(&mut self, env: usize) -> ObsSlices<'_> {
        let l = self.layout;
        ObsSlices {
            grid: &mut self.grid[env * l.grid_len()..(env + 1) * l.grid_len()],
            vector: &mut self.vector[env * l.vector_len()..(env + 1) * l.vector_len()],
            message: &mut self.message[env * l.message_len()..(env + 1) * l.message_len()],
            mask: &mut self.mask[env * l.mask_len()..(env + 1) * l.mask_len()],
        }
    }
}

/// One episode's parts of an [`ObsBuf`].
#[derive(Debug)]
pub struct ObsSlices<'a> {
    /// `[n_agents, 4, F, F]`.
    pub grid: &'a mut [f32],
    /// `[n_agents, 3]`.
    pub vector: &'a mut [f32],
    /// `[n_agents, n_agents, 5]`.
    pub message: &'a mut [f32],
    /// `[n_agents, 5]`.
    pub mask: &'a mut [bool],
}
