//! VDN + double DQN over recurrent, parameter-shared agents (docs/spec.md §6; EPyMARL `q_learner.py`).
//!
//! One update:
//! 1. sample `B` sequences ([`Replay::sample`]) and run the online network's recurrent pass for
//!    all `B × N` agent sequences at once (agent-slot one-hot appended to the vector input);
//! 2. Q of the taken actions, with the messages the agents actually saw (actions of the agents
//!    earlier in that step's leader order), summed over agents (VDN);
//! 3. next-state actions chosen greedily by the online network *in leader order* (rank `k`
//!    sees the greedy actions of ranks `0..k` as its message), masked actions excluded;
//! 4. evaluated by the target network with those messages, summed over agents;
//! 5. `y = r + γ (1 − terminated) Q_tot^target(s', a*)` (truncation bootstraps), masked MSE
//!    over filled transitions, global-norm gradient clipping, Adam.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::activation::log_softmax;
use burn::tensor::{Bool, Device, Int, Tensor, TensorData};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::hierarchy::MetaInfo;
use crate::net::{QNet, QNetConfig, tensor3, to_vec};
use crate::policy::Policy;
use crate::replay::{Batch, Episode, Replay};
use phalanx_env::ObsShape;

pub use crate::hyper::{Counters, EpsilonSchedule, LearnerConfig};
pub use crate::net::{MASKED_Q, masked_argmax};

/// What one update reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateStats {
    /// Masked mean squared TD error.
    pub td_loss: f32,
    /// Mean team Q of the taken actions over filled transitions.
    pub q_taken: f32,
    /// Global gradient norm before clipping.
    pub grad_norm: f32,
}

/// What one behaviour-cloning update ([`Learner::imitation_update_on`]) reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImitationStats {
    /// Mean cross-entropy of the labels under the masked action scores, over filled rows.
    pub loss: f32,
    /// Share of filled rows whose greedy action (masked argmax) is the label.
    pub accuracy: f32,
    /// Global gradient norm before clipping.
    pub grad_norm: f32,
}

/// What one policy-gradient update ([`Learner::policy_gradient_update_on`]) reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolicyGradientStats {
    /// The policy-gradient loss, `−Σ A_b log π(a | s)` over the filled rows.
    pub loss: f32,
    /// The behaviour-cloning loss of the expert batch, when the update had one.
    pub cloning_loss: Option<f32>,
    /// Global gradient norm before clipping.
    pub grad_norm: f32,
}

/// The learner: online and target networks, optimiser, replay, counters and RNG.
pub struct Learner {
    pub(crate) net_config: QNetConfig,
    pub(crate) config: LearnerConfig,
    pub(crate) agent_counts: Vec<usize>,
    pub(crate) device: Device,
    pub(crate) online: QNet,
    pub(crate) target: QNet,
    pub(crate) optim: ModuleOptimizer,
    /// One buffer per agent count, in the order of `agent_counts`.
    pub(crate) replays: Vec<Replay>,
    pub(crate) rng: ChaCha8Rng,
    pub(crate) counters: Counters,
    /// For a meta policy: what its checkpoints and policy files record of the hierarchy.
    pub(crate) meta: Option<MetaInfo>,
    /// The team vector's dead band of the environments it learns in: its policies act with
    /// it and its files record it ([`Learner::set_team_deadband`]).
    pub(crate) team_deadband: f64,
}

impl Learner {
    /// A fresh learner for teams of each of the `agent_counts` (one shared network, one
    /// replay buffer per count); `device` must have autodiff enabled
    /// (e.g. `Device::flex().autodiff()`). Everything random derives from `seed`.
    ///
    /// # Panics
    /// If `agent_counts` is empty or a count is 0 or above the network's agent slots.
    pub fn new(
        net_config: QNetConfig,
        config: LearnerConfig,
        agent_counts: &[usize],
        seed: u64,
        device: &Device,
    ) -> Self {
        assert!(device.is_autodiff(), "the learner needs an autodiff device");
        let mut agent_counts = agent_counts.to_vec();
        agent_counts.sort_unstable();
        agent_counts.dedup();
        assert!(!agent_counts.is_empty(), "the learner needs at least one agent count");
        for &n_agents in &agent_counts {
            assert!(
                (1..=net_config.n_agents_max).contains(&n_agents),
                "{n_agents} agents do not fit {} agent slots",
                net_config.n_agents_max
            );
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let online = net_config.init(&mut rng, device);
        let target = online.valid();
        let optim = AdamConfig::new().init();
        let shape = obs_shape(&net_config);
        let capacity = (config.replay_capacity / agent_counts.len()).max(1);
        let replays = agent_counts.iter().map(|&n| Replay::new(capacity, n, shape)).collect();
        Self {
            net_config,
            config,
            agent_counts,
            device: device.clone(),
            online,
            target,
            optim,
            replays,
            rng,
            counters: Counters::default(),
            meta: None,
            team_deadband: phalanx_env::obs::TEAM_DEADBAND,
        }
    }

    /// Network sizes.
    pub fn net_config(&self) -> &QNetConfig {
        &self.net_config
    }

    /// Hyper-parameters.
    pub fn config(&self) -> &LearnerConfig {
        &self.config
    }

    /// The team sizes the learner trains, ascending.
    pub fn agent_counts(&self) -> &[usize] {
        &self.agent_counts
    }

    /// For a meta policy, its formation weights and low-level policies.
    pub fn meta(&self) -> Option<&MetaInfo> {
        self.meta.as_ref()
    }

    /// Record the hierarchy a meta policy is trained in (written with every checkpoint and
    /// policy file).
    pub fn set_meta(&mut self, meta: MetaInfo) {
        self.meta = Some(meta);
    }

    /// Run counters.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Current exploration rate.
    pub fn epsilon(&self) -> f64 {
        self.config.epsilon.value(self.counters.env_steps)
    }

    /// The replay buffers, one per agent count (in the order of [`Learner::agent_counts`]).
    pub fn replays(&self) -> &[Replay] {
        &self.replays
    }

    /// Empties every buffer (the counters, networks and optimiser stay).
    pub fn clear_replays(&mut self) {
        self.replays.iter_mut().for_each(Replay::clear);
    }

    /// Store an episode in the buffer of its agent count.
    ///
    /// # Panics
    /// If the learner does not train teams of that size.
    pub fn store(&mut self, episode: Episode) {
        let n_agents = episode.n_agents;
        let idx = self
            .agent_counts
            .iter()
            .position(|&n| n == n_agents)
            .unwrap_or_else(|| panic!("the learner does not train teams of {n_agents}"));
        self.replays[idx].push(episode);
    }

    /// The learner's RNG (exploration, episode seeds, replay sampling).
    pub fn rng_mut(&mut self) -> &mut ChaCha8Rng {
        &mut self.rng
    }

    /// A greedy/ε-greedy acting policy with the current online weights (no autodiff), acting
    /// with the learner's team-vector dead band.
    pub fn policy(&self) -> Policy {
        let mut policy = Policy::new(&self.online.valid(), self.net_config.clone());
        policy.set_team_deadband(self.team_deadband).expect("checked when set");
        policy
    }

    /// Learns in environments whose team vector has the dead band `cells`
    /// ([`phalanx_env::EnvConfig::team_deadband`]): its policies act with it, and its
    /// checkpoints and policy files record it where it is not the default, so a policy loaded
    /// from them acts as trained.
    ///
    /// # Errors
    /// A band that is negative or not a number.
    pub fn set_team_deadband(&mut self, cells: f64) -> Result<(), phalanx_env::EnvError> {
        phalanx_env::check_team_deadband(cells)?;
        self.team_deadband = cells;
        Ok(())
    }

    /// One gradient update on a batch sampled from one agent count's buffer; `None` while no
    /// buffer holds `learning_starts` episodes. The buffers that do take turns, update by update.
    pub fn update(&mut self) -> Option<UpdateStats> {
        let batch = self.sample()?;
        Some(self.update_on(&batch))
    }

    /// One behaviour-cloning update on a batch sampled as [`Learner::update`] samples (the
    /// buffers holding `learning_starts` episodes take turns); `None` while none does.
    pub fn imitation_update(&mut self) -> Option<ImitationStats> {
        let batch = self.sample()?;
        Some(self.imitation_update_on(&batch))
    }

    /// A batch from the buffers that hold `learning_starts` episodes, taking turns update by
    /// update; `None` while none does.
    fn sample(&mut self) -> Option<Batch> {
        let ready: Vec<usize> = (0..self.replays.len())
            .filter(|&idx| self.replays[idx].len() >= self.config.learning_starts.max(1))
            .collect();
        if ready.is_empty() {
            return None;
        }
        let replay = &self.replays[ready[(self.counters.updates % ready.len() as u64) as usize]];
        Some(replay.sample(self.config.batch_size, self.config.sequence, &mut self.rng))
    }

    /// One behaviour-cloning update on `batch`, whose actions are the expert's labels
    /// (`docs/imitation.md`): the cross-entropy of each agent's label under the softmax of
    /// its masked action scores, each agent's message holding the labels of the agents
    /// ranked before it (what it sees at test time when they act as the expert would),
    /// averaged over filled rows; global-norm clipping, Adam. The target network follows the
    /// online one (cloning has no bootstrap).
    pub fn imitation_update_on(&mut self, batch: &Batch) -> ImitationStats {
        let (loss, accuracy) = self.cloning_loss(batch);
        let (loss, grad_norm) = self.descend(loss);
        ImitationStats { loss, accuracy, grad_norm }
    }

    /// The behaviour-cloning loss of `batch` (the mean cross-entropy of its labels over the
    /// filled rows, `[1]`) and the share of filled rows whose greedy action is the label.
    fn cloning_loss(&self, batch: &Batch) -> (Tensor<1>, f32) {
        let (chosen, filled, correct) = self.label_log_probs(batch, 1.0);
        let n_filled = filled.iter().sum::<f32>().max(1.0);
        let filled = tensor2(filled, [batch.batch * batch.n_agents, batch.len], &self.device);
        ((chosen * filled).sum().neg().div_scalar(n_filled), correct / n_filled) // [1]
    }

    /// One policy-gradient update of the student on its own episodes `batch` (whose actions
    /// it drew itself from the softmax of its scores at `temperature`,
    /// [`crate::Policy::set_sampling`]), each sequence `b` weighted by `advantages[b]`:
    /// `−Σ A_b log π(a | s)` over the filled rows, divided by their count (`π` the softmax at
    /// `temperature`, each agent's message holding the actions of the agents ranked before
    /// it); with `cloning` above 0, plus `cloning` times the behaviour-cloning loss of a
    /// batch drawn from the buffers (the expert data, as [`Learner::imitation_update`] draws
    /// it; none while they are empty), so that what the expert taught on states the
    /// rollouts do not visit is kept; global-norm clipping, one Adam step.
    ///
    /// # Panics
    /// If `advantages` has not one value per sequence.
    pub fn policy_gradient_update_on(
        &mut self,
        batch: &Batch,
        advantages: &[f32],
        temperature: f32,
        cloning: f32,
    ) -> PolicyGradientStats {
        assert_eq!(advantages.len(), batch.batch, "one advantage per sequence");
        let (chosen, filled, _) = self.label_log_probs(batch, temperature);
        let n_filled = filled.iter().sum::<f32>().max(1.0);
        let rows_per_seq = batch.n_agents * batch.len;
        let weights: Vec<f32> =
            filled.iter().enumerate().map(|(i, &f)| f * advantages[i / rows_per_seq]).collect();
        let weights = tensor2(weights, [batch.batch * batch.n_agents, batch.len], &self.device);
        let loss = (chosen * weights).sum().neg().div_scalar(n_filled); // [1]
        let expert = if cloning > 0.0 { self.sample() } else { None };
        let Some(expert) = expert else {
            let (loss, grad_norm) = self.descend(loss);
            return PolicyGradientStats { loss, cloning_loss: None, grad_norm };
        };
        let policy_loss = to_vec(loss.clone().detach())[0];
        let (cloning_loss, _) = self.cloning_loss(&expert);
        let (_, grad_norm) = self.descend(loss + cloning_loss.clone().mul_scalar(cloning));
        let cloning_loss = Some(to_vec(cloning_loss.detach())[0]);
        PolicyGradientStats { loss: policy_loss, cloning_loss, grad_norm }
    }

    /// A fresh Adam (the moments of the updates so far forgotten) at learning rate `lr`: the
    /// start of a phase with another objective (the fine-tuning after cloning).
    pub fn restart_optimizer(&mut self, lr: f64) {
        self.optim = AdamConfig::new().init();
        self.config.lr = lr;
    }

    /// The log-probability `[B·N, L]` of each row's action of `batch` under the softmax of
    /// its masked scores divided by `temperature` (each agent's message holding the actions of the agents ranked
    /// before it), the filled flag of each row (`[B·N·L]`) and how many filled rows' greedy
    /// action is the batch's.
    fn label_log_probs(&self, batch: &Batch, temperature: f32) -> (Tensor<2>, Vec<f32>, f32) {
        let cfg = &self.net_config;
        let (n_batch, n_agents, len) = (batch.batch, batch.n_agents, batch.len);
        let (n_obs, n_actions, rows) = (len + 1, cfg.n_actions, batch.batch * batch.n_agents);
        let ranks = ranks_of(&batch.order, n_batch * n_obs, n_agents);
        let teams = vec![n_agents; n_batch];
        let (obs, vec) = batch_inputs(batch, cfg, &self.device);
        let (features, _) = self.online.forward_recurrent(obs, vec, None, &teams); // [B*N, L+1, H]
        let labels = pad_actions(&batch.actions, rows, len);
        let msgs = messages(&ranks, &labels, batch, cfg, n_agents); // [B, N, L+1, M]
        let msgs = tensor3(msgs, [rows, n_obs, cfg.message_dim()], &self.device);
        let scores = self.online.head(features, msgs); // [B*N, L+1, A]
        let allowed = Tensor::<3, Bool>::from_data(
            TensorData::new(batch.action_mask.clone(), [rows, n_obs, n_actions]),
            &self.device,
        );
        let scores = mask_q(scores, allowed).narrow(1, 0, len); // [B*N, L, A]
        let log_p = log_softmax(scores.clone().div_scalar(temperature), 2); // [B*N, L, A]
        let idx: Vec<i64> = batch.actions.iter().map(|&a| i64::from(a)).collect();
        let idx = Tensor::<3, Int>::from_data(TensorData::new(idx, [rows, len, 1]), &self.device);
        let chosen = log_p.gather(2, idx).reshape([rows, len]); // [B*N, L]
        let mut filled = Vec::with_capacity(rows * len);
        for b in 0..n_batch {
            for _agent in 0..n_agents {
                filled.extend_from_slice(&batch.filled[b * len..(b + 1) * len]);
            }
        }
        let greedy = to_vec(scores.detach()); // [B*N, L, A]
        let correct: f32 = (0..rows * len)
            .filter(|&row| filled[row] > 0.0)
            .filter(|&row| {
                let q = &greedy[row * n_actions..(row + 1) * n_actions];
                let best = (0..n_actions).fold(0, |best, a| if q[a] > q[best] { a } else { best });
                best == usize::from(batch.actions[row])
            })
            .count() as f32;
        (chosen, filled, correct)
    }

    /// One gradient update on the given batch.
    pub fn update_on(&mut self, batch: &Batch) -> UpdateStats {
        let cfg = &self.net_config;
        let (n_batch, n_agents, len) = (batch.batch, batch.n_agents, batch.len);
        let n_obs = len + 1;
        let n_actions = cfg.n_actions;
        let ranks = ranks_of(&batch.order, n_batch * n_obs, n_agents);
        let teams = vec![n_agents; n_batch]; // rows `b * N + agent`

        let (features, q_taken) = {
            let (obs, vec) = batch_inputs(batch, cfg, &self.device);
            let (features, _) = self.online.forward_recurrent(obs, vec, None, &teams); // [B*N, L+1, H]
            let taken_actions = pad_actions(&batch.actions, n_batch * n_agents, len);
            let msgs = messages(&ranks, &taken_actions, batch, cfg, n_agents); // [B, N, L+1, M]
            let msgs = tensor3(msgs, [n_batch * n_agents, n_obs, cfg.message_dim()], &self.device);
            let q = self.online.head(features.clone(), msgs); // [B*N, L+1, A]
            let q = q.reshape([n_batch, n_agents, n_obs, n_actions]).narrow(2, 0, len); // [B, N, L, A]
            let idx: Vec<i64> = batch.actions.iter().map(|&a| i64::from(a)).collect();
            let idx = Tensor::<4, Int>::from_data(
                TensorData::new(idx, [n_batch, n_agents, len, 1]),
                &self.device,
            ); // [B, N, L, 1]
            let chosen = q.gather(3, idx).reshape([n_batch, n_agents, len]); // [B, N, L]
            (features, vdn_sum(chosen)) // [B, L]
        };

        // Double DQN: greedy next actions from the online net (no gradient), in leader order.
        let detached = features.detach(); // [B*N, L+1, H]
        let mut greedy = vec![0_u8; n_batch * n_agents * n_obs];
        for rank in 0..n_agents {
            let msgs = messages_upto(&ranks, &greedy, batch, cfg, n_agents, rank);
            let msgs = tensor3(msgs, [n_batch * n_agents, n_obs, cfg.message_dim()], &self.device);
            let q = to_vec(self.online.head(detached.clone(), msgs)); // [B*N, L+1, A]
            for b in 0..n_batch {
                for t in 0..n_obs {
                    let agent_idx = batch.order[(b * n_obs + t) * n_agents + rank];
                    let row = (b * n_agents + agent_idx) * n_obs + t;
                    greedy[row] = masked_argmax(
                        &q[row * n_actions..(row + 1) * n_actions],
                        &batch.action_mask[row * n_actions..(row + 1) * n_actions],
                    ) as u8;
                }
            }
        }
        let plain = self.device.clone().inner();
        let (obs, vec) = batch_inputs(batch, cfg, &plain);
        let (target_features, _) = self.target.forward_recurrent(obs, vec, None, &teams); // [B*N, L+1, H]
        let msgs = messages(&ranks, &greedy, batch, cfg, n_agents);
        let msgs = tensor3(msgs, [n_batch * n_agents, n_obs, cfg.message_dim()], &plain);
        let q_target = to_vec(self.target.head(target_features, msgs)); // [B*N, L+1, A]
        let mut next_values = vec![0.0_f32; n_batch * len];
        for b in 0..n_batch {
            for t in 0..len {
                next_values[b * len + t] = (0..n_agents)
                    .map(|agent_idx| {
                        let row = (b * n_agents + agent_idx) * n_obs + t + 1;
                        q_target[row * n_actions + usize::from(greedy[row])]
                    })
                    .sum();
            }
        }
        let targets =
            td_targets(&batch.rewards, &batch.terminated, &next_values, self.config.gamma);

        let targets = tensor2(targets, [n_batch, len], &self.device); // [B, L]
        let filled = tensor2(batch.filled.clone(), [n_batch, len], &self.device); // [B, L]
        let n_filled = batch.filled.iter().sum::<f32>().max(1.0);
        let q_mean = to_vec((q_taken.clone().detach() * filled.clone()).sum())[0] / n_filled;
        let td = (q_taken - targets) * filled; // [B, L]
        let loss = td.square().sum().div_scalar(n_filled); // [1]
        let (td_loss, grad_norm) = self.descend(loss);
        UpdateStats { td_loss, q_taken: q_mean, grad_norm }
    }

    /// One optimiser step down `loss`: gradients, global-norm clipping, Adam, the update
    /// counted and the target network synchronised every `target_update_interval` updates.
    /// Returns the loss's value and the gradient norm before clipping.
    fn descend(&mut self, loss: Tensor<1>) -> (f32, f32) {
        let value = to_vec(loss.clone().detach())[0];
        let mut grads = GradientsParams::from_grads(loss.backward(), &self.online);
        let grad_norm = clip_global_norm(&self.online, &mut grads, self.config.grad_clip_norm);
        self.online = self.optim.step(self.config.lr, self.online.clone(), grads);
        self.counters.updates += 1;
        if self.counters.updates.is_multiple_of(self.config.target_update_interval.max(1)) {
            self.target = self.online.valid();
        }
        (value, grad_norm)
    }
}

/// The observation shape a network expects.
pub fn obs_shape(config: &QNetConfig) -> ObsShape {
    ObsShape {
        channels: config.channels,
        fov: config.fov,
        env_vec: config.env_vec,
        n_actions: config.n_actions,
    }
}

/// Replace the Q-values of masked actions by [`MASKED_Q`].
///
/// # Shapes
/// - `q`, `allowed`: `[batch, time, A]`
pub fn mask_q(q: Tensor<3>, allowed: Tensor<3, Bool>) -> Tensor<3> {
    q.mask_fill(allowed.bool_not(), MASKED_Q) // [batch, time, A]
}

/// VDN mixer: the team Q is the sum of the agents' Q.
///
/// # Shapes
/// - `q_agents`: `[batch, n_agents, time]`
/// - returns `[batch, time]`
pub fn vdn_sum(q_agents: Tensor<3>) -> Tensor<2> {
    let [batch, _, time] = q_agents.dims();
    q_agents.sum_dim(1).reshape([batch, time]) // [batch, time]
}

/// One-step TD targets `r + γ (1 − terminated) next`, all slices `[B, L]`.
pub fn td_targets(
    rewards: &[f32],
    terminated: &[f32],
    next_values: &[f32],
    gamma: f32,
) -> Vec<f32> {
    assert!(rewards.len() == terminated.len() && rewards.len() == next_values.len());
    rewards
        .iter()
        .zip(terminated)
        .zip(next_values)
        .map(|((&r, &done), &next)| r + gamma * (1.0 - done) * next)
        .collect()
}

/// Scale the gradients so that their global L2 norm is at most `max_norm`; returns the norm
/// before clipping.
fn clip_global_norm(model: &QNet, grads: &mut GradientsParams, max_norm: Option<f32>) -> f32 {
    struct SquaredNorms<'a> {
        grads: &'a GradientsParams,
        parts: Vec<Tensor<1>>,
    }
    impl ModuleVisitor for SquaredNorms<'_> {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            if let Some(grad) = self.grads.get::<D>(param.id) {
                self.parts.push(grad.square().sum());
            }
        }
    }
    struct Scale<'a> {
        grads: &'a mut GradientsParams,
        scale: f32,
    }
    impl ModuleVisitor for Scale<'_> {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            if let Some(grad) = self.grads.remove::<D>(param.id) {
                self.grads.register(param.id, grad.mul_scalar(self.scale));
            }
        }
    }
    let mut norms = SquaredNorms { grads, parts: Vec::new() };
    model.visit(&mut norms);
    if norms.parts.is_empty() {
        return 0.0;
    }
    let norm = to_vec(Tensor::cat(norms.parts, 0).sum())[0].sqrt();
    if let Some(max_norm) = max_norm
        && norm > max_norm
    {
        model.visit(&mut Scale { grads, scale: max_norm / (norm + 1e-6) });
    }
    norm
}

/// Network inputs of a batch: grids `[B*N, L+1, C, F, F]` and vectors `[B*N, L+1, V]` with
/// the agent-slot one-hot.
fn batch_inputs(batch: &Batch, cfg: &QNetConfig, device: &Device) -> (Tensor<5>, Tensor<3>) {
    let rows = batch.batch * batch.n_agents;
    let n_obs = batch.len + 1;
    let grid = Tensor::<5>::from_data(
        TensorData::new(batch.grid.clone(), [rows, n_obs, cfg.channels, cfg.fov, cfg.fov]),
        device,
    );
    let vec_dim = cfg.vec_dim();
    let mut vec = vec![0.0_f32; rows * n_obs * vec_dim];
    for row in 0..rows {
        let agent_idx = row % batch.n_agents;
        for t in 0..n_obs {
            let src = (row * n_obs + t) * cfg.env_vec;
            let dst = (row * n_obs + t) * vec_dim;
            vec[dst..dst + cfg.env_vec].copy_from_slice(&batch.vec[src..src + cfg.env_vec]);
            vec[dst + cfg.env_vec + agent_idx] = 1.0;
        }
    }
    (grid, tensor3(vec, [rows, n_obs, vec_dim], device))
}

/// `ranks[(bt) * N + agent] = rank` from `order[(bt) * N + rank] = agent`.
fn ranks_of(order: &[usize], n_steps: usize, n_agents: usize) -> Vec<usize> {
    let mut ranks = vec![0; n_steps * n_agents];
    for step in 0..n_steps {
        for rank in 0..n_agents {
            ranks[step * n_agents + order[step * n_agents + rank]] = rank;
        }
    }
    ranks
}

/// Actions `[rows, L]` padded to `[rows, L + 1]` (no action after the last observation).
fn pad_actions(actions: &[u8], rows: usize, len: usize) -> Vec<u8> {
    let mut res = vec![0; rows * (len + 1)];
    for row in 0..rows {
        res[row * (len + 1)..row * (len + 1) + len]
            .copy_from_slice(&actions[row * len..(row + 1) * len]);
    }
    res
}

/// Messages `[B, N, L+1, M]`: agent `i` sees the actions of all agents ranked before it.
fn messages(
    ranks: &[usize],
    actions: &[u8],
    batch: &Batch,
    cfg: &QNetConfig,
    n_agents: usize,
) -> Vec<f32> {
    messages_upto(ranks, actions, batch, cfg, n_agents, n_agents)
}

/// Messages `[B, N, L+1, M]` from `actions` `[B, N, L+1]`, counting only senders ranked below
/// `rank_limit` (the agents already decided).
fn messages_upto(
    ranks: &[usize],
    actions: &[u8],
    batch: &Batch,
    cfg: &QNetConfig,
    n_agents: usize,
    rank_limit: usize,
) -> Vec<f32> {
    let n_obs = batch.len + 1;
    let msg_dim = cfg.message_dim();
    let mut res = vec![0.0_f32; batch.batch * n_agents * n_obs * msg_dim];
    for b in 0..batch.batch {
        for t in 0..n_obs {
            let step = b * n_obs + t;
            for receiver in 0..n_agents {
                let receiver_rank = ranks[step * n_agents + receiver];
                let dst = ((b * n_agents + receiver) * n_obs + t) * msg_dim;
                for sender in 0..n_agents {
                    let sender_rank = ranks[step * n_agents + sender];
                    if sender_rank < receiver_rank && sender_rank < rank_limit {
                        let action = usize::from(actions[(b * n_agents + sender) * n_obs + t]);
                        res[dst + sender * cfg.n_actions + action] = 1.0;
                    }
                }
            }
        }
    }
    res
}

pub(crate) fn tensor2(data: Vec<f32>, shape: [usize; 2], device: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(data, shape), device)
}
