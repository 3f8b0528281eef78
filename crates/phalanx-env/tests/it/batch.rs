//! The batched environment: the same observations as single episodes and the same result on
//! any thread count.

use phalanx_core::{Action, Instance};
use phalanx_env::{BatchEnv, Env, EnvConfig, ObsBuf, PoolConfig, TrainPool};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn pool() -> TrainPool {
    TrainPool::new(&PoolConfig { n_maps: 8, ..PoolConfig::default() }).unwrap()
}

/// Every buffer of every step: channels, vectors, masks, rewards, formation losses.
type Trace = (Vec<f32>, Vec<f32>, Vec<bool>, Vec<f32>, Vec<f32>);

/// Runs `n_steps` random steps on a batch; returns the trace.
fn run(instances: &[Instance], n_steps: usize) -> Trace {
    let mut batch = BatchEnv::new(EnvConfig::default(), instances.len(), 3).unwrap();
    batch.reset_all(instances).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut trace = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n_steps {
        let actions: Vec<Action> = (0..instances.len() * 3)
            .map(|_| Action::ALL[rng.random_range(0..5u32) as usize])
            .collect();
        batch.step(&actions);
        trace.0.extend_from_slice(&batch.obs().grid);
        trace.1.extend_from_slice(&batch.obs().vector);
        trace.2.extend_from_slice(&batch.obs().mask);
        trace.3.extend_from_slice(batch.rewards());
        trace.4.extend(batch.outcomes().iter().map(|o| o.formation_loss as f32));
    }
    trace
}

#[test]
fn batch_is_the_same_on_any_thread_count() {
    let pool = pool();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let instances: Vec<Instance> = (0..40).map(|_| pool.sample(3, &mut rng)).collect();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
    let a = one.install(|| run(&instances, 30));
    let b = four.install(|| run(&instances, 30));
    assert!(a == b, "results differ between 1 and 4 threads");
}

#[test]
fn batch_observations_equal_single_episode_observations() {
    let pool = pool();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let instances: Vec<Instance> = (0..20).map(|_| pool.sample(3, &mut rng)).collect();
    let mut batch = BatchEnv::new(EnvConfig::default(), 20, 3).unwrap();
    batch.reset_all(&instances).unwrap();
    let mut singles: Vec<Env> = instances
        .iter()
        .map(|inst| {
            let mut env = Env::new(EnvConfig::default()).unwrap();
            env.reset(inst).unwrap();
            env
        })
        .collect();
    let mut obs = ObsBuf::new(batch.layout(), 1);
    for _ in 0..50 {
        let actions: Vec<Action> =
            (0..60).map(|_| Action::ALL[rng.random_range(0..5u32) as usize]).collect();
        batch.step(&actions);
        for (e, env) in singles.iter_mut().enumerate() {
            if env.is_done() {
                continue;
            }
            let step = env.step(&actions[e * 3..e * 3 + 3]);
            assert_eq!(step.rewards, &batch.rewards()[e * 3..e * 3 + 3]);
            assert_eq!(step.team_reward, batch.outcomes()[e].team_reward);
            env.observe_into(&mut obs);
            for agent in 0..3 {
                assert_eq!(obs.agent_grid(0, agent), batch.obs().agent_grid(e, agent));
                assert_eq!(obs.agent_vector(0, agent), batch.obs().agent_vector(e, agent));
                assert_eq!(obs.agent_mask(0, agent), batch.obs().agent_mask(e, agent));
            }
        }
    }
}

#[test]
fn batch_turns_write_each_agents_message() {
    let pool = pool();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let instances: Vec<Instance> = (0..10).map(|_| pool.sample(3, &mut rng)).collect();
    let mut batch = BatchEnv::new(EnvConfig::default(), 10, 3).unwrap();
    batch.reset_all(&instances).unwrap();
    batch.begin_turns(phalanx_env::LeaderRule::PathFinding);
    let chosen = [Action::Up, Action::Right, Action::Wait];
    for (k, &action) in chosen.iter().enumerate() {
        for e in 0..10 {
            let agent = batch.turn_agent(e, k);
            let msg = batch.obs().agent_message(e, agent);
            // One one-hot row per agent that acted before.
            assert_eq!(msg.iter().filter(|&&v| v == 1.0).count(), k);
            for j in 0..k {
                let before = batch.turn_agent(e, j);
                assert_eq!(msg[before * 5 + chosen[j].index()], 1.0);
            }
        }
        batch.choose(&[action; 10]);
    }
    batch.step_chosen();
    assert!(batch.obs().message.iter().all(|&v| v == 0.0));
}
