//! Environment throughput in agent-steps per second (every step builds every agent's
//! observation), the reset of a 1024×1024 episode, and a batch of 256 episodes (run with
//! `RAYON_NUM_THREADS=1` and `=2` to read the speed-up).
//!
//! `cargo bench -p phalanx-env --bench env -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use phalanx_core::{Action, Cell, DistanceMap, Grid, Instance};
use phalanx_env::{
    Env, EnvConfig, MarlEnv, ObsBuffers, PoolConfig, PoolEnv, StepOut, step_lockstep,
};
use phalanx_gen::{GenConfig, generate, random_grid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `n_agents` random starts and goals in the largest free region of a random wall map.
fn crowded(side: u32, density: f64, n_agents: usize, fov: u32, seed: u64) -> Instance {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let grid: Grid = random_grid(side, side, density, fov / 2, &[], &mut rng);
    let free: Vec<Cell> = grid.free_cells().collect();
    loop {
        let source = free[rng.random_range(0..free.len() as u32) as usize];
        let dm = DistanceMap::bfs(&grid, source);
        let mut region: Vec<Cell> = free.iter().copied().filter(|&c| dm.get(c).is_some()).collect();
        if region.len() < free.len() / 2 {
            continue;
        }
        let mut pick = |rng: &mut ChaCha8Rng| {
            for i in 0..n_agents {
                let j = rng.random_range(i as u32..region.len() as u32) as usize;
                region.swap(i, j);
            }
            region[..n_agents].to_vec()
        };
        let starts = pick(&mut rng);
        let goals = pick(&mut rng);
        return Instance::new(grid, starts, goals).expect("one region");
    }
}

/// Steps one episode with random actions, observing every agent every step.
fn bench_steps(c: &mut Criterion, name: &str, inst: &Instance, fov: u32) {
    let n = inst.n_agents();
    let config = EnvConfig { fov, step_limit: Some(u32::MAX), ..EnvConfig::default() };
    let mut env = Env::new(config).unwrap();
    env.reset(inst).unwrap();
    let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let actions: Vec<Action> =
        (0..n * 4096).map(|_| Action::ALL[rng.random_range(0..5u32) as usize]).collect();
    let mut group = c.benchmark_group("env_step");
    group.throughput(Throughput::Elements(n as u64));
    let mut t = 0;
    group.bench_function(BenchmarkId::new(name, n), |b| {
        b.iter(|| {
            if env.is_done() {
                env.reset(inst).unwrap();
            }
            let chunk = &actions[(t % 4096) * n..(t % 4096 + 1) * n];
            t += 1;
            black_box(env.step(chunk).team_reward);
            env.observe(&mut obs);
            black_box(&obs.grid);
        })
    });
    group.finish();
    // What was timed kept the world consistent.
    let mut cells = env.positions().to_vec();
    cells.sort_unstable();
    cells.dedup();
    assert_eq!(cells.len(), n, "two agents in one cell");
}

fn steps(c: &mut Criterion) {
    let small =
        generate(&GenConfig { size: 32, density: 0.15, n_agents: 3, seed: 1, fov: 9 }).unwrap();
    bench_steps(c, "32x32_d0.15_fov9", &small, 9);
    let crowd = crowded(64, 0.3, 64, 11, 2);
    bench_steps(c, "64x64_d0.3_fov11", &crowd, 11);
}

fn reset(c: &mut Criterion) {
    let big =
        generate(&GenConfig { size: 1024, density: 0.15, n_agents: 3, seed: 3, fov: 9 }).unwrap();
    let mut env = Env::new(EnvConfig::default()).unwrap();
    env.reset(&big).unwrap();
    let mut group = c.benchmark_group("env_reset");
    group.sample_size(20);
    group.bench_function("1024x1024_3_agents", |b| {
        b.iter(|| env.reset(black_box(&big)).unwrap());
    });
    group.finish();
    assert_eq!(env.cost_to_go(0) as usize, {
        let dm = DistanceMap::bfs(big.grid(), big.goals()[0]);
        dm.get(big.starts()[0]).unwrap() as usize
    });
}

fn lockstep(c: &mut Criterion) {
    let n_envs = 256;
    let config = EnvConfig { step_limit: Some(u32::MAX), ..EnvConfig::default() };
    let first =
        PoolEnv::new(phalanx_env::Task::PathFinding, &PoolConfig::default(), config, 3).unwrap();
    let mut envs: Vec<PoolEnv> = vec![first; n_envs];
    let mut obs: Vec<ObsBuffers> =
        envs.iter().map(|env| ObsBuffers::new(env.n_agents(), env.obs_shape())).collect();
    for (seed, (env, obs)) in envs.iter_mut().zip(&mut obs).enumerate() {
        env.reset(seed as u64, obs);
    }
    let offsets: Vec<usize> = (0..n_envs).map(|e| 3 * e).collect();
    let mut outs = vec![StepOut::default(); n_envs];
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let steps: Vec<Vec<u8>> =
        (0..64).map(|_| (0..n_envs * 3).map(|_| rng.random_range(0..5u8)).collect()).collect();
    let threads = rayon::current_num_threads();
    let mut group = c.benchmark_group("env_lockstep");
    group.throughput(Throughput::Elements((n_envs * 3) as u64));
    let mut t = 0;
    group.bench_function(BenchmarkId::new(format!("256x3_32x32_threads{threads}"), n_envs), |b| {
        b.iter(|| {
            step_lockstep(&mut envs, &mut obs, &steps[t % steps.len()], &offsets, &mut outs);
            t += 1;
            black_box(obs[0].grid.len());
        })
    });
    group.finish();
}

/// What the Python vector does per step, on one thread: 64 environments of generated
/// episodes, each stepped with random actions and observed (channels, goal vector, mask,
/// leader order), an ended episode replaced at once by the generated one of the next seed.
fn vector(c: &mut Criterion) {
    let n_envs = 64;
    let mut group = c.benchmark_group("env_vector");
    for (agents, size, density) in [(3, 32, 0.15), (25, 64, 0.3)] {
        let gen_config = |seed| GenConfig { size, density, n_agents: agents, seed, fov: 9 };
        let mut envs: Vec<(Env, u64)> = (0..n_envs as u64)
            .map(|seed| {
                let mut env = Env::new(EnvConfig::default()).unwrap();
                env.reset(&generate(&gen_config(seed)).unwrap()).unwrap();
                (env, seed)
            })
            .collect();
        let mut obs = ObsBuffers::new(agents, envs[0].0.obs_shape());
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let actions: Vec<Action> =
            (0..agents * 4096).map(|_| Action::ALL[rng.random_range(0..5u32) as usize]).collect();
        let mut t = 0;
        group.throughput(Throughput::Elements((n_envs * agents) as u64));
        let name = format!("{n_envs}x{agents}_{size}x{size}_d{density}");
        group.bench_function(BenchmarkId::new(name, agents), |b| {
            b.iter(|| {
                for (env, seed) in &mut envs {
                    let chunk = &actions[(t % 4096) * agents..(t % 4096 + 1) * agents];
                    t += 1;
                    let step = env.step(chunk);
                    if step.terminated || step.truncated {
                        env.observe(&mut obs);
                        *seed += n_envs as u64;
                        env.reset(&generate(&gen_config(*seed)).unwrap()).unwrap();
                    }
                    env.observe(&mut obs);
                    env.begin_turns(phalanx_env::LeaderRule::PathFinding);
                    black_box(&obs.grid);
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, steps, reset, lockstep, vector);
criterion_main!(benches);
