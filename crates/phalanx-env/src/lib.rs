//! The simulation environment of phalanx: the world every policy is trained and evaluated
//! in.
//!
//! - [`Env`] runs one episode: collision resolution (SPEC §1), observations (SPEC §4, the
//!   encoding is documented in [`obs`] and `docs/observation.md`), rewards, action masks and
//!   termination of the three tasks (SPEC §5), and leader-ordered sequential acting with
//!   action messages (SPEC §6).
//! - [`BatchEnv`] steps many episodes together, in parallel, into flat buffers ([`ObsBuf`])
//!   that become tensors without copies; a step allocates nothing.
//! - [`TrainPool`] and [`EvalMaps`] keep training and evaluation maps apart by
//!   construction; [`formation_instance`] makes formation-training episodes.
//! - [`sim`] is the `phalanx sim` command.
//!
//! ```ignore
//! use phalanx_core::Action;
//! use phalanx_env::{Env, EnvConfig, ObsBuf};
//! use phalanx_gen::GenConfig;
//!
//! let mut env = Env::new(EnvConfig::default())?;
//! let instance = env.reset_generated(&GenConfig { seed: 7, ..GenConfig::default() })?;
//! let mut obs = ObsBuf::new(env.layout(), 1);
//! env.observe_into(&mut obs);
//! let step = env.step(&[Action::Up, Action::Wait, Action::Right]);
//! println!("{} {:?}", step.team_reward, step.info.cancelled);
//! env.observe_into(&mut obs);
//! ```

mod batch;
mod config;
mod env;
mod formation;
pub mod obs;
mod pool;
pub mod sim;

pub use batch::{BatchEnv, Outcome};
pub use config::{Clip, EnvConfig, EnvError, LeaderRule, Task};
pub use env::{Env, MAX_AGENTS, Step, StepInfo};
pub use formation::{MAX_PLACEMENT_ATTEMPTS, formation_instance};
pub use obs::{ObsBuf, ObsLayout, ObsSlices};
pub use pool::{EvalConfig, EvalMaps, PoolConfig, TrainPool, eval_seed, train_seed};
