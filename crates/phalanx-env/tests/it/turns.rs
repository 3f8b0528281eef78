//! Sequential acting: the leader order of docs/spec.md §6, the messages, and the equivalence of
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

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(100))]

    /// The leader order equals a slow sort: by BFS distance, or by the floating-point
    /// distance to the centroid, then by index.
    #[test]
    fn leader_order_matches_a_slow_sort(seed in proptest::prelude::any::<u64>(), steps in 0usize..20) {
        use phalanx_core::DistanceMap;
        use rand::{Rng, SeedableRng};
        let inst = crate::reference::random_instance(seed, 8, 6);
        let mut env = Env::new(EnvConfig::default()).unwrap();
        env.reset(&inst).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..steps {
            if env.is_done() {
                break;
            }
            let actions: Vec<Action> =
                (0..inst.n_agents()).map(|_| Action::ALL[rng.random_range(0..5u32) as usize]).collect();
            env.step(&actions);
        }
        let pos = env.positions().to_vec();
        let n = pos.len();
        let mut by_cost: Vec<u16> = (0..n as u16).collect();
        by_cost.sort_by_key(|&i| {
            let dm = DistanceMap::bfs(inst.grid(), inst.goals()[i as usize]);
            (dm.get(pos[i as usize]).unwrap(), i)
        });
        proptest::prop_assert_eq!(env.begin_turns(LeaderRule::PathFinding), &by_cost[..]);
        let cx = pos.iter().map(|p| f64::from(p.x)).sum::<f64>() / n as f64;
        let cy = pos.iter().map(|p| f64::from(p.y)).sum::<f64>() / n as f64;
        let d = |i: u16| (f64::from(pos[i as usize].x) - cx).hypot(f64::from(pos[i as usize].y) - cy);
        let mut by_centroid: Vec<u16> = (0..n as u16).collect();
        by_centroid.sort_by(|&a, &b| d(a).total_cmp(&d(b)).then(a.cmp(&b)));
        let order = env.begin_turns(LeaderRule::Formation).to_vec();
        // Equal up to floating-point ties: the keys along the order never decrease.
        for w in order.windows(2) {
            proptest::prop_assert!(d(w[0]) <= d(w[1]) + 1e-9);
        }
        let mut sorted = order.clone();
        sorted.sort_unstable();
        proptest::prop_assert_eq!(sorted, (0..n as u16).collect::<Vec<_>>());
        let near_tie = (0..n as u16).any(|a| (0..a).any(|b| (d(a) - d(b)).abs() < 1e-9));
        if !near_tie {
            proptest::prop_assert_eq!(order, by_centroid);
        }
    }
}
