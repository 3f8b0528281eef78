//! The scripted leader–follower meta rule: who runs which low-level policy, when the team
//! closes up, and for how long.

use phalanx_core::{Cell, Grid, Instance};
use phalanx_env::{EnvConfig, HierEnv, MetaInputs, ObsBuffers};
use phalanx_rl::ScriptedMeta;

/// A team of three on an open 12 × 6 map; goals a row at y = 1 from x = 8.
fn episode(starts: &[Cell]) -> (HierEnv, ObsBuffers) {
    let goals = [Cell::new(8, 1), Cell::new(9, 1), Cell::new(10, 1)];
    let inst = Instance::new(Grid::from_fn(12, 6, |_| false), starts.to_vec(), goals.to_vec());
    let mut hier = HierEnv::new(EnvConfig::default(), 3, MetaInputs::default()).unwrap();
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst.unwrap(), 1.0, &mut meta).unwrap();
    (hier, meta)
}

#[test]
fn the_front_agent_path_finds_and_the_others_follow() {
    let (hier, meta) = episode(&[Cell::new(1, 1), Cell::new(2, 1), Cell::new(4, 1)]);
    let mut rule = ScriptedMeta::new(None, 8);
    let mut choices = [9; 3];
    rule.choose(std::slice::from_ref(&hier), std::slice::from_ref(&meta), &mut choices);
    // Agent 2 is nearest its goal (cost 6 against 7 and 7).
    assert_eq!(choices, [1, 1, 0]);
}

#[test]
fn a_deformed_team_closes_up_while_it_helps_and_at_most_patience_steps() {
    // Deformed: L_f > 0 (agent 2 two cells ahead of its slot).
    let (hier, meta) = episode(&[Cell::new(1, 1), Cell::new(2, 1), Cell::new(5, 1)]);
    assert!(hier.env().formation_loss() > 0.5);
    let (envs, obs) = (std::slice::from_ref(&hier), std::slice::from_ref(&meta));
    let mut choices = [9; 3];
    // Above the threshold: everyone closes up (formation); below it, the leader moves on.
    ScriptedMeta::new(Some(0.5), 8).choose(envs, obs, &mut choices);
    assert_eq!(choices, [1, 1, 1]);
    ScriptedMeta::new(Some(10.0), 8).choose(envs, obs, &mut choices);
    assert_eq!(choices, [1, 1, 0]);
    // The same state again: closing up did not lower L_f, so the leader moves on.
    let mut rule = ScriptedMeta::new(Some(0.5), 8);
    rule.choose(envs, obs, &mut choices);
    rule.choose(envs, obs, &mut choices);
    assert_eq!(choices, [1, 1, 0]);
    // Patience 0: never closes up.
    ScriptedMeta::new(Some(0.5), 0).choose(envs, obs, &mut choices);
    assert_eq!(choices, [1, 1, 0]);
    // A reset forgets the run.
    rule.reset();
    rule.choose(envs, obs, &mut choices);
    assert_eq!(choices, [1, 1, 1]);
}
