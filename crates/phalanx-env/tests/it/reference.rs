//! A slow, obviously correct environment (naive fixed-point collision resolution,
//! observations built cell by cell from fresh BFS maps) checked against the fast one on
//! random states.

use phalanx_core::{Action, Cell, DistanceMap, Grid, Instance};
use phalanx_env::obs::COST_SENTINEL;
use phalanx_env::{Clip, Env, EnvConfig, ObsBuffers, Task};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Positions after the joint action and the cancelled flags: cancel blocked moves, then
/// repeatedly cancel every mover in a vertex conflict or a swap until nothing changes.
pub(crate) fn slow_resolve(
    grid: &Grid,
    pos: &[Cell],
    actions: &[Action],
) -> (Vec<Cell>, Vec<bool>) {
    let n = pos.len();
    let mut cancelled: Vec<bool> =
        (0..n).map(|i| grid.is_blocked(actions[i].apply(pos[i]))).collect();
    loop {
        let next: Vec<Cell> =
            (0..n).map(|i| if cancelled[i] { pos[i] } else { actions[i].apply(pos[i]) }).collect();
        let mut changed = false;
        for i in 0..n {
            if next[i] == pos[i] {
                continue;
            }
            let vertex = (0..n).any(|j| j != i && next[j] == next[i]);
            let swap = (0..n).any(|j| j != i && next[j] == pos[i] && pos[j] == next[i]);
            if vertex || swap {
                cancelled[i] = true;
                changed = true;
            }
        }
        if !changed {
            return (next, cancelled);
        }
    }
}

/// Agent `agent`'s four channels, cell by cell from the documented encoding.
pub(crate) fn slow_grid(
    grid: &Grid,
    pos: &[Cell],
    goals: &[Cell],
    fov: usize,
    agent: usize,
) -> Vec<f32> {
    let n = pos.len();
    let r = (fov / 2) as i32;
    let k = (fov - 1) as i32;
    let dm = DistanceMap::bfs(grid, goals[agent]);
    let own = dm.get(pos[agent]).unwrap() as i32;
    let ident = |j: usize| (j + 1) as f32 / n as f32;
    let mut out = vec![0.0; 4 * fov * fov];
    for row in 0..fov {
        for col in 0..fov {
            let cell = pos[agent].offset(col as i32 - r, row as i32 - r);
            let at = |ch: usize| (ch * fov + row) * fov + col;
            out[at(0)] = if grid.is_blocked(cell) { 1.0 } else { 0.0 };
            if let Some(j) = pos.iter().position(|&p| p == cell) {
                out[at(1)] = ident(j);
            }
            let parked = (0..n).any(|j| j != agent && pos[j] == cell && goals[j] == cell);
            out[at(2)] = match dm.get(cell) {
                _ if parked => COST_SENTINEL,
                None => COST_SENTINEL,
                // Multiplying by the reciprocal, as the fast writer does (the same up to rounding).
                Some(d) => (d as i32 - own).clamp(-k, k) as f32 * (1.0 / k as f32),
            };
            let goal_cell = goals[agent].offset(col as i32 - r, row as i32 - r);
            if let Some(j) = goals.iter().position(|&g| g == goal_cell) {
                out[at(3)] = ident(j);
            }
        }
    }
    out
}

/// Agent `agent`'s mask under `clip`.
fn slow_mask(grid: &Grid, pos: &[Cell], goals: &[Cell], clip: Clip, agent: usize) -> Vec<bool> {
    let dm = DistanceMap::bfs(grid, goals[agent]);
    Action::ALL
        .iter()
        .map(|&a| {
            let to = a.apply(pos[agent]);
            match clip {
                _ if a == Action::Wait => true,
                Clip::None => true,
                Clip::Formation => grid.is_free(to),
                Clip::PathFinding => dm.get(to).is_some_and(|d| d <= dm.get(pos[agent]).unwrap()),
            }
        })
        .collect()
}

/// A random instance on a small map, drawn from `seed`.
pub(crate) fn random_instance(seed: u64, max_side: u32, max_agents: usize) -> Instance {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        let (w, h) = (rng.random_range(2..=max_side), rng.random_range(1..=max_side));
        let density = rng.random_range(0.0..0.35);
        let grid = Grid::from_fn(w, h, |_| rng.random_bool(density));
        let mut free: Vec<Cell> = grid.free_cells().collect();
        let n = rng.random_range(1..=max_agents);
        if free.len() < n {
            continue;
        }
        let mut pick = |free: &mut Vec<Cell>| {
            let mut cells = free.clone();
            for i in 0..n {
                let j = rng.random_range(i..cells.len());
                cells.swap(i, j);
            }
            cells.truncate(n);
            cells
        };
        let starts = pick(&mut free);
        let goals = pick(&mut free);
        if let Ok(inst) = Instance::new(grid, starts, goals) {
            return inst;
        }
    }
}

fn task_of(idx: u8) -> Task {
    [Task::PathFinding, Task::Formation, Task::Meta][idx as usize % 3]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn fast_env_matches_the_reference(
        seed in any::<u64>(),
        fov_half in 1usize..=4,
        task in any::<u8>(),
        actions in proptest::collection::vec(0usize..5, 0..60),
    ) {
        let inst = random_instance(seed, 8, 4);
        let fov = 2 * fov_half + 1;
        let task = task_of(task);
        let config = EnvConfig { fov: fov as u32, task, ..EnvConfig::default() };
        let mut env = Env::new(config).unwrap();
        env.reset(&inst).unwrap();
        let n = inst.n_agents();
        let grid = inst.grid();
        let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
        let mut pos = inst.starts().to_vec();
        for (t, chunk) in actions.chunks(n).enumerate() {
            // Observation of the current state.
            env.observe(&mut obs);
            for agent in 0..n {
                let slow = slow_grid(grid, &pos, inst.goals(), fov, agent);
                prop_assert_eq!(obs.grid_of(agent), &slow[..], "t {} agent {}", t, agent);
                let mask = slow_mask(grid, &pos, inst.goals(), task.clip(), agent);
                prop_assert_eq!(obs.mask_of(agent), &mask[..]);
                let [ux, uy, d] = env.goal_vector(agent);
                let v = obs.vec_of(agent);
                prop_assert!((f64::from(v[0]) - ux).abs() < 1e-6 && (f64::from(v[1]) - uy).abs() < 1e-6);
                prop_assert!((f64::from(v[2]) - d / (d + fov as f64)).abs() < 1e-6);
            }
            if chunk.len() < n || env.is_done() {
                break;
            }
            let joint: Vec<Action> = chunk.iter().map(|&a| Action::from_index(a).unwrap()).collect();
            let (next, cancelled) = slow_resolve(grid, &pos, &joint);
            let step = env.step(&joint);
            prop_assert_eq!(step.info.cancelled, &cancelled[..]);
            prop_assert_eq!(step.info.n_cancelled as usize, cancelled.iter().filter(|&&x| x).count());
            let team: f32 = step.rewards.iter().sum();
            prop_assert!((team - step.team_reward).abs() < 1e-3);
            pos = next;
            prop_assert_eq!(env.positions(), &pos[..]);
            for i in 0..n {
                for j in 0..i {
                    prop_assert_ne!(pos[i], pos[j]);
                }
            }
        }
    }
}
