//! Generator tests: settings checks, regions, formation, density, determinism.

use phalanx_core::{Cell, DistanceMap, formation_loss};
use proptest::prelude::*;

use super::*;

fn config(size: u32, density: f64, n_agents: usize, seed: u64) -> GenConfig {
    GenConfig { size, density, n_agents, seed, fov: 9 }
}

#[test]
fn rejects_bad_settings() {
    assert_eq!(generate(&config(7, 0.1, 3, 0)), Err(GenError::Size(7)));
    assert_eq!(generate(&config(32, 0.5, 3, 0)), Err(GenError::Density(0.5)));
    assert!(matches!(generate(&config(32, f64::NAN, 3, 0)), Err(GenError::Density(_))));
    assert!(matches!(generate(&config(32, 0.1, 26, 0)), Err(GenError::Agents { max: 25, .. })));
    assert!(matches!(generate(&config(32, 0.1, 0, 0)), Err(GenError::Agents { .. })));
    assert_eq!(generate(&GenConfig { fov: 8, ..config(32, 0.1, 3, 0) }), Err(GenError::Fov(8)));
    assert!(generate(&config(512, 0.05, 100, 0)).is_ok());
}

#[test]
fn known_instance_is_stable_across_platforms_and_versions() {
    // Pins the RNG stream: a change here changes every generated benchmark instance.
    let inst = generate(&config(20, 0.15, 3, 1)).unwrap();
    let grid = inst.grid();
    assert_eq!(inst.starts(), &[Cell::new(3, 2), Cell::new(0, 2), Cell::new(4, 4)]);
    assert_eq!(grid.n_blocked(), 60);
    let blocked_ids: u64 = (0..20)
        .flat_map(|y| (0..20).map(move |x| Cell::new(x, y)))
        .filter(|&c| grid.is_blocked(c))
        .map(|c| u64::from(grid.id(c).0))
        .sum();
    assert_eq!(blocked_ids, 13_104);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn instances_follow_the_paper(size in 8u32..64, density in 0.0f64..=0.4, k in 1usize..=25, seed: u64) {
        let inst = generate(&config(size, density, k, seed)).unwrap();
        let r = region_side(size) as i32;
        let far = size as i32 - r;
        let grid = inst.grid();
        prop_assert_eq!(grid.width(), size);
        // Density met exactly (rounded), unless the free regions leave too few cells.
        let in_region = |x: i32, y: i32| (x < r && y < r) || (x >= far && y >= far);
        let blockable = (0..size as i32).flat_map(|y| (0..size as i32).map(move |x| (x, y))).filter(|&(x, y)| !in_region(x, y)).count();
        let target = ((density * f64::from(size * size)).round() as usize).min(blockable);
        prop_assert_eq!(grid.n_blocked(), target);
        for y in 0..r {
            for x in 0..r {
                prop_assert!(grid.is_free(Cell::new(x, y)));
                prop_assert!(grid.is_free(Cell::new(far + x, far + y)));
            }
        }
        for (s, g) in inst.starts().iter().zip(inst.goals()) {
            prop_assert!(s.x < r && s.y < r);
            prop_assert_eq!(*g, s.offset(far, far));
            prop_assert!(DistanceMap::bfs(grid, *g).get(*s).is_some());
        }
        prop_assert_eq!(formation_loss(inst.starts(), inst.goals()), 0.0);
        prop_assert_eq!(&inst, &generate(&config(size, density, k, seed)).unwrap());
    }
}

/// The longest horizontal or vertical run of blocked cells.
fn longest_run(grid: &phalanx_core::Grid) -> u32 {
    let side = grid.width() as i32;
    let mut best = 0;
    for a in 0..side {
        let (mut row, mut col) = (0, 0);
        for b in 0..side {
            row = if grid.is_blocked(Cell::new(b, a)) { row + 1 } else { 0 };
            col = if grid.is_blocked(Cell::new(a, b)) { col + 1 } else { 0 };
            best = best.max(row).max(col);
        }
    }
    best
}

#[test]
fn walls_are_short_straight_segments() {
    // On a sparse map segments rarely touch, so the longest straight run shows the wall
    // length: `max_wall` cells; with `max_wall = 1` two single cells touch at most.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let grid = random_grid(64, 64, 0.02, 4, &[], &mut rng);
    assert_eq!(grid.n_blocked(), 82);
    assert_eq!(longest_run(&grid), 4);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let single = random_grid(64, 64, 0.02, 1, &[], &mut rng);
    assert_eq!(single.n_blocked(), 82);
    assert_eq!(longest_run(&single), 2);
}

#[test]
fn large_maps_use_ten_cell_regions() {
    let inst = generate(&config(512, 0.15, 4, 9)).unwrap();
    assert!(inst.goals().iter().all(|g| g.x >= 502 && g.y >= 502));
    assert_eq!(region_side(511), 5);
    assert_eq!(region_side(512), 10);
}

#[test]
fn formations_on_a_given_map_are_translated_reachable_and_far() {
    // Two rooms joined by a door: the far half of the map is the other room.
    let grid = Grid::from_fn(40, 12, |c| c.x == 20 && c.y != 6);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut trips = Vec::new();
    for _ in 0..20 {
        let inst = formation_on_map(&grid, 4, 5, &mut rng).unwrap();
        let (s, g) = (inst.starts(), inst.goals());
        let (dx, dy) = (g[0].x - s[0].x, g[0].y - s[0].y);
        assert!(s.iter().zip(g).all(|(s, g)| g.x - s.x == dx && g.y - s.y == dy));
        for (s, g) in s.iter().zip(g) {
            trips.push(DistanceMap::bfs(&grid, *s).get(*g).expect("every goal is reachable"));
        }
    }
    // Long trips: the far half of the map (its largest distances are about 30 to 45).
    let mean = trips.iter().sum::<u32>() as f64 / trips.len() as f64;
    assert!(mean >= 15.0, "mean trip {mean}");
    assert!(trips.iter().all(|&d| d > 0));
    // The same stream, the same instance.
    let a = formation_on_map(&grid, 3, 5, &mut ChaCha8Rng::seed_from_u64(9));
    let b = formation_on_map(&grid, 3, 5, &mut ChaCha8Rng::seed_from_u64(9));
    assert_eq!(a.unwrap().starts(), b.unwrap().starts());
    // No room: a map with one free cell cannot hold two agents.
    let tiny = Grid::from_fn(8, 8, |c| c != Cell::new(0, 0));
    assert!(formation_on_map(&tiny, 2, 5, &mut rng).is_none());
}

/// Every free cell of `grid` reaches every other.
fn connected(grid: &Grid) -> bool {
    let free: Vec<Cell> = grid.free_cells().collect();
    let dist = phalanx_core::DistanceMap::bfs(grid, free[0]);
    free.iter().all(|&c| dist.get(c).is_some())
}

#[test]
fn mazes_are_connected_corridors_of_their_width() {
    for (side, corridor, seed) in [(32, 2, 0), (32, 2, 1), (33, 1, 2), (64, 3, 3)] {
        let grid = maze(side, corridor, seed).unwrap();
        assert_eq!(grid, maze(side, corridor, seed).unwrap());
        assert!(connected(&grid), "{side} {corridor} {seed}");
        // No free square wider than a corridor: the walls stand on the lattice.
        let w = corridor as i32 + 1;
        let free_square = |x: i32, y: i32| {
            (0..w).all(|dy| (0..w).all(|dx| !grid.is_blocked(Cell::new(x + dx, y + dy))))
        };
        let s = side as i32 - w;
        assert!(!(0..=s).any(|y| (0..=s).any(|x| free_square(x, y))));
        // Long corridors: the farthest cell from the corner is many sides away.
        let dist = phalanx_core::DistanceMap::bfs(&grid, Cell::new(1, 1));
        let far = grid.free_cells().filter_map(|c| dist.get(c)).max().unwrap();
        assert!(far > 2 * side, "{far}");
    }
    assert_ne!(maze(32, 2, 0), maze(32, 2, 1));
    assert_eq!(maze(4097, 2, 0), Err(GenError::Size(4097)));
    assert!(matches!(maze(8, 3, 0), Err(GenError::Kind { side: 8, .. })));
    assert!(matches!(maze(32, 0, 0), Err(GenError::Kind { .. })));
    assert_eq!(maze(0, 2, 0), Err(GenError::Size(0)));
    assert!(matches!(maze(32, u32::MAX, 0), Err(GenError::Kind { .. })));
}

#[test]
fn rooms_are_connected_by_one_cell_doors() {
    for (side, room, seed) in [(64, 7, 0), (64, 7, 1), (20, 7, 2), (65, 4, 3)] {
        let grid = rooms(side, room, seed).unwrap();
        assert_eq!(grid, rooms(side, room, seed).unwrap());
        assert!(connected(&grid), "{side} {room} {seed}");
        // The walls are the lattice lines but for their doors; each room is free inside.
        let p = room as i32 + 1;
        for c in grid.free_cells() {
            if c.x % p == 0 && c.y % p == 0 {
                panic!("a door at a wall crossing {c}");
            }
        }
        assert!(grid.free_cells().filter(|c| c.x % p == 0 || c.y % p == 0).count() > 0);
        assert!(!grid.is_blocked(Cell::new(1, 1)));
    }
    assert_ne!(rooms(64, 7, 0), rooms(64, 7, 1));
    assert!(matches!(rooms(9, 7, 0), Err(GenError::Kind { side: 9, .. })));
    assert!(rooms(10, 7, 0).is_ok());
    assert_eq!(rooms(0, 7, 0), Err(GenError::Size(0)));
    assert!(matches!(rooms(64, u32::MAX, 0), Err(GenError::Kind { .. })));
}
