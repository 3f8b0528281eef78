//! The environment's step allocates nothing in steady state: a counting global allocator
//! counts every heap allocation of the process while episodes step after a warm-up: single
//! episodes with sequential acting, and the lockstep step training takes
//! ([`step_lockstep`] over [`PoolEnv`]s of mixed team sizes) on rayon pools of one and of
//! two threads.
//!
//! Its own binary without the test harness, so that nothing else allocates meanwhile.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use phalanx_core::{Action, Instance};
use phalanx_env::{
    Env, EnvConfig, LeaderRule, MarlEnv, ObsBuffers, PoolConfig, PoolEnv, StepOut, Task, TrainPool,
    step_lockstep,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: defers to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `f`.
fn count(f: impl FnOnce()) -> usize {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    f();
    COUNTING.store(false, Ordering::SeqCst);
    ALLOCATIONS.load(Ordering::SeqCst)
}

fn random_actions(rng: &mut ChaCha8Rng, n: usize) -> Vec<Action> {
    (0..n).map(|_| Action::ALL[rng.random_range(0..5u32) as usize]).collect()
}

fn single_episodes(instances: &[Instance], rng: &mut ChaCha8Rng) -> usize {
    let mut env = Env::new(EnvConfig { task: Task::Meta, ..EnvConfig::default() }).unwrap();
    env.reset(&instances[0]).unwrap();
    let mut obs = ObsBuffers::new(env.n_agents(), env.obs_shape());
    let actions = random_actions(rng, 3 * 200);
    let mut run = |env: &mut Env| {
        for chunk in actions.chunks(3) {
            if env.is_done() {
                break;
            }
            env.begin_turns(LeaderRule::Formation);
            for &action in chunk {
                env.choose(action);
            }
            env.step_chosen();
            env.observe(&mut obs);
        }
    };
    run(&mut env);
    env.reset(&instances[1]).unwrap();
    count(|| run(&mut env))
}

fn lockstep(task: Task, threads: usize, rng: &mut ChaCha8Rng) -> usize {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let config = PoolConfig { n_maps: 4, ..PoolConfig::default() };
    let first = PoolEnv::new(task, &config, EnvConfig::default(), 3).unwrap();
    let mut envs: Vec<PoolEnv> = (0..24).map(|e| first.with_agents(3 + e % 3).unwrap()).collect();
    let mut obs: Vec<ObsBuffers> =
        envs.iter().map(|env| ObsBuffers::new(env.n_agents(), env.obs_shape())).collect();
    let mut offsets = Vec::new();
    let mut rows = 0;
    for (seed, (env, obs)) in envs.iter_mut().zip(&mut obs).enumerate() {
        env.reset(seed as u64, obs);
        offsets.push(rows);
        rows += env.n_agents();
    }
    let mut outs = vec![StepOut::default(); envs.len()];
    // 40 steps: no episode ends (none reaches its goals or formation; the limit is 96).
    let steps: Vec<Vec<u8>> =
        (0..40).map(|_| (0..rows).map(|_| rng.random_range(0..5u8)).collect()).collect();
    pool.install(|| {
        for actions in &steps[..10] {
            step_lockstep(&mut envs, &mut obs, actions, &offsets, &mut outs);
        }
        count(|| {
            for actions in &steps[10..] {
                step_lockstep(&mut envs, &mut obs, actions, &offsets, &mut outs);
            }
        })
    })
}

fn main() {
    let pool = TrainPool::new(&PoolConfig { n_maps: 4, ..PoolConfig::default() }).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let instances: Vec<Instance> = (0..64).map(|_| pool.sample(3, &mut rng)).collect();
    let single = single_episodes(&instances, &mut rng);
    let mut lockstep_counts = Vec::new();
    for task in [Task::PathFinding, Task::Formation] {
        for threads in [1, 2] {
            lockstep_counts.push((task, threads, lockstep(task, threads, &mut rng)));
        }
    }
    let report = format!(
        "allocations: single {single}, lockstep (task, threads, count) {lockstep_counts:?}"
    );
    assert!(single == 0 && lockstep_counts.iter().all(|it| it.2 == 0), "{report}");
    std::io::Write::write_all(&mut std::io::stdout(), format!("{report}\n").as_bytes()).unwrap();
}
