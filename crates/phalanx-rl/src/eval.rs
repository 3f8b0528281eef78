//! Greedy evaluation of a learned policy on given instances, many episodes in lockstep.
//!
//! A low-level policy runs each instance as one episode of a [`TaskEnv`] of its task (its
//! rewards, clipping and leader rule); the hierarchy ([`Hierarchy`]) runs it as a
//! [`phalanx_env::HierEnv`] (the meta policy choosing each agent's low-level policy every step). Policies
//! act greedily (ε = 0) in leader order with action messages, until the task terminates (all
//! agents on their goals; for [`Task::Formation`], `L_f = 0`) or the step limit truncates
//! it. Instances go through in batches of `batch` episodes, one batched policy call per step;
//! an episode that has ended stops stepping while its batch finishes.
//!
//! Every rollout is recorded as a [`Plan`] and scored like any planner's plan: by
//! [`phalanx_core::validate`] (the environment never makes an invalid one) and
//! [`PlanMetrics`]. Greedy acting is deterministic, and the random actions of extra
//! [`Rollouts`] come from seeded streams, so the figures depend only on the policy, the
//! instances and the seed (not on the thread count).

use phalanx_core::{Instance, Plan, PlanMetrics, Stall, ViolationKind, validate};
use phalanx_env::{Choice, Env, EnvConfig, EnvError, ObsBuffers, StepOut, Task, TaskEnv};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::hierarchy::{Episodes, Hierarchy};
use crate::keep::Keep;
use crate::policy::{Policy, row_offsets};

/// What one evaluated episode measured, with its plan.
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
    /// Sum of costs ([`PlanMetrics::sum_of_costs`]).
    pub sum_of_costs: usize,
    /// Table II formation loss: `Σ_{t=1..steps} L_f(t)` divided by the map side
    /// ([`PlanMetrics::formation_loss`]).
    pub formation_loss: f64,
    /// Mean per-step `L_f` ([`PlanMetrics::formation_loss_mean`]).
    pub formation_loss_mean: f64,
    /// `L_f` at the start.
    pub start_formation_loss: f64,
    /// `L_f` after the last step.
    pub final_formation_loss: f64,
    /// For the hierarchy, the fraction of agent-steps that ran the formation policy.
    pub formation_share: Option<f64>,
    /// Agent decisions of every rollout of the instance (agents × steps, summed).
    pub decisions: u64,
    /// Short of the goals: whether the team ended standing still or oscillating
    /// ([`Stall`]).
    #[serde(skip)]
    pub stall: Option<Stall>,
    /// The joint positions of every step, starts first.
    #[serde(skip)]
    pub plan: Plan,
    /// For the hierarchy, each step's choices (`[steps, n_agents]`, [`Choice`] indices).
    #[serde(skip)]
    pub choices: Option<Vec<u8>>,
}

/// Test-time rollouts (docs/spec.md §6, the paper's protocol for decentralised methods): each
/// instance is played `count` times, the first greedily, the others with a random allowed
/// action taken with probability `epsilon` per agent and step (in the hierarchy: an action
/// allowed by the agent's chosen low-level policy, the meta choice staying greedy); the best
/// rollout by `keep` counts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rollouts {
    /// Rollouts per instance (at least 1).
    pub count: usize,
    /// Probability of a random action in the rollouts after the first.
    pub epsilon: f64,
    /// Seed of the random actions.
    pub seed: u64,
    /// Which rollout counts (`None`: the policy's own, [`Policy::keep`]; the hierarchy's:
    /// [`Keep::Fastest`]). Not written when `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep: Option<Keep>,
}

impl Rollouts {
    /// The random-action rate of rollout `r`: the first is greedy.
    fn epsilon_of(&self, r: usize) -> f64 {
        if r == 0 { 0.0 } else { self.epsilon }
    }
}

impl Default for Rollouts {
    /// One greedy rollout.
    fn default() -> Self {
        Rollouts { count: 1, epsilon: 0.0, seed: 0, keep: None }
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
    let keep = rollouts.keep.unwrap_or(policy.keep());
    // The second rollout at the policy's other band, with environments of its own.
    let second = policy.rollout_band().filter(|_| env.team_vector);
    let second = second.map(|cells| EnvConfig { team_deadband: cells, ..env.clone() });
    let temperature = policy.rollout_temperature();
    let (mut envs, mut second_envs) = (Vec::new(), Vec::new());
    let mut play =
        |chunk: &[Instance], caps: &[usize], solved: &[bool], r: usize, rng: &mut ChaCha8Rng| {
            let epsilon = rollouts.epsilon_of(r);
            match (&second, temperature) {
                (Some(second), _) if r == 1 => {
                    play_low_level(policy, task, second, chunk, caps, 0.0, rng, &mut second_envs)
                }
                (_, Some(temperature)) if r > 0 && solved.contains(&true) => play_refining(
                    policy,
                    task,
                    env,
                    chunk,
                    caps,
                    solved,
                    temperature,
                    epsilon,
                    rng,
                    &mut envs,
                ),
                _ => play_low_level(policy, task, env, chunk, caps, epsilon, rng, &mut envs),
            }
        };
    evaluate_with(&mut play, instances, batch, rollouts, keep, progress)
}

/// A rollout of `chunk` with the policy's rollout temperature ([`Policy::rollout_temperature`]):
/// the instances an earlier rollout solved (`solved`) are played drawing each action from the
/// softmax of the scores at `temperature`, for a tighter or faster plan than the one kept; the
/// others greedily with random actions at `epsilon`, for a plan at all (the latter first, the
/// random draws from `rng`).
#[allow(clippy::too_many_arguments, reason = "one rollout's inputs")]
fn play_refining(
    policy: &mut Policy,
    task: Task,
    env: &EnvConfig,
    chunk: &[Instance],
    caps: &[usize],
    solved: &[bool],
    temperature: f32,
    epsilon: f64,
    rng: &mut ChaCha8Rng,
    envs: &mut Vec<TaskEnv>,
) -> Result<Vec<EvalEpisode>, EnvError> {
    let greedy = policy.sampling();
    let mut played: Vec<Option<EvalEpisode>> = vec![None; chunk.len()];
    for refine in [false, true] {
        let part: Vec<usize> = (0..chunk.len()).filter(|&e| solved[e] == refine).collect();
        if part.is_empty() {
            continue;
        }
        let instances: Vec<Instance> = part.iter().map(|&e| chunk[e].clone()).collect();
        let caps: Vec<usize> = part.iter().map(|&e| caps[e]).collect();
        let (sampling, epsilon) = if refine { (Some(temperature), 0.0) } else { (greedy, epsilon) };
        policy.set_sampling(sampling);
        let out = play_low_level(policy, task, env, &instances, &caps, epsilon, rng, envs);
        policy.set_sampling(greedy);
        for (&e, episode) in part.iter().zip(out?) {
            played[e] = Some(episode);
        }
    }
    Ok(played.into_iter().map(|it| it.expect("every instance is in one part")).collect())
}

/// One rollout of `policy` on every instance at the random-action rate `rollouts.epsilon`
/// (ε = 1: a uniformly random allowed action every step), the random draws from
/// `rollouts.seed`; `rollouts.count` is ignored.
///
/// # Errors
/// If the simulator refuses an instance.
pub fn evaluate_at(
    policy: &mut Policy,
    task: Task,
    env: &EnvConfig,
    instances: &[Instance],
    batch: usize,
    rollouts: Rollouts,
) -> Result<Vec<EvalEpisode>, EnvError> {
    let mut rng = ChaCha8Rng::seed_from_u64(rollouts.seed);
    let mut res = Vec::with_capacity(instances.len());
    let mut envs = Vec::new();
    for chunk in instances.chunks(batch.max(1)) {
        let (caps, epsilon) = (vec![usize::MAX; chunk.len()], rollouts.epsilon);
        res.extend(play_low_level(policy, task, env, chunk, &caps, epsilon, &mut rng, &mut envs)?);
    }
    Ok(res)
}

/// [`evaluate`] for the hierarchy: every instance as a meta-task episode ([`phalanx_env::HierEnv`]).
///
/// # Errors
/// If the simulator refuses an instance (field of view, agent count).
pub fn evaluate_hierarchy(
    hierarchy: &mut Hierarchy,
    env: &EnvConfig,
    instances: &[Instance],
    batch: usize,
    rollouts: Rollouts,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<EvalEpisode>, EnvError> {
    let mut episodes = Episodes::new();
    let mut play =
        |chunk: &[Instance], caps: &[usize], _: &[bool], r: usize, rng: &mut ChaCha8Rng| {
            play_hierarchy(hierarchy, env, chunk, caps, rollouts.epsilon_of(r), rng, &mut episodes)
        };
    let keep = rollouts.keep.unwrap_or_default();
    evaluate_with(&mut play, instances, batch, rollouts, keep, progress)
}

/// Rollout `r` of a chunk of instances in lockstep: `(chunk, caps, solved, r, rng)`; episode
/// `e` stops unsolved after `caps[e]` steps (see [`Tracks::new`]); `solved[e]`: whether an
/// earlier rollout solved it.
type Play<'a> = dyn FnMut(
        &[Instance],
        &[usize],
        &[bool],
        usize,
        &mut ChaCha8Rng,
    ) -> Result<Vec<EvalEpisode>, EnvError>
    + 'a;

/// The rollouts of every chunk, keeping each instance's best by `keep`.
fn evaluate_with(
    play: &mut Play<'_>,
    instances: &[Instance],
    batch: usize,
    rollouts: Rollouts,
    keep: Keep,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<EvalEpisode>, EnvError> {
    let mut res: Vec<EvalEpisode> = Vec::with_capacity(instances.len());
    for (c, chunk) in instances.chunks(batch.max(1)).enumerate() {
        let uncapped = vec![usize::MAX; chunk.len()];
        let unsolved = vec![false; chunk.len()];
        let mut best = play(chunk, &uncapped, &unsolved, 0, &mut ChaCha8Rng::seed_from_u64(0))?;
        for r in 1..rollouts.count {
            let mut rng = ChaCha8Rng::seed_from_u64(rollouts.seed);
            rng.set_stream(((c as u64) << 20) | r as u64);
            // A rollout still running after the steps past which it cannot be kept stops
            // there (the random draws of the others do not change).
            let caps: Vec<usize> = best.iter().map(|kept| cap(keep, kept)).collect();
            let solved: Vec<bool> = best.iter().map(|kept| kept.success).collect();
            let again = play(chunk, &caps, &solved, r, &mut rng)?;
            for (kept, new) in best.iter_mut().zip(again) {
                let decisions = kept.decisions + new.decisions;
                if better(&new, kept, keep) {
                    *kept = new;
                }
                kept.decisions = decisions;
            }
        }
        res.extend(best);
        progress(res.len());
    }
    Ok(res)
}

/// The most steps a rollout of `episode`'s instance may take within the makespan budget of
/// [`Keep::Within`] (`budget` × the lower bound).
fn budget_steps(budget: f64, episode: &EvalEpisode) -> usize {
    (budget * f64::from(episode.lower_bound)).floor() as usize
}

/// Whether `episode` is solved within the makespan budget of [`Keep::Within`].
fn within(budget: f64, episode: &EvalEpisode) -> bool {
    episode.success && episode.steps <= budget_steps(budget, episode)
}

/// The steps after which a rollout can no longer beat `kept`, the best one so far by `keep`.
fn cap(keep: Keep, kept: &EvalEpisode) -> usize {
    match keep {
        Keep::Fastest if kept.success => kept.steps,
        // Within the budget, a slower rollout may still be tighter; past it, only a faster
        // one counts.
        Keep::Within(budget) if kept.success => budget_steps(budget, kept).max(kept.steps),
        _ => usize::MAX,
    }
}

/// Whether rollout `a` is better than `b` by `keep` (solved before unsolved always, then
/// within the budget of [`Keep::Within`] before past it).
fn better(a: &EvalEpisode, b: &EvalEpisode, keep: Keep) -> bool {
    let solved = (!a.success).cmp(&!b.success);
    let steps = a.steps.cmp(&b.steps);
    let loss = a.formation_loss.total_cmp(&b.formation_loss);
    let order = match keep {
        Keep::Fastest => solved.then(steps).then(loss),
        Keep::Tightest => solved.then(loss).then(steps),
        Keep::Within(budget) => match (within(budget, a), within(budget, b)) {
            (true, true) => loss.then(steps),
            (a_in, b_in) => solved.then((!a_in).cmp(&!b_in)).then(steps).then(loss),
        },
    };
    order.is_lt()
}

/// The trajectories of a chunk's episodes while they run.
struct Tracks<'a> {
    chunk: &'a [Instance],
    plans: Vec<Plan>,
    collisions: Vec<u64>,
    terminated: Vec<bool>,
    running: Vec<bool>,
    caps: &'a [usize],
    lower_bounds: Vec<u32>,
    choices: Option<Vec<Vec<u8>>>,
}

impl<'a> Tracks<'a> {
    /// Episodes at their starts: `sims[e]` runs episode `e` (reset to its instance), whose
    /// lower bound and whether it starts solved are read from it; with `hier`, choices are
    /// recorded too. Episode `e` stops after `caps[e]` steps unless it terminated by then
    /// (unsolved, as when truncated).
    fn new(chunk: &'a [Instance], caps: &'a [usize], sims: &[&Env], hier: bool) -> Self {
        let lower_bounds = sims.iter().map(|sim| lower_bound(sim)).collect();
        let solved: Vec<bool> = sims.iter().map(|sim| sim.is_done()).collect();
        let plans = chunk
            .iter()
            .map(|inst| {
                let mut plan = Plan::new(inst.n_agents());
                plan.push(inst.starts());
                plan
            })
            .collect();
        Tracks {
            chunk,
            plans,
            collisions: vec![0; chunk.len()],
            terminated: solved.clone(),
            running: solved.iter().map(|&done| !done).collect(),
            caps,
            lower_bounds,
            choices: hier.then(|| vec![Vec::new(); chunk.len()]),
        }
    }

    /// Records episode `e`'s step.
    fn record(&mut self, e: usize, out: &StepOut, positions: &[phalanx_core::Cell]) {
        self.plans[e].push(positions);
        self.collisions[e] += u64::from(out.collisions);
        self.terminated[e] = out.terminated;
        let capped = self.plans[e].horizon() >= self.caps[e];
        self.running[e] = !(out.terminated || out.truncated || capped);
    }

    /// Scores every plan with the validator and the plan metrics. A rollout that stops short
    /// of the goals (truncated, or a formation episode) breaks only the validator's last
    /// rule, `GoalNotReached`: an unsuccessful plan, not an invalid one.
    ///
    /// # Panics
    /// If a plan breaks any other rule: the environment resolves every conflict, so that is a
    /// bug.
    fn finish(self) -> Vec<EvalEpisode> {
        let mut choices = self.choices.map(Vec::into_iter);
        self.chunk
            .iter()
            .zip(self.plans)
            .enumerate()
            .map(|(e, (instance, plan))| {
                if let Err(violation) = validate(instance, &plan)
                    && !matches!(violation.kind, ViolationKind::GoalNotReached { .. })
                {
                    panic!("a learned rollout broke the rules: {violation}");
                }
                let m = PlanMetrics::of(instance, &plan);
                let choices = choices.as_mut().map(|it| it.next().expect("one per episode"));
                let formation_share = choices.as_ref().map(|c| {
                    let formation = c.iter().filter(|&&it| it == Choice::Formation as u8).count();
                    formation as f64 / c.len().max(1) as f64
                });
                EvalEpisode {
                    n_agents: instance.n_agents(),
                    success: self.terminated[e],
                    steps: plan.horizon(),
                    lower_bound: self.lower_bounds[e],
                    collisions: self.collisions[e],
                    sum_of_costs: m.sum_of_costs,
                    formation_loss: m.formation_loss,
                    formation_loss_mean: m.formation_loss_mean,
                    start_formation_loss: m.formation_loss_per_step[0],
                    final_formation_loss: m.formation_loss_per_step.last().copied().unwrap_or(0.0),
                    formation_share,
                    decisions: (instance.n_agents() * plan.horizon()) as u64,
                    stall: Stall::of(&plan, instance.goals()),
                    plan,
                    choices,
                }
            })
            .collect()
    }
}

/// The largest start-to-goal BFS distance of the episode `env` runs.
fn lower_bound(env: &Env) -> u32 {
    (0..env.n_agents()).map(|a| env.cost_to_go(a)).max().unwrap_or(0)
}

/// One rollout of a low-level policy on every instance of `chunk` in lockstep. `envs` are
/// the environments of the last call, reused where the agent count allows: the rollouts of
/// an instance then search its distance maps once (`Env::reset` keeps them).
#[allow(clippy::too_many_arguments, reason = "one rollout's inputs")]
fn play_low_level(
    policy: &mut Policy,
    task: Task,
    env: &EnvConfig,
    chunk: &[Instance],
    caps: &[usize],
    epsilon: f64,
    rng: &mut ChaCha8Rng,
    envs: &mut Vec<TaskEnv>,
) -> Result<Vec<EvalEpisode>, EnvError> {
    envs.truncate(chunk.len());
    let mut obs = Vec::with_capacity(chunk.len());
    for (e, instance) in chunk.iter().enumerate() {
        let n = instance.n_agents();
        let fits = |it: &TaskEnv| it.env().n_agents() == n;
        let task_env = reuse(envs, e, fits, || TaskEnv::new(task, env.clone(), n))?;
        let mut buffers = ObsBuffers::new(n, task_env.obs_shape());
        task_env.reset_to(instance, &mut buffers)?;
        obs.push(buffers);
    }
    let sims: Vec<&Env> = envs.iter().map(|it| it.env()).collect();
    let mut tracks = Tracks::new(chunk, caps, &sims, false);
    let offsets = row_offsets(chunk.iter().map(Instance::n_agents));
    let mut actions = vec![0_u8; chunk.iter().map(Instance::n_agents).sum()];
    policy.reset();
    while tracks.running.contains(&true) {
        policy.act_batch(&obs, epsilon, rng, &mut actions, None);
        for (e, task_env) in envs.iter_mut().enumerate() {
            if tracks.running[e] {
                let (at, n) = (offsets[e], chunk[e].n_agents());
                let out = task_env.step(&actions[at..at + n], &mut obs[e]);
                tracks.record(e, &out, task_env.env().positions());
            }
        }
    }
    Ok(tracks.finish())
}

/// `envs[e]` when it `fits`, else a fresh environment from `make` in its place (`envs` holds
/// at least `e` environments).
fn reuse<T>(
    envs: &mut Vec<T>,
    e: usize,
    fits: impl Fn(&T) -> bool,
    make: impl FnOnce() -> Result<T, EnvError>,
) -> Result<&mut T, EnvError> {
    if !envs.get(e).is_some_and(fits) {
        let fresh = make()?;
        if e < envs.len() {
            envs[e] = fresh;
        } else {
            envs.push(fresh);
        }
    }
    Ok(&mut envs[e])
}

/// One rollout of the hierarchy on every instance of `chunk` in lockstep
/// ([`Hierarchy::start`], [`Hierarchy::step`]): the meta policy chooses greedily, the low
/// level acts with random actions at rate `epsilon`. `episodes` are those of the last call,
/// reused where the agent count allows (see [`play_low_level`]).
fn play_hierarchy(
    hierarchy: &mut Hierarchy,
    env: &EnvConfig,
    chunk: &[Instance],
    caps: &[usize],
    epsilon: f64,
    rng: &mut ChaCha8Rng,
    episodes: &mut Episodes,
) -> Result<Vec<EvalEpisode>, EnvError> {
    hierarchy.start(episodes, chunk, env)?;
    let sims: Vec<&Env> = (0..chunk.len()).map(|e| episodes.env(e).env()).collect();
    let mut tracks = Tracks::new(chunk, caps, &sims, true);
    let mut outs = Vec::with_capacity(chunk.len());
    while tracks.running.contains(&true) {
        hierarchy.step(episodes, &tracks.running, epsilon, rng, &mut outs);
        for (e, out) in outs.iter().enumerate() {
            if let Some(out) = out {
                tracks.record(e, out, episodes.env(e).env().positions());
                if let Some(all) = tracks.choices.as_mut() {
                    all[e].extend_from_slice(episodes.choices(e));
                }
            }
        }
    }
    Ok(tracks.finish())
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
    /// Episodes that ended short of the goals with the team standing still.
    pub standing: usize,
    /// Episodes that ended short of the goals with the team oscillating.
    pub oscillating: usize,
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
            standing: episodes.iter().filter(|it| it.stall == Some(Stall::Standing)).count(),
            oscillating: episodes.iter().filter(|it| it.stall == Some(Stall::Oscillating)).count(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{EvalEpisode, Keep, better, cap};

    #[test]
    fn a_keep_rule_is_parsed_from_its_name_only() {
        assert_eq!("fastest".parse::<Keep>(), Ok(Keep::Fastest));
        assert_eq!("tightest".parse::<Keep>(), Ok(Keep::Tightest));
        assert_eq!("within:1.1".parse::<Keep>(), Ok(Keep::Within(1.1)));
        assert_eq!(
            "Tightest".parse::<Keep>(),
            Err("keep \"Tightest\": one of fastest, tightest, within:BUDGET".into())
        );
        for bad in ["within:0.99", "within:x", "within:inf", "within:"] {
            let err = bad.parse::<Keep>().unwrap_err();
            assert!(err.contains("is not a number of at least 1"), "{bad}: {err}");
        }
        for keep in [Keep::Fastest, Keep::Tightest, Keep::Within(1.25)] {
            assert_eq!(keep.to_string().parse(), Ok(keep));
        }
    }

    fn episode(success: bool, steps: usize, loss: f64) -> EvalEpisode {
        EvalEpisode {
            n_agents: 3,
            success,
            steps,
            lower_bound: 20,
            collisions: 0,
            sum_of_costs: 0,
            formation_loss: loss,
            formation_loss_mean: 0.0,
            start_formation_loss: 0.0,
            final_formation_loss: 0.0,
            formation_share: None,
            decisions: 0,
            stall: None,
            plan: phalanx_core::Plan::new(3),
            choices: None,
        }
    }

    #[test]
    fn within_a_budget_the_tightest_counts_and_past_it_the_fastest() {
        let within = Keep::Within(1.1); // 22 steps on a lower bound of 20
        let (fast, tight, slow_tight) =
            (episode(true, 20, 2.0), episode(true, 22, 1.0), episode(true, 23, 0.1));
        assert!(better(&tight, &fast, within) && !better(&fast, &tight, within));
        assert!(better(&fast, &slow_tight, within) && better(&tight, &slow_tight, within));
        // Both past the budget: the faster.
        let slower = episode(true, 30, 0.0);
        assert!(better(&slow_tight, &slower, within));
        // Solved before unsolved, whatever the loss.
        assert!(better(&slower, &episode(false, 10, 0.0), within));
        // A rollout can still beat the best so far until the budget's steps, or until the
        // best's own steps when it is past the budget.
        assert_eq!(cap(within, &fast), 22);
        assert_eq!(cap(within, &slower), 30);
        assert_eq!(cap(within, &episode(false, 40, 0.0)), usize::MAX);
        assert_eq!(cap(Keep::Fastest, &slower), 30);
        assert_eq!(cap(Keep::Tightest, &slower), usize::MAX);
    }
}
