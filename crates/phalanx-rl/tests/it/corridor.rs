//! A toy cooperative problem with a known optimum: two agents on a 1-D corridor of four cells
//! both start at cell 0 and must both stand on cell 3.
//! Each step costs the team −1; the step that brings both to the end pays +10 and terminates.
//! Up and Down are always masked, Left at cell 0, Right at cell 3. The optimal return is 8
//! (Right, Right, Right), reached in three steps.

use phalanx_env::{MarlEnv, ObsBuffers, ObsShape, StepOut};
use phalanx_rl::train::run_episode;
use phalanx_rl::{
    Collector, EncoderConfig, EpsilonSchedule, Learner, LearnerConfig, QNetConfig, SequenceMode,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const CELLS: usize = 4;
const LIMIT: usize = 10;

/// The corridor environment.
pub(crate) struct Corridor {
    pos: [usize; 2],
    t: usize,
}

impl Corridor {
    pub(crate) fn new() -> Self {
        Self { pos: [0, 0], t: 0 }
    }

    fn write(&self, obs: &mut ObsBuffers) {
        obs.grid.fill(0.0);
        for agent_idx in 0..2 {
            obs.grid[agent_idx * CELLS + self.pos[agent_idx]] = 1.0;
            let other = self.pos[1 - agent_idx] as f32 / 3.0;
            obs.vec[agent_idx * 3..agent_idx * 3 + 3].copy_from_slice(&[
                other,
                self.t as f32 / LIMIT as f32,
                0.0,
            ]);
            let mask = &mut obs.action_mask[agent_idx * 5..agent_idx * 5 + 5];
            // Up, Down, Left, Right, Wait.
            mask.copy_from_slice(&[
                false,
                false,
                self.pos[agent_idx] > 0,
                self.pos[agent_idx] < 3,
                true,
            ]);
        }
        // The agent further ahead leads.
        obs.order = if self.pos[1] > self.pos[0] { vec![1, 0] } else { vec![0, 1] };
    }
}

impl MarlEnv for Corridor {
    fn n_agents(&self) -> usize {
        2
    }

    fn obs_shape(&self) -> ObsShape {
        ObsShape { channels: CELLS, fov: 1, env_vec: 3, n_actions: 5 }
    }

    fn reset(&mut self, _seed: u64, obs: &mut ObsBuffers) {
        *self = Self::new();
        self.write(obs);
    }

    fn step(&mut self, actions: &[u8], obs: &mut ObsBuffers) -> StepOut {
        for (pos, &action) in self.pos.iter_mut().zip(actions) {
            match action {
                2 => *pos = pos.saturating_sub(1),
                3 => *pos = (*pos + 1).min(CELLS - 1),
                _ => {}
            }
        }
        self.t += 1;
        self.write(obs);
        let done = self.pos == [3, 3];
        StepOut {
            team_reward: if done { 10.0 } else { -1.0 },
            terminated: done,
            truncated: !done && self.t >= LIMIT,
            ..StepOut::default()
        }
    }
}

/// A small network for the corridor.
pub(crate) fn corridor_net() -> QNetConfig {
    QNetConfig {
        channels: CELLS,
        fov: 1,
        env_vec: 3,
        n_agents_max: 2,
        n_actions: 5,
        encoder: EncoderConfig::Mlp { hidden: vec![32] },
        lstm_hidden: 32,
        lstm_layers: 1,
        head_hidden: 32,
        centralised: false,
    }
}

/// Learner settings that solve the corridor in a few seconds.
pub(crate) fn corridor_learner() -> LearnerConfig {
    LearnerConfig {
        gamma: 0.95,
        lr: 3e-3,
        batch_size: 16,
        replay_capacity: 500,
        sequence: SequenceMode::Episodes,
        target_update_interval: 25,
        epsilon: EpsilonSchedule { start: 1.0, end: 0.05, decay_steps: 600 },
        grad_clip_norm: Some(10.0),
        learning_starts: 16,
        train_every: 4,
    }
}

#[test]
fn corridor_is_solved() {
    let device = crate::train_device();
    let mut learner = Learner::new(corridor_net(), corridor_learner(), &[2], 11, &device);
    let mut env = Corridor::new();
    let mut n_updates = 0;
    learner.train(
        &mut Collector::new(vec![Corridor::new(), Corridor::new()], LIMIT),
        1200,
        &mut |name: &'static str, _step, _value| {
            if name == phalanx_rl::metrics::TD_LOSS {
                n_updates += 1;
            }
        },
    );
    assert!(n_updates > 100, "only {n_updates} updates");

    let mut policy = learner.policy();
    let mut obs = ObsBuffers::new(2, env.obs_shape());
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let episode = run_episode(&mut env, &mut policy, &mut obs, 0, LIMIT, |_| 0.0, &mut rng);
    assert!(episode.terminated, "greedy policy did not finish: {:?}", episode.actions);
    assert_eq!(episode.len, 3, "greedy actions {:?}", episode.actions);
    assert_eq!(episode.team_return(), 8.0);
}
