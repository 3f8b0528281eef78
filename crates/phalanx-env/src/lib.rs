//! The simulation environment of phalanx: the world every policy is trained and evaluated
//! in.
//!
//! - [`Env`] runs one episode: collision resolution (docs/spec.md §1), observations (docs/spec.md §4, the
//!   encoding is documented in [`obs`] and `docs/observation.md`), rewards, action masks and
//!   termination of the three tasks (docs/spec.md §5), and leader-ordered sequential acting with
//!   action messages (docs/spec.md §6).
//! - [`MarlEnv`] is the interface training and evaluation step, with flat observation
//!   buffers ([`ObsBuffers`]) that become tensors without copies; [`TaskEnv`] is the
//!   simulator with a task's rewards, clipping and leader order, [`PoolEnv`] the low-level
//!   training environment on the pool; [`step_lockstep`] steps many environments in
//!   parallel, allocating nothing.
//! - [`HierEnv`] is the hierarchy's episode: the meta task with the meta, path-finding and
//!   formation-frame observations of every step (`docs/hierarchy.md`).
//! - [`TrainPool`] and [`EvalMaps`] keep training and evaluation maps apart by
//!   construction; [`formation_instance`] makes formation-training episodes.
//! - [`sim`] is the `phalanx sim` command.
//!
//! ```ignore
//! use phalanx_core::Action;
//! use phalanx_env::{Env, EnvConfig, ObsBuffers};
//! use phalanx_gen::GenConfig;
//!
//! let mut env = Env::new(EnvConfig::default())?;
//! let instance = env.reset_generated(&GenConfig { seed: 7, ..GenConfig::default() })?;
//! let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
//! env.observe(&mut obs);
//! let step = env.step(&[Action::Up, Action::Wait, Action::Right]);
//! println!("{} {:?}", step.team_reward, step.info.cancelled);
//! env.observe(&mut obs);
//! ```

mod config;
mod env;
mod formation;
mod hier;
mod marl;
pub mod obs;
mod pool;
pub mod sim;
mod task;

pub use config::{Clip, EnvConfig, EnvError, LeaderRule, MAX_AGENTS, Task, check_team_deadband};
pub use env::{Env, Step, StepInfo};
pub use formation::{MAX_PLACEMENT_ATTEMPTS, formation_instance};
pub use hier::{Choice, HierEnv, MetaInputs, clip_claimed};
pub use marl::{MarlEnv, ObsBuffers, ObsShape, StepOut, step_lockstep};
pub use phalanx_gen::GenConfig;
pub use pool::{EvalMaps, MapKind, PoolConfig, TrainPool, WIDE_SIDE, eval_seed, train_seed};
pub use task::{PoolEnv, Shaping, TaskEnv};
