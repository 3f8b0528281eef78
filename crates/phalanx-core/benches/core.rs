//! Criterion benchmarks of the core: BFS distance maps, plan validation with metrics and the
//! formation loss.

use criterion::{Criterion, criterion_group, criterion_main};
use phalanx_core::{
    Cell, DistanceMap, Grid, Instance, Plan, PlanMetrics, formation_loss, validate,
};

/// A 1024×1024 grid with ~15 % obstacles in a fixed pseudo-random pattern (no generator
/// dependency here; the generator has its own benchmark).
fn grid_1024() -> Grid {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    Grid::from_fn(1024, 1024, |c| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        c.x > 10 && c.y > 10 && state % 100 < 15
    })
}

fn bfs(c: &mut Criterion) {
    let grid = grid_1024();
    let dm = DistanceMap::bfs(&grid, Cell::new(0, 0));
    assert!(dm.get(Cell::new(5, 5)).is_some());
    c.bench_function("bfs/1024x1024/d0.15", |b| {
        b.iter(|| DistanceMap::bfs(&grid, Cell::new(0, 0)))
    });
    let mut dm = dm;
    let mut queue = Vec::new();
    c.bench_function("bfs_recompute/1024x1024/d0.15", |b| {
        b.iter(|| dm.recompute(&grid, Cell::new(3, 3), &mut queue))
    });
}

/// Three agents walking a 2 000-step serpentine on an open 64×64 map.
fn validate_2000(c: &mut Criterion) {
    let path: Vec<Cell> = (0..2001)
        .map(|t| {
            let row = t / 60;
            let col = t % 60;
            Cell::new(if row % 2 == 0 { col } else { 59 - col }, 2 * row)
        })
        .collect();
    // Rows advance by 2 between serpentine lines: insert the vertical step explicitly.
    let mut walk = vec![path[0]];
    for &next in &path[1..] {
        let last = *walk.last().unwrap();
        if last.manhattan(next) > 1 {
            walk.push(Cell::new(last.x, last.y + 1));
            walk.push(Cell::new(last.x, last.y + 2));
        } else {
            walk.push(next);
        }
        if walk.len() > 2000 {
            break;
        }
    }
    walk.truncate(2001);
    let paths: Vec<Vec<Cell>> =
        (0..3).map(|a| walk.iter().map(|c| c.offset(a * 2 + 1, 0)).collect()).collect();
    let goals: Vec<Cell> = paths.iter().map(|p| *p.last().unwrap()).collect();
    let starts: Vec<Cell> = paths.iter().map(|p| p[0]).collect();
    let inst = Instance::new(Grid::new(70, 140), starts, goals).unwrap();
    let plan = Plan::from_paths(&paths);
    assert_eq!(plan.horizon(), 2000);
    validate(&inst, &plan).unwrap();
    c.bench_function("validate_with_metrics/3x2000", |b| {
        b.iter(|| {
            validate(&inst, &plan).unwrap();
            PlanMetrics::of(&inst, &plan)
        })
    });
}

/// The loss of a team of 3 and of 25 out of formation (every agent one cell off its place).
fn loss(c: &mut Criterion) {
    for n in [3_i32, 25] {
        let goals: Vec<Cell> = (0..n).map(|i| Cell::new(10 + i % 5, 10 + i / 5)).collect();
        let positions: Vec<Cell> = goals
            .iter()
            .enumerate()
            .map(|(i, g)| Cell::new(g.x + 30 + (i % 2) as i32, g.y + 7))
            .collect();
        c.bench_function(&format!("formation_loss/{n}"), |b| {
            b.iter(|| formation_loss(std::hint::black_box(&positions), &goals))
        });
    }
}

criterion_group!(benches, bfs, validate_2000, loss);
criterion_main!(benches);
