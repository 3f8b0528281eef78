//! Sequential acting: the leader order of SPEC §6, the messages, and the equivalence of
//! acting in turn with a joint step.

use phalanx_core::Action::{self, Right, Up, Wait};
use phalanx_env::{Env, EnvConfig, LeaderRule};

use crate::{c, instance};

#[test]
fn formation_order_is_nearest_the_centroid_then_index() {
    let inst = instance(
        8,
        3,
        &[],
        &[c(0, 0), c(1, 0), c(2, 0), c(1, 2)],
        &[c(4, 0), c(5, 0), c(6, 0), c(5, 2)],
    );
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&inst).unwrap();
    // Centroid (1, 0.5): agent 1 at 0.5, agents 0 and 2 at √1.25, agent 3 at 1.5.
    assert_eq!(env.begin_turns(LeaderRule::Formation), &[1, 0, 2, 3]);
}

#[test]
fn path_finding_order_is_smallest_cost_then_index() {
    let inst = instance(8, 1, &[], &[c(0, 0), c(3, 0), c(5, 0)], &[c(7, 0), c(6, 0), c(1, 0)]);
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&inst).unwrap();
    // Costs 7, 3, 4.
    assert_eq!(env.begin_turns(LeaderRule::PathFinding), &[1, 2, 0]);
    let inst = instance(8, 1, &[], &[c(0, 0), c(2, 0)], &[c(3, 0), c(5, 0)]);
    env.reset(&inst).unwrap();
    assert_eq!(env.begin_turns(LeaderRule::PathFinding), &[0, 1]);
}

#[test]
fn messages_hold_the_actions_chosen_before() {
    let inst = instance(8, 3, &[], &[c(0, 0), c(1, 0), c(2, 0)], &[c(4, 0), c(5, 0), c(6, 0)]);
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&inst).unwrap();
    // Costs 4, 4, 4: order by index.
    assert_eq!(env.begin_turns(LeaderRule::PathFinding), &[0, 1, 2]);
    let mut msg = vec![9.0; 15];
    env.write_message(0, &mut msg);
    assert!(msg.iter().all(|&v| v == 0.0));
    assert_eq!(env.choose(Right), Some(1));
    env.write_message(1, &mut msg);
    assert_eq!(msg, one_hot(&[(0, Right)]));
    assert_eq!(env.choose(Up), Some(2));
    env.write_message(2, &mut msg);
    assert_eq!(msg, one_hot(&[(0, Right), (1, Up)]));
    // The leader's message stays empty; agent 1 never sees agent 2's action.
    assert_eq!(env.choose(Wait), None);
    env.write_message(1, &mut msg);
    assert_eq!(msg, one_hot(&[(0, Right)]));
    let turned = env.step_chosen();
    let (rewards, n_cancelled) = (turned.rewards.to_vec(), turned.info.n_cancelled);
    let after = env.positions().to_vec();
    env.reset(&inst).unwrap();
    let joint = env.step(&[Right, Up, Wait]);
    assert_eq!((joint.rewards.to_vec(), joint.info.n_cancelled), (rewards, n_cancelled));
    assert_eq!(env.positions(), &after[..]);
    assert_eq!(after, [c(1, 0), c(1, 1), c(2, 0)]);
}

fn one_hot(chosen: &[(usize, Action)]) -> Vec<f32> {
    let mut v = vec![0.0; 15];
    for &(agent, action) in chosen {
        v[agent * 5 + action.index()] = 1.0;
    }
    v
}
