//! Greedy evaluation of a policy on given instances, many episodes in lockstep.
//!
//! Each instance runs as one episode of a [`TaskEnv`] of the task (its rewards, clipping and
//! leader rule), the policy acting greedily (ε = 0) in leader order with action messages, until
//! the task terminates (all agents on their goals; for [`Task::Formation`], `L_f = 0`) or the
//! step limit truncates it. Instances go through in batches of `batch` episodes, one batched
//! policy call per step; an episode that has ended stops stepping while its batch finishes.
//! Greedy acting is deterministic, and the random actions of extra [`Rollouts`] come from
//! seeded streams, so the figures depend only on the policy, the instances and the seed (not
//! on the thread count).

use phalanx_core::Instance;
use phalanx_env::{EnvConfig, EnvError, Task};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::policy::{Policy, row_offsets};
use phalanx_env::{ObsBuffers, TaskEnv};

/// What one evaluated episode measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalEpisode {
    /// Agents.
    pub n_agents: usize,
    /// The task terminated within the step limit.
    pub success: bool,
    /// Steps run (the makespan when `success`).
    pub steps: usize,
    /// Shortest-path lower bound on the makespan: the largest single-agent BFS distance from
    /// start to goal.
    pub lower_bound: u32,
    /// Moves cancelled by collisions.
    pub collisions: u64,
    /// Table II formation loss: `Σ_{t=1..steps} L_f(t)` divided by the map side.
    pub formation_loss: f64,
    /// `L_f` after the last step.
    pub final_formation_loss: f64,
}

/// Test-time rollouts (SPEC §6, the paper's protocol for decentralised methods): each
/// instance is played `count` times, the first greedily, the others with a random allowed
/// action taken with probability `epsilon` per agent and step; the best rollout counts
/// (solved before unsolved, then fewer steps, then lower formation loss).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Rollouts {
    /// Rollouts per instance (at least 1).
    pub count: usize,
    /// Probability of a random action in the rollouts after the first.
    pub epsilon: f64,
    /// Seed of the random actions.
    pub seed: u64,
}

impl Default for Rollouts {
    /// One greedy rollout.
    fn default() -> Self {
        Rollouts { count: 1, epsilon: 0.0, seed: 0 }
    }
}

/// Runs `policy` on every instance (in order) for `task` with the field of view and step
/// limit of `env`, `batch` episodes at a time, `rollouts` times each (see [`Rollouts`]);
/// `progress` is called once per finished batch with the number of instances done so far.
///
/// # Errors
/// If the simulator refuses an instance (field of view, agent count).
pub fn evaluate(
    policy: &mut Policy,
    task: Task,
    env: &EnvConfig,
    instances: &[Instance],
    batch: usize,
    rollouts: Rollouts,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<EvalEpisode>, EnvError> {
    let mut res: Vec<EvalEpisode> = Vec::with_capacity(instances.len());
    for (c, chunk) in instances.chunks(batch.max(1)).enumerate() {
        let mut best = play(policy, task, env, chunk, 0.0, &mut ChaCha8Rng::seed_from_u64(0))?;
        for r in 1..rollouts.count {
            let mut rng = ChaCha8Rng::seed_from_u64(rollouts.seed);
            rng.set_stream(((c as u64) << 20) | r as u64);
            let again = play(policy, task, env, chunk, rollouts.epsilon, &mut rng)?;
            for (kept, new) in best.iter_mut().zip(again) {
                if better(&new, kept) {
                    *kept = new;
                }
            }
        }
        res.extend(best);
        progress(res.len());
    }
    Ok(res)
}

/// Solved before unsolved, then fewer steps, then lower formation loss.
fn better(a: &EvalEpisode, b: &EvalEpisode) -> bool {
    (!a.success, a.steps, a.formation_loss) < (!b.success, b.steps, b.formation_loss)
}

/// One rollout of every instance of `chunk` in lockstep.
fn play(
    policy: &mut Policy,
    task: Task,
    env: &EnvConfig,
    chunk: &[Instance],
    epsilon: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<EvalEpisode>, EnvError> {
    let mut envs = Vec::with_capacity(chunk.len());
    let mut obs = Vec::with_capacity(chunk.len());
    let mut episodes = Vec::with_capacity(chunk.len());
    for instance in chunk {
        let mut task_env = TaskEnv::new(task, env.clone(), instance.n_agents())?;
        let mut buffers = ObsBuffers::new(instance.n_agents(), task_env.obs_shape());
        task_env.reset_to(instance, &mut buffers)?;
        let sim = task_env.env();
        let lower_bound = (0..instance.n_agents()).map(|a| sim.cost_to_go(a)).max();
        episodes.push(EvalEpisode {
            n_agents: instance.n_agents(),
            success: sim.is_done(),
            steps: 0,
            lower_bound: lower_bound.unwrap_or(0),
            collisions: 0,
            formation_loss: 0.0,
            final_formation_loss: sim.formation_loss(),
        });
        envs.push(task_env);
        obs.push(buffers);
    }
    let offsets = row_offsets(chunk.iter().map(Instance::n_agents));
    let mut running: Vec<bool> = episodes.iter().map(|it| !it.success).collect();
    let mut actions = vec![0_u8; chunk.iter().map(Instance::n_agents).sum()];
    policy.reset();
    while running.contains(&true) {
        policy.act_batch(&obs, epsilon, rng, &mut actions, None);
        for (e, task_env) in envs.iter_mut().enumerate() {
            let (at, n) = (offsets[e], chunk[e].n_agents());
            if running[e] {
                let out = task_env.step(&actions[at..at + n], &mut obs[e]);
                let episode = &mut episodes[e];
                let loss = task_env.env().formation_loss();
                episode.steps += 1;
                episode.collisions += u64::from(out.collisions);
                episode.formation_loss += loss;
                episode.final_formation_loss = loss;
                episode.success = out.terminated;
                running[e] = !(out.terminated || out.truncated);
            }
        }
    }
    for (episode, instance) in episodes.iter_mut().zip(chunk) {
        episode.formation_loss /= f64::from(instance.grid().side());
    }
    Ok(episodes)
}

/// Aggregates of [`evaluate`]'s episodes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalSummary {
    /// Episodes.
    pub episodes: usize,
    /// Fraction of episodes that terminated within the step limit.
    pub success_rate: f64,
    /// Mean steps of the successful episodes (the makespan in path finding; the steps to
    /// reach the formation in formation episodes); `NaN` (JSON `null`) without success.
    pub makespan: f64,
    /// Mean shortest-path lower bound of the successful episodes.
    pub lower_bound: f64,
    /// `makespan / lower_bound` (the mean makespan over the mean lower bound).
    pub makespan_ratio: f64,
    /// Mean cancelled moves per episode.
    pub collisions: f64,
    /// Mean Table II formation loss (`Σ L_f / side`) per episode.
    pub formation_loss: f64,
    /// Mean `L_f` after the last step.
    pub final_formation_loss: f64,
}

impl EvalSummary {
    /// Summarise evaluated episodes.
    pub fn of(episodes: &[EvalEpisode]) -> Self {
        let n = episodes.len().max(1) as f64;
        let solved: Vec<&EvalEpisode> = episodes.iter().filter(|it| it.success).collect();
        let mean_solved = |f: &dyn Fn(&EvalEpisode) -> f64| {
            if solved.is_empty() {
                f64::NAN
            } else {
                solved.iter().map(|it| f(it)).sum::<f64>() / solved.len() as f64
            }
        };
        let makespan = mean_solved(&|it| it.steps as f64);
        let lower_bound = mean_solved(&|it| f64::from(it.lower_bound));
        Self {
            episodes: episodes.len(),
            success_rate: solved.len() as f64 / n,
            makespan,
            lower_bound,
            makespan_ratio: makespan / lower_bound,
            collisions: episodes.iter().map(|it| it.collisions as f64).sum::<f64>() / n,
            formation_loss: episodes.iter().map(|it| it.formation_loss).sum::<f64>() / n,
            final_formation_loss: episodes.iter().map(|it| it.final_formation_loss).sum::<f64>()
                / n,
        }
    }
}
