//! The `phalanx sim` command as a library function: roll out a scripted policy (random,
//! greedy or a given plan) on one instance or on freshly generated evaluation instances and
//! report the validator's metrics and the environment's speed.

use std::time::Instant;

use phalanx_core::{Action, Instance, Plan, PlanMetrics};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use thiserror::Error;

use crate::{Env, EnvConfig, EnvError, EvalMaps, ObsBuffers};

/// Which policy drives the agents.
#[derive(Debug, Clone, PartialEq)]
pub enum SimPolicy {
    /// Uniformly random actions (ChaCha8 seeded with [`SimArgs::seed`]).
    Random,
    /// Each agent takes the first move, in action order, that lowers its BFS distance to
    /// its goal, and waits on its goal.
    Greedy,
    /// Replays a plan: agent `i` takes `Action::between(X_t[i], X_{t+1}[i])`, then waits.
    Plan(Plan),
}

/// Where the episodes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum SimSource {
    /// One episode on this instance.
    Instance(Instance),
    /// `episodes` evaluation instances (see [`EvalMaps`]) generated with these settings.
    Generated {
        /// The settings of the instances; `seed` is the stream's base seed.
        maps: phalanx_gen::GenConfig,
        /// Number of episodes.
        episodes: usize,
    },
}

/// Arguments of [`run`].
#[derive(Debug, Clone, PartialEq)]
pub struct SimArgs {
    /// The episodes.
    pub source: SimSource,
    /// The policy.
    pub policy: SimPolicy,
    /// Field of view of the observations built every step.
    pub fov: u32,
    /// Seed of the random policy and base seed of generated instances.
    pub seed: u64,
}

/// Metrics of one episode, as [`PlanMetrics::of`] computes them on the trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeReport {
    /// Generator seed of the instance (`None` for a given instance).
    pub instance_seed: Option<u64>,
    /// All agents on their goals within the step limit.
    pub success: bool,
    /// First step with all agents on their goals (steps run on failure).
    pub makespan: usize,
    /// Sum of costs.
    pub sum_of_costs: usize,
    /// Cancelled moves.
    pub collisions: u64,
    /// Σ per-step `L_f` over steps `1..=makespan`, divided by the map side (Table II).
    pub formation_loss: f64,
    /// Mean per-step `L_f`.
    pub formation_loss_mean: f64,
}

/// What `phalanx sim` prints: aggregates over the episodes, then every episode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimReport {
    /// Number of episodes.
    pub episodes: usize,
    /// Fraction of episodes solved (1 or 0 for one instance).
    pub success: f64,
    /// Mean makespan.
    pub makespan: f64,
    /// Total cancelled moves.
    pub collisions: u64,
    /// Mean of the episodes' Table II formation loss.
    pub formation_loss: f64,
    /// Agent-steps simulated (agents × steps, summed over episodes).
    pub agent_steps: u64,
    /// Wall seconds of the rollouts (policy, step and observations).
    pub seconds: f64,
    /// `agent_steps / seconds`.
    pub agent_steps_per_s: f64,
    /// Per-episode metrics.
    pub per_episode: Vec<EpisodeReport>,
}

/// Why `sim` cannot run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// The environment or the generator refused.
    #[error(transparent)]
    Env(#[from] EnvError),
    /// The plan is for another number of agents.
    #[error("the plan has {found} agents but the instance has {expected}")]
    PlanAgents {
        /// Agents of the instance.
        expected: usize,
        /// Agents of the plan.
        found: usize,
    },
    /// The plan does not begin at the instance's starts.
    #[error("the plan does not begin at the instance's starts")]
    PlanStart,
    /// A plan policy needs a given instance.
    #[error("a plan can only be replayed on its own instance")]
    PlanNeedsInstance,
    /// The plan moves an agent by more than one cell.
    #[error("the plan moves agent {agent} by more than one cell at step {step}")]
    PlanJump {
        /// Step index `t + 1`.
        step: usize,
        /// The agent.
        agent: usize,
    },
}

/// Runs the episodes and measures them.
pub fn run(args: &SimArgs) -> Result<SimReport, SimError> {
    let mut env = Env::new(EnvConfig { fov: args.fov, ..EnvConfig::default() })?;
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let mut per_episode = Vec::new();
    let mut agent_steps = 0u64;
    let mut seconds = 0.0;
    let mut one = |inst: &Instance, seed: Option<u64>, rng: &mut ChaCha8Rng| {
        let started = Instant::now();
        let (trajectory, collisions) = rollout(&mut env, inst, &args.policy, rng)?;
        seconds += started.elapsed().as_secs_f64();
        agent_steps += (inst.n_agents() * trajectory.horizon()) as u64;
        let m = PlanMetrics::of(inst, &trajectory);
        per_episode.push(EpisodeReport {
            instance_seed: seed,
            success: m.success,
            makespan: m.makespan,
            sum_of_costs: m.sum_of_costs,
            collisions,
            formation_loss: m.formation_loss,
            formation_loss_mean: m.formation_loss_mean,
        });
        Ok::<(), SimError>(())
    };
    match &args.source {
        SimSource::Instance(inst) => one(inst, None, &mut rng)?,
        SimSource::Generated { maps, episodes } => {
            if matches!(args.policy, SimPolicy::Plan(_)) {
                return Err(SimError::PlanNeedsInstance);
            }
            let maps = EvalMaps::new(maps.clone());
            for e in 0..*episodes as u64 {
                one(&maps.instance(e)?, Some(maps.seed(e)), &mut rng)?;
            }
        }
    }
    let n = per_episode.len().max(1) as f64;
    Ok(SimReport {
        episodes: per_episode.len(),
        success: per_episode.iter().filter(|e| e.success).count() as f64 / n,
        makespan: per_episode.iter().map(|e| e.makespan as f64).sum::<f64>() / n,
        collisions: per_episode.iter().map(|e| e.collisions).sum(),
        formation_loss: per_episode.iter().map(|e| e.formation_loss).sum::<f64>() / n,
        agent_steps,
        seconds,
        agent_steps_per_s: if seconds > 0.0 { agent_steps as f64 / seconds } else { 0.0 },
        per_episode,
    })
}

/// Runs one episode of `policy` on `instance` until it terminates or is truncated, building
/// every agent's observation every step; returns the trajectory (starts first) and the
/// number of cancelled moves.
pub fn rollout(
    env: &mut Env,
    instance: &Instance,
    policy: &SimPolicy,
    rng: &mut ChaCha8Rng,
) -> Result<(Plan, u64), SimError> {
    let n = instance.n_agents();
    if let SimPolicy::Plan(plan) = policy
        && plan.n_agents() != n
    {
        return Err(SimError::PlanAgents { expected: n, found: plan.n_agents() });
    }
    if let SimPolicy::Plan(plan) = policy
        && (plan.is_empty() || plan.at(0) != instance.starts())
    {
        return Err(SimError::PlanStart);
    }
    env.reset(instance)?;
    let mut obs = ObsBuffers::new(n, env.obs_shape());
    let mut trajectory = Plan::new(n);
    trajectory.push(env.positions());
    let mut actions = vec![Action::Wait; n];
    let mut collisions = 0;
    env.observe(&mut obs);
    if env.on_goal().iter().all(|&x| x) {
        return Ok((trajectory, 0));
    }
    for t in 0.. {
        for (agent, slot) in actions.iter_mut().enumerate() {
            *slot = match policy {
                SimPolicy::Random => {
                    Action::ALL[rng.random_range(0..Action::COUNT as u32) as usize]
                }
                SimPolicy::Greedy => greedy(env, agent),
                SimPolicy::Plan(plan) => {
                    if t + 1 < plan.n_steps() {
                        let (from, to) = (plan.at(t)[agent], plan.at(t + 1)[agent]);
                        Action::between(from, to)
                            .ok_or(SimError::PlanJump { step: t + 1, agent })?
                    } else {
                        Action::Wait
                    }
                }
            };
        }
        let step = env.step(&actions);
        collisions += u64::from(step.info.n_cancelled);
        let done = step.terminated || step.truncated;
        trajectory.push(env.positions());
        env.observe(&mut obs);
        if done {
            break;
        }
    }
    Ok((trajectory, collisions))
}

/// The greedy policy's action for `agent`.
fn greedy(env: &Env, agent: usize) -> Action {
    let here = env.positions()[agent];
    let d = env.cost_to_go(agent);
    Action::MOVES
        .into_iter()
        .find(|a| env.distance(agent, a.apply(here)).is_some_and(|n| n < d))
        .unwrap_or(Action::Wait)
}
