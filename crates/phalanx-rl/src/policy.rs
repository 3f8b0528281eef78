//! Acting with a frozen network, for one episode or for many episodes in lockstep.
//!
//! One call of [`Policy::act_batch`] decides a step of every episode of the batch:
//! 1. one recurrent step for all agents of all episodes (`Σ N_e` rows, one batched pass);
//! 2. the head in leader order: at rank `k`, the agents ranked `k` of every episode go through
//!    the head together, each with the message of the actions its team chose at ranks `0..k`;
//! 3. ε-greedy among the allowed actions (a masked action is never chosen), or, for a policy
//!    with a stall escape ([`Policy::set_escape`]), the escape's random action where an agent
//!    keeps coming back to one cell ([`crate::escape`]).
//!
//! Episodes may have different agent counts. The recurrent state of each episode is carried
//! between calls; [`Policy::reset_envs`] clears the rows of episodes that start again.

use std::sync::Arc;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::escape::{Escape, Stuck};
use crate::frozen::{FrozenNet, State};
use crate::keep::Keep;
use crate::net::{MASKED_Q, QNet, QNetConfig, masked_argmax};
use phalanx_env::obs::VECTOR_LEN;
use phalanx_env::{EnvConfig, ObsBuffers, Task};

/// A frozen Q-network that acts: batched recurrent step, then the head in leader order.
///
/// It runs a plain copy of the network's weights (`crate::frozen`: the same layers written
/// for their fixed sizes, agreeing with [`QNet`]'s forward pass to rounding); clones share
/// the weights.
#[derive(Clone, Debug)]
pub struct Policy {
    net: Arc<FrozenNet>,
    config: QNetConfig,
    state: Option<State>,
    escape: Option<Escape>,
    /// Each row's side of the escape (rows as in the last [`Policy::act_batch`]).
    stuck: Vec<Stuck>,
    /// The team vector's dead band of the environments it acts in ([`Policy::env_config`]).
    team_deadband: f64,
    /// When set, actions are drawn from the softmax of the masked scores at this
    /// temperature instead of taken greedily ([`Policy::set_sampling`]).
    sampling: Option<f32>,
    /// Which of its test-time rollouts counts unless the caller says ([`Policy::keep`]).
    keep: Keep,
    /// The dead band of its second test-time rollout ([`Policy::rollout_band`]).
    rollout_band: Option<f64>,
    /// The sampling temperature of its test-time rollouts after the first
    /// ([`Policy::rollout_temperature`]).
    rollout_temperature: Option<f32>,
}

/// Why a saved recurrent state does not fit a policy's network.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RecurrentStateError {
    /// Another number of LSTM layers.
    #[error("{found} recurrent layers, the network has {expected}")]
    Layers {
        /// Layers in the state.
        found: usize,
        /// Layers of the network.
        expected: usize,
    },
    /// A layer's cell and hidden values are not whole rows of the network's width.
    #[error("recurrent state of {cell} and {hidden} values, not rows of {width}")]
    Shape {
        /// Cell values.
        cell: usize,
        /// Hidden values.
        hidden: usize,
        /// The LSTM width.
        width: usize,
    },
}

impl Policy {
    /// A policy acting with a copy of `net`'s weights (`config`: its sizes).
    pub fn new(net: &QNet, config: QNetConfig) -> Self {
        Self {
            net: Arc::new(net.frozen(&config)),
            config,
            state: None,
            escape: None,
            team_deadband: phalanx_env::obs::TEAM_DEADBAND,
            stuck: vec![],
            sampling: None,
            keep: Keep::Fastest,
            rollout_band: None,
            rollout_temperature: None,
        }
    }

    /// Acts with the stall escape `escape` from now on (`None`: greedy as trained, the
    /// default); forgets the cells seen.
    pub fn set_escape(&mut self, escape: Option<Escape>) {
        self.escape = escape;
        self.stuck.clear();
    }

    /// Draws each action from the softmax of the agent's masked scores divided by
    /// `temperature` instead of taking the best (`None`: greedy, the default): the
    /// stochastic policy of the student's fine-tuning on the meta reward
    /// ([`crate::imitation::finetune`]). ε-random actions and the stall escape come first.
    ///
    /// # Panics
    /// If the temperature is not a positive number.
    pub fn set_sampling(&mut self, temperature: Option<f32>) {
        self.sampling = positive(temperature);
    }

    /// The temperature its actions are drawn at (`None`: greedy).
    pub fn sampling(&self) -> Option<f32> {
        self.sampling
    }

    /// The stall escape it acts with.
    pub fn escape(&self) -> Option<Escape> {
        self.escape
    }

    /// Acts in environments whose team vector has the dead band `cells` (its
    /// [`Policy::env_config`]; default [`phalanx_env::obs::TEAM_DEADBAND`], what the
    /// planners' student was trained with): a test-time knob between formation and speed
    /// for a network that reads the team vector (`docs/imitation.md`).
    ///
    /// # Errors
    /// A band that is negative or not a number.
    pub fn set_team_deadband(&mut self, cells: f64) -> Result<(), phalanx_env::EnvError> {
        phalanx_env::check_team_deadband(cells)?;
        self.team_deadband = cells;
        Ok(())
    }

    /// The team vector's dead band of the environments it acts in.
    pub fn team_deadband(&self) -> f64 {
        self.team_deadband
    }

    /// Keeps its test-time rollouts by `keep` unless the caller's [`crate::Rollouts`] say
    /// otherwise (default [`Keep::Fastest`]; the planners' student: [`Keep::STUDENT`]).
    pub fn set_keep(&mut self, keep: Keep) {
        self.keep = keep;
    }

    /// The rule that keeps one of its test-time rollouts.
    pub fn keep(&self) -> Keep {
        self.keep
    }

    /// Plays its second test-time rollout greedily at the team vector's dead band `cells`
    /// instead of its own (`None`, the default: at its own, with random actions as every
    /// rollout after the first, as the planners' student plays since 2026-12-07).
    /// Only a network that reads the team vector acts differently.
    ///
    /// # Errors
    /// A band that is negative or not a number.
    pub fn set_rollout_band(&mut self, cells: Option<f64>) -> Result<(), phalanx_env::EnvError> {
        if let Some(cells) = cells {
            phalanx_env::check_team_deadband(cells)?;
        }
        self.rollout_band = cells;
        Ok(())
    }

    /// The dead band of its second test-time rollout.
    pub fn rollout_band(&self) -> Option<f64> {
        self.rollout_band
    }

    /// Plays its test-time rollouts after the first (but the one at [`Policy::rollout_band`])
    /// on an instance an earlier rollout solved drawing each action from the softmax of its
    /// masked scores at `temperature`, without random actions; on one none solved yet greedily
    /// with random actions, as every such rollout without it (`None`, the default; the
    /// planners' student: [`crate::STUDENT_ROLLOUT_TEMPERATURE`]).
    ///
    /// # Panics
    /// If the temperature is not a positive number.
    pub fn set_rollout_temperature(&mut self, temperature: Option<f32>) {
        self.rollout_temperature = positive(temperature);
    }

    /// The sampling temperature of its test-time rollouts after the first.
    pub fn rollout_temperature(&self) -> Option<f32> {
        self.rollout_temperature
    }

    /// The network sizes.
    pub fn config(&self) -> &QNetConfig {
        &self.config
    }

    /// The settings of an environment of `task` this policy acts in: its network's field of
    /// view, the place vector on the meta task when the network reads a vector of 6 (the
    /// planners' student, `docs/imitation.md`), the place and team vectors when it reads 9
    /// (with its [`Policy::team_deadband`]), the rest the defaults (the step limit
    /// `3 × side`). Every command, the benchmark and the Python package derive a policy's
    /// environment here (a hierarchy's: `Hierarchy::env_config`).
    pub fn env_config(&self, task: Task) -> EnvConfig {
        let meta = task == Task::Meta;
        let place_vector = meta && self.config.env_vec >= 2 * VECTOR_LEN;
        let team_vector = meta && self.config.env_vec == 3 * VECTOR_LEN;
        let fov = self.config.fov as u32;
        let team_deadband = self.team_deadband;
        EnvConfig { fov, task, place_vector, team_vector, team_deadband, ..EnvConfig::default() }
    }

    /// Replace the weights, keeping the recurrent state (a learner's policy after an update).
    pub fn set_net(&mut self, net: &QNet) {
        self.net = Arc::new(net.frozen(&self.config));
    }

    /// Forget the recurrent state of every episode (call at the start of new episodes).
    pub fn reset(&mut self) {
        self.state = None;
        self.stuck.clear();
    }

    /// Forget the recurrent state of the episodes `e` with `restart[e]`, keeping the others;
    /// `agents[e]` is episode `e`'s agent count, as in the last [`Policy::act_batch`].
    pub fn reset_envs(&mut self, agents: &[usize], restart: &[bool]) {
        assert_eq!(agents.len(), restart.len(), "one flag per episode");
        if restart.iter().all(|&it| it) {
            self.reset();
            return;
        }
        let mut row = 0;
        for (&n, &reset) in agents.iter().zip(restart) {
            for agent in 0..n {
                if reset && let Some(stuck) = self.stuck.get_mut(row + agent) {
                    *stuck = Stuck::new(agent);
                }
            }
            row += n;
        }
        let Some(state) = self.state.as_mut() else { return };
        let hidden = self.config.lstm_hidden;
        let mut row = 0;
        for (&n, &reset) in agents.iter().zip(restart) {
            if reset {
                for (cell, h) in state.iter_mut() {
                    cell[row * hidden..(row + n) * hidden].fill(0.0);
                    h[row * hidden..(row + n) * hidden].fill(0.0);
                }
            }
            row += n;
        }
    }

    /// The recurrent state carried between calls, per layer `(cell, hidden)`, each `[rows, H]`
    /// row-major (rows as in the last [`Policy::act_batch`]); `None` when it is all zeros.
    pub(crate) fn recurrent_state(&self) -> Option<Vec<(Vec<f32>, Vec<f32>)>> {
        self.state.clone()
    }

    /// Restore a state from [`Policy::recurrent_state`].
    ///
    /// # Errors
    /// When the layers or their sizes do not fit the network.
    pub(crate) fn set_recurrent_state(
        &mut self,
        layers: Option<Vec<(Vec<f32>, Vec<f32>)>>,
    ) -> Result<(), RecurrentStateError> {
        let Some(layers) = layers else {
            self.state = None;
            return Ok(());
        };
        let hidden = self.config.lstm_hidden;
        if layers.len() != self.config.lstm_layers {
            return Err(RecurrentStateError::Layers {
                found: layers.len(),
                expected: self.config.lstm_layers,
            });
        }
        for (cell, h) in &layers {
            let rows = cell.len() / hidden;
            if cell.len() != rows * hidden || h.len() != cell.len() {
                return Err(RecurrentStateError::Shape {
                    cell: cell.len(),
                    hidden: h.len(),
                    width: hidden,
                });
            }
        }
        self.state = Some(layers);
        Ok(())
    }

    /// Choose every agent's action for the current observation, ε-greedily among the allowed
    /// actions, agents in `obs.order`. Writes `actions[agent_idx]`.
    pub fn act(
        &mut self,
        obs: &ObsBuffers,
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
    ) {
        let mut q = vec![0.0; obs.n_agents * self.config.n_actions];
        self.act_with_q(obs, epsilon, rng, actions, &mut q);
    }

    /// [`Policy::act`] that also writes each agent's Q-values (`[N, A]`, row `agent_idx`, the
    /// message being the actions chosen before it; masked actions hold [`MASKED_Q`]).
    pub fn act_with_q(
        &mut self,
        obs: &ObsBuffers,
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
        q_out: &mut [f32],
    ) {
        self.act_batch(std::slice::from_ref(obs), epsilon, rng, actions, Some(q_out));
    }

    /// One step of every episode in `obs` (episode `e` has `obs[e].n_agents` agents).
    /// `actions` is laid out episode after episode (`[Σ N_e]`, agent order within an
    /// episode); `q_out`, when given, `[Σ N_e, A]` in the same order.
    ///
    /// Random draws happen rank by rank, episode by episode within a rank, so the result for a
    /// seed depends only on the inputs.
    ///
    /// # Panics
    /// If an episode has more agents than the network's slots, the buffers disagree with the
    /// network, or the batch's agent counts differ from the last call's without a reset.
    pub fn act_batch(
        &mut self,
        obs: &[ObsBuffers],
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
        mut q_out: Option<&mut [f32]>,
    ) {
        let obs: Vec<&ObsBuffers> = obs.iter().collect();
        let rows: usize = obs.iter().map(|env| env.n_agents).sum();
        assert_eq!(actions.len(), rows, "one action per agent");
        if let Some(q) = &q_out {
            assert_eq!(q.len(), rows * self.config.n_actions, "one Q row per agent");
        }
        let features = self.recurrent_step(&obs);
        let mut stuck = std::mem::take(&mut self.stuck);
        if self.escape.is_some() && stuck.len() != rows {
            stuck = obs.iter().flat_map(|env| (0..env.n_agents).map(Stuck::new)).collect();
        }
        let escape = self.escape.map(|escape| (escape, stuck.as_mut_slice()));
        let mut turns = Turns::new(&obs, &self.config).escaping(escape);
        let max_agents = obs.iter().map(|env| env.n_agents).max().unwrap_or(0);
        for rank in 0..max_agents {
            let acting: Vec<usize> = (0..obs.len()).filter(|&e| rank < obs[e].n_agents).collect();
            let q = q_out.as_deref_mut();
            turns.act(rank, &acting, self, &features, &obs, epsilon, rng, actions, None, q);
        }
        self.stuck = stuck;
    }

    /// The recurrent step of every agent of every episode of `obs` (one batched pass; the
    /// state is carried to the next call): the features `[Σ N_e, H]` its head reads.
    ///
    /// # Panics
    /// As [`Policy::act_batch`].
    pub fn recurrent_step(&mut self, obs: &[&ObsBuffers]) -> Vec<f32> {
        let cfg = &self.config;
        let (fov, channels, vec_dim) = (cfg.fov, cfg.channels, cfg.vec_dim());
        let rows: usize = obs.iter().map(|env| env.n_agents).sum();
        let mut grid = Vec::with_capacity(rows * channels * fov * fov);
        let mut vec = vec![0.0_f32; rows * vec_dim];
        let mut row = 0;
        for env in obs {
            assert!(env.n_agents <= cfg.n_agents_max, "more agents than the network's slots");
            assert_eq!(env.shape.grid_len(), channels * fov * fov, "observation of another size");
            assert_eq!(env.shape.env_vec, cfg.env_vec, "vector of another size");
            grid.extend_from_slice(&env.grid);
            for agent_idx in 0..env.n_agents {
                let out = &mut vec[row * vec_dim..(row + 1) * vec_dim];
                out[..cfg.env_vec].copy_from_slice(
                    &env.vec[agent_idx * cfg.env_vec..(agent_idx + 1) * cfg.env_vec],
                );
                out[cfg.env_vec + agent_idx] = 1.0;
                row += 1;
            }
        }
        let teams: Vec<usize> = obs.iter().map(|env| env.n_agents).collect();
        self.team_rows(&grid, &vec, &teams)
    }

    /// Whether the network reads the whole team's observations ([`QNetConfig::centralised`]):
    /// then it acts only through [`Policy::act_batch`], never one agent alone.
    pub fn is_centralised(&self) -> bool {
        self.config.centralised
    }

    /// The recurrent step of prepared inputs of one agent each (`grid` `[rows, C, F, F]`,
    /// `vec` `[rows, V]` with the agent-slot one-hot), carrying the state: the features
    /// `[rows, H]`.
    ///
    /// # Panics
    /// If the rows differ from the last call's without a reset, or the network is
    /// centralised (it needs the team's rows).
    pub(crate) fn recurrent_rows(&mut self, grid: &[f32], vec: &[f32]) -> Vec<f32> {
        assert!(!self.is_centralised(), "a centralised network acts for whole teams only");
        let rows = vec.len() / self.config.vec_dim();
        self.team_rows(grid, vec, &[rows])
    }

    /// [`Policy::recurrent_rows`] of rows laid out as teams (`teams`: their agent counts).
    fn team_rows(&mut self, grid: &[f32], vec: &[f32], teams: &[usize]) -> Vec<f32> {
        self.net.recurrent(grid, vec, teams, &mut self.state)
    }

    /// The head's Q-values `[n, A]` of `features` `[n, H]` with `message` `[n, M]`.
    pub(crate) fn head(&self, features: &[f32], message: &[f32]) -> Vec<f32> {
        self.net.head(features, message)
    }
}

/// One step's heads in leader order over a batch of episodes, rank by rank: the caller
/// hands each group of agents (those at one rank of some episodes) to the policy they run,
/// and the turns carry each team's message (the one-hot actions chosen at earlier ranks,
/// whichever policy chose them) from rank to rank. Every policy of a step must share the
/// action count and agent slots, so the message means the same to every one.
pub(crate) struct Turns<'s> {
    offsets: Vec<usize>,
    /// `[E, M]`, one message per episode.
    messages: Vec<f32>,
    n_actions: usize,
    msg_dim: usize,
    /// The stall escape and every row's side of it, when the policy has one.
    escape: Option<(Escape, &'s mut [Stuck])>,
}

impl<'s> Turns<'s> {
    /// Turns for the episodes of `obs` (their agent counts), for policies of `config`'s
    /// action count and agent slots.
    pub(crate) fn new(obs: &[&ObsBuffers], config: &QNetConfig) -> Turns<'s> {
        Turns {
            offsets: row_offsets(obs.iter().map(|env| env.n_agents)),
            messages: vec![0.0; obs.len() * config.message_dim()],
            n_actions: config.n_actions,
            msg_dim: config.message_dim(),
            escape: None,
        }
    }

    /// The same turns, every row acting with the stall escape `escape` (the rule and each
    /// row's side of it, rows as in `obs`): an agent not acting at random by ε counts its
    /// cell and may step out of a stall ([`crate::escape`]).
    pub(crate) fn escaping(self, escape: Option<(Escape, &'s mut [Stuck])>) -> Turns<'s> {
        Turns { escape, ..self }
    }

    /// The agents at `rank` of the episodes `episodes` (ascending, each with more than `rank`
    /// agents) go through `policy`'s head together (`features`: its recurrent features of the
    /// whole batch, `[Σ N_e, 1, H]`; `obs`: its observations, for the order and the masks),
    /// each with its team's message; then ε-greedy among the allowed actions, random draws
    /// episode by episode. The allowed actions are the observation's mask, or those of
    /// `masks[row]` when given (`[Σ N_e, A]`). Writes `actions[row]` and, when given, the
    /// masked Q-values `q_out[row]`; with [`Turns::escaping`], a stalled agent may step out.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn act(
        &mut self,
        rank: usize,
        episodes: &[usize],
        policy: &Policy,
        features: &[f32],
        obs: &[&ObsBuffers],
        epsilon: f64,
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
        masks: Option<&[bool]>,
        mut q_out: Option<&mut [f32]>,
    ) {
        let (n_actions, msg_dim) = (self.n_actions, self.msg_dim);
        let cfg = policy.config();
        assert_eq!((cfg.n_actions, cfg.message_dim()), (n_actions, msg_dim), "policies differ");
        if episodes.is_empty() {
            return;
        }
        let hidden = cfg.lstm_hidden;
        let mut feat = Vec::with_capacity(episodes.len() * hidden);
        let mut msg = Vec::with_capacity(episodes.len() * msg_dim);
        for &e in episodes {
            let row = self.offsets[e] + obs[e].order[rank];
            feat.extend_from_slice(&features[row * hidden..(row + 1) * hidden]);
            msg.extend_from_slice(&self.messages[e * msg_dim..(e + 1) * msg_dim]);
        }
        let mut q_all = policy.head(&feat, &msg); // [n, A]
        for (i, &e) in episodes.iter().enumerate() {
            let agent_idx = obs[e].order[rank];
            let row = self.offsets[e] + agent_idx;
            let mask = match masks {
                Some(masks) => &masks[row * n_actions..(row + 1) * n_actions],
                None => obs[e].mask_of(agent_idx),
            };
            let q = &mut q_all[i * n_actions..(i + 1) * n_actions];
            for (value, &ok) in q.iter_mut().zip(mask) {
                if !ok {
                    *value = MASKED_Q;
                }
            }
            let random = rng.random::<f64>() < epsilon;
            let stalled = self.escape.as_mut().is_some_and(|(rule, stuck)| {
                stuck[row].visit(rule, obs[e].vec_of(agent_idx)) && !random
            });
            let action = if random {
                let allowed = mask.iter().filter(|&&ok| ok).count();
                let pick = rng.random_range(0..allowed);
                (0..n_actions).filter(|&a| mask[a]).nth(pick).expect("pick < allowed")
            } else if stalled
                && let Some((rule, stuck)) = self.escape.as_mut()
                && let Some(out) = stuck[row].step_out(rule, mask)
            {
                out
            } else if let Some(temperature) = policy.sampling {
                masked_sample(q, mask, temperature, rng)
            } else {
                masked_argmax(q, mask)
            };
            actions[row] = action as u8;
            if let Some(out) = q_out.as_deref_mut() {
                out[row * n_actions..(row + 1) * n_actions].copy_from_slice(q);
            }
            self.messages[e * msg_dim + agent_idx * n_actions + action] = 1.0;
        }
    }
}

/// `temperature`, checked to be a positive number (or none).
///
/// # Panics
/// If it is not.
fn positive(temperature: Option<f32>) -> Option<f32> {
    assert!(temperature.is_none_or(|t| t.is_finite() && t > 0.0), "temperature {temperature:?}");
    temperature
}

/// An allowed action drawn from the softmax of the scores `q` divided by `temperature`.
fn masked_sample(q: &[f32], mask: &[bool], temperature: f32, rng: &mut ChaCha8Rng) -> usize {
    let best = masked_argmax(q, mask);
    let weights: Vec<f64> = q
        .iter()
        .zip(mask)
        .map(|(&v, &ok)| if ok { f64::from((v - q[best]) / temperature).exp() } else { 0.0 })
        .collect();
    let mut draw = rng.random::<f64>() * weights.iter().sum::<f64>();
    for (a, &w) in weights.iter().enumerate() {
        if w > 0.0 && draw < w {
            return a;
        }
        draw -= w;
    }
    best
}

/// Where each episode's agents start in a batch laid out episode after episode: the running
/// sum of the agent counts before it.
pub(crate) fn row_offsets(agent_counts: impl Iterator<Item = usize>) -> Vec<usize> {
    agent_counts
        .scan(0, |next, n| {
            let at = *next;
            *next += n;
            Some(at)
        })
        .collect()
}
