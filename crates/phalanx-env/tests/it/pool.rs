//! Training pool, evaluation stream and formation-training episodes.

use phalanx_core::formation_loss;
use phalanx_env::{
    Env, EnvConfig, EvalMaps, GenConfig, MapKind, PoolConfig, Task, TrainPool, WIDE_SIDE,
    eval_seed, formation_instance, train_seed,
};
use phalanx_gen::{MAZE_CORRIDOR, ROOM_SIDE};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn training_and_evaluation_seeds_never_meet() {
    for base in [0, 1, u64::MAX] {
        for i in 0..10_000 {
            assert!(train_seed(base, i) >> 63 == 0);
            assert!(eval_seed(base, i) >> 63 == 1);
        }
    }
    let maps = EvalMaps::new(GenConfig { size: 32, density: 0.15, n_agents: 3, fov: 9, seed: 0 });
    assert!((0..100).all(|i| maps.seed(i) != train_seed(0, i)));
}

#[test]
fn paper_pool_is_deterministic_and_dense_enough() {
    let pool = TrainPool::new(&PoolConfig::default()).unwrap();
    assert_eq!(pool.len(), 100);
    let again = TrainPool::new(&PoolConfig::default()).unwrap();
    for i in 0..100 {
        assert_eq!(pool.map(i), again.map(i));
        assert_eq!((pool.map(i).width(), pool.map(i).height()), (32, 32));
        assert!((pool.map(i).density() - 0.15).abs() < 0.01);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    for _ in 0..50 {
        let inst = pool.sample(5, &mut rng);
        assert_eq!(formation_loss(inst.starts(), inst.goals()), 0.0);
    }
}

#[test]
fn a_share_of_the_episodes_start_in_wide_formations() {
    let pool = TrainPool::new(&PoolConfig { n_maps: 10, ..PoolConfig::default() }).unwrap();
    // A share of 0 draws exactly what `sample` draws, and leaves the stream where it does.
    let (mut a, mut b) = (ChaCha8Rng::seed_from_u64(3), ChaCha8Rng::seed_from_u64(3));
    for _ in 0..20 {
        assert_eq!(pool.sample_episode(4, 0.0, &mut a), pool.sample(4, &mut b));
    }
    assert_eq!(a, b);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut wide = 0;
    for _ in 0..40 {
        let inst = pool.sample_episode(4, 1.0, &mut rng);
        let (starts, goals) = (inst.starts(), inst.goals());
        assert_eq!(formation_loss(starts, goals), 0.0, "the goals translate the starts");
        // Wide: drawn from the top-left square, translated into the bottom-right one; else
        // (no free draw) the pool's own regions of 5 cells a side.
        let side = starts.iter().map(|c| c.x.max(c.y)).max().unwrap() + 1;
        let shift = goals[0].x - starts[0].x;
        assert!(starts.iter().zip(goals).all(|(s, g)| g.x - s.x == shift && g.y - s.y == shift));
        if shift == 32 - WIDE_SIDE as i32 {
            assert!(side <= WIDE_SIDE as i32, "{starts:?}");
            wide += usize::from(side > 5);
        } else {
            assert_eq!(shift, 32 - 5, "the pool's own: {starts:?}");
            assert!(side <= 5, "{starts:?}");
        }
    }
    assert!(wide >= 30, "{wide} of 40 teams wider than the pool's 5 cells");
    // Maps no wider than the square have no wide episodes: the pool's own are drawn.
    let small = TrainPool::new(&PoolConfig { n_maps: 2, size: 10, ..PoolConfig::default() });
    let small = small.unwrap();
    assert!(small.sample_wide(3, &mut rng).is_none());
    let inst = small.sample_episode(3, 1.0, &mut rng);
    assert!(inst.starts().iter().all(|c| c.x.max(c.y) < 5));
}

#[test]
fn formation_episodes_see_a_neighbour_and_end_in_formation() {
    let pool = TrainPool::new(&PoolConfig { n_maps: 10, ..PoolConfig::default() }).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in [2, 3, 4, 6] {
        for _ in 0..20 {
            let inst = pool.sample_formation(k, &mut rng).unwrap();
            let s = inst.starts();
            for i in 0..k {
                let sees = (0..k).any(|j| {
                    j != i && s[i].x.abs_diff(s[j].x) <= 4 && s[i].y.abs_diff(s[j].y) <= 4
                });
                assert!(sees, "agent {i} sees nobody in {s:?}");
            }
            assert!(formation_loss(s, inst.goals()) > 0.0);
        }
    }
    // Walking every agent to its goal ends the formation episode at L_f = 0 or at the limit.
    let inst = formation_instance(pool.map(0), 3, 9, &mut rng).unwrap();
    let mut env = Env::new(EnvConfig { task: Task::Formation, ..EnvConfig::default() }).unwrap();
    env.reset(&inst).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let (trajectory, _) =
        phalanx_env::sim::rollout(&mut env, &inst, &phalanx_env::sim::SimPolicy::Greedy, &mut rng)
            .unwrap();
    let last = trajectory.at(trajectory.horizon());
    let ended_in_formation = formation_loss(last, inst.goals()) == 0.0;
    assert!(ended_in_formation || trajectory.horizon() == env.step_limit() as usize);
    // The episode ends at the first step in formation, never later.
    assert!(
        (0..trajectory.horizon()).all(|t| formation_loss(trajectory.at(t), inst.goals()) > 0.0)
    );
}

/// The checked-in MovingAI maps (`test-data/movingai`).
fn movingai(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../test-data/movingai").join(name)
}

#[test]
fn a_pool_of_ones_own_maps_places_formations_on_them() {
    let warehouse = movingai("warehouse-10-20-10-2-1.map");
    let room = movingai("room-64-64-8.map");
    let config = PoolConfig { maps: vec![warehouse, room], ..PoolConfig::default() };
    let pool = TrainPool::new(&config).unwrap();
    assert!(pool.is_own());
    assert_eq!(pool.len(), 2);
    let sides: Vec<(u32, u32)> =
        (0..2).map(|i| (pool.map(i).width(), pool.map(i).height())).collect();
    assert_eq!(sides, [(161, 63), (64, 64)]);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut seen = [false; 2];
    for _ in 0..40 {
        for inst in [pool.sample(4, &mut rng), pool.sample_episode(4, 1.0, &mut rng)] {
            // Goals are the formation translated; every agent reaches its goal on the map.
            assert_eq!(formation_loss(inst.starts(), inst.goals()), 0.0);
            let on = (0..2).find(|&i| inst.grid() == pool.map(i)).expect("one of the maps");
            seen[on] = true;
            for (&s, &g) in inst.starts().iter().zip(inst.goals()) {
                assert!(phalanx_core::DistanceMap::bfs(inst.grid(), g).get(s).is_some());
            }
        }
    }
    assert_eq!(seen, [true, true], "both maps are drawn");
    // The same seed, the same episode.
    let again = TrainPool::new(&config).unwrap();
    let draw = |pool: &TrainPool| pool.sample(3, &mut ChaCha8Rng::seed_from_u64(9));
    assert_eq!(draw(&pool), draw(&again));
    // A directory holds its .map files.
    let dir = PoolConfig { maps: vec![movingai("")], ..PoolConfig::default() };
    assert_eq!(TrainPool::new(&dir).unwrap().len(), 9);
}

#[test]
fn maze_and_rooms_pools_place_formations_anywhere_on_their_maps() {
    for (kind, size) in [(MapKind::Maze, 32), (MapKind::Rooms, 64)] {
        let config = PoolConfig { n_maps: 5, size, kind, ..PoolConfig::default() };
        let pool = TrainPool::new(&config).unwrap();
        assert!(pool.is_own() && pool.len() == 5);
        let seeds = (0..5).map(|i| train_seed(0, i));
        let maps: Vec<_> = match kind {
            MapKind::Maze => seeds.map(|s| phalanx_gen::maze(size, MAZE_CORRIDOR, s)).collect(),
            _ => seeds.map(|s| phalanx_gen::rooms(size, ROOM_SIDE, s)).collect(),
        };
        assert!((0..5).all(|i| Ok(pool.map(i)) == maps[i].as_ref()));
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for n in 3..=8 {
            let inst = pool.sample_episode(n, 0.5, &mut rng);
            assert_eq!(formation_loss(inst.starts(), inst.goals()), 0.0);
        }
        // The kind is written only when it is not the paper's.
        let json = serde_json::to_string(&config).unwrap();
        assert!(
            json.contains(&format!("\"kind\":\"{}\"", ["maze", "rooms"][(size / 64) as usize]))
        );
        assert_eq!(serde_json::from_str::<PoolConfig>(&json).unwrap(), config);
    }
    assert!(!serde_json::to_string(&PoolConfig::default()).unwrap().contains("kind"));
    // A side too small for rooms is refused with the generator's reason.
    let tiny = PoolConfig { size: 9, kind: MapKind::Rooms, ..PoolConfig::default() };
    let err = TrainPool::new(&tiny).unwrap_err().to_string();
    assert!(err.contains("9x9 map holds no two rooms"), "{err}");
}

#[test]
fn own_maps_that_cannot_be_read_or_hold_no_formation_are_refused_naming_the_file() {
    let err = |maps: Vec<std::path::PathBuf>| {
        TrainPool::new(&PoolConfig { maps, ..PoolConfig::default() }).unwrap_err().to_string()
    };
    let missing = movingai("no-such.map");
    let why = err(vec![missing]);
    assert!(why.starts_with("training map:") && why.contains("no-such.map"), "{why}");
    let dir = tempfile::tempdir().unwrap();
    let walled = dir.path().join("walled.map");
    std::fs::write(&walled, "type octile\nheight 2\nwidth 2\nmap\n.@\n@@\n").unwrap();
    let why = err(vec![walled]);
    assert!(why.contains("walled.map") && why.contains("no two free cells"), "{why}");
    let empty = tempfile::tempdir().unwrap();
    let why = err(vec![empty.path().to_path_buf()]);
    assert!(why.contains("holds no .map file"), "{why}");
}
