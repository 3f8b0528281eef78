//! Integration tests of phalanx-rl: network shapes, learner maths, replay, checkpoints and a toy
//! cooperative problem the learner must solve.

mod adapter;
mod agent;
mod checkpoint;
mod corridor;
mod learner;
mod net;
mod policy;
mod replay;
mod scripted;

use burn::tensor::Device;

/// The test device: burn's pure-Rust CPU backend with autodiff.
pub(crate) fn train_device() -> Device {
    Device::flex().autodiff()
}

/// The test device without autodiff.
pub(crate) fn plain_device() -> Device {
    Device::flex()
}
