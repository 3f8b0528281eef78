//! Unit tests of the search core's internals (constraints, goal hold, the two orders, MDDs).

use phalanx_core::{Cell, CellId, DistanceMap, Grid};

use super::*;
use crate::Budget;

fn line(n: u32) -> Grid {
    Grid::new(n, 1)
}

fn ids(cells: &[u32]) -> Path {
    cells.iter().map(|&c| CellId(c)).collect()
}

fn run_with<O: low::Order>(
    grid: &Grid,
    order: O,
    start: u32,
    goal: u32,
    cons: &Constraints,
) -> LowResult {
    let dist = DistanceMap::bfs(grid, grid.cell(CellId(goal)));
    let mut low = LowLevel::new(grid, order);
    let query = Query {
        start: CellId(start),
        goal: CellId(goal),
        dist: dist.as_slice(),
        constraints: cons,
        cat: None,
        max_time: u32::MAX / 2,
        node_limit: None,
    };
    let mut expanded = 0;
    low.search(&query, &Budget::unlimited().start(), &mut expanded)
}

fn run(grid: &Grid, start: u32, goal: u32, cons: &Constraints) -> LowResult {
    run_with(grid, AStarOrder::default(), start, goal, cons)
}

fn found(cells: &[u32]) -> LowResult {
    LowResult::Found { path: ids(cells), lower_bound: cells.len() as u32 - 1 }
}

#[test]
fn straight_line_and_vertex_constraint() {
    let grid = line(4);
    assert_eq!(run(&grid, 0, 3, &Constraints::default()), found(&[0, 1, 2, 3]));
    let cons = Constraints::of(&[Constraint::Vertex { cell: CellId(2), t: 2 }]);
    assert_eq!(run(&grid, 0, 3, &cons), found(&[0, 1, 1, 2, 3]));
    // Focal search with w = 1 finds an optimal path too, with its cost as the bound.
    assert_eq!(run_with(&grid, FocalOrder::new(1.0), 0, 3, &cons), found(&[0, 1, 1, 2, 3]));
}

#[test]
fn goal_hold_waits_past_the_last_goal_constraint() {
    let grid = Grid::new(3, 2);
    let cons = Constraints::of(&[Constraint::Vertex { cell: CellId(2), t: 6 }]);
    let LowResult::Found { path, .. } = run(&grid, 0, 2, &cons) else { panic!("no path") };
    assert_eq!(path.len(), 8);
    assert_eq!(*path.last().unwrap(), CellId(2));
    assert_ne!(path[6], CellId(2));
}

#[test]
fn edge_constraint_and_infeasible() {
    let grid = line(2);
    let cons = Constraints::of(&[Constraint::Edge { from: CellId(0), to: CellId(1), t: 1 }]);
    assert_eq!(run(&grid, 0, 1, &cons), found(&[0, 0, 1]));
    let blocked = Constraints::of(&[Constraint::BlockedFrom { cell: CellId(1), t: 0 }]);
    assert_eq!(run(&grid, 0, 1, &blocked), LowResult::Infeasible);
    let late = Constraints::of(&[Constraint::FinishNotBefore { t: 4 }]);
    let LowResult::Found { path, .. } = run(&grid, 0, 1, &late) else { panic!("no path") };
    assert_eq!(path_cost(&path), 4);
}

#[test]
fn conflicts_and_their_split() {
    // Agent 0 moves right along a line of 3 while agent 1 moves left: they meet at cell 1
    // at t = 1, a vertex conflict, split into the same constraint for each.
    let paths = [Rc::new(ids(&[0, 1, 2])), Rc::new(ids(&[2, 1, 0]))];
    let found = conflicts(&paths);
    let first = Conflict::earliest(&found).unwrap();
    assert_eq!(first.kind, ConflictKind::Vertex { cell: CellId(1) });
    assert_eq!(first.t, 1);
    let [(a1, c1), (a2, c2)] = first.split();
    assert_eq!((a1, a2), (AgentId(0), AgentId(1)));
    assert_eq!(c1, Constraint::Vertex { cell: CellId(1), t: 1 });
    assert_eq!(c2, c1);
    // A swap on two cells is an edge conflict, split into the two directions.
    let swap = [Rc::new(ids(&[0, 1])), Rc::new(ids(&[1, 0]))];
    let edge = Conflict::earliest(&conflicts(&swap)).unwrap();
    assert_eq!(edge.kind, ConflictKind::Edge { from: CellId(0), to: CellId(1) });
    let [(_, c1), (_, c2)] = edge.split();
    assert_eq!(c1, Constraint::Edge { from: CellId(0), to: CellId(1), t: 1 });
    assert_eq!(c2, Constraint::Edge { from: CellId(1), to: CellId(0), t: 1 });
    // The conflict-avoidance table of agent 0 counts agent 1's path only.
    let cat = ConflictTable::of_others(&paths, AgentId(0));
    assert_eq!(cat.count(CellId(0), CellId(1), 1), 1);
    assert_eq!(cat.count(CellId(0), CellId(0), 1), 0);
}

#[test]
fn mdd_singletons() {
    // 3x2 open grid from (0,0) to (2,1): cost 3, three shortest paths.
    let grid = Grid::new(3, 2);
    let dist = DistanceMap::bfs(&grid, Cell::new(2, 1));
    let clock = Budget::unlimited().start();
    let mut scratch = MddScratch::new();
    let cons = Constraints::default();
    let query = MddQuery {
        start: CellId(0),
        goal: CellId(5),
        cost: 3,
        dist: dist.as_slice(),
        constraints: &cons,
    };
    let mdd = Mdd::build(&grid, &query, &clock, &mut scratch).unwrap();
    let layers: Vec<Path> = [&[0][..], &[1, 3], &[2, 4], &[5]].iter().map(|l| ids(l)).collect();
    assert_eq!(mdd.layers, layers);
    assert!(mdd.is_singleton(CellId(0), 0));
    assert!(!mdd.is_singleton(CellId(1), 1));
    assert!(mdd.is_singleton(CellId(5), 7));
}
