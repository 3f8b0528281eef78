//! Batched acting and evaluation: many episodes in one policy call act exactly as each one
//! alone, recurrent state is cleared per episode, and evaluation does not depend on the batch.

use phalanx_core::Instance;
use phalanx_env::PoolConfig;
use phalanx_env::{EnvConfig, EvalMaps, MarlEnv, ObsBuffers, PoolEnv, Task};
use phalanx_rl::{EvalSummary, Keep, QNetConfig, Rollouts, evaluate};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::plain_device;

fn policy() -> phalanx_rl::Policy {
    policy_of(false)
}

fn policy_of(centralised: bool) -> phalanx_rl::Policy {
    let config = QNetConfig { centralised, ..QNetConfig::default() };
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(3), &plain_device());
    phalanx_rl::Policy::new(&net, config)
}

/// Teams of 2, 3 and 4 agents on pool maps, each after a reset from its own seed.
fn observations() -> (Vec<PoolEnv>, Vec<ObsBuffers>) {
    let pool = PoolConfig { n_maps: 3, ..PoolConfig::default() };
    let first = PoolEnv::new(Task::PathFinding, &pool, EnvConfig::default(), 2).unwrap();
    let mut envs =
        vec![first.clone(), first.with_agents(3).unwrap(), first.with_agents(4).unwrap()];
    let obs = envs
        .iter_mut()
        .enumerate()
        .map(|(seed, env)| {
            let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
            env.reset(seed as u64, &mut obs);
            obs
        })
        .collect();
    (envs, obs)
}

/// Q-values (bits) of every agent for two steps, acting on all episodes at once or on each
/// alone; the second step checks the carried recurrent state.
fn q_two_steps(batched: bool, centralised: bool) -> Vec<u32> {
    let (mut envs, mut obs) = observations();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut res = Vec::new();
    let mut singles: Vec<_> = envs.iter().map(|_| policy_of(centralised)).collect();
    let mut joint = policy_of(centralised);
    for _ in 0..2 {
        let n: usize = obs.iter().map(|it| it.n_agents).sum();
        let (mut actions, mut q) = (vec![0_u8; n], vec![0.0_f32; n * 5]);
        if batched {
            joint.act_batch(&obs, 0.0, &mut rng, &mut actions, Some(&mut q));
        } else {
            let mut at = 0;
            for (e, env_obs) in obs.iter().enumerate() {
                let k = env_obs.n_agents;
                singles[e].act_with_q(
                    env_obs,
                    0.0,
                    &mut rng,
                    &mut actions[at..at + k],
                    &mut q[at * 5..(at + k) * 5],
                );
                at += k;
            }
        }
        res.extend(q.iter().map(|it| it.to_bits()));
        let mut at = 0;
        for (env, env_obs) in envs.iter_mut().zip(&mut obs) {
            let k = env_obs.n_agents;
            env.step(&actions[at..at + k], env_obs);
            at += k;
        }
    }
    res
}

#[test]
fn batched_acting_equals_acting_alone() {
    // A centralised network's rows read their own team only, so it batches as well.
    for centralised in [false, true] {
        let (batched, alone) = (q_two_steps(true, centralised), q_two_steps(false, centralised));
        assert_eq!(batched.len(), 2 * 9 * 5);
        // Rows of one batch may differ in the last bit from a batch of one (matrix kernels
        // block by rows), so compare values, not bits.
        for (a, b) in batched.iter().zip(&alone) {
            let (a, b) = (f32::from_bits(*a), f32::from_bits(*b));
            assert!((a - b).abs() <= 1e-5 * (1.0 + a.abs()), "{a} vs {b}, {centralised}");
        }
    }
}

#[test]
fn reset_envs_clears_only_the_restarted_episodes() {
    let (_, obs) = observations();
    let n: usize = obs.iter().map(|it| it.n_agents).sum();
    let agents: Vec<usize> = obs.iter().map(|it| it.n_agents).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut q_of = |policy: &mut phalanx_rl::Policy| {
        let (mut actions, mut q) = (vec![0_u8; n], vec![0.0_f32; n * 5]);
        policy.act_batch(&obs, 0.0, &mut rng, &mut actions, Some(&mut q));
        q
    };
    let (mut fresh, mut warm) = (policy(), policy());
    let first = q_of(&mut fresh);
    let _ = q_of(&mut warm);
    let second = q_of(&mut warm);
    warm.reset_envs(&agents, &[false, true, false]);
    let after_reset = q_of(&mut warm);
    let third = {
        let mut again = policy();
        let _ = q_of(&mut again);
        let _ = q_of(&mut again);
        q_of(&mut again)
    };
    // Episode 1 (agents 2..5) starts again: its Q equals a fresh policy's first step.
    let rows = |q: &[f32], from: usize, to: usize| q[from * 5..to * 5].to_vec();
    assert_eq!(rows(&after_reset, 2, 5), rows(&first, 2, 5));
    assert_ne!(rows(&second, 2, 5), rows(&first, 2, 5), "the state matters");
    // Episodes 0 and 2 keep their state: as a policy that never reset, at its third step.
    assert_eq!(rows(&after_reset, 0, 2), rows(&third, 0, 2));
    assert_eq!(rows(&after_reset, 5, 9), rows(&third, 5, 9));
}

#[test]
fn with_a_rollout_temperature_solved_instances_are_sampled_and_the_others_searched() {
    let instances = instances(6);
    let shipped = || phalanx_rl::models::load(None, "pathfinding").unwrap().0;
    let own = Rollouts { count: 4, epsilon: 1.0, seed: 1, keep: Some(Keep::Tightest) };
    let play = |policy: &mut phalanx_rl::Policy, limit: u32| {
        let env = EnvConfig { step_limit: Some(limit), ..EnvConfig::default() };
        evaluate(policy, Task::PathFinding, &env, &instances, 3, own, &mut |_| {}).unwrap()
    };
    let mut sampled = shipped();
    sampled.set_rollout_temperature(Some(0.5));
    // An instance no rollout solved is played with random actions as before (none is solved
    // in 2 steps: the same rollouts, draw for draw).
    let unsolved = play(&mut shipped(), 2);
    assert!(unsolved.iter().all(|it| !it.success));
    assert_eq!(play(&mut sampled, 2), unsolved);
    // One the greedy rollout solved is played again drawing from the softmax, not walking at
    // random (ε = 1): solved again, and the tightest kept is tighter somewhere.
    let greedy = play(&mut shipped(), 40);
    assert!(greedy.iter().filter(|it| it.success).count() >= 3, "the shipped policy solves");
    let refined = play(&mut sampled, 40);
    assert_eq!(play(&mut sampled, 40), refined, "the same draws");
    let mut tighter = 0;
    for (kept, walked) in refined.iter().zip(&greedy) {
        assert_eq!(kept.success, walked.success);
        assert!(kept.formation_loss <= walked.formation_loss);
        tighter += usize::from(kept.formation_loss < walked.formation_loss);
    }
    assert!(tighter > 0, "no sampled rollout was tighter");
}

fn instances(n: usize) -> Vec<Instance> {
    let maps = EvalMaps::new(phalanx_gen::GenConfig {
        size: 16,
        density: 0.1,
        n_agents: 3,
        fov: 9,
        seed: 4,
    });
    (0..n as u64).map(|idx| maps.instance(idx).unwrap()).collect()
}

#[test]
fn evaluation_does_not_depend_on_the_batch_and_extra_rollouts_never_hurt() {
    let instances = instances(6);
    let env = EnvConfig { step_limit: Some(40), ..EnvConfig::default() };
    let run = |batch: usize, rollouts: Rollouts| {
        evaluate(&mut policy(), Task::PathFinding, &env, &instances, batch, rollouts, &mut |_| {})
            .unwrap()
    };
    let one = run(1, Rollouts::default());
    let all = run(6, Rollouts::default());
    let summary = |eps: &[phalanx_rl::EvalEpisode]| {
        eps.iter().map(|it| (it.success, it.steps, it.collisions)).collect::<Vec<_>>()
    };
    assert_eq!(summary(&one), summary(&all));
    for (episode, instance) in one.iter().zip(&instances) {
        assert_eq!(episode.n_agents, 3);
        assert!(episode.steps >= 1 && episode.steps <= 40);
        assert!(!episode.success || episode.steps >= episode.lower_bound as usize);
        assert!(episode.lower_bound >= 1 && episode.lower_bound < 4 * instance.grid().side());
    }
    let more = run(3, Rollouts { count: 4, epsilon: 0.3, seed: 1, ..Rollouts::default() });
    for (best, greedy) in more.iter().zip(&one) {
        assert!(best.success >= greedy.success);
        if best.success == greedy.success {
            assert!(best.steps <= greedy.steps);
        }
    }
    let (a, b) = (EvalSummary::of(&more), EvalSummary::of(&one));
    assert!(a.success_rate >= b.success_rate);
    // The same rollouts, the one with the lowest formation loss kept: solved as often, never
    // a higher loss, never fewer steps.
    let keeping = |keep| run(3, Rollouts { count: 4, epsilon: 0.3, seed: 1, keep: Some(keep) });
    let tightest = keeping(Keep::Tightest);
    for (tight, fast) in tightest.iter().zip(&more) {
        assert_eq!(tight.success, fast.success);
        assert!(tight.formation_loss <= fast.formation_loss);
        assert!(tight.steps >= fast.steps);
    }
    // Within a budget no rollout exceeds, the same as the tightest; within a budget of the
    // lower bound itself, the tightest of the rollouts that take no more, else the fastest.
    assert_eq!(keeping(Keep::Within(1e9)), tightest);
    for (kept, fast) in keeping(Keep::Within(1.0)).iter().zip(&more) {
        assert_eq!(kept.success, fast.success);
        if fast.success && fast.steps == fast.lower_bound as usize {
            assert_eq!(kept.steps, fast.steps);
            assert!(kept.formation_loss <= fast.formation_loss);
        } else {
            assert_eq!(kept, fast);
        }
    }
    // The policy's own rule unless the rollouts name one.
    let mut tight = policy();
    tight.set_keep(Keep::Tightest);
    let own = Rollouts { count: 4, epsilon: 0.3, seed: 1, ..Rollouts::default() };
    let env = EnvConfig { step_limit: Some(40), ..EnvConfig::default() };
    let played = evaluate(&mut tight, Task::PathFinding, &env, &instances, 3, own, &mut |_| {});
    assert_eq!(played.unwrap(), tightest);
    // A policy without the team vector has no dead band: a second one changes nothing.
    let mut second = policy();
    second.set_rollout_band(Some(0.0)).unwrap();
    let played = evaluate(&mut second, Task::PathFinding, &env, &instances, 3, own, &mut |_| {});
    assert_eq!(played.unwrap(), more);
}
