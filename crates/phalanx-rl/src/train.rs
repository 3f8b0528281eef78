//! The training loop: collect episodes with ε-greedy acting, many in lockstep ([`Collector`]),
//! store them, update on replay.
//!
//! Metrics go to a caller-supplied sink under the names listed in [`metrics`] (and in
//! `docs/learning.md`); the library never prints.

use std::time::Instant;

use burn::module::Module as _;
use phalanx_env::{MarlEnv, ObsBuffers, StepOut, step_lockstep};
use rand::Rng;

use crate::learner::Learner;
use crate::policy::{Policy, row_offsets};
use crate::replay::Episode;

/// Metric names (CleanRL style namespaces).
pub mod metrics {
    /// Team return of a finished training episode.
    pub const EPISODIC_RETURN: &str = "charts/episodic_return";
    /// Steps of a finished training episode.
    pub const EPISODIC_LENGTH: &str = "charts/episodic_length";
    /// 1 if the episode terminated (goal reached), 0 if truncated.
    pub const SUCCESS: &str = "charts/success_rate";
    /// Exploration rate at the end of the episode (recorded last for each episode).
    pub const EPSILON: &str = "charts/epsilon";
    /// Moves cancelled by collisions in a finished training episode.
    pub const COLLISIONS: &str = "charts/collisions";
    /// Mean `L_f` over the steps of a finished training episode (the positions after each
    /// step).
    pub const FORMATION_LOSS: &str = "charts/formation_loss";
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
    /// Behaviour cloning: mean cross-entropy of the expert's labels in an update.
    pub const IMITATION_LOSS: &str = "losses/imitation_loss";
    /// Behaviour cloning: share of an update's labels the network's greedy action matches.
    pub const IMITATION_ACCURACY: &str = "charts/imitation_accuracy";
    /// Imitation: samples (agents × steps) in the training data.
    pub const IMITATION_SAMPLES: &str = "charts/imitation_samples";
    /// Fine-tuning: mean return of an iteration's rollouts (the negative meta cost).
    pub const FINETUNE_RETURN: &str = "charts/finetune_return";
    /// Fine-tuning: share of an iteration's rollouts that reached the goals.
    pub const FINETUNE_SUCCESS: &str = "charts/finetune_success";
    /// Fine-tuning: mean Table II formation loss of an iteration's rollouts.
    pub const FINETUNE_FORMATION_LOSS: &str = "charts/finetune_formation_loss";
    /// Fine-tuning: mean steps of an iteration's rollouts.
    pub const FINETUNE_STEPS: &str = "charts/finetune_steps";
    /// Fine-tuning: the policy-gradient loss of an update.
    pub const POLICY_LOSS: &str = "losses/policy_gradient";
    /// Imitation: the greedy student's success rate on the validation instances.
    pub const VAL_SUCCESS: &str = "val/success_rate";
    /// Imitation: the greedy student's Table II formation loss on the validation instances
    /// (mean over the rows of each row's mean).
    pub const VAL_FORMATION_LOSS: &str = "val/formation_loss";
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
    let mut episode = Episode::begin(env, seed, obs);
    debug_assert!({
        obs.check();
        true
    });
    policy.reset();
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

/// Episodes played in lockstep for training: `n_envs` environments (teams of possibly
/// different sizes), one batched policy call per step for all of them
/// ([`Policy::act_batch`]), stepped in parallel by [`step_lockstep`] (rayon; results by
/// index, so the thread count does not change them). A finished episode goes to the learner's replay and its environment
/// starts a new one at once, from a seed drawn from the learner's RNG.
///
/// The collector lives across [`Learner::train`] calls, so a run split into chunks (for
/// checkpoints) continues its episodes.
pub struct Collector<E: MarlEnv> {
    pub(crate) envs: Vec<E>,
    pub(crate) obs: Vec<ObsBuffers>,
    pub(crate) agents: Vec<usize>,
    offsets: Vec<usize>,
    outs: Vec<StepOut>,
    pub(crate) running: Vec<Episode>,
    pub(crate) collisions: Vec<u64>,
    /// Sum of `L_f` over the steps so far of each running episode.
    pub(crate) formation_loss: Vec<f64>,
    actions: Vec<u8>,
    restart: Vec<bool>,
    pub(crate) policy: Option<Policy>,
    /// The learner's update count the policy's weights come from.
    pub(crate) weights_of: u64,
    pub(crate) max_steps: usize,
    pub(crate) since_update: u64,
}

impl<E: MarlEnv + Send> Collector<E> {
    /// A collector over `envs`; episodes longer than `max_episode_steps` are cut (truncated).
    ///
    /// # Panics
    /// If `envs` is empty.
    pub fn new(envs: Vec<E>, max_episode_steps: usize) -> Self {
        assert!(!envs.is_empty(), "a collector needs environments");
        let obs: Vec<ObsBuffers> =
            envs.iter().map(|env| ObsBuffers::new(env.n_agents(), env.obs_shape())).collect();
        let agents: Vec<usize> = envs.iter().map(MarlEnv::n_agents).collect();
        let offsets = row_offsets(agents.iter().copied());
        let total = agents.iter().sum();
        Self {
            obs,
            offsets,
            outs: vec![StepOut::default(); envs.len()],
            running: Vec::new(),
            collisions: vec![0; envs.len()],
            formation_loss: vec![0.0; envs.len()],
            actions: vec![0; total],
            restart: vec![false; envs.len()],
            policy: None,
            weights_of: 0,
            max_steps: max_episode_steps.max(1),
            since_update: 0,
            agents,
            envs,
        }
    }

    /// Number of environments.
    pub fn n_envs(&self) -> usize {
        self.envs.len()
    }

    /// Agents of each environment.
    pub fn agent_counts(&self) -> &[usize] {
        &self.agents
    }
}

impl Learner {
    /// Train until `total_env_steps` more environment steps have been taken (a step of one
    /// environment counts one; the last lockstep step may overshoot by `n_envs - 1`).
    /// One gradient update per `train_every` environment steps once a replay buffer holds
    /// `learning_starts` episodes.
    ///
    /// # Panics
    /// If an environment's team size is not one the learner trains.
    pub fn train<E: MarlEnv + Send>(
        &mut self,
        collector: &mut Collector<E>,
        total_env_steps: u64,
        sink: &mut impl MetricSink,
    ) {
        for &n in &collector.agents {
            assert!(self.agent_counts.contains(&n), "the learner does not train teams of {n}");
        }
        let end = self.counters.env_steps + total_env_steps;
        let started = Instant::now();
        let steps_at_start = self.counters.env_steps;
        while self.counters.env_steps < end {
            self.collect_step(collector, sink);
            let train_every = self.config.train_every.max(1);
            while collector.since_update >= train_every {
                collector.since_update -= train_every;
                let timer = Instant::now();
                let Some(stats) = self.update() else {
                    collector.since_update = 0;
                    break;
                };
                let now = self.counters.env_steps;
                sink.record(metrics::UPDATE_MS, now, timer.elapsed().as_secs_f64() * 1e3);
                sink.record(metrics::TD_LOSS, now, f64::from(stats.td_loss));
                sink.record(metrics::Q_VALUES, now, f64::from(stats.q_taken));
                sink.record(metrics::GRAD_NORM, now, f64::from(stats.grad_norm));
            }
        }
        let elapsed = started.elapsed().as_secs_f64().max(1e-9);
        let now = self.counters.env_steps;
        sink.record(metrics::SPS, now, (now - steps_at_start) as f64 / elapsed);
    }

    /// One lockstep step of every environment of `collector`; finished episodes are stored
    /// and logged, and their environments reset.
    fn collect_step<E: MarlEnv + Send>(
        &mut self,
        collector: &mut Collector<E>,
        sink: &mut impl MetricSink,
    ) {
        let c = collector;
        if c.running.is_empty() {
            for (env, obs) in c.envs.iter_mut().zip(&mut c.obs) {
                c.running.push(Episode::begin(env, self.rng.random::<u64>(), obs));
            }
            c.policy = None;
        }
        let updates = self.counters.updates;
        match &mut c.policy {
            Some(policy) if c.weights_of != updates => policy.set_net(&self.online.valid()),
            Some(_) => {}
            None => c.policy = Some(self.policy()),
        }
        c.weights_of = updates;
        let policy = c.policy.as_mut().expect("set above");
        let epsilon = self.epsilon();
        policy.act_batch(&c.obs, epsilon, &mut self.rng, &mut c.actions, None);

        let actions = &c.actions;
        step_lockstep(&mut c.envs, &mut c.obs, actions, &c.offsets, &mut c.outs);
        for (e, out) in c.outs.iter().enumerate() {
            let (at, n) = (c.offsets[e], c.agents[e]);
            let episode = &mut c.running[e];
            episode.push_step(&actions[at..at + n], out.team_reward, &c.obs[e]);
            c.collisions[e] += u64::from(out.collisions);
            c.formation_loss[e] += out.formation_loss;
            self.counters.env_steps += 1;
            c.since_update += 1;
            let done = out.terminated || out.truncated || episode.len >= c.max_steps;
            c.restart[e] = done;
            if !done {
                continue;
            }
            episode.terminated = out.terminated;
            let now = self.counters.env_steps;
            sink.record(metrics::EPISODIC_RETURN, now, f64::from(episode.team_return()));
            sink.record(metrics::EPISODIC_LENGTH, now, episode.len as f64);
            sink.record(metrics::COLLISIONS, now, std::mem::take(&mut c.collisions[e]) as f64);
            let loss_sum = std::mem::take(&mut c.formation_loss[e]);
            sink.record(metrics::FORMATION_LOSS, now, loss_sum / episode.len.max(1) as f64);
            sink.record(metrics::SUCCESS, now, if out.terminated { 1.0 } else { 0.0 });
            sink.record(metrics::EPSILON, now, epsilon);
            let started = Episode::begin(&mut c.envs[e], self.rng.random::<u64>(), &mut c.obs[e]);
            let finished = std::mem::replace(episode, started);
            self.counters.episodes += 1;
            self.store(finished);
        }
        policy.reset_envs(&c.agents, &c.restart);
    }
}
