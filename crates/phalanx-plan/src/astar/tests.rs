//! Unit tests of the space-time A* internals (constraints, goal hold, MDDs).

use super::*;

fn line(n: u32) -> Grid {
    Grid::new(n, 1)
}

fn run(grid: &Grid, start: u32, goal: u32, cons: &Constraints) -> LowResult {
    let dist = DistanceMap::bfs(grid, grid.cell(CellId(goal)));
    let mut low = LowLevel::new(grid);
    let query = Query {
        start,
        goal,
        dist: dist.as_slice(),
        constraints: cons,
        cat: None,
        max_time: u32::MAX / 2,
        node_limit: None,
    };
    let mut expanded = 0;
    low.search(&query, &Budget::unlimited().start(), &mut expanded)
}

#[test]
fn straight_line_and_vertex_constraint() {
    let grid = line(4);
    assert_eq!(run(&grid, 0, 3, &Constraints::default()), LowResult::Found(vec![0, 1, 2, 3]));
    let mut cons = Constraints::default();
    cons.add_vertex(2, 2);
    assert_eq!(run(&grid, 0, 3, &cons), LowResult::Found(vec![0, 1, 1, 2, 3]));
}

#[test]
fn goal_hold_waits_past_the_last_goal_constraint() {
    let grid = Grid::new(3, 2);
    let mut cons = Constraints::default();
    cons.add_vertex(2, 6);
    let LowResult::Found(path) = run(&grid, 0, 2, &cons) else { panic!("no path") };
    assert_eq!(path.len(), 8);
    assert_eq!(*path.last().unwrap(), 2);
    assert_ne!(path[6], 2);
}

#[test]
fn edge_constraint_and_infeasible() {
    let grid = line(2);
    let mut cons = Constraints::default();
    cons.add_edge(0, 1, 1);
    assert_eq!(run(&grid, 0, 1, &cons), LowResult::Found(vec![0, 0, 1]));
    let mut blocked = Constraints::default();
    blocked.blocked_from.insert(1, 0);
    assert_eq!(run(&grid, 0, 1, &blocked), LowResult::Infeasible);
}

#[test]
fn mdd_singletons() {
    // 3x2 open grid from (0,0) to (2,1): cost 3, three shortest paths.
    let grid = Grid::new(3, 2);
    let dist = DistanceMap::bfs(&grid, Cell::new(2, 1));
    let clock = Budget::unlimited().start();
    let mut scratch = MddScratch::new();
    let cons = Constraints::default();
    let mdd = Mdd::build(&grid, 0, 5, 3, dist.as_slice(), &cons, &clock, &mut scratch).unwrap();
    assert_eq!(mdd.layers, vec![vec![0], vec![1, 3], vec![2, 4], vec![5]]);
    assert!(mdd.is_singleton(0, 0));
    assert!(!mdd.is_singleton(1, 1));
    assert!(mdd.is_singleton(5, 7));
}
