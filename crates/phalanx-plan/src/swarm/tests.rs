//! Sanity tests of SWARM-MAPF-R (baselines.md §3.3).

use std::time::Duration;

use phalanx_core::{Cell, Grid, Instance, PlanMetrics, validate};

use super::*;

fn c(x: i32, y: i32) -> Cell {
    Cell::new(x, y)
}

/// The formation-aware sub-solver: these tests do not depend on CBS.
fn jsa_config() -> SwarmConfig {
    SwarmConfig { sub_solver: SubSolver::JointAStar { w: 1.0 }, ..SwarmConfig::default() }
}

fn l_formation(at: Cell) -> Vec<Cell> {
    vec![at, at.offset(1, 0), at.offset(0, 1)]
}

#[test]
fn empty_map_is_a_rigid_translation() {
    let starts = l_formation(c(1, 1));
    let goals = l_formation(c(14, 12));
    let inst = Instance::new(Grid::new(16, 16), starts, goals).unwrap();
    let config = SwarmConfig::default();
    let leader = centroid_leader(inst.goals());
    let lp = leader_plan(&inst, &config, leader).unwrap();
    assert_eq!(lp.segments.len(), 1);
    assert_eq!(lp.segments[0].kind, SegmentKind::Open);
    let report = solve(&inst, &config, &Budget::default());
    let plan = report.result.unwrap();
    validate(&inst, &plan).unwrap();
    let m = PlanMetrics::of(&inst, &plan);
    assert_eq!(m.formation_loss, 0.0);
    assert_eq!(m.makespan, inst.starts()[leader].manhattan(inst.goals()[leader]) as usize);
}

#[test]
fn one_wide_gap_is_one_critical_segment() {
    // A vertical wall at x = 8 with a one-cell gap at y = 6.
    let grid = Grid::from_fn(16, 12, |p| p.x == 8 && p.y != 6);
    let starts = l_formation(c(1, 5));
    let goals = l_formation(c(13, 5));
    let inst = Instance::new(grid, starts, goals).unwrap();
    let config = jsa_config();
    let lp = leader_plan(&inst, &config, centroid_leader(inst.goals())).unwrap();
    let kinds: Vec<SegmentKind> = lp.segments.iter().map(|s| s.kind).collect();
    assert_eq!(kinds, [SegmentKind::Open, SegmentKind::Critical, SegmentKind::Open]);
    let plan = solve(&inst, &config, &Budget::default()).result.unwrap();
    validate(&inst, &plan).unwrap();
    let m = PlanMetrics::of(&inst, &plan);
    // Loss only while squeezing through the gap.
    let crit = lp.segments[1];
    assert!(m.formation_loss > 0.0);
    let lossy: Vec<usize> =
        (0..=m.makespan).filter(|&t| m.formation_loss_per_step[t] > 0.0).collect();
    assert!(lossy.first().is_some_and(|&t| t + 2 >= crit.first), "{lossy:?} vs {crit:?}");
}

#[test]
fn starts_out_of_formation_get_a_gathering_segment() {
    let starts = vec![c(0, 0), c(3, 0), c(0, 3)];
    let goals = l_formation(c(9, 9));
    let inst = Instance::new(Grid::new(12, 12), starts, goals).unwrap();
    let config = jsa_config();
    let lp = leader_plan(&inst, &config, centroid_leader(inst.goals())).unwrap();
    assert_eq!(lp.segments[0].kind, SegmentKind::Critical);
    assert_eq!(lp.segments[0].first, 0);
    let plan = solve(&inst, &config, &Budget::default()).result.unwrap();
    validate(&inst, &plan).unwrap();
}

#[test]
fn unsolvable_swap_is_an_outcome() {
    let inst =
        Instance::new(Grid::new(2, 1), vec![c(0, 0), c(1, 0)], vec![c(1, 0), c(0, 0)]).unwrap();
    let report = solve(&inst, &jsa_config(), &Budget::default());
    assert_eq!(report.result, Err(PlanFailure::Unsolvable));
}

#[test]
fn merge_gaps_joins_close_segments() {
    let mut critical = [false, true, false, true, false, false, true, false];
    merge_gaps(&mut critical, 2);
    assert_eq!(critical, [false, true, true, true, false, false, true, false]);
}

#[test]
fn every_plan_is_valid_on_walled_maps() {
    for (seed, sub_solver) in [(1, SubSolver::Cbs), (2, SubSolver::JointAStar { w: 1.0 })] {
        for gap in [2, 5, 9] {
            let grid = Grid::from_fn(14, 14, |p| {
                (p.x == 5 && p.y != gap) || (p.x == 9 && p.y != 13 - gap + seed)
            });
            let inst = Instance::new(grid, l_formation(c(1, 1)), l_formation(c(11, 11))).unwrap();
            let config = SwarmConfig { sub_solver, ..SwarmConfig::default() };
            let plan = solve(&inst, &config, &Budget::default()).result.unwrap();
            validate(&inst, &plan).unwrap();
        }
    }
}

#[test]
fn generated_instances_give_valid_plans() {
    // Every instance is solved (the planner is complete) and every plan passes the validator,
    // with the default (CBS) and the formation-aware sub-solver.
    for (size, density, n_agents) in [(20, 0.15, 3), (20, 0.05, 5), (64, 0.15, 4)] {
        for seed in 1..=3 {
            let gen_config = phalanx_gen::GenConfig { size, density, n_agents, seed, fov: 9 };
            let inst = phalanx_gen::generate(&gen_config).unwrap();
            for config in [SwarmConfig::default(), jsa_config()] {
                let report = solve(&inst, &config, &Budget::seconds(30.0));
                let plan = report.result.unwrap_or_else(|failure| {
                    panic!("{size} {density} {n_agents} seed {seed}: {failure}")
                });
                validate(&inst, &plan).unwrap();
            }
        }
    }
}

#[test]
fn budgets_and_leader_choices_are_outcomes() {
    let grid = Grid::from_fn(16, 12, |p| p.x == 8 && p.y != 6);
    let inst = Instance::new(grid, l_formation(c(1, 5)), l_formation(c(13, 5))).unwrap();
    let zero = Budget { time_limit: Some(Duration::ZERO), node_limit: None };
    let res = solve(&inst, &SwarmConfig::default(), &zero).result;
    assert!(matches!(res, Err(PlanFailure::Timeout)), "{res:?}");
    let try_all = SwarmConfig { leader_choice: LeaderChoice::TryAll, ..SwarmConfig::default() };
    let plan = solve(&inst, &try_all, &Budget::seconds(10.0)).result.unwrap();
    validate(&inst, &plan).unwrap();
    let clearance = SwarmConfig { clearance: 1, lambda: f64::INFINITY, ..SwarmConfig::default() };
    let plan = solve(&inst, &clearance, &Budget::seconds(10.0)).result.unwrap();
    validate(&inst, &plan).unwrap();
}
