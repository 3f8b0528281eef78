//! The balancing weight of the meta reward (the paper's Eq. 14): `w_f = T / R*`, where `R*`
//! is the range of `E[Σ_{t<T} ΔL_f]` between a trained formation policy (the best) and a
//! random policy (the worst), estimated on the same start states.
//!
//! `Σ_{t<T} ΔL_f = L_f(T) − L_f(0)`: the sum telescopes, so each episode contributes the
//! change of its formation loss over `T` steps. Start states are formation-training
//! placements (the team scattered within each other's view, a random target layout, docs/spec.md §5)
//! on fresh maps of the evaluation stream, where the formation policy is what it was trained
//! to be. An episode that reaches the formation ends there (`L_f` stays 0). The random policy
//! takes a uniformly random action among those formation clipping allows. `T` defaults to
//! `1 / (1 − γ) = 20` steps, the meta learner's discount horizon: the span over which the meta
//! policy weighs one step's path-finding reward (+1) against the formation loss it causes.
//! The spread is a bootstrap over episodes (pairs of the two policies' episodes on one start
//! state resampled together).

use phalanx_env::{EnvConfig, EnvError, EvalMaps, GenConfig, Task};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::eval::{EvalEpisode, Rollouts, evaluate, evaluate_at};
use crate::policy::Policy;

/// Settings of the estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WeightConfig {
    /// Steps per episode `T` (default 20, `1 / (1 − γ)` for γ = 0.95).
    pub horizon: u32,
    /// Start states per team size (default 500).
    pub episodes: usize,
    /// Map side of the fresh maps (default 32, the training maps' side).
    pub size: u32,
    /// Obstacle density (default 0.15).
    pub density: f64,
    /// Base seed of the evaluation stream and the random policy (default 0).
    pub seed: u64,
    /// Bootstrap resamples for the interval (default 2000).
    pub resamples: usize,
}

impl Default for WeightConfig {
    fn default() -> Self {
        // The default maps' side and density.
        let phalanx_env::GenConfig { size, density, .. } = phalanx_env::GenConfig::default();
        WeightConfig { horizon: 20, episodes: 500, size, density, seed: 0, resamples: 2000 }
    }
}

/// The estimate for one team size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WeightEstimate {
    /// Agents per team.
    pub n_agents: usize,
    /// Steps per episode `T`.
    pub horizon: u32,
    /// Start states.
    pub episodes: usize,
    /// Mean `L_f` of the start states.
    pub start_loss: f64,
    /// `E[Σ ΔL_f]` of the formation policy.
    pub formation: f64,
    /// `E[Σ ΔL_f]` of the random policy.
    pub random: f64,
    /// `R* = random − formation`.
    pub range: f64,
    /// 95 % bootstrap interval of `R*`.
    pub range_interval: [f64; 2],
    /// `w_f = T / R*`.
    pub weight: f64,
    /// 95 % bootstrap interval of `w_f`.
    pub weight_interval: [f64; 2],
}

/// Estimates `w_f` for teams of each of `agent_counts` with the formation policy `formation`.
///
/// # Errors
/// If a map has no room for a team's placement after many tries, or the simulator refuses
/// the settings.
///
/// # Panics
/// If `config.episodes` or `config.resamples` is 0.
pub fn estimate_weight(
    formation: &mut Policy,
    agent_counts: &[usize],
    config: &WeightConfig,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<WeightEstimate>, EnvError> {
    assert!(config.episodes > 0 && config.resamples > 0, "episodes and resamples must be positive");
    let env =
        EnvConfig { step_limit: Some(config.horizon), ..formation.env_config(Task::Formation) };
    let mut res = Vec::with_capacity(agent_counts.len());
    let mut done = 0;
    for &n_agents in agent_counts {
        let maps = EvalMaps::new(GenConfig {
            size: config.size,
            density: config.density,
            n_agents: 1,
            fov: env.fov,
            seed: config.seed,
        });
        let starts = maps.formation_instances(n_agents, config.episodes)?;
        let greedy = Rollouts::default();
        let mut step_progress = |k: usize| progress(done + k);
        let policy =
            evaluate(formation, Task::Formation, &env, &starts, 50, greedy, &mut step_progress)?;
        done += starts.len();
        // ε = 1: every action uniformly among the allowed ones.
        let random_rollouts =
            Rollouts { count: 1, epsilon: 1.0, seed: config.seed, ..Rollouts::default() };
        let random = evaluate_at(formation, Task::Formation, &env, &starts, 50, random_rollouts)?;
        let change = |it: &EvalEpisode| it.final_formation_loss - it.start_formation_loss;
        let a: Vec<f64> = policy.iter().map(change).collect();
        let b: Vec<f64> = random.iter().map(change).collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let range = mean(&b) - mean(&a);
        let horizon = f64::from(config.horizon);
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x5eed_b007);
        let mut ranges: Vec<f64> = (0..config.resamples)
            .map(|_| {
                let (mut sa, mut sb) = (0.0, 0.0);
                for _ in 0..a.len() {
                    let i = rng.random_range(0..a.len());
                    sa += a[i];
                    sb += b[i];
                }
                (sb - sa) / a.len() as f64
            })
            .collect();
        ranges.sort_by(f64::total_cmp);
        let quantile = |q: f64| ranges[((ranges.len() - 1) as f64 * q).round() as usize];
        let range_interval = [quantile(0.025), quantile(0.975)];
        res.push(WeightEstimate {
            n_agents,
            horizon: config.horizon,
            episodes: starts.len(),
            start_loss: mean(&policy.iter().map(|it| it.start_formation_loss).collect::<Vec<_>>()),
            formation: mean(&a),
            random: mean(&b),
            range,
            range_interval,
            weight: horizon / range,
            weight_interval: [horizon / range_interval[1], horizon / range_interval[0]],
        });
    }
    Ok(res)
}
