//! Fine-tuning the cloned student on the meta reward (`docs/imitation.md`, *Fine-tuning*):
//! a policy gradient with a group baseline.
//!
//! Each iteration draws a team size and `instances` instances of the training pools, and
//! plays every instance `rollouts` times with the student drawing its actions from the
//! softmax of its scores ([`Policy::set_sampling`]). An episode's return is the meta
//! reward's cost, `−Σ_t (step_cost + L_f(t)) / side` (the Table II formation loss plus
//! `step_cost` times the makespan over the side), less `fail_cost` when the team did not
//! reach its goals. Its advantage is its return less the mean of its instance's rollouts,
//! over their spread: the rollouts of one instance are each other's baseline, so no critic is
//! needed and the instance's difficulty cancels. One Adam step then raises the
//! log-probability of every action of the better rollouts and lowers that of the worse
//! ([`Learner::policy_gradient_update_on`]). With [`FinetuneConfig::cloning`] above 0 the
//! same step also descends the cloning loss of a batch of expert data (by default the run's
//! `more_data` sets, the corridors the rollouts never play), so that the fine-tuning keeps
//! what cloning taught there.

use phalanx_env::{EnvConfig, ObsBuffers, PoolConfig, TaskEnv, TrainPool};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::learner::Learner;
use crate::policy::Policy;
use crate::replay::{Batch, Episode};

/// Settings of a fine-tuning run; the defaults are the shipped student's
/// (`models/imitation`, docs/imitation.md *Fine-tuning on the meta reward*).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FinetuneConfig {
    /// The training pools; each iteration draws one, uniformly.
    pub pools: Vec<PoolConfig>,
    /// Team sizes; each iteration draws one, uniformly.
    pub agents: Vec<usize>,
    /// Share of instances whose team starts wide (`TrainPool::sample_episode`).
    pub wide_share: f64,
    /// Iterations (one update each).
    pub iterations: u64,
    /// Instances per iteration.
    pub instances: usize,
    /// Rollouts per instance (the group of the baseline).
    pub rollouts: usize,
    /// The softmax temperature of the rollouts' actions.
    pub temperature: f32,
    /// Cost of a step against a unit of `L_f` for one step (default 2, the shipped
    /// student's fine-tunings but its last, at 0.5: docs/imitation.md, *A dearer step at a
    /// narrower band*, *Fine-tuning on larger maps*).
    pub step_cost: f64,
    /// Cost of not reaching the goals, in units of the return.
    pub fail_cost: f64,
    /// Adam's learning rate (a fresh Adam: the cloning's moments are forgotten).
    pub lr: f64,
    /// Smallest spread the advantages are divided by.
    pub min_spread: f64,
    /// Seed of the iterations' draws.
    pub seed: u64,
    /// The team vector's dead band of the rollouts' environments, which the fine-tuned
    /// student then acts with and its files record ([`crate::Learner::set_team_deadband`]);
    /// `null`: the data's (`data.env.team_deadband`). The shipped student was cloned at the
    /// default 1.5, fine-tuned at 0.6 with `step_cost` 2 (the defaults; docs/imitation.md,
    /// *The dead band in fine-tuning*, *A dearer step at a narrower band*), and last at 0.3
    /// with `step_cost` 0.5 (*Fine-tuning on larger maps*).
    pub team_deadband: Option<f64>,
    /// Weight of a behaviour-cloning term in every update: the cross-entropy of a batch of
    /// expert data (`cloning_data`, drawn as a cloning update draws it) added to the
    /// policy-gradient loss, so that the fine-tuning keeps what the expert taught where its
    /// rollouts do not go. Default 1, the shipped student's; 0: none.
    pub cloning: f64,
    /// The expert data of the cloning term; default `more`.
    pub cloning_data: CloningData,
}

/// The expert data the fine-tuning's cloning term draws on ([`FinetuneConfig::cloning_data`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CloningData {
    /// The `more_data` sets only (the default): what the fine-tuning's own pools do not
    /// cover (mazes and rooms beside the paper's maps), so that the cloning term keeps it
    /// without pulling the paper's maps back to the cloned behaviour.
    #[default]
    More,
    /// Everything the run cloned: `data`, `more_data` and the DAgger rounds.
    All,
}

impl Default for FinetuneConfig {
    fn default() -> FinetuneConfig {
        let pool = PoolConfig::default();
        FinetuneConfig {
            pools: vec![
                PoolConfig { size: 20, density: 0.05, ..pool.clone() },
                PoolConfig { size: 20, density: 0.15, ..pool.clone() },
                pool,
            ],
            agents: vec![3, 4, 5],
            wide_share: 0.5,
            iterations: 800,
            instances: 4,
            rollouts: 8,
            temperature: 0.5,
            step_cost: 2.0,
            fail_cost: 1.0,
            lr: 1e-4,
            min_spread: 0.02,
            seed: 1,
            team_deadband: Some(0.6),
            cloning: 1.0,
            cloning_data: CloningData::More,
        }
    }
}

impl FinetuneConfig {
    /// Refuses values a run cannot follow, naming the field and its value.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn check(&self) -> Result<(), String> {
        if self.pools.is_empty() || self.agents.is_empty() {
            return Err("finetune: no pool or no team size".into());
        }
        if self.instances == 0 || self.rollouts < 2 {
            return Err(format!(
                "finetune: {} instances of {} rollouts; at least 1 instance of 2 rollouts",
                self.instances, self.rollouts
            ));
        }
        if !(self.temperature.is_finite() && self.temperature > 0.0) {
            return Err(format!("finetune.temperature: {} is not positive", self.temperature));
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(format!("finetune.lr: {} is not positive", self.lr));
        }
        let finite =
            [self.wide_share, self.step_cost, self.fail_cost, self.min_spread, self.cloning];
        if finite.iter().any(|v| !(v.is_finite() && *v >= 0.0)) || self.min_spread == 0.0 {
            return Err("finetune: wide_share, step_cost, fail_cost and cloning must be 0 or \
                        more, min_spread more than 0"
                .into());
        }
        if let Some(cells) = self.team_deadband {
            phalanx_env::check_team_deadband(cells)
                .map_err(|err| format!("finetune.team_deadband: {err}"))?;
        }
        if self.wide_share > 1.0 {
            return Err(format!("finetune.wide_share: {} is not a share", self.wide_share));
        }
        Ok(())
    }
}

/// What one iteration's rollouts measured.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct IterationStats {
    /// Team size.
    pub n_agents: usize,
    /// Map side.
    pub side: u32,
    /// Share of rollouts that reached the goals.
    pub success: f64,
    /// Mean steps.
    pub steps: f64,
    /// Mean Table II formation loss.
    pub formation_loss: f64,
    /// Mean return.
    pub ret: f64,
    /// The update's policy-gradient loss.
    pub policy_loss: f32,
    /// The update's behaviour-cloning loss ([`FinetuneConfig::cloning`]).
    pub cloning_loss: Option<f32>,
    /// Gradient norm before clipping.
    pub grad_norm: f32,
}

/// The pools and settings of a run.
pub struct Finetune {
    config: FinetuneConfig,
    pools: Vec<TrainPool>,
    env: EnvConfig,
}

impl Finetune {
    /// A run of `config` whose student acts in environments of `env`, with the dead band of
    /// `config` where it names one.
    ///
    /// # Errors
    /// If a pool cannot be made or the settings are out of range.
    pub fn new(config: FinetuneConfig, mut env: EnvConfig) -> Result<Finetune, String> {
        config.check()?;
        env.team_deadband = config.team_deadband.unwrap_or(env.team_deadband);
        let pools = config
            .pools
            .iter()
            .map(|pool| TrainPool::new(pool).map_err(|err| format!("finetune.pools: {err}")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Finetune { config, pools, env })
    }

    /// The settings.
    pub fn config(&self) -> &FinetuneConfig {
        &self.config
    }

    /// The team vector's dead band of its rollouts.
    pub fn team_deadband(&self) -> f64 {
        self.env.team_deadband
    }

    /// Iteration `iteration`: its rollouts with the learner's policy, their advantages, and
    /// one update.
    pub fn iteration(&self, learner: &mut Learner, iteration: u64) -> IterationStats {
        let cfg = &self.config;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        rng.set_stream(iteration);
        let pool = &self.pools[rng.random_range(0..self.pools.len())];
        let n = cfg.agents[rng.random_range(0..cfg.agents.len())];
        let instances: Vec<_> =
            (0..cfg.instances).map(|_| pool.sample_episode(n, cfg.wide_share, &mut rng)).collect();
        let side = instances[0].grid().side();
        let mut policy = learner.policy();
        policy.set_sampling(Some(cfg.temperature));
        let played = self.play(&mut policy, &instances, &mut rng);
        let returns: Vec<f64> = played
            .iter()
            .map(|p| {
                -(cfg.step_cost * p.episode.len as f64 + p.loss_sum) / f64::from(side)
                    - if p.episode.terminated { 0.0 } else { cfg.fail_cost }
            })
            .collect();
        let advantages = group_advantages(&returns, cfg.rollouts, cfg.min_spread);
        let episodes: Vec<&Episode> = played.iter().map(|p| &p.episode).collect();
        let batch = Batch::of_episodes(&episodes, n, learner_shape(learner));
        let update = learner.policy_gradient_update_on(
            &batch,
            &advantages,
            cfg.temperature,
            cfg.cloning as f32,
        );
        let count = played.len() as f64;
        IterationStats {
            n_agents: n,
            side,
            success: played.iter().filter(|p| p.episode.terminated).count() as f64 / count,
            steps: played.iter().map(|p| p.episode.len as f64).sum::<f64>() / count,
            formation_loss: played.iter().map(|p| p.loss_sum).sum::<f64>()
                / count
                / f64::from(side),
            ret: returns.iter().sum::<f64>() / count,
            policy_loss: update.loss,
            cloning_loss: update.cloning_loss,
            grad_norm: update.grad_norm,
        }
    }

    /// Every instance played `rollouts` times in lockstep, the policy sampling.
    fn play(
        &self,
        policy: &mut Policy,
        instances: &[phalanx_core::Instance],
        rng: &mut ChaCha8Rng,
    ) -> Vec<Played> {
        let k = self.config.rollouts;
        let n = instances[0].n_agents();
        let mut envs = Vec::with_capacity(instances.len() * k);
        let mut obs = Vec::with_capacity(instances.len() * k);
        let mut played = Vec::with_capacity(instances.len() * k);
        for instance in instances {
            for _ in 0..k {
                let mut env = TaskEnv::new(self.env.task, self.env.clone(), n)
                    .expect("the pool's teams fit the environment");
                let mut o = ObsBuffers::new(n, env.obs_shape());
                env.reset_to(instance, &mut o).expect("pool instances fit the environment");
                played.push(Played { episode: Episode::start(&o), loss_sum: 0.0, done: false });
                envs.push(env);
                obs.push(o);
            }
        }
        policy.reset();
        let mut actions = vec![0_u8; envs.len() * n];
        while played.iter().any(|p| !p.done) {
            policy.act_batch(&obs, 0.0, rng, &mut actions, None);
            for (e, p) in played.iter_mut().enumerate() {
                if p.done {
                    continue;
                }
                let joint = &actions[e * n..(e + 1) * n];
                let out = envs[e].step(joint, &mut obs[e]);
                p.episode.push_step(joint, out.team_reward, &obs[e]);
                p.loss_sum += out.formation_loss;
                if out.terminated || out.truncated {
                    p.done = true;
                    p.episode.terminated = out.terminated;
                }
            }
        }
        played
    }
}

/// One rollout: its episode (its steps, and whether it reached the goals), `Σ L_f`.
struct Played {
    episode: Episode,
    loss_sum: f64,
    done: bool,
}

fn learner_shape(learner: &Learner) -> phalanx_env::ObsShape {
    crate::learner::obs_shape(learner.net_config())
}

/// Each return less the mean of its group (`group` consecutive returns), over the group's
/// standard deviation (at least `min_spread`).
pub fn group_advantages(returns: &[f64], group: usize, min_spread: f64) -> Vec<f32> {
    returns
        .chunks(group)
        .flat_map(|chunk| {
            let mean = chunk.iter().sum::<f64>() / chunk.len() as f64;
            let var = chunk.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / chunk.len() as f64;
            let spread = var.sqrt().max(min_spread);
            chunk.iter().map(move |r| ((r - mean) / spread) as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use burn::tensor::Device;

    use super::*;
    use phalanx_core::Instance;

    use crate::imitation::learn::ImitationConfig;

    #[test]
    fn advantages_are_centred_on_each_instance_and_scaled_by_its_spread() {
        let returns = [1.0, 3.0, -10.0, -10.0, 5.0, 5.0, 5.0, 5.01];
        let adv = group_advantages(&returns, 2, 0.02);
        assert_eq!(&adv[..4], &[-1.0, 1.0, 0.0, 0.0]);
        // A spread below the floor is not blown up to ±1.
        assert!(adv[6].abs() < 0.3 && (adv[6] + adv[7]).abs() < 1e-6, "{adv:?}");
        assert!(adv[4] == 0.0 && adv[5] == 0.0);
    }

    /// A learner of the student's network and settings (seed 5).
    fn learner(config: &ImitationConfig) -> Learner {
        let device = Device::flex().autodiff();
        Learner::new(config.net.clone(), config.learner_config(), &config.data.agents, 5, &device)
    }

    /// The scores of every agent at the first step of `instance` (greedy, leader order).
    fn first_scores(policy: &Policy, env: &EnvConfig, instance: &Instance) -> Vec<f32> {
        let mut policy = policy.clone();
        let n = instance.n_agents();
        let mut sim = TaskEnv::new(env.task, env.clone(), n).unwrap();
        let mut obs = ObsBuffers::new(n, sim.obs_shape());
        sim.reset_to(instance, &mut obs).unwrap();
        let (mut actions, mut q) = (vec![0; n], vec![0.0; n * 5]);
        policy.act_with_q(&obs, 0.0, &mut ChaCha8Rng::seed_from_u64(0), &mut actions, &mut q);
        q
    }

    #[test]
    fn an_iteration_plays_every_instance_as_often_as_asked_and_moves_the_network() {
        let config = ImitationConfig::default();
        let settings = FinetuneConfig {
            pools: vec![PoolConfig { n_maps: 2, size: 16, ..PoolConfig::default() }],
            agents: vec![3],
            instances: 2,
            rollouts: 3,
            ..FinetuneConfig::default()
        };
        let env = config.data.env.clone();
        let run = Finetune::new(settings.clone(), env.clone()).unwrap();
        let mut learner = learner(&config);
        let before = learner.policy();
        let stats = run.iteration(&mut learner, 0);
        assert_eq!((stats.n_agents, stats.side), (3, 16));
        assert!(stats.steps > 0.0 && stats.ret.is_finite() && stats.grad_norm > 0.0, "{stats:?}");
        assert_eq!(learner.counters().updates, 1);
        let instance = run.pools[0].sample(3, &mut ChaCha8Rng::seed_from_u64(1));
        let moved = first_scores(&learner.policy(), &env, &instance);
        assert_ne!(first_scores(&before, &env, &instance), moved, "the update moved nothing");
        // The same iteration from the same network draws the same rollouts.
        assert_eq!(run.iteration(&mut self::learner(&config), 0), stats);
        // Its rollouts play at its dead band, the data's when it names none.
        assert_eq!(run.team_deadband(), 0.6);
        let data_band = FinetuneConfig { team_deadband: None, ..settings.clone() };
        assert_eq!(Finetune::new(data_band, env.clone()).unwrap().team_deadband(), 1.5);
        let bad = FinetuneConfig { team_deadband: Some(-1.0), ..settings.clone() };
        assert!(Finetune::new(bad, env.clone()).is_err_and(|e| e.contains("team_deadband")));
        let bad = FinetuneConfig { rollouts: 1, ..settings };
        assert!(Finetune::new(bad, env).is_err_and(|err| err.contains("rollouts")));
    }

    #[test]
    fn the_cloning_term_draws_on_the_expert_data_and_is_off_at_zero() {
        let mut config = ImitationConfig::default();
        config.data.pool = PoolConfig { n_maps: 2, size: 16, ..PoolConfig::default() };
        config.data.agents = vec![3];
        config.data.episodes = 2;
        config.data.expert = crate::imitation::ExpertChoice::Swarm;
        let settings = FinetuneConfig {
            pools: vec![config.data.pool.clone()],
            agents: vec![3],
            instances: 1,
            rollouts: 2,
            ..FinetuneConfig::default()
        };
        let with = |cloning: f64| {
            let settings = FinetuneConfig { cloning, ..settings.clone() };
            Finetune::new(settings, config.data.env.clone()).unwrap()
        };
        let data = crate::imitation::generate(&config.data, &|_| {}).unwrap().0;
        let mut expert = learner(&config);
        crate::imitation::learn::add_to_learner(&mut expert, &data).unwrap();
        let cloned = with(1.0).iteration(&mut expert, 0);
        assert!(cloned.cloning_loss.is_some_and(|l| l.is_finite() && l > 0.0), "{cloned:?}");
        // The rollouts are the same; the update is not.
        let mut plain = learner(&config);
        let alone = with(0.0).iteration(&mut plain, 0);
        assert_eq!((alone.cloning_loss, alone.ret), (None, cloned.ret));
        let instance = with(0.0).pools[0].sample(3, &mut ChaCha8Rng::seed_from_u64(1));
        let env = &config.data.env;
        let scores = |l: &Learner| first_scores(&l.policy(), env, &instance);
        assert_ne!(scores(&expert), scores(&plain), "the cloning term changed nothing");
        // At 0 the data is not drawn on; without data there is no term.
        let mut unused = learner(&config);
        crate::imitation::learn::add_to_learner(&mut unused, &data).unwrap();
        assert_eq!(with(0.0).iteration(&mut unused, 0), alone);
        assert_eq!(scores(&unused), scores(&plain));
        let mut empty = learner(&config);
        assert_eq!(with(1.0).iteration(&mut empty, 0), alone);
        let bad = FinetuneConfig { cloning: -1.0, ..settings };
        assert!(Finetune::new(bad, env.clone()).is_err_and(|err| err.contains("cloning")));
    }

    #[test]
    fn a_positive_advantage_makes_the_taken_actions_likelier_and_a_negative_one_rarer() {
        let config = ImitationConfig::default();
        let env = config.data.env.clone();
        let pool = TrainPool::new(&PoolConfig { n_maps: 2, size: 16, ..PoolConfig::default() });
        let instance = pool.unwrap().sample(3, &mut ChaCha8Rng::seed_from_u64(2));
        let run = Finetune::new(FinetuneConfig::default(), env.clone()).unwrap();
        let mut policy = learner(&config).policy();
        policy.set_sampling(Some(1.0));
        let played = run.play(
            &mut policy,
            std::slice::from_ref(&instance),
            &mut ChaCha8Rng::seed_from_u64(3),
        );
        let episode = &played[0].episode;
        let batch = Batch::of_episodes(&[episode], 3, crate::learner::obs_shape(&config.net));
        // The probability of the first agent's first action under the network.
        let first = episode.order[0];
        let action = usize::from(episode.actions[first]);
        let prob = |learner: &Learner| {
            let q = first_scores(&learner.policy(), &env, &instance);
            let q = &q[first * 5..(first + 1) * 5];
            let max = q.iter().copied().fold(f32::MIN, f32::max);
            let sum: f32 = q.iter().map(|v| (v - max).exp()).sum();
            (q[action] - max).exp() / sum
        };
        let start = prob(&learner(&config));
        for (advantage, likelier) in [(1.0, true), (-1.0, false)] {
            let mut it = learner(&config);
            for _ in 0..3 {
                it.policy_gradient_update_on(&batch, &[advantage], 1.0, 0.0);
            }
            assert_eq!(
                prob(&it) > start,
                likelier,
                "advantage {advantage}: {start} -> {}",
                prob(&it)
            );
        }
    }
}
