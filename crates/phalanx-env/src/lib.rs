//! The simulation environment of phalanx: the world every policy is trained and evaluated
//! in. One [`Env`] runs one episode (collision resolution of SPEC §1, the observations of
//! SPEC §4, the rewards, masks and termination of SPEC §5, the leader-ordered acting of
//! SPEC §6); a [`BatchEnv`] steps many episodes together into flat buffers; [`TrainPool`]
//! and [`EvalMaps`] keep training and evaluation maps apart; [`sim`] is the `phalanx sim`
//! command.
//!
//! The observation encoding is documented in [`obs`] and in `docs/observation.md`.
//!
//! ```ignore
//! use phalanx_env::{Env, EnvConfig, ObsBuf};
//! let mut env = Env::new(EnvConfig::default())?;
//! env.reset(&instance)?;
//! let mut obs = ObsBuf::new(env.layout(), 1);
//! env.observe_into(&mut obs);
//! let step = env.step(&[Action::Up, Action::Wait, Action::Right]);
//! ```

mod config;
mod env;
pub mod obs;

pub use config::{Clip, EnvConfig, EnvError, LeaderRule, Task};
pub use env::{Env, MAX_AGENTS, Step, StepInfo};
pub use obs::{ObsBuf, ObsLayout, ObsSlices};
mod batch;
pub use batch::{BatchEnv, Outcome};
mod formation;
mod pool;
pub use formation::{MAX_PLACEMENT_ATTEMPTS, formation_instance};
pub use pool::{EvalConfig, EvalMaps, PoolConfig, TrainPool, eval_seed, train_seed};
pub mod sim;
