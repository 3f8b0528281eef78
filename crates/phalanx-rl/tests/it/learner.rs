//! Learner maths: VDN sum, TD targets, action masking, ε schedule, determinism.

use burn::tensor::{Bool, Tensor, TensorData};
use phalanx_rl::learner::{MASKED_Q, mask_q, masked_argmax, td_targets, vdn_sum};
use phalanx_rl::{Collector, EpsilonSchedule, Learner, LearnerConfig, QNetConfig, SequenceMode};

use crate::corridor::{Corridor, corridor_learner, corridor_net};

#[test]
fn vdn_sums_over_agents() {
    let device = crate::plain_device();
    // [batch 1, agents 3, time 2]
    let q = Tensor::<3>::from_data(
        TensorData::new(vec![1.0_f32, 2.0, 10.0, 20.0, 100.0, 200.0], [1, 3, 2]),
        &device,
    );
    assert_eq!(vdn_sum(q).into_data().try_to_vec::<f32>().unwrap(), vec![111.0, 222.0]);
}

#[test]
fn td_target_terminal_does_not_bootstrap() {
    // r = 10, terminated: y = 10 whatever the next value.
    assert_eq!(td_targets(&[10.0], &[1.0], &[123.0], 0.95), vec![10.0]);
}

#[test]
fn td_target_truncated_bootstraps() {
    // r = -1, truncated (not terminated), next team Q 4: y = -1 + 0.5 * 4 = 1.
    assert_eq!(td_targets(&[-1.0], &[0.0], &[4.0], 0.5), vec![1.0]);
}

#[test]
fn td_targets_of_a_sequence() {
    let y = td_targets(&[-1.0, -1.0, 10.0], &[0.0, 0.0, 1.0], &[2.0, 8.0, 50.0], 0.5);
    assert_eq!(y, vec![0.0, 3.0, 10.0]);
}

#[test]
fn masked_action_is_never_chosen() {
    // Action 1 has the largest Q but is masked (clipped): the greedy choice is action 3.
    let q = [0.5, 9.0, -1.0, 2.0, 1.0];
    let allowed = [true, false, true, true, true];
    assert_eq!(masked_argmax(&q, &allowed), 3);
    // Ties go to the smallest index.
    assert_eq!(masked_argmax(&[1.0, 1.0], &[true, true]), 0);
}

#[test]
fn masked_action_is_never_bootstrapped() {
    // Double DQN: the online net picks among allowed actions, the target net evaluates.
    let online = [0.0, 5.0, 1.0];
    let target = [7.0, 100.0, 3.0];
    let allowed = [true, false, true];
    let a_star = masked_argmax(&online, &allowed);
    assert_eq!(a_star, 2);
    let y = td_targets(&[1.0], &[0.0], &[target[a_star]], 0.5);
    assert_eq!(y, vec![2.5]);
}

#[test]
fn mask_q_fills_masked_actions() {
    let device = crate::plain_device();
    let q = Tensor::<3>::from_data(TensorData::new(vec![1.0_f32, 2.0, 3.0], [1, 1, 3]), &device);
    let allowed =
        Tensor::<3, Bool>::from_data(TensorData::new(vec![true, false, true], [1, 1, 3]), &device);
    let masked = mask_q(q, allowed).into_data().try_to_vec::<f32>().unwrap();
    assert_eq!(masked, vec![1.0, MASKED_Q, 3.0]);
    assert_eq!(masked_argmax(&masked, &[true; 3]), 2);
}

#[test]
fn epsilon_decays_linearly() {
    let schedule = EpsilonSchedule { start: 1.0, end: 0.1, decay_steps: 100 };
    assert_eq!(schedule.value(0), 1.0);
    assert!((schedule.value(50) - 0.55).abs() < 1e-12);
    assert_eq!(schedule.value(100), 0.1);
    assert_eq!(schedule.value(1000), 0.1);
}

/// TD losses of a short training run on `n_envs` corridors in lockstep.
fn td_losses(config: LearnerConfig, seed: u64, steps: u64, n_envs: usize) -> Vec<f64> {
    let device = crate::train_device();
    let mut learner = Learner::new(corridor_net(), config, &[2], seed, &device);
    let mut losses = Vec::new();
    let envs = (0..n_envs).map(|_| Corridor::new()).collect();
    learner.train(&mut Collector::new(envs, 10), steps, &mut |name: &'static str, _, value| {
        if name == phalanx_rl::metrics::TD_LOSS {
            losses.push(value);
        }
    });
    losses
}

#[test]
fn same_seed_same_losses_on_any_thread_count() {
    let config = LearnerConfig { learning_starts: 4, ..corridor_learner() };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| td_losses(config.clone(), 5, 200, 3))
    };
    let first = run(1);
    assert!(first.len() >= 10, "only {} updates", first.len());
    assert_eq!(first, run(1));
    assert_eq!(first, run(2));
}

#[test]
fn windows_with_burn_in_train() {
    let mut config = corridor_learner();
    config.sequence = SequenceMode::Windows { len: 4, burn_in: 2 };
    config.learning_starts = 4;
    let losses = td_losses(config, 3, 150, 1);
    assert!(losses.len() >= 10, "only {} updates", losses.len());
    assert!(losses.iter().all(|it| it.is_finite()));
}

#[test]
fn configs_round_trip_through_json() {
    let paper = LearnerConfig::paper();
    assert_eq!((paper.gamma, paper.batch_size, paper.lr), (0.95, 32, 2e-6));
    assert_eq!(paper.sequence, SequenceMode::Episodes);
    let json = serde_json::to_string(&paper).unwrap();
    assert_eq!(serde_json::from_str::<LearnerConfig>(&json).unwrap(), paper);
    let net = QNetConfig::paper();
    assert_eq!((net.lstm_layers, net.lstm_hidden), (2, 256));
    let json = serde_json::to_string(&net).unwrap();
    assert_eq!(serde_json::from_str::<QNetConfig>(&json).unwrap(), net);
}

#[test]
fn a_centralised_learner_trains_and_reads_back() {
    let device = crate::train_device();
    let net = QNetConfig { centralised: true, ..corridor_net() };
    let config = LearnerConfig { learning_starts: 2, ..corridor_learner() };
    let mut learner = Learner::new(net, config, &[2], 9, &device);
    let mut losses = Vec::new();
    let mut collector = Collector::new(vec![Corridor::new()], 10);
    learner.train(&mut collector, 80, &mut |name: &'static str, _, value| {
        if name == phalanx_rl::metrics::TD_LOSS {
            losses.push(value);
        }
    });
    assert!(!losses.is_empty() && losses.iter().all(|it| it.is_finite()), "{losses:?}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("learner.ckpt");
    learner.save(&path).unwrap();
    let loaded = Learner::load(&path, &device).unwrap();
    assert!(loaded.net_config().centralised);
    let (policy, header) =
        phalanx_rl::policy_file::load_policy_any(&path, &crate::plain_device()).unwrap();
    assert!(policy.is_centralised() && header.net_config.centralised);
    // No agent acts with it alone, and no decentralised hierarchy stands on it.
    let err = phalanx_rl::LowLevel::new(policy.clone(), policy.clone()).unwrap_err();
    assert_eq!(err.to_string(), "the path-finding policy is centralised");
    let err = phalanx_rl::AgentPolicy::new(policy, 0).unwrap_err();
    assert_eq!(err, phalanx_rl::AgentError::Centralised);
}
