//! Soak: evaluation episodes one batch after another in one process hold no more memory at
//! the end than after the first batch. A counting global allocator tracks the bytes the
//! process holds; each batch's instances and results are dropped once summed, so what could
//! grow is the policy, the environments and their buffers.
//!
//! Its own binary without the test harness (nothing else allocates meanwhile). By default
//! 128 episodes; `PHALANX_SOAK_EPISODES=10000 cargo test --release -p phalanx-rl --test
//! soak` is the long soak of docs/learning.md.

#![allow(clippy::print_stdout, reason = "the soak reports its figures")]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use phalanx_env::{EnvConfig, EvalMaps, GenConfig, Task};
use phalanx_rl::{Rollouts, evaluate};

struct Counting;

static HELD: AtomicUsize = AtomicUsize::new(0);

// SAFETY: defers to the system allocator; only counts the bytes held.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        HELD.fetch_add(layout.size(), Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        HELD.fetch_add(new_size, Ordering::Relaxed);
        HELD.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Episodes per batch.
const BATCH: usize = 32;

fn main() {
    let episodes: usize =
        std::env::var("PHALANX_SOAK_EPISODES").ok().and_then(|it| it.parse().ok()).unwrap_or(128);
    let (mut policy, _) =
        phalanx_rl::models::load(None, "pathfinding").expect("the shipped policy");
    let env = EnvConfig { step_limit: Some(48), ..EnvConfig::default() };
    let maps = EvalMaps::new(GenConfig { size: 16, density: 0.15, n_agents: 3, seed: 9, fov: 9 });
    let rollouts = Rollouts { count: 1, epsilon: 0.0, seed: 0, ..Rollouts::default() };
    let (mut after_first, mut solved, mut done) = (None, 0, 0);
    while done < episodes {
        let n = BATCH.min(episodes - done);
        let instances: Vec<_> =
            (done..done + n).map(|i| maps.instance(i as u64).expect("an instance")).collect();
        let results = evaluate(
            &mut policy,
            Task::PathFinding,
            &env,
            &instances,
            BATCH,
            rollouts,
            &mut |_| {},
        )
        .expect("evaluating");
        solved += results.iter().filter(|it| it.success).count();
        done += n;
        drop((instances, results));
        after_first.get_or_insert(HELD.load(Ordering::SeqCst));
    }
    let (start, end) = (after_first.unwrap_or_default(), HELD.load(Ordering::SeqCst));
    println!(
        "soak: {done} episodes ({solved} solved), {start} bytes held after the first batch, \
         {end} at the end"
    );
    assert!(solved > done / 2, "the policy solves most episodes ({solved} of {done})");
    assert!(end <= start + 64 * 1024, "memory grew from {start} to {end} bytes");
}
