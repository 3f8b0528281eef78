//! The environment's step allocates nothing in steady state: a counting global allocator
//! counts every heap allocation of the process while episodes step after a warm-up (single
//! episodes, batches on a rayon pool of one and of two threads, and sequential acting).
//!
//! Its own binary without the test harness, so that nothing else allocates meanwhile.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use phalanx_core::{Action, Instance};
use phalanx_env::{BatchEnv, Env, EnvConfig, LeaderRule, ObsBuf, PoolConfig, Task, TrainPool};
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
    let mut obs = ObsBuf::new(env.layout(), 1);
    let actions = random_actions(rng, 3 * 200);
    let mut run = |env: &mut Env| {
        for chunk in actions.chunks(3) {
            if env.is_done() {
                break;
            }
            env.step(chunk);
            env.observe_into(&mut obs);
            env.begin_turns(LeaderRule::Formation);
        }
    };
    run(&mut env);
    env.reset(&instances[1]).unwrap();
    count(|| run(&mut env))
}

fn batch(instances: &[Instance], threads: usize, rng: &mut ChaCha8Rng) -> usize {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let mut batch = BatchEnv::new(EnvConfig::default(), instances.len(), 3).unwrap();
    batch.reset_all(instances).unwrap();
    let steps: Vec<Vec<Action>> =
        (0..40).map(|_| random_actions(rng, 3 * instances.len())).collect();
    let turns = [Action::Up; 64];
    pool.install(|| {
        for actions in &steps[..10] {
            batch.step(actions);
        }
        count(|| {
            for actions in &steps[10..30] {
                batch.step(actions);
            }
            for _ in 0..5 {
                batch.begin_turns(LeaderRule::PathFinding);
                for _ in 0..3 {
                    batch.choose(&turns[..instances.len()]);
                }
                batch.step_chosen();
            }
        })
    })
}

fn main() {
    let pool = TrainPool::new(&PoolConfig { n_maps: 4, ..PoolConfig::default() }).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let instances: Vec<Instance> = (0..64).map(|_| pool.sample(3, &mut rng)).collect();
    let single = single_episodes(&instances, &mut rng);
    let one = batch(&instances, 1, &mut rng);
    let two = batch(&instances, 2, &mut rng);
    let report =
        format!("allocations: single {single}, batch on 1 thread {one}, on 2 threads {two}");
    assert_eq!((single, one, two), (0, 0, 0), "{report}");
    std::io::Write::write_all(&mut std::io::stdout(), format!("{report}\n").as_bytes()).unwrap();
}
