//! One test per rule of the validator, on a small map.

use crate::{Cell, Grid, Instance, Plan, Violation, ViolationKind, validate};

fn c(x: i32, y: i32) -> Cell {
    Cell::new(x, y)
}

/// 4×3 map with one obstacle at (1, 1); agent 0 goes (0,0) -> (2,0), agent 1 (0,2) -> (3,2).
fn instance() -> Instance {
    let grid = Grid::from_fn(4, 3, |cell| cell == c(1, 1));
    Instance::new(grid, vec![c(0, 0), c(0, 2)], vec![c(2, 0), c(3, 2)]).unwrap()
}

#[track_caller]
fn check(paths: &[&[(i32, i32)]], expect: Option<(usize, Option<usize>, ViolationKind)>) {
    let paths: Vec<Vec<Cell>> =
        paths.iter().map(|p| p.iter().map(|&(x, y)| c(x, y)).collect()).collect();
    let res = validate(&instance(), &Plan::from_paths(&paths));
    let expect = expect.map(|(step, agent, kind)| Violation { step, agent, kind });
    assert_eq!(res.err(), expect);
}

#[test]
fn valid_plan() {
    check(&[&[(0, 0), (1, 0), (2, 0)], &[(0, 2), (1, 2), (2, 2), (3, 2)]], None);
}

#[test]
fn following_is_allowed() {
    let grid = Grid::new(4, 1);
    let inst = Instance::new(grid, vec![c(1, 0), c(0, 0)], vec![c(3, 0), c(2, 0)]).unwrap();
    let plan =
        Plan::from_paths(&[vec![c(1, 0), c(2, 0), c(3, 0)], vec![c(0, 0), c(1, 0), c(2, 0)]]);
    assert_eq!(validate(&inst, &plan), Ok(()));
}

#[test]
fn wrong_agent_count() {
    let plan = Plan::from_paths(&[vec![c(0, 0)]]);
    let err = validate(&instance(), &plan).unwrap_err();
    assert_eq!(err.kind, ViolationKind::AgentCount { expected: 2, found: 1 });
    assert_eq!(err.to_string(), "step 0: the plan has 1 agents but the instance has 2");
}

#[test]
fn empty_plan() {
    assert_eq!(validate(&instance(), &Plan::new(2)).unwrap_err().kind, ViolationKind::Empty);
}

#[test]
fn wrong_start() {
    check(
        &[&[(1, 0), (2, 0)], &[(0, 2), (1, 2), (2, 2), (3, 2)]],
        Some((0, Some(0), ViolationKind::WrongStart { expected: c(0, 0), found: c(1, 0) })),
    );
}

#[test]
fn out_of_bounds() {
    check(
        &[&[(0, 0), (1, 0), (2, 0)], &[(0, 2), (0, 3)]],
        Some((1, Some(1), ViolationKind::OutOfBounds { cell: c(0, 3) })),
    );
}

#[test]
fn obstacle() {
    check(
        &[&[(0, 0), (0, 1), (1, 1)], &[(0, 2), (1, 2), (2, 2), (3, 2)]],
        Some((2, Some(0), ViolationKind::Obstacle { cell: c(1, 1) })),
    );
}

#[test]
fn jump() {
    check(
        &[&[(0, 0), (2, 0)], &[(0, 2), (1, 2), (2, 2), (3, 2)]],
        Some((1, Some(0), ViolationKind::Jump { from: c(0, 0), to: c(2, 0) })),
    );
}

#[test]
fn vertex_conflict() {
    check(
        &[&[(0, 0), (0, 1), (0, 1), (1, 0), (2, 0)], &[(0, 2), (0, 1)]],
        Some((1, Some(1), ViolationKind::VertexConflict { other: 0, cell: c(0, 1) })),
    );
}

#[test]
fn swap_conflict() {
    check(
        &[&[(0, 0), (0, 1), (0, 2)], &[(0, 2), (0, 1), (0, 0)]],
        Some((1, Some(1), ViolationKind::VertexConflict { other: 0, cell: c(0, 1) })),
    );
    check(
        &[&[(0, 0), (0, 1), (0, 2), (1, 2)], &[(0, 2), (0, 2), (0, 1), (0, 0)]],
        Some((2, Some(1), ViolationKind::SwapConflict { other: 0, from: c(0, 2), to: c(0, 1) })),
    );
}

#[test]
fn goal_not_reached() {
    check(
        &[&[(0, 0), (1, 0)], &[(0, 2), (1, 2), (2, 2), (3, 2)]],
        Some((3, Some(0), ViolationKind::GoalNotReached { cell: c(1, 0), goal: c(2, 0) })),
    );
}

#[test]
fn many_agents_vertex_conflict_uses_sorting() {
    let grid = Grid::new(40, 3);
    let starts: Vec<Cell> = (0..40).map(|x| c(x, 0)).collect();
    let goals: Vec<Cell> = (0..40).map(|x| c(x, 2)).collect();
    let inst = Instance::new(grid, starts.clone(), goals.clone()).unwrap();
    let mut paths: Vec<Vec<Cell>> = (0..40).map(|x| vec![c(x, 0), c(x, 1), c(x, 2)]).collect();
    assert_eq!(validate(&inst, &Plan::from_paths(&paths)), Ok(()));
    // Agent 36 steps right onto agent 37, who waits.
    paths[36][1] = c(37, 0);
    paths[37][1] = c(37, 0);
    let err = validate(&inst, &Plan::from_paths(&paths)).unwrap_err();
    assert_eq!((err.step, err.agent), (1, Some(37)));
    assert_eq!(err.kind, ViolationKind::VertexConflict { other: 36, cell: c(37, 0) });
}
