//! The learner's hyper-parameters and run counters: plain data, read by the learner and
//! carried in the header of every checkpoint and policy file.

use serde::{Deserialize, Serialize};

/// How training sequences are cut from episodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SequenceMode {
    /// Whole episodes, padded to the longest in the batch (the paper; EPyMARL).
    Episodes,
    /// Windows of `len` trained transitions, preceded by up to `burn_in` transitions that only
    /// warm the LSTM state (R2D2). A window near the episode start has a shorter burn-in.
    Windows {
        /// Trained transitions per window.
        len: usize,
        /// Transitions run before the window without loss.
        burn_in: usize,
    },
}

/// Linear ε-greedy schedule over environment steps (default: the learner's, 1.0 → 0.05 over
/// 30 000 steps).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EpsilonSchedule {
    /// ε at step 0.
    pub start: f64,
    /// ε from `decay_steps` on.
    pub end: f64,
    /// Environment steps of the linear decay.
    pub decay_steps: u64,
}

impl Default for EpsilonSchedule {
    fn default() -> Self {
        LearnerConfig::default().epsilon
    }
}

impl EpsilonSchedule {
    /// ε after `env_steps` environment steps.
    pub fn value(&self, env_steps: u64) -> f64 {
        if env_steps >= self.decay_steps || self.decay_steps == 0 {
            return self.end;
        }
        let frac = env_steps as f64 / self.decay_steps as f64;
        self.start + (self.end - self.start) * frac
    }
}

/// Learner hyper-parameters. Defaults are those both shipped policies were trained with (see
/// `docs/learning.md`);
/// [`LearnerConfig::paper`] is the paper's setting. A settings file may give any subset of
/// the fields (the others keep their defaults).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LearnerConfig {
    /// Discount γ (paper: 0.95).
    pub gamma: f32,
    /// Adam learning rate (default 5e-4 as EPyMARL; paper: 2e-6).
    pub lr: f64,
    /// Sequences per update (paper: 32).
    pub batch_size: usize,
    /// Replay capacity in episodes (default 5000, as EPyMARL), split evenly between the
    /// agent counts trained.
    pub replay_capacity: usize,
    /// How sequences are cut (default windows of 12 with burn-in 4; paper: whole episodes).
    pub sequence: SequenceMode,
    /// Hard target update every this many updates (default 200).
    pub target_update_interval: u64,
    /// Exploration schedule (default 1.0 → 0.05 over 30 000 environment steps).
    pub epsilon: EpsilonSchedule,
    /// Clip the global gradient norm to this value (default 10, as EPyMARL); `None`: no clip.
    pub grad_clip_norm: Option<f32>,
    /// Episodes in the replay buffer before the first update (default 32).
    pub learning_starts: usize,
    /// Environment steps per update (default 8).
    pub train_every: u64,
}

impl Default for LearnerConfig {
    fn default() -> Self {
        Self {
            gamma: 0.95,
            lr: 5e-4,
            batch_size: 32,
            replay_capacity: 5000,
            sequence: SequenceMode::Windows { len: 12, burn_in: 4 },
            target_update_interval: 200,
            epsilon: EpsilonSchedule { start: 1.0, end: 0.05, decay_steps: 30_000 },
            grad_clip_norm: Some(10.0),
            learning_starts: 32,
            train_every: 8,
        }
    }
}

impl LearnerConfig {
    /// The paper's hyper-parameters: γ 0.95, batch 32, Adam lr 2e-6, whole-episode replay.
    pub fn paper() -> Self {
        Self { lr: 2e-6, sequence: SequenceMode::Episodes, ..Self::default() }
    }
}

/// Counters of a training run (saved in checkpoints).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counters {
    /// Environment steps taken.
    pub env_steps: u64,
    /// Gradient updates done.
    pub updates: u64,
    /// Episodes finished.
    pub episodes: u64,
}
