//! The expert answers from arbitrary joint states with valid first steps, re-plans only off
//! its plan, and refuses joint states that are no instance.

use phalanx_core::{DistanceMap, PlanMetrics, validate};
use phalanx_gen::GenConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// A generated instance and `n` random joint states on its map: distinct free cells from
/// which every agent reaches its goal.
fn random_states(seed: u64, n_agents: usize, n: usize) -> (Instance, Vec<Vec<Cell>>) {
    let config = GenConfig { size: 16, density: 0.15, n_agents, seed, fov: 9 };
    let instance = phalanx_gen::generate(&config).unwrap();
    let grid = instance.grid();
    let maps: Vec<DistanceMap> =
        instance.goals().iter().map(|&g| DistanceMap::bfs(grid, g)).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut states = Vec::new();
    while states.len() < n {
        let mut cells: Vec<Cell> = Vec::new();
        while cells.len() < n_agents {
            let c = Cell::new(rng.random_range(0..16), rng.random_range(0..16));
            if grid.is_free(c) && !cells.contains(&c) && maps[cells.len()].get(c).is_some() {
                cells.push(c);
            }
        }
        states.push(cells);
    }
    (instance, states)
}

/// Applies each agent's action to its cell.
fn apply(positions: &[Cell], actions: &[Action]) -> Vec<Cell> {
    positions.iter().zip(actions).map(|(&p, a)| a.apply(p)).collect()
}

/// Follows `expert` from `start` until the goals (at most `limit` steps), the positions
/// after each step pushed on a plan.
fn follow(expert: &mut Expert, start: &[Cell], goals: &[Cell], limit: usize) -> Plan {
    let mut plan = Plan::new(start.len());
    plan.push(start);
    let mut positions = start.to_vec();
    let mut actions = vec![Action::Wait; start.len()];
    for _ in 0..limit {
        if positions == goals {
            break;
        }
        expert.act(&positions, &mut actions).unwrap();
        positions = apply(&positions, &actions);
        plan.push(&positions);
    }
    plan
}

#[test]
fn first_steps_from_arbitrary_joint_states_form_valid_plans() {
    // Joint-state A* on two agents only: from random states, three take seconds in a debug
    // build.
    let runs = [
        (ExpertPlanner::Swarm, 1, 3),
        (ExpertPlanner::Swarm, 2, 4),
        (ExpertPlanner::Swarm, 3, 5),
        (ExpertPlanner::JointAStar { w: 1.0 }, 4, 2),
        (ExpertPlanner::Cbs, 5, 4),
    ];
    for (planner, seed, n_agents) in runs {
        let config = ExpertConfig { planner, ..ExpertConfig::default() };
        {
            let (instance, states) = random_states(seed, n_agents, 3);
            for start in states {
                let mut expert = Expert::new(&instance, &config);
                let plan = follow(&mut expert, &start, instance.goals(), 200);
                let from = Instance::new(instance.grid().clone(), start, instance.goals().to_vec())
                    .unwrap();
                validate(&from, &plan).unwrap();
                // On its own plan the expert plans once.
                assert_eq!(expert.stats().replans, 1, "{planner:?} seed {seed}");
                assert_eq!(expert.stats().calls as usize, plan.horizon());
            }
        }
    }
}

#[test]
fn re_planning_at_every_step_still_reaches_the_goals_validly() {
    // A fresh expert at each step: only first steps of fresh plans are taken.
    let (instance, states) = random_states(7, 3, 3);
    for start in states {
        let mut plan = Plan::new(start.len());
        plan.push(&start);
        let mut positions = start.clone();
        let mut actions = vec![Action::Wait; start.len()];
        for _ in 0..200 {
            if positions == instance.goals() {
                break;
            }
            Expert::new(&instance, &ExpertConfig::default()).act(&positions, &mut actions).unwrap();
            positions = apply(&positions, &actions);
            plan.push(&positions);
        }
        let from =
            Instance::new(instance.grid().clone(), start, instance.goals().to_vec()).unwrap();
        validate(&from, &plan).unwrap();
    }
}

#[test]
fn leaving_the_plan_re_plans_from_where_the_agents_are() {
    let (instance, _) = random_states(11, 3, 1);
    let mut expert = Expert::new(&instance, &ExpertConfig::default());
    let start = instance.starts().to_vec();
    let mut actions = vec![Action::Wait; 3];
    expert.act(&start, &mut actions).unwrap();
    let on_plan = apply(&start, &actions);
    assert!(expert.on_plan(&on_plan));
    // Stay where we were instead: off the plan, so the next call plans again.
    assert!(!expert.on_plan(&start));
    expert.act(&start, &mut actions).unwrap();
    assert_eq!(expert.stats().replans, 2);
    let rest = follow(&mut expert, &apply(&start, &actions), instance.goals(), 200);
    assert_eq!(rest.at(rest.horizon()), instance.goals());
    let metrics = PlanMetrics::of(&instance, &rest);
    assert!(metrics.makespan > 0);
}

#[test]
fn at_the_goals_every_agent_waits() {
    let (instance, _) = random_states(5, 4, 1);
    let mut expert = Expert::new(&instance, &ExpertConfig::default());
    let mut actions = vec![Action::Up; 4];
    expert.act(instance.goals(), &mut actions).unwrap();
    assert_eq!(actions, [Action::Wait; 4]);
    expert.act(instance.goals(), &mut actions).unwrap();
    assert_eq!(actions, [Action::Wait; 4]);
    assert_eq!(expert.stats().replans, 1);
}

#[test]
fn a_joint_state_that_is_no_instance_is_an_error() {
    let (instance, _) = random_states(5, 3, 1);
    let mut expert = Expert::new(&instance, &ExpertConfig::default());
    let s = instance.starts()[0];
    let mut actions = vec![Action::Wait; 3];
    let err = expert.act(&[s, s, instance.starts()[2]], &mut actions).unwrap_err();
    assert!(matches!(err, ExpertError::State(InstanceError::Duplicate { .. })), "{err}");
    assert!(err.to_string().contains("not an instance"));
}
