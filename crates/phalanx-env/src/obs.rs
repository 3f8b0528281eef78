//! The observation encoding (docs/spec.md §4); the buffers it is written into are
//! [`crate::ObsBuffers`].
//!
//! | part | shape | value |
//! |---|---|---|
//! | channel 0, obstacles | `F × F` | 1 for a blocked or outside cell, else 0 |
//! | channel 1, positions | `F × F` | agent `j` (this one included, at the centre) as `(j + 1) / n_agents`, 0 for no agent |
//! | channel 2, cost | `F × F` | `clamp(d(c) − d(own), −(F−1), F−1) / (F−1)` in `[−1, 1]`; [`COST_SENTINEL`] for blocked, outside or cut-off cells and for the cell of another agent standing on its own goal |
//! | channel 3, formation | `F × F` | agent `j`'s goal at `goal_j − goal_self` from the centre, as `(j + 1) / n_agents` (this agent's goal is the centre) |
//! | vector | `3` | `(dx / ‖d‖, dy / ‖d‖, ‖d‖ / (‖d‖ + F))` for `d = goal − position`, zeros on the goal |
//! | message | `n_agents × 5` | row `j` one-hot of the action agent `j` chose earlier in this step, zero rows for agents not yet acted ([`crate::Env::write_message`]; policies build theirs from the actions of the ranks before them) |
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

/// The default dead band of the team vector ([`crate::EnvConfig::team_deadband`]): it is
/// zeros while the agent in front is closer than this many cells to its place on the team
/// ([`crate::Env::write_team_vector`]), so a team one cell out of shape is left to the
/// followers' place vectors and the agent in front does not wait for it.
pub const TEAM_DEADBAND: f64 = 1.5;

/// Number of actions, the width of a message row and of a mask.
pub const N_ACTIONS: usize = phalanx_core::Action::COUNT;
