//! The hierarchy's episode: the low level's acting order after the meta choices and where the
//! formation frame is anchored.

use phalanx_env::{EnvConfig, HierEnv, ObsBuffers};

use crate::{c, instance};

/// A team of three in a row along x = 1..3 on a 12 × 4 map, goals the same row shifted by 8;
/// agent 2 is in front (nearest its goal), agent 1 at the centre.
fn row() -> (HierEnv, ObsBuffers) {
    let inst = instance(12, 4, &[], &[c(1, 1), c(2, 1), c(3, 1)], &[c(9, 1), c(10, 1), c(11, 1)]);
    let mut hier = HierEnv::new(EnvConfig::default(), 3, false).unwrap();
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, 1.0, &mut meta).unwrap();
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
    assert_eq!(hier.env().frame_goals(), [c(2, 1), c(3, 1), c(4, 1)]);
    // Down (action 1): every slot one step down instead.
    hier.place_frame(Some(1));
    assert_eq!(hier.env().frame_goals(), [c(1, 0), c(2, 0), c(3, 0)]);
    // Without a move, the front agent's slot is its own cell.
    hier.place_frame(None);
    assert_eq!(hier.env().frame_goals(), [c(1, 1), c(2, 1), c(3, 1)]);
}

#[test]
fn a_team_closing_up_gathers_on_its_front_agent() {
    let inst = instance(12, 4, &[], &[c(1, 1), c(2, 2), c(4, 1)], &[c(8, 1), c(9, 1), c(10, 1)]);
    let mut hier = HierEnv::new(EnvConfig::default(), 3, false).unwrap();
    let mut meta = ObsBuffers::new(3, hier.meta_shape());
    hier.reset_to(&inst, 1.0, 1.0, &mut meta).unwrap();
    // Costs 7, 8, 6: agent 2 is in front; everyone chooses formation.
    assert_eq!(meta.order, [2, 0, 1]);
    hier.set_choices(&[1, 1, 1]);
    hier.place_frame(None);
    // The slots are placed with agent 2's on its own cell, not the centre agent's.
    assert_eq!(hier.env().frame_goals(), [c(2, 1), c(3, 1), c(4, 1)]);
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
