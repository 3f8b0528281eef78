//! The lockstep step of training ([`step_lockstep`]): the same observations and outcomes as
//! stepping each environment alone, and the same result on any thread count.

use phalanx_env::{
    EnvConfig, MarlEnv, ObsBuffers, PoolConfig, PoolEnv, StepOut, Task, step_lockstep,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Environments of `task` with teams of 3, 4 and 5 in turn, reset from seeds `0..n`.
fn make(task: Task, n: usize) -> (Vec<PoolEnv>, Vec<ObsBuffers>) {
    let pool = PoolConfig { n_maps: 8, ..PoolConfig::default() };
    let first = PoolEnv::new(task, &pool, EnvConfig::default(), 3).unwrap();
    let mut envs: Vec<PoolEnv> = (0..n).map(|e| first.with_agents(3 + e % 3).unwrap()).collect();
    let mut obs: Vec<ObsBuffers> =
        envs.iter().map(|env| ObsBuffers::new(env.n_agents(), env.obs_shape())).collect();
    for (seed, (env, obs)) in envs.iter_mut().zip(&mut obs).enumerate() {
        env.reset(seed as u64, obs);
    }
    (envs, obs)
}

/// Every buffer and outcome of `n_steps` random lockstep steps (ended episodes restart).
fn run(task: Task, n_steps: usize) -> (Vec<ObsBuffers>, Vec<StepOut>) {
    let (mut envs, mut obs) = make(task, 12);
    let offsets: Vec<usize> = envs
        .iter()
        .scan(0, |at, env| {
            let here = *at;
            *at += env.n_agents();
            Some(here)
        })
        .collect();
    let rows: usize = envs.iter().map(MarlEnv::n_agents).sum();
    let mut outs = vec![StepOut::default(); envs.len()];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut trace = (Vec::new(), Vec::new());
    for t in 0..n_steps {
        let actions: Vec<u8> = (0..rows).map(|_| rng.random_range(0..5u8)).collect();
        step_lockstep(&mut envs, &mut obs, &actions, &offsets, &mut outs);
        trace.0.extend(obs.iter().cloned());
        trace.1.extend_from_slice(&outs);
        for (e, out) in outs.iter().enumerate() {
            if out.terminated || out.truncated {
                envs[e].reset((1000 + t * 12 + e) as u64, &mut obs[e]);
            }
        }
    }
    trace
}

#[test]
fn lockstep_is_the_same_on_any_thread_count() {
    for task in [Task::PathFinding, Task::Formation] {
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        let a = one.install(|| run(task, 40));
        let b = four.install(|| run(task, 40));
        assert!(a == b, "{task:?}: results differ between 1 and 4 threads");
    }
}

#[test]
fn lockstep_equals_stepping_each_environment_alone() {
    let (mut envs, mut obs) = make(Task::PathFinding, 6);
    let (mut alone, mut alone_obs) = make(Task::PathFinding, 6);
    let offsets: Vec<usize> = (0..6).map(|e| (0..e).map(|k| 3 + k % 3).sum()).collect();
    let mut outs = vec![StepOut::default(); 6];
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..30 {
        let actions: Vec<u8> = (0..24).map(|_| rng.random_range(0..5u8)).collect();
        if outs.iter().any(|out| out.terminated || out.truncated) {
            break;
        }
        step_lockstep(&mut envs, &mut obs, &actions, &offsets, &mut outs);
        for e in 0..6 {
            let n = alone[e].n_agents();
            let out = alone[e].step(&actions[offsets[e]..offsets[e] + n], &mut alone_obs[e]);
            assert_eq!(out, outs[e]);
            assert_eq!(alone_obs[e], obs[e]);
        }
    }
}
