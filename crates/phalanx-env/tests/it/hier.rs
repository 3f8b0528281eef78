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
