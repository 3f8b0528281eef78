//! The hierarchy's episode: the low level's acting order after the meta choices and where the
//! formation frame is anchored.

use phalanx_core::Action;
use phalanx_env::{Env, EnvConfig, HierEnv, MetaInputs, ObsBuffers, Task};

use crate::{c, instance};

/// A team of three in a row along x = 1..3 on a 12 × 4 map, goals the same row shifted by 8;
/// agent 2 is in front (nearest its goal), agent 1 at the centre.
fn row() -> (HierEnv, ObsBuffers) {
    let inst = instance(12, 4, &[], &[c(1, 1), c(2, 1), c(3, 1)], &[c(9, 1), c(10, 1), c(11, 1)]);
    let mut hier = HierEnv::new(EnvConfig::default(), 3, MetaInputs::default()).unwrap();
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, &mut meta).unwrap();
    (hier, meta)
}

#[test]
fn path_finders_act_first_then_formation_followers_from_the_centre() {
    let (mut hier, meta) = row();
    // The meta order is the path-finding rule's: front first (costs 8, 8, 8: by index).
    assert_eq!(meta.order, [0, 1, 2]);
    hier.set_choices(&[1, 1, 0]);
    assert_eq!(hier.pathfinding_obs().order, [2, 1, 0]);
    assert_eq!(hier.leader(), 2);
    hier.set_choices(&[1, 1, 1]);
    // Formation only: nearest the centroid (agent 1) first.
    assert_eq!(hier.leader(), 1);
}

#[test]
fn the_frame_moves_with_a_path_finding_leader() {
    let (mut hier, _) = row();
    hier.set_choices(&[0, 1, 1]);
    assert_eq!(hier.leader(), 0);
    // The leader moves right (action 3): every slot moves one step right.
    hier.place_frame(Some(3));
    assert_eq!(hier.frame_goals(), [c(2, 1), c(3, 1), c(4, 1)]);
    // Down (action 1): every slot one step down instead.
    hier.place_frame(Some(1));
    assert_eq!(hier.frame_goals(), [c(1, 0), c(2, 0), c(3, 0)]);
    // Without a move, the front agent's slot is its own cell.
    hier.place_frame(None);
    assert_eq!(hier.frame_goals(), [c(1, 1), c(2, 1), c(3, 1)]);
}

#[test]
fn a_team_closing_up_gathers_on_its_front_agent() {
    let inst = instance(12, 4, &[], &[c(1, 1), c(2, 2), c(4, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let mut hier = HierEnv::new(EnvConfig::default(), 3, MetaInputs::default()).unwrap();
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, &mut meta).unwrap();
    // Costs 7, 8, 6: agent 2 is in front; everyone chooses formation.
    assert_eq!(meta.order, [2, 0, 1]);
    hier.set_choices(&[1, 1, 1]);
    hier.place_frame(None);
    // The slots are placed with agent 2's on its own cell, not the centre agent's.
    assert_eq!(hier.frame_goals(), [c(2, 1), c(3, 1), c(4, 1)]);
}

#[test]
fn moves_into_cells_earlier_agents_take_are_clipped() {
    // Agents 0, 1, 2 in a row at x = 1, 2, 3 (y = 1); actions: 0 Up, 1 Down, 2 Left, 3 Right,
    // 4 Wait.
    let (hier, _) = row();
    let all = [true; 5];
    let mut mask = all;
    // Agent 2 moved left into agent 1's cell: agent 1 may not move right (a swap) and may
    // still wait or go elsewhere.
    hier.clip_claimed(1, &[2], &[4, 4, 2], &mut mask);
    assert_eq!(mask, [true, true, true, false, true]);
    // Agents 0 and 2 moved up, to (1, 2) and (3, 2): their old cells are free after the
    // step, and none of agent 1's moves lands on (1, 2) or (3, 2).
    let mut mask = all;
    hier.clip_claimed(1, &[0, 2], &[0, 4, 0], &mut mask);
    assert_eq!(mask, all);
    // Agent 0 waits at (1, 1): agent 1 may not move left into it; agent 2 moved down to
    // (3, 0): agent 1 may still move down to (2, 0).
    let mut mask = all;
    hier.clip_claimed(1, &[0, 2], &[4, 4, 1], &mut mask);
    assert_eq!(mask, [true, true, false, true, true]);
    // Agent 0 moved right into agent 1's cell: moving left (a swap) is clipped, waiting
    // (then agent 0's move is cancelled) is not; a move already masked stays masked.
    let mut mask = [false, true, true, true, true];
    hier.clip_claimed(1, &[0], &[3, 4, 4], &mut mask);
    assert_eq!(mask, [false, true, false, true, true]);
}

#[test]
fn a_translating_team_moves_front_first() {
    // Agents 1, 2, 3 in a row at x = 1, 2, 3 behind agent 0 at x = 4 (y = 1), all travelling
    // right; agent 0 leads (costs all 6: by index).
    let starts = [c(4, 1), c(1, 1), c(2, 1), c(3, 1)];
    let goals = [c(10, 1), c(7, 1), c(8, 1), c(9, 1)];
    let inst = instance(12, 4, &[], &starts, &goals);
    let mut hier = HierEnv::new(EnvConfig::default(), 4, MetaInputs::default()).unwrap();
    let mut meta = ObsBuffers::new(4, hier.meta_shape());
    hier.reset_to(&inst, 1.0, &mut meta).unwrap();
    hier.set_choices(&[0, 1, 1, 1]);
    // The formation rule alone: nearest the centroid (x = 2.5) first, ties by index.
    assert_eq!(hier.pathfinding_obs().order, [0, 2, 3, 1]);
    // The leader moves right: each follower's slot is the cell of the one ahead of it, so
    // the one ahead acts first and the next one moves into the cell it leaves.
    hier.place_frame(Some(3));
    assert_eq!(hier.pathfinding_obs().order, [0, 3, 2, 1]);
    assert_eq!(hier.formation_obs().order, [0, 3, 2, 1]);
    // A leader that waits leaves every slot where its agent stands: the rule's order.
    hier.set_choices(&[0, 1, 1, 1]);
    hier.place_frame(Some(4));
    assert_eq!(hier.formation_obs().order, [0, 2, 3, 1]);
}

#[test]
fn the_meta_observation_reads_the_place() {
    // Goals in a row; agent 2 in front (cost 4), the layout placed on it: (4, 1), (5, 1),
    // (6, 1). Agent 0 stands one row above its place, agent 1 one cell left of it.
    let inst = instance(12, 4, &[], &[c(4, 2), c(4, 1), c(6, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let inputs = MetaInputs { place: true };
    let mut hier = HierEnv::new(EnvConfig::default(), 3, inputs).unwrap();
    assert_eq!(inputs.vector_len(), 6);
    assert_eq!(hier.meta_shape().env_vec, 6);
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, &mut meta).unwrap();
    assert_eq!(meta.order[0], 2);
    let pathfinding = hier.pathfinding_obs();
    for agent in 0..3 {
        let v = meta.vec_of(agent);
        assert_eq!(&v[..3], pathfinding.vec_of(agent), "agent {agent}: the goal vector first");
    }
    // Then the place vector: each place is one cell away (1 / (1 + 9) for a view of 9).
    assert_eq!(&meta.vec_of(0)[3..], [0.0, -1.0, 0.1]);
    assert_eq!(&meta.vec_of(1)[3..], [1.0, 0.0, 0.1]);
    assert_eq!(&meta.vec_of(2)[3..], [0.0, 0.0, 0.0]);
    // Without the inputs, the vector is the goal vector alone.
    let mut plain = HierEnv::new(EnvConfig::default(), 3, MetaInputs::default()).unwrap();
    let mut meta = ObsBuffers::new(3, plain.meta_shape());
    plain.reset_to(&inst, 1.0, &mut meta).unwrap();
    assert_eq!(meta.vec_of(0), plain.pathfinding_obs().vec_of(0));
}

#[test]
fn the_environment_writes_the_meta_observations_place_vector() {
    // The student's observation (`EnvConfig::place_vector`) holds what the hierarchy's meta
    // observation holds: the goal vector, then the place vector on the agent in front, at
    // every step; the hierarchy's own low level never reads it.
    let inst = instance(12, 4, &[], &[c(4, 2), c(4, 1), c(6, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let config = EnvConfig { task: Task::Meta, place_vector: true, ..EnvConfig::default() };
    let mut hier = HierEnv::new(config.clone(), 3, MetaInputs { place: true }).unwrap();
    assert_eq!(hier.pathfinding_obs().shape.env_vec, 3);
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, &mut meta).unwrap();
    let mut env = Env::new(config).unwrap();
    assert_eq!(env.obs_shape().env_vec, 6);
    env.reset(&inst).unwrap();
    let mut obs = ObsBuffers::new(3, env.obs_shape());
    let moves = [[Action::Down, Action::Right, Action::Right], [Action::Right; 3]];
    for (t, joint) in moves.iter().enumerate() {
        env.observe(&mut obs);
        assert_eq!(env.front(), meta.order[0], "step {t}");
        assert_eq!(obs.vec, meta.vec, "step {t}");
        env.step(joint);
        hier.set_choices(&[0, 0, 0]);
        hier.step(&joint.map(|a| a.index() as u8), &mut meta);
    }
}

#[test]
fn the_team_vector_points_the_agent_in_front_back_to_a_team_behind_it() {
    // Goals in a row (8..10, 1); agent 2 is in front, agents 0 and 1 have fallen behind it.
    let inst = instance(16, 4, &[], &[c(1, 1), c(2, 1), c(6, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let plain = EnvConfig { task: Task::Meta, place_vector: true, ..EnvConfig::default() };
    let config = EnvConfig { team_vector: true, ..plain.clone() };
    let mut env = Env::new(config).unwrap();
    assert_eq!(env.obs_shape().env_vec, 9);
    env.reset(&inst).unwrap();
    assert_eq!(env.front(), 2);
    // Mean of the cells (3, 1), of the goals (9, 1): the layout shifted by (-6, 0) puts the
    // places at (2, 1), (3, 1), (4, 1): agent 2 stands two cells ahead of its place, and
    // only the agent in front reads the vector.
    assert_eq!(env.team_shift(), (-6.0, 0.0));
    let mut obs = ObsBuffers::new(3, env.obs_shape());
    env.observe(&mut obs);
    assert_eq!(&obs.vec_of(2)[6..], [-1.0, 0.0, (2.0_f64 / 11.0) as f32]);
    assert_eq!(&obs.vec_of(0)[6..], [0.0; 3]);
    assert_eq!(&obs.vec_of(1)[6..], [0.0; 3]);
    // The goal and place vectors come first, as without the team vector.
    let mut place = Env::new(plain).unwrap();
    place.reset(&inst).unwrap();
    let mut without = ObsBuffers::new(3, place.obs_shape());
    place.observe(&mut without);
    for agent in 0..3 {
        assert_eq!(&obs.vec_of(agent)[..6], without.vec_of(agent), "agent {agent}");
    }
    // A team less out of shape is within the dead band (agent 2 two thirds of a cell ahead
    // of its place): zeros; so is a team on its goals.
    let near = instance(16, 4, &[], &[c(4, 1), c(5, 1), c(7, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    env.reset(&near).unwrap();
    assert_eq!(env.front(), 2);
    env.observe(&mut obs);
    assert_eq!(&obs.vec_of(2)[6..], [0.0; 3]);
    env.reset(&instance(16, 4, &[], &[c(8, 1), c(9, 1), c(10, 1)], &[c(8, 1), c(9, 1), c(10, 1)]))
        .unwrap();
    env.observe(&mut obs);
    assert!(obs.vec.iter().all(|&v| v == 0.0));
    // The team vector needs the place vector.
    let lone = EnvConfig { task: Task::Meta, team_vector: true, ..EnvConfig::default() };
    assert!(Env::new(lone).is_err());
}

#[test]
fn a_narrower_dead_band_shows_the_agent_in_front_a_smaller_lag() {
    // Agent 2 two thirds of a cell ahead of its place on the team: within the default band
    // of 1.5 cells, outside one of 0.5.
    let near = instance(16, 4, &[], &[c(4, 1), c(5, 1), c(7, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let base = EnvConfig {
        task: Task::Meta,
        place_vector: true,
        team_vector: true,
        ..EnvConfig::default()
    };
    assert_eq!(base.team_deadband, phalanx_env::obs::TEAM_DEADBAND);
    let team_vector = |band: f64| {
        let mut env = Env::new(EnvConfig { team_deadband: band, ..base.clone() }).unwrap();
        env.reset(&near).unwrap();
        let mut obs = ObsBuffers::new(3, env.obs_shape());
        env.observe(&mut obs);
        obs.vec_of(2)[6..].to_vec()
    };
    assert_eq!(team_vector(1.5), [0.0; 3]);
    let shown = team_vector(0.5);
    assert!(shown[0] < 0.0 && shown[1] == 0.0 && shown[2] > 0.0, "{shown:?}");
    assert_eq!(team_vector(0.0), shown);
    // The band is a number of cells, 0 or more; the default is not written.
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let err = Env::new(EnvConfig { team_deadband: bad, ..base.clone() }).err().unwrap();
        assert!(err.to_string().contains("dead band"), "{err}");
    }
    assert!(!serde_json::to_string(&base).unwrap().contains("team_deadband"));
    let narrow = EnvConfig { team_deadband: 0.75, ..base.clone() };
    let text = serde_json::to_string(&narrow).unwrap();
    assert!(text.contains("\"team_deadband\":0.75"), "{text}");
    assert_eq!(serde_json::from_str::<EnvConfig>(&text).unwrap(), narrow);
}
