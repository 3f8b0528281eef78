//! The rewards of Table I, per task, on hand-made corridors.

use phalanx_core::Action::{self, Left, Right, Up, Wait};
use phalanx_env::{Clip, Env, EnvConfig, ObsBuffers, Task};

use crate::{c, instance};

fn env(task: Task) -> Env {
    Env::new(EnvConfig { task, formation_weight: 2.0, ..EnvConfig::default() }).unwrap()
}

#[test]
fn path_finding_rewards_and_termination() {
    // Agent 0: (0,0) -> (2,0); agent 1: (4,0) -> (3,0). One row, 5 cells.
    let inst = instance(5, 1, &[], &[c(0, 0), c(4, 0)], &[c(2, 0), c(3, 0)]);
    let mut env = env(Task::PathFinding);
    env.reset(&inst).unwrap();
    let step = env.step(&[Right, Wait]);
    assert_eq!(step.rewards, &[1.0, -0.25]);
    assert_eq!(step.team_reward, 0.75);
    // Agent 1 moves away from its goal (0), agent 0 moves towards (+1).
    let step = env.step(&[Right, Right]);
    assert_eq!(step.rewards, &[1.0, -50.0]);
    assert!(!step.terminated);
    let step = env.step(&[Wait, Left]);
    assert!(step.terminated && !step.truncated);
    assert_eq!(step.rewards, &[-0.25 + 100.0, 1.0 + 100.0]);
}

#[test]
fn formation_rewards_and_termination() {
    // Goals side by side; agent 1 starts two cells away from agent 0.
    let inst = instance(6, 1, &[], &[c(0, 0), c(2, 0)], &[c(4, 0), c(5, 0)]);
    let mut env = env(Task::Formation);
    env.reset(&inst).unwrap();
    let step = env.step(&[Wait, Right]);
    let lf = step.info.formation_loss as f32;
    assert!(lf > 0.0);
    assert_eq!(step.rewards, &[-0.25 - lf, -lf]);
    // (1, 0) and (2, 0): side by side again.
    let step = env.step(&[Right, Left]);
    assert_eq!(step.info.formation_loss, 0.0);
    assert!(step.terminated);
    assert_eq!(step.rewards, &[100.0, 100.0]);
}

#[test]
fn meta_rewards_weight_the_formation_loss() {
    let inst = instance(6, 1, &[], &[c(0, 0), c(1, 0)], &[c(4, 0), c(5, 0)]);
    let mut env = env(Task::Meta);
    env.reset(&inst).unwrap();
    let step = env.step(&[Wait, Right]);
    let lf = step.info.formation_loss as f32;
    assert!(lf > 0.0);
    assert_eq!(step.rewards, &[-2.0 * lf, 1.0 - 2.0 * lf]);
}

#[test]
fn meta_idle_cost_charges_each_agent_off_its_goal_that_did_not_get_closer() {
    // Agents 0 and 1 start off their goals, agent 2 on its goal.
    let inst = instance(6, 5, &[], &[c(0, 0), c(0, 2), c(5, 4)], &[c(2, 0), c(2, 2), c(5, 4)]);
    // Each agent's reward less the formation term, as (progress, idle cost).
    let rewards = |actions: &[Action]| {
        let mut env = Env::new(EnvConfig {
            task: Task::Meta,
            formation_weight: 2.0,
            idle_cost: 0.5,
            ..EnvConfig::default()
        })
        .unwrap();
        env.reset(&inst).unwrap();
        let step = env.step(actions);
        let w_lf = 2.0 * step.info.formation_loss as f32;
        // The environment adds `-w · L_f - idle` to the progress reward.
        let split = |r: f32| {
            [(0.0, 0.0), (1.0, 0.0), (0.0, 0.5), (1.0, 0.5)]
                .into_iter()
                .find(|&(progress, idle): &(f32, f32)| progress + (-w_lf - idle) == r)
                .unwrap_or((f32::NAN, f32::NAN))
        };
        step.rewards.iter().map(|&r| split(r)).collect::<Vec<(f32, f32)>>()
    };
    // Nobody gets closer: the agents off their goals pay.
    assert_eq!(rewards(&[Wait, Wait, Wait]), [(0.0, 0.5), (0.0, 0.5), (0.0, 0.0)]);
    // Agent 0 gets closer, agent 1 waits: agent 1 pays, whatever its team mate did.
    assert_eq!(rewards(&[Right, Wait, Wait]), [(1.0, 0.0), (0.0, 0.5), (0.0, 0.0)]);
    // Moving away is idle too.
    assert_eq!(rewards(&[Right, Up, Wait]), [(1.0, 0.0), (0.0, 0.5), (0.0, 0.0)]);
}

#[test]
fn truncated_at_three_times_the_side() {
    let inst = instance(4, 2, &[], &[c(0, 0)], &[c(3, 1)]);
    let mut env = env(Task::PathFinding);
    env.reset(&inst).unwrap();
    assert_eq!(env.step_limit(), 12);
    for t in 1..=12 {
        let step = env.step(&[Wait]);
        assert!(!step.terminated);
        assert_eq!(step.truncated, t == 12);
    }
    assert!(env.is_done());
}

#[test]
fn a_route_longer_than_two_sides_gets_half_again_its_length() {
    // A 5 × 5 snake: the route from (0, 0) to (0, 4) is 12 steps; 3 × side would be 15.
    let walls: Vec<_> = (0..4).map(|x| c(x, 1)).chain((1..5).map(|x| c(x, 3))).collect();
    let inst = instance(5, 5, &walls, &[c(0, 0)], &[c(0, 4)]);
    let mut env = env(Task::PathFinding);
    env.reset(&inst).unwrap();
    assert_eq!((env.step_limit(), inst.step_limit()), (18, 18));
    // A configured limit stays the limit.
    let config = EnvConfig { step_limit: Some(7), ..EnvConfig::default() };
    let mut env = Env::new(config).unwrap();
    env.reset(&inst).unwrap();
    assert_eq!(env.step_limit(), 7);
}

#[test]
fn masks_follow_the_clipping() {
    // . . .
    // . # .     agent at (0,0), goal (2,2)
    // a . .
    let inst = instance(3, 3, &[c(1, 1)], &[c(0, 0)], &[c(2, 2)]);
    for (task, expected) in [
        (Task::PathFinding, [true, false, false, true, true]),
        (Task::Formation, [true, false, false, true, true]),
        // The end-to-end baselines clip as formation does (docs/spec.md §7).
        (Task::Meta, [true, false, false, true, true]),
    ] {
        let mut env = env(task);
        env.reset(&inst).unwrap();
        let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
        env.observe(&mut obs);
        assert_eq!(obs.mask_of(0), &expected, "{task:?}");
    }
    // Path-finding clipping forbids moving away: from (1, 0) Left goes up the gradient.
    let inst = instance(3, 3, &[c(1, 1)], &[c(1, 0)], &[c(2, 2)]);
    let mut env = env(Task::PathFinding);
    env.reset(&inst).unwrap();
    let mut mask = [false; 5];
    env.write_mask(0, Clip::PathFinding, &mut mask);
    assert_eq!(mask, [false, false, false, true, true]);
    env.write_mask(0, Clip::Formation, &mut mask);
    assert_eq!(mask, [false, false, true, true, true]);
}
