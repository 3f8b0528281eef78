//! The adapters over `phalanx-env`: observations, masks and orders after reset and random
//! masked steps, episodes ending by the step limit, and a short training run.

use phalanx_env::{EnvConfig, MarlEnv, ObsBuffers, PoolConfig, PoolEnv, Task};
use phalanx_rl::{Collector, Learner, LearnerConfig, QNetConfig};
use rand::SeedableRng;
use rand::seq::IndexedRandom;
use rand_chacha::ChaCha8Rng;

const STEP_LIMIT: u32 = 20;

fn small_pool() -> PoolConfig {
    PoolConfig { n_maps: 4, ..PoolConfig::default() }
}

fn env_config() -> EnvConfig {
    EnvConfig { step_limit: Some(STEP_LIMIT), ..EnvConfig::default() }
}

/// Checks the buffers' invariants and that every value is finite.
#[track_caller]
fn check_obs(obs: &ObsBuffers) {
    obs.check();
    assert!(obs.grid.iter().all(|it| it.is_finite()), "grid has a non-finite value");
    assert!(obs.vec.iter().all(|it| it.is_finite()), "vector has a non-finite value");
}

/// Plays one episode with random allowed actions; returns `(steps, terminated)`.
fn random_episode(env: &mut impl MarlEnv, seed: u64) -> (u32, bool) {
    let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    env.reset(seed, &mut obs);
    check_obs(&obs);
    let mut actions = vec![0_u8; env.n_agents()];
    for step in 1..=STEP_LIMIT {
        for (agent_idx, action) in actions.iter_mut().enumerate() {
            let allowed: Vec<u8> =
                (0..5_u8).filter(|&a| obs.mask_of(agent_idx)[a as usize]).collect();
            *action = *allowed.choose(&mut rng).expect("at least one legal action");
        }
        let out = env.step(&actions, &mut obs);
        check_obs(&obs);
        assert!(out.team_reward.is_finite());
        assert!(!(out.terminated && out.truncated), "terminated and truncated at once");
        if out.terminated || out.truncated {
            return (step, out.terminated);
        }
    }
    panic!("the episode did not end by the step limit {STEP_LIMIT}");
}

#[test]
fn path_finding_random_episode_is_truncated_at_the_limit() {
    let mut env = PoolEnv::new(Task::PathFinding, &small_pool(), env_config(), 3).unwrap();
    assert_eq!(env.obs_shape().grid_len(), 4 * 9 * 9);
    // The goal region is across a 32 × 32 map: random walks cannot reach it in 20 steps.
    assert_eq!(random_episode(&mut env, 1), (STEP_LIMIT, false));
    assert_eq!(random_episode(&mut env, 2), (STEP_LIMIT, false));
}

#[test]
fn path_finding_reset_is_deterministic() {
    let mut env = PoolEnv::new(Task::PathFinding, &small_pool(), env_config(), 3).unwrap();
    let mut a = ObsBuffers::new(3, env.obs_shape());
    let mut b = ObsBuffers::new(3, env.obs_shape());
    env.reset(7, &mut a);
    env.reset(99, &mut b);
    env.reset(7, &mut b);
    assert_eq!(a, b);
}

#[test]
fn formation_random_episode_ends_by_the_limit() {
    let mut env = PoolEnv::new(Task::Formation, &small_pool(), env_config(), 4).unwrap();
    for seed in 0..3 {
        let (steps, terminated) = random_episode(&mut env, seed);
        assert!(terminated || steps == STEP_LIMIT, "seed {seed}: ended early without success");
    }
}

#[test]
fn learner_trains_on_path_finding_with_mixed_team_sizes() {
    let device = crate::train_device();
    let three = PoolEnv::new(Task::PathFinding, &small_pool(), env_config(), 3).unwrap();
    let envs = vec![three.with_agents(4).unwrap(), three.clone(), three];
    let config = LearnerConfig { learning_starts: 2, batch_size: 8, ..LearnerConfig::default() };
    let mut learner = Learner::new(QNetConfig::default(), config, &[3, 4], 5, &device);
    let mut n_returns = 0;
    learner.train(
        &mut Collector::new(envs, 96),
        600,
        &mut |name: &'static str, _step, value: f64| {
            assert!(value.is_finite(), "{name} = {value}");
            n_returns += usize::from(name == phalanx_rl::metrics::EPISODIC_RETURN);
        },
    );
    let counters = learner.counters();
    assert!(counters.env_steps >= 600);
    assert_eq!(counters.episodes as usize, n_returns);
    assert!(counters.updates > 0, "no update in 600 steps");
    let stored: Vec<(usize, usize)> =
        learner.replays().iter().map(|replay| (replay.n_agents(), replay.len())).collect();
    assert_eq!(stored.iter().map(|it| it.0).collect::<Vec<_>>(), [3, 4]);
    assert!(stored.iter().all(|it| it.1 > 0), "episodes per team size {stored:?}");
}

#[test]
fn an_episode_is_rebuilt_from_its_seed_and_actions() {
    let config = LearnerConfig { learning_starts: 1000, ..LearnerConfig::default() };
    let device = crate::train_device();
    let mut learner = Learner::new(QNetConfig::default(), config, &[3], 2, &device);
    let env = PoolEnv::new(Task::Formation, &small_pool(), env_config(), 3)
        .unwrap()
        .with_shaping(Some(phalanx_env::Shaping { weight: 5.0, gamma: 1.0 }));
    let mut collector = Collector::new(vec![env.clone()], STEP_LIMIT as usize);
    learner.train(&mut collector, 60, &mut |_: &'static str, _, _| {});
    assert!(learner.replays()[0].len() >= 3);
    let mut env = env;
    let mut obs = ObsBuffers::new(3, env.obs_shape());
    for stored in learner.replays()[0].episodes() {
        let seed = stored.seed.expect("collected episodes know their seed");
        let limit = STEP_LIMIT as usize;
        let rebuilt =
            phalanx_rl::Episode::replay(&mut env, &mut obs, seed, &stored.actions, true, limit)
                .unwrap();
        assert_eq!(rebuilt.grid, stored.grid);
        assert_eq!(
            (rebuilt.vec, rebuilt.action_mask),
            (stored.vec.clone(), stored.action_mask.clone())
        );
        assert_eq!(
            (rebuilt.rewards, rebuilt.order),
            (stored.rewards.clone(), stored.order.clone())
        );
        assert_eq!(rebuilt.terminated, stored.terminated);
        // Other actions are not this episode: the replay says so instead of inventing one.
        let cut = &stored.actions[..stored.actions.len() - 3];
        let err = phalanx_rl::Episode::replay(&mut env, &mut obs, seed, cut, true, limit);
        let steps = cut.len() / 3;
        assert_eq!(err.unwrap_err(), phalanx_rl::ReplayError::NotEnded { steps });
    }
}
