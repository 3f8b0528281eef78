//! Decentralised learned policies for multi-agent path finding in formation (docs/spec.md §6).
//!
//! - [`net`]: the recurrent Q-network shared by all agents (encoder, LSTM, head with the action
//!   message after the LSTM);
//! - [`replay`]: episode replay, padded episodes or windows with burn-in;
//! - [`learner`]: VDN + double DQN with a target network and masked actions;
//! - [`policy`]: acting, one episode or many in lockstep (batched inference, leader order);
//! - [`agent`]: one agent acting alone on its own observation and message (decentralised);
//! - [`eval`]: greedy evaluation on given instances, in lockstep batches;
//! - [`hierarchy`]: the meta policy's low level over the two frozen policies, and the whole
//!   hierarchy at test time, which owns an episode and a step;
//! - [`meta_env`]: the meta policy's training environment ([`MetaEnv`]) and the schedule of
//!   its formation-weight multiples;
//! - [`weight`]: the balancing weight `w_f` of Eq. 14;
//! - [`settings`]: a training run's settings, the task defaults and the collectors they build;
//! - [`train`]: the collect/update loop ([`Collector`]) and its metric names;
//! - [`models`]: finding and loading trained policies (a file, a directory or the shipped
//!   `models/`) and the hierarchy of a meta policy over its low level;
//! - [`policy_file`]: the file format of policy files and checkpoints (checksummed sections)
//!   and loading a policy for acting;
//! - [`checkpoint`]: atomic checkpoints of the whole learner with typed load errors;
//! - [`imitation`]: imitation data: expert rollouts on the training pool, labels in the acting
//!   order, the data file.
//!
//! The environments it trains on implement `phalanx_env::MarlEnv` (flat observation buffers,
//! action masks, leader order); `phalanx_env::PoolEnv` is the low-level tasks' one.
//!
//! Built on burn 0.22: modules carry no backend type parameter, the backend and autodiff are
//! chosen at run time through the [`burn::tensor::Device`] (`Device::flex()` is the pure-Rust
//! CPU backend; `.autodiff()` enables training).
//!
//! ```ignore
//! use burn::tensor::Device;
//! use phalanx_rl::{Collector, Learner, LearnerConfig, QNetConfig};
//!
//! let device = Device::flex().autodiff();
//! let mut learner = Learner::new(QNetConfig::default(), LearnerConfig::default(), &[3], 7, &device);
//! let mut collector = Collector::new(envs, 96); // e.g. 16 `PoolEnv`s, episodes cut at 96 steps
//! learner.train(&mut collector, 100_000, &mut |name, step, value| log(name, step, value));
//! learner.save("run/checkpoint.bin".as_ref())?;
//! ```

pub mod agent;
pub mod checkpoint;
pub mod escape;
pub mod eval;
mod frozen;
pub mod hierarchy;
mod hyper;
pub mod imitation;
pub mod keep;
pub mod learner;
pub mod meta_env;
pub mod models;
pub mod net;
pub mod policy;
pub mod policy_file;
pub mod replay;
mod resume;
pub mod settings;
pub mod train;
pub mod weight;

pub use agent::{AgentError, AgentHierarchy, AgentPolicy, Features};
pub use escape::Escape;
pub use eval::evaluate_hierarchy;
pub use eval::{EvalEpisode, EvalSummary, Rollouts, evaluate};
pub use hierarchy::{
    Episodes, FormationWeight, Hierarchy, LowLevel, MetaInfo, MetaPolicy, Multiples, PolicyRef,
    ScriptedMeta,
};
pub use keep::{Keep, STUDENT_ROLLOUT_TEMPERATURE, STUDENT_TEAM_DEADBAND};
pub use learner::{
    Counters, EpsilonSchedule, ImitationStats, Learner, LearnerConfig, PolicyGradientStats,
    UpdateStats,
};
pub use meta_env::{MetaEnv, MetaEnvConfig};
pub use net::{EncoderConfig, NetConfigError, QNet, QNetConfig, RecurrentState};
pub use policy::{Policy, RecurrentStateError};
pub use policy_file::CheckpointError;
pub use replay::{Batch, Episode, Replay, ReplayError, SequenceMode};
pub use resume::{CollectionError, ResumeError};
pub use settings::{MetaSettings, SettingsError, TrainConfig, TrainTask};
pub use train::{Collector, MetricSink, metrics};
pub use weight::{WeightConfig, WeightEstimate, estimate_weight};
