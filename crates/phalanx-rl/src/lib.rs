//! Decentralised learned policies for multi-agent path finding in formation (SPEC §6).
//!
//! - [`net`]: the recurrent Q-network shared by all agents (encoder, LSTM, head with the action
//!   message after the LSTM);
//! - [`env`](mod@env): the environment interface the learner trains on ([`MarlEnv`], flat buffers);
//! - [`adapter`]: [`MarlEnv`] over `phalanx-env` ([`PoolEnv`], one type for every task);
//! - [`replay`]: episode replay, padded episodes or windows with burn-in;
//! - [`learner`]: VDN + double DQN with a target network, masked actions, ε-greedy acting;
//! - [`train`]: the collect/update loop and its metric names;
//! - [`checkpoint`]: atomic checkpoints of the whole learner with typed load errors.
//!
//! Built on burn 0.22: modules carry no backend type parameter, the backend and autodiff are
//! chosen at run time through the [`burn::tensor::Device`] (`Device::flex()` is the pure-Rust
//! CPU backend; `.autodiff()` enables training).
//!
//! ```ignore
//! use burn::tensor::Device;
//! use phalanx_rl::{Learner, LearnerConfig, QNetConfig};
//!
//! let device = Device::flex().autodiff();
//! let mut learner = Learner::new(QNetConfig::default(), LearnerConfig::default(), 3, 7, &device);
//! learner.train(&mut env, 100_000, 96, &mut |name, step, value| log(name, step, value));
//! learner.save("run/checkpoint.bin".as_ref())?;
//! ```

pub mod adapter;
pub mod checkpoint;
pub mod env;
pub mod learner;
pub mod net;
pub mod replay;
pub mod train;

pub use adapter::PoolEnv;
pub use checkpoint::CheckpointError;
pub use env::{MarlEnv, ObsBuffers, ObsShape, StepOut};
pub use learner::{Counters, EpsilonSchedule, Learner, LearnerConfig, Policy, UpdateStats};
pub use net::{EncoderConfig, QNet, QNetConfig, RecurrentState};
pub use replay::{Batch, Episode, Replay, SequenceMode};
pub use train::{MetricSink, metrics};
