//! The training loop: collect episodes with ε-greedy acting, store them, update on replay.
//!
//! Metrics go to a caller-supplied sink under the names listed in [`metrics`] (and in
//! `docs/learning.md`); the library never prints.

use std::time::Instant;

use rand::Rng;

use crate::env::{MarlEnv, ObsBuffers};
use crate::learner::{Learner, Policy};
use crate::replay::Episode;

/// Metric names (CleanRL style namespaces).
pub mod metrics {
    /// Team return of a finished training episode.
    pub const EPISODIC_RETURN: &str = "charts/episodic_return";
    /// Steps of a finished training episode.
    pub const EPISODIC_LENGTH: &str = "charts/episodic_length";
    /// 1 if the episode terminated (goal reached), 0 if truncated.
    pub const SUCCESS: &str = "charts/success_rate";
    /// Exploration rate at the end of the episode.
    pub const EPSILON: &str = "charts/epsilon";
    /// Masked mean squared TD error of an update.
    pub const TD_LOSS: &str = "losses/td_loss";
    /// Mean team Q of the taken actions in an update.
    pub const Q_VALUES: &str = "losses/q_values";
    /// Global gradient norm before clipping.
    pub const GRAD_NORM: &str = "losses/grad_norm";
    /// Environment steps per second of wall-clock time (acting and learning together).
    pub const SPS: &str = "perf/sps";
    /// Milliseconds per gradient update.
    pub const UPDATE_MS: &str = "perf/update_ms";
}

/// Receives `(name, env_step, value)` for every logged metric.
pub trait MetricSink {
    /// Record one value.
    fn record(&mut self, name: &'static str, env_step: u64, value: f64);
}

impl<F: FnMut(&'static str, u64, f64)> MetricSink for F {
    fn record(&mut self, name: &'static str, env_step: u64, value: f64) {
        self(name, env_step, value);
    }
}

/// Play one episode with `policy` at exploration rate `epsilon(step_in_episode)` and record it.
/// `max_steps` guards against environments that never end (the episode counts as truncated).
pub fn run_episode<E: MarlEnv>(
    env: &mut E,
    policy: &mut Policy,
    obs: &mut ObsBuffers,
    seed: u64,
    max_steps: usize,
    mut epsilon: impl FnMut(usize) -> f64,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Episode {
    env.reset(seed, obs);
    debug_assert!({
        obs.check();
        true
    });
    policy.reset();
    let mut episode = Episode::start(obs);
    let mut actions = vec![0_u8; env.n_agents()];
    for step in 0..max_steps {
        policy.act(obs, epsilon(step), rng, &mut actions);
        let out = env.step(&actions, obs);
        episode.push_step(&actions, out.team_reward, obs);
        if out.terminated || out.truncated {
            episode.terminated = out.terminated;
            break;
        }
    }
    episode
}

impl Learner {
    /// Train until `total_env_steps` more environment steps have been taken.
    /// Episodes longer than `max_episode_steps` are cut (truncated).
    pub fn train<E: MarlEnv>(
        &mut self,
        env: &mut E,
        total_env_steps: u64,
        max_episode_steps: usize,
        sink: &mut impl MetricSink,
    ) {
        assert_eq!(env.n_agents(), self.n_agents(), "environment and learner disagree on agents");
        let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
        let end = self.counters().env_steps + total_env_steps;
        let started = Instant::now();
        let steps_at_start = self.counters().env_steps;
        let mut since_update = 0_u64;
        while self.counters().env_steps < end {
            let mut policy = self.policy();
            let seed = self.rng.random::<u64>();
            let schedule = self.config.epsilon;
            let env_steps = self.counters.env_steps;
            let episode = run_episode(
                env,
                &mut policy,
                &mut obs,
                seed,
                max_episode_steps,
                |step| schedule.value(env_steps + step as u64),
                &mut self.rng,
            );
            let counters = &mut self.counters;
            counters.env_steps += episode.len as u64;
            counters.episodes += 1;
            let now = counters.env_steps;
            sink.record(metrics::EPISODIC_RETURN, now, f64::from(episode.team_return()));
            sink.record(metrics::EPISODIC_LENGTH, now, episode.len as f64);
            sink.record(metrics::SUCCESS, now, if episode.terminated { 1.0 } else { 0.0 });
            sink.record(metrics::EPSILON, now, self.epsilon());
            since_update += episode.len as u64;
            self.replay_mut().push(episode);
            let train_every = self.config().train_every.max(1);
            while since_update >= train_every {
                since_update -= train_every;
                let timer = Instant::now();
                let Some(stats) = self.update() else {
                    since_update = 0;
                    break;
                };
                sink.record(metrics::UPDATE_MS, now, timer.elapsed().as_secs_f64() * 1e3);
                sink.record(metrics::TD_LOSS, now, f64::from(stats.td_loss));
                sink.record(metrics::Q_VALUES, now, f64::from(stats.q_taken));
                sink.record(metrics::GRAD_NORM, now, f64::from(stats.grad_norm));
            }
            let elapsed = started.elapsed().as_secs_f64().max(1e-9);
            sink.record(metrics::SPS, now, (now - steps_at_start) as f64 / elapsed);
        }
    }
}
