//! The recurrent Q-network shared by all agents (docs/spec.md §6).
//!
//! One agent's pass: observation encoder (conv or MLP over the `C × F × F` channels, plus the
//! goal vector and the agent-slot one-hot), a stack of LSTM layers, then a small head that takes
//! the recurrent features *and* the action message (one-hot actions of the agents that acted
//! earlier in this step) and returns one Q-value per action.
//! The message enters after the LSTM so that all agents' recurrent passes batch together and
//! only the head runs in leader order.
//!
//! burn 0.22 modules carry no backend type parameter: the backend (flex CPU, CUDA, ...) and
//! autodiff are properties of the [`Device`] the parameters live on, chosen at run time.
//! Parameters are initialised from a seeded [`ChaCha8Rng`] (not burn's device RNG, which is
//! shared process state), so the same seed gives the same network on any thread count.

use burn::module::{Module, ModuleMapper, Param, ParamId};
use burn::nn::conv::Conv2d;
use burn::nn::{Linear, PaddingConfig2d};
use burn::tensor::activation::{relu, sigmoid, tanh};
use burn::tensor::{Device, Int, Tensor, TensorData};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::frozen::{Conv, Dense, FrozenNet, Lstm};

/// Observation encoder choice.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EncoderConfig {
    /// Flatten the channels, concatenate the vector input, then dense layers with ReLU.
    Mlp {
        /// Width of each hidden layer (the last one is the encoder output).
        hidden: Vec<usize>,
    },
    /// 3 × 3 convolutions ("same" padding, ReLU) over the channels, then one dense layer over
    /// the flattened maps and the vector input.
    Conv {
        /// Output channels of each convolution.
        channels: Vec<usize>,
        /// Width of the dense layer after the convolutions (the encoder output).
        hidden: usize,
    },
}

/// Why a network configuration cannot be built ([`QNetConfig::check`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NetConfigError {
    /// A size that is zero or above [`QNetConfig::MAX_SIZE`].
    #[error("network {field} {value} must be between 1 and {}", QNetConfig::MAX_SIZE)]
    Size {
        /// The field.
        field: &'static str,
        /// Its value.
        value: usize,
    },
    /// The field of view must be odd (the agent at its centre).
    #[error("network fov {0} must be odd")]
    EvenFov(usize),
    /// The number of weights overflows.
    #[error("the network has too many weights")]
    TooLarge,
}

/// Sizes of the Q-network (a settings file may give any subset of the fields).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct QNetConfig {
    /// Observation channels `C` (docs/spec.md §4: 4).
    pub channels: usize,
    /// Field of view `F` (odd; docs/spec.md §4: 9).
    pub fov: usize,
    /// Length of the environment's vector observation (goal vector: 3).
    pub env_vec: usize,
    /// Agent slots: the agent-slot one-hot and the message have one block per slot.
    pub n_agents_max: usize,
    /// Number of actions `A` (5 for path finding and formation, 2 for meta).
    pub n_actions: usize,
    /// Observation encoder.
    pub encoder: EncoderConfig,
    /// LSTM hidden size `H` (paper: 256).
    pub lstm_hidden: usize,
    /// Number of stacked LSTM layers (paper: 2).
    pub lstm_layers: usize,
    /// Hidden width of the head (features + message -> hidden -> Q).
    pub head_hidden: usize,
    /// Centralised (the CTCE baseline, docs/spec.md §7): every agent's row also reads the
    /// encodings of its whole team, one block per agent slot, through a dense "team" layer
    /// between the encoder and the LSTM. Such a network acts only with the team's
    /// observations at hand (centralised execution); `false` (the default): each agent reads
    /// its own observation alone.
    pub centralised: bool,
}

impl Default for QNetConfig {
    /// The cheap default: MLP encoder (128), 1 × LSTM-128, head 64; 5 actions, 8 agent slots.
    fn default() -> Self {
        Self {
            channels: 4,
            fov: 9,
            env_vec: 3,
            n_agents_max: 8,
            n_actions: 5,
            encoder: EncoderConfig::Mlp { hidden: vec![128] },
            lstm_hidden: 128,
            lstm_layers: 1,
            head_hidden: 64,
            centralised: false,
        }
    }
}

impl QNetConfig {
    /// The paper's network: conv encoder (32, 32 channels, dense 256), 2 × LSTM-256, head 128.
    pub fn paper() -> Self {
        Self {
            encoder: EncoderConfig::Conv { channels: vec![32, 32], hidden: 256 },
            lstm_hidden: 256,
            lstm_layers: 2,
            head_hidden: 128,
            ..Self::default()
        }
    }

    /// Width of the vector input: environment vector plus the agent-slot one-hot.
    pub fn vec_dim(&self) -> usize {
        self.env_vec + self.n_agents_max
    }

    /// Width of the message input: one action one-hot per agent slot.
    pub fn message_dim(&self) -> usize {
        self.n_agents_max * self.n_actions
    }

    /// The largest width, channel count or layer count a network may have: far beyond any
    /// network phalanx trains (the paper's widest layer is 256), small enough that a corrupt
    /// file cannot ask for a network that does not fit in memory.
    pub const MAX_SIZE: usize = 1 << 14;

    /// Checks that the network can be built: an odd field of view, at least one LSTM layer
    /// and one encoder layer, no size zero or above [`QNetConfig::MAX_SIZE`].
    ///
    /// # Errors
    /// Names the first field that does not fit.
    pub fn check(&self) -> Result<(), NetConfigError> {
        let (widths, layers): (Vec<(&'static str, usize)>, usize) = match &self.encoder {
            EncoderConfig::Mlp { hidden } => {
                (hidden.iter().map(|&w| ("encoder.hidden", w)).collect(), hidden.len())
            }
            EncoderConfig::Conv { channels, hidden } => {
                let mut widths: Vec<_> =
                    channels.iter().map(|&c| ("encoder.channels", c)).collect();
                widths.push(("encoder.hidden", *hidden));
                (widths, channels.len() + 1)
            }
        };
        let sizes = [
            ("channels", self.channels),
            ("fov", self.fov),
            ("env_vec", self.env_vec),
            ("n_agents_max", self.n_agents_max),
            ("n_actions", self.n_actions),
            ("lstm_hidden", self.lstm_hidden),
            ("lstm_layers", self.lstm_layers),
            ("head_hidden", self.head_hidden),
            ("encoder layers", layers),
        ];
        for (field, value) in sizes.into_iter().chain(widths) {
            if value == 0 || value > Self::MAX_SIZE {
                return Err(NetConfigError::Size { field, value });
            }
        }
        if self.fov.is_multiple_of(2) {
            return Err(NetConfigError::EvenFov(self.fov));
        }
        if self.n_params().is_none() {
            return Err(NetConfigError::TooLarge);
        }
        Ok(())
    }

    /// The number of weights of the network, `None` if it overflows.
    pub fn n_params(&self) -> Option<usize> {
        let dense = |d_in: usize, d_out: usize| d_in.checked_mul(d_out)?.checked_add(d_out);
        let area = self.fov.checked_mul(self.fov)?;
        let mut total = 0usize;
        let enc_out = match &self.encoder {
            EncoderConfig::Mlp { hidden } => {
                let mut d_in = self.channels.checked_mul(area)?.checked_add(self.vec_dim())?;
                for &width in hidden {
                    total = total.checked_add(dense(d_in, width)?)?;
                    d_in = width;
                }
                d_in
            }
            EncoderConfig::Conv { channels, hidden } => {
                let mut c_in = self.channels;
                for &c_out in channels {
                    total = total.checked_add(dense(c_in.checked_mul(9)?, c_out)?)?;
                    c_in = c_out;
                }
                let d_in = c_in.checked_mul(area)?.checked_add(self.vec_dim())?;
                total = total.checked_add(dense(d_in, *hidden)?)?;
                *hidden
            }
        };
        if self.centralised {
            let team_in = self.n_agents_max.checked_add(1)?.checked_mul(enc_out)?;
            total = total.checked_add(dense(team_in, enc_out)?)?;
        }
        let gates = self.lstm_hidden.checked_mul(4)?;
        let mut d_in = enc_out;
        for _ in 0..self.lstm_layers {
            let layer =
                d_in.checked_add(self.lstm_hidden)?.checked_mul(gates)?.checked_add(gates)?;
            total = total.checked_add(layer)?;
            d_in = self.lstm_hidden;
        }
        let head_in = self.lstm_hidden.checked_add(self.message_dim())?;
        total = total.checked_add(dense(head_in, self.head_hidden)?)?;
        total.checked_add(dense(self.head_hidden, self.n_actions)?)
    }

    /// Build the network with parameters drawn from `rng` on `device`.
    ///
    /// # Panics
    /// If [`QNetConfig::check`] fails (files and settings are checked before).
    pub fn init(&self, rng: &mut ChaCha8Rng, device: &Device) -> QNet {
        assert!(!self.fov.is_multiple_of(2), "field of view must be odd, got {}", self.fov);
        assert!(self.lstm_layers >= 1, "at least one LSTM layer is needed");
        let grid_len = self.channels * self.fov * self.fov;
        let (convs, dense, enc_out) = match &self.encoder {
            EncoderConfig::Mlp { hidden } => {
                assert!(!hidden.is_empty(), "the MLP encoder needs at least one layer");
                let mut d_in = grid_len + self.vec_dim();
                let mut dense = Vec::new();
                for &width in hidden {
                    dense.push(linear(rng, d_in, width, true, device));
                    d_in = width;
                }
                (Vec::new(), dense, d_in)
            }
            EncoderConfig::Conv { channels, hidden } => {
                let mut c_in = self.channels;
                let mut convs = Vec::new();
                for &c_out in channels {
                    convs.push(conv3x3(rng, c_in, c_out, device));
                    c_in = c_out;
                }
                let d_in = c_in * self.fov * self.fov + self.vec_dim();
                (convs, vec![linear(rng, d_in, *hidden, true, device)], *hidden)
            }
        };
        let mut lstm = Vec::new();
        let mut d_in = enc_out;
        for _ in 0..self.lstm_layers {
            lstm.push(LstmLayer::init(rng, d_in, self.lstm_hidden, device));
            d_in = self.lstm_hidden;
        }
        let head_hidden =
            linear(rng, self.lstm_hidden + self.message_dim(), self.head_hidden, true, device);
        let head_out = linear(rng, self.head_hidden, self.n_actions, true, device);
        // Drawn last, so that a decentralised network of a seed is the one it always was.
        let team = self
            .centralised
            .then(|| linear(rng, (self.n_agents_max + 1) * enc_out, enc_out, true, device));
        QNet { convs, dense, lstm, head_hidden, head_out, team }.map(&mut SequentialIds(0))
    }
}

/// Gives the parameters the ids 0, 1, … in the order the module visits them, instead of
/// burn's random ones: two runs with the same seed then write byte-identical policy files and
/// checkpoints (a file that is loaded keeps the ids it holds).
struct SequentialIds(u64);

impl ModuleMapper for SequentialIds {
    fn map_float<const D: usize>(&mut self, mut param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        param.id = ParamId::from(self.0);
        self.0 += 1;
        param
    }
}

/// The Q-network. Build it with [`QNetConfig::init`].
#[derive(Module, Debug)]
pub struct QNet {
    convs: Vec<Conv2d>,
    dense: Vec<Linear>,
    lstm: Vec<LstmLayer>,
    head_hidden: Linear,
    head_out: Linear,
    /// The team layer of a centralised network ([`QNetConfig::centralised`]): own encoding and
    /// the team's, one block per agent slot, to the encoder's width.
    team: Option<Linear>,
}

/// Recurrent state of a batch: `(cell, hidden)` per LSTM layer, each `[batch, H]`.
#[derive(Clone, Debug)]
pub struct RecurrentState {
    /// One `(cell, hidden)` pair per layer.
    pub layers: Vec<(Tensor<2>, Tensor<2>)>,
}

impl RecurrentState {
    /// Zero state for `batch` sequences.
    pub fn zeros(config: &QNetConfig, batch: usize, device: &Device) -> Self {
        let zeros = || Tensor::<2>::zeros([batch, config.lstm_hidden], device);
        Self { layers: (0..config.lstm_layers).map(|_| (zeros(), zeros())).collect() }
    }

    /// Cut the state from the autodiff graph.
    pub fn detach(self) -> Self {
        Self { layers: self.layers.into_iter().map(|(c, h)| (c.detach(), h.detach())).collect() }
    }
}

impl QNet {
    /// This network (of `config`) with `extra` more environment-vector inputs after those
    /// it has, their weights zero: it computes exactly what it did whatever they hold, so a
    /// network that reads more can start from one that reads less.
    pub fn widen_env_vec(mut self, config: &QNetConfig, extra: usize) -> QNet {
        let first = &mut self.dense[0];
        let weight = first.weight.val(); // [d_in, E]
        let [d_in, width] = weight.dims();
        let at = d_in - config.n_agents_max; // the agent-slot one-hot follows the vector
        let zeros = Tensor::<2>::zeros([extra, width], &weight.device());
        let head = weight.clone().slice([0..at, 0..width]);
        let tail = weight.slice([at..d_in, 0..width]);
        first.weight = Param::initialized(first.weight.id, Tensor::cat(vec![head, zeros, tail], 0));
        self
    }

    /// Whether the network is centralised ([`QNetConfig::centralised`]).
    pub fn is_centralised(&self) -> bool {
        self.team.is_some()
    }

    /// The agent slots of a centralised network's team layer (its input is the own encoding
    /// and one per slot); 0 for a decentralised network.
    fn n_slots(&self) -> usize {
        self.team.as_ref().map_or(0, |team| {
            let [d_in, d_out] = team.weight.dims();
            d_in / d_out - 1
        })
    }

    /// Encoder and LSTM layers over a batch of observation sequences.
    ///
    /// `state` is the state before the first step (`None`: zeros). `teams` lays the rows out
    /// as teams: the agent counts of consecutive blocks of rows, each block a team in
    /// agent-slot order (`[3, 3]`: rows 0–2 one team, 3–5 another); only a centralised
    /// network reads it.
    ///
    /// # Shapes
    /// - `obs`: `[batch, time, C, F, F]`
    /// - `vec`: `[batch, time, V]` (environment vector, then agent-slot one-hot)
    /// - returns features `[batch, time, H]` and the state after the last step
    ///
    /// # Panics
    /// For a centralised network, if `teams` does not add up to `batch` or a team has more
    /// agents than the network's slots.
    pub fn forward_recurrent(
        &self,
        obs: Tensor<5>,
        vec: Tensor<3>,
        state: Option<RecurrentState>,
        teams: &[usize],
    ) -> (Tensor<3>, RecurrentState) {
        let [batch, time, channels, fov, _] = obs.dims();
        let vec_dim = vec.dims()[2];
        let vec = vec.reshape([batch * time, vec_dim]); // [batch * time, V]
        let mut x = if self.convs.is_empty() {
            let grid = obs.reshape([batch * time, channels * fov * fov]); // [batch * time, C*F*F]
            Tensor::cat(vec![grid, vec], 1) // [batch * time, C*F*F + V]
        } else {
            let mut maps = obs.reshape([batch * time, channels, fov, fov]); // [batch * time, C, F, F]
            for conv in &self.convs {
                maps = relu(conv.forward(maps)); // [batch * time, C', F, F]
            }
            let [_, c_out, _, _] = maps.dims();
            let flat = maps.reshape([batch * time, c_out * fov * fov]); // [batch * time, C'*F*F]
            Tensor::cat(vec![flat, vec], 1) // [batch * time, C'*F*F + V]
        };
        for layer in &self.dense {
            x = relu(layer.forward(x)); // [batch * time, E]
        }
        if let Some(team) = &self.team {
            let pooled = team_blocks(x.clone(), teams, batch, time, self.n_slots()); // [batch * time, S*E]
            x = relu(team.forward(Tensor::cat(vec![x, pooled], 1))); // [batch * time, E]
        }
        let enc_dim = x.dims()[1];
        let mut seq = x.reshape([batch, time, enc_dim]); // [batch, time, E]
        let device = seq.device();
        let mut state_in = state.map(|it| it.layers.into_iter());
        let mut layers_out = Vec::with_capacity(self.lstm.len());
        for layer in &self.lstm {
            let init = match &mut state_in {
                Some(it) => it.next().expect("state has one entry per LSTM layer"),
                None => {
                    let zeros = Tensor::<2>::zeros([batch, layer.d_hidden()], &device);
                    (zeros.clone(), zeros)
                }
            };
            let (out, last) = layer.forward(seq, init);
            seq = out; // [batch, time, H]
            layers_out.push(last);
        }
        (seq, RecurrentState { layers: layers_out })
    }

    /// The weights as plain arrays, for acting (`config`: the network's sizes).
    pub(crate) fn frozen(&self, config: &QNetConfig) -> FrozenNet {
        // A layer's bias, zeros where it has none.
        let bias = |bias: &Option<Param<Tensor<1>>>, n: usize| {
            bias.as_ref().map_or_else(|| vec![0.0; n], |b| to_vec(b.val()))
        };
        let dense = |layer: &Linear| {
            let [d_in, d_out] = layer.weight.dims();
            let weight = to_vec(layer.weight.val());
            Dense { d_in, d_out, weight, bias: bias(&layer.bias, d_out) }
        };
        let convs = self
            .convs
            .iter()
            .map(|conv| {
                let [c_out, c_in, _, _] = conv.weight.dims();
                let kernels = to_vec(conv.weight.val());
                Conv::of_kernels(c_in, c_out, &kernels, bias(&conv.bias, c_out))
            })
            .collect();
        let lstm = self
            .lstm
            .iter()
            .map(|layer| Lstm {
                input: dense(&layer.input),
                recurrent: to_vec(layer.recurrent.weight.val()),
                hidden: layer.d_hidden(),
            })
            .collect();
        FrozenNet {
            channels: config.channels,
            fov: config.fov,
            vec_dim: config.vec_dim(),
            convs,
            dense: self.dense.iter().map(dense).collect(),
            team: self.team.as_ref().map(|team| (dense(team), self.n_slots())),
            lstm,
            head_hidden: dense(&self.head_hidden),
            head_out: dense(&self.head_out),
        }
    }

    /// The Q head: recurrent features plus the action message.
    ///
    /// # Shapes
    /// - `features`: `[batch, time, H]`
    /// - `messages`: `[batch, time, M]` (`M = n_agents_max * n_actions`)
    /// - returns `[batch, time, A]`
    pub fn head(&self, features: Tensor<3>, messages: Tensor<3>) -> Tensor<3> {
        let x = Tensor::cat(vec![features, messages], 2); // [batch, time, H + M]
        let x = relu(self.head_hidden.forward(x)); // [batch, time, head_hidden]
        self.head_out.forward(x) // [batch, time, A]
    }
}

/// The team encodings each row of a centralised network reads: for the row of agent `i` of a
/// team at time `t`, the encodings of every agent of that team at `t`, one block per agent
/// slot, zeros in the slots the team does not fill.
///
/// # Shapes
/// - `x`: `[batch * time, E]`, rows `(row, t)` row-major
/// - returns `[batch * time, slots * E]`
fn team_blocks(
    x: Tensor<2>,
    teams: &[usize],
    batch: usize,
    time: usize,
    slots: usize,
) -> Tensor<2> {
    assert_eq!(teams.iter().sum::<usize>(), batch, "the teams must cover the batch's rows");
    let [rows, enc_dim] = x.dims();
    let device = x.device();
    let zero = rows as i64; // the index of the zero row appended below
    let mut idx = Vec::with_capacity(rows * slots);
    let mut first = 0;
    for &n in teams {
        assert!(n <= slots, "a team of {n} agents does not fit {slots} agent slots");
        for _agent in 0..n {
            for t in 0..time {
                idx.extend(
                    (0..slots).map(|j| if j < n { ((first + j) * time + t) as i64 } else { zero }),
                );
            }
        }
        first += n;
    }
    let padded = Tensor::cat(vec![x, Tensor::<2>::zeros([1, enc_dim], &device)], 0); // [rows + 1, E]
    let idx = Tensor::<1, Int>::from_data(TensorData::new(idx, [rows * slots]), &device);
    padded.select(0, idx).reshape([rows, slots * enc_dim]) // [batch * time, S*E]
}

/// One LSTM layer with fused gates: the input projection runs once over the whole sequence and
/// only the `[batch, H] × [H, 4H]` recurrent product runs per step.
/// Gate order in the `4H` axis: input, forget, cell, output.
#[derive(Module, Debug)]
pub struct LstmLayer {
    input: Linear,
    recurrent: Linear,
}

impl LstmLayer {
    /// Uniform(±1/√H) weights (PyTorch's LSTM default); forget-gate bias 1.
    fn init(rng: &mut ChaCha8Rng, d_input: usize, d_hidden: usize, device: &Device) -> Self {
        let bound = 1.0 / (d_hidden as f32).sqrt();
        let weight = |rng: &mut ChaCha8Rng, rows: usize| {
            let data: Vec<f32> =
                (0..rows * 4 * d_hidden).map(|_| rng.random_range(-bound..bound)).collect();
            Param::from_tensor(Tensor::from_data(
                TensorData::new(data, [rows, 4 * d_hidden]),
                device,
            ))
        };
        let input_weight = weight(rng, d_input);
        let recurrent_weight = weight(rng, d_hidden);
        let bias: Vec<f32> = (0..4 * d_hidden)
            .map(|idx| if (d_hidden..2 * d_hidden).contains(&idx) { 1.0 } else { 0.0 })
            .collect();
        let bias =
            Param::from_tensor(Tensor::from_data(TensorData::new(bias, [4 * d_hidden]), device));
        Self {
            input: Linear { weight: input_weight, bias: Some(bias) },
            recurrent: Linear { weight: recurrent_weight, bias: None },
        }
    }

    fn d_hidden(&self) -> usize {
        self.recurrent.weight.dims()[0]
    }

    /// # Shapes
    /// - `seq`: `[batch, time, D]`, `state`: `(cell, hidden)` each `[batch, H]`
    /// - returns `[batch, time, H]` and the last `(cell, hidden)`
    fn forward(
        &self,
        seq: Tensor<3>,
        state: (Tensor<2>, Tensor<2>),
    ) -> (Tensor<3>, (Tensor<2>, Tensor<2>)) {
        let [batch, time, _] = seq.dims();
        let d_hidden = self.d_hidden();
        let projected = self.input.forward(seq); // [batch, time, 4H]
        let (mut cell, mut hidden) = state; // [batch, H] each
        let mut outputs = Vec::with_capacity(time);
        for x_t in time_steps(projected) {
            let x_t = x_t.reshape([batch, 4 * d_hidden]); // [batch, 4H]
            let gates = x_t + self.recurrent.forward(hidden); // [batch, 4H]
            let mut parts = gates.chunk(4, 1).into_iter(); // 4 × [batch, H]
            let mut next = || parts.next().expect("four gates");
            let (i, f, g, o) = (next(), next(), next(), next());
            cell = sigmoid(f) * cell + sigmoid(i) * tanh(g); // [batch, H]
            hidden = sigmoid(o) * tanh(cell.clone()); // [batch, H]
            outputs.push(hidden.clone());
        }
        let out = if time == 1 {
            outputs.pop().expect("one step").reshape([batch, 1, d_hidden]) // [batch, 1, H]
        } else {
            Tensor::stack(outputs, 1) // [batch, time, H]
        };
        (out, (cell, hidden))
    }
}

/// The time steps of `seq`, in order, each `[batch, 1, D]`, cut by halving the sequence
/// again and again. The gradient of a cut is the cut tensor's shape in zeros with the cut's
/// gradient written in (burn's `slice` backward), so cutting one step at a time from the
/// whole sequence costs `time²` zeroed rows in every backward pass (on 128² maps, episodes
/// of 300 steps, most of a fine-tuning update), and halving `2 · time · log₂ time`. The
/// values and gradients are the same: every row of a gradient is its one step's, the
/// others' zeros added to it (docs/learning.md, *The recurrent layer's time steps*).
fn time_steps(seq: Tensor<3>) -> Vec<Tensor<3>> {
    fn cut(seq: Tensor<3>, steps: &mut Vec<Tensor<3>>) {
        let time = seq.dims()[1];
        if time == 1 {
            steps.push(seq);
        } else if time > 1 {
            let half = time / 2;
            cut(seq.clone().narrow(1, 0, half), steps);
            cut(seq.narrow(1, half, time - half), steps);
        }
    }
    let mut steps = Vec::with_capacity(seq.dims()[1]);
    cut(seq, &mut steps);
    steps
}

/// Dense layer with Uniform(±1/√fan_in) weights and biases (PyTorch's default).
fn linear(
    rng: &mut ChaCha8Rng,
    d_input: usize,
    d_output: usize,
    bias: bool,
    device: &Device,
) -> Linear {
    let bound = 1.0 / (d_input as f32).sqrt();
    let weight: Vec<f32> =
        (0..d_input * d_output).map(|_| rng.random_range(-bound..bound)).collect();
    let weight =
        Param::from_tensor(Tensor::from_data(TensorData::new(weight, [d_input, d_output]), device));
    let bias = bias.then(|| {
        let data: Vec<f32> = (0..d_output).map(|_| rng.random_range(-bound..bound)).collect();
        Param::from_tensor(Tensor::from_data(TensorData::new(data, [d_output]), device))
    });
    Linear { weight, bias }
}

/// 3 × 3 convolution, stride 1, "same" padding, Uniform(±1/√fan_in) weights and biases.
fn conv3x3(rng: &mut ChaCha8Rng, c_in: usize, c_out: usize, device: &Device) -> Conv2d {
    let fan_in = c_in * 9;
    let bound = 1.0 / (fan_in as f32).sqrt();
    let weight: Vec<f32> = (0..c_out * fan_in).map(|_| rng.random_range(-bound..bound)).collect();
    let bias: Vec<f32> = (0..c_out).map(|_| rng.random_range(-bound..bound)).collect();
    Conv2d {
        weight: Param::from_tensor(Tensor::from_data(
            TensorData::new(weight, [c_out, c_in, 3, 3]),
            device,
        )),
        bias: Some(Param::from_tensor(Tensor::from_data(TensorData::new(bias, [c_out]), device))),
        stride: [1, 1],
        kernel_size: [3, 3],
        dilation: [1, 1],
        groups: 1,
        padding: PaddingConfig2d::Same,
    }
}

/// Q-value given to masked actions before a max or argmax ("−∞-like", finite to keep sums finite).
pub const MASKED_Q: f32 = -1.0e9;

/// Index of the largest allowed Q-value (ties: the smallest index). Panics if nothing is allowed.
pub fn masked_argmax(q: &[f32], allowed: &[bool]) -> usize {
    assert_eq!(q.len(), allowed.len(), "Q and mask lengths differ");
    let mut best = None;
    for (idx, (&value, &ok)) in q.iter().zip(allowed).enumerate() {
        if ok && best.is_none_or(|(_, best_value)| value > best_value) {
            best = Some((idx, value));
        }
    }
    best.expect("at least one action must be allowed").0
}

/// A `[d0, d1, d2]` tensor from row-major data.
pub(crate) fn tensor3(data: Vec<f32>, shape: [usize; 3], device: &Device) -> Tensor<3> {
    Tensor::from_data(TensorData::new(data, shape), device)
}

/// A float tensor's values, row-major.
pub(crate) fn to_vec<const D: usize>(tensor: Tensor<D>) -> Vec<f32> {
    tensor.into_data().try_to_vec::<f32>().expect("float tensor data")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The halved cuts are the sequence's steps in order, and a loss over them has the
    /// gradient the one-step-at-a-time cuts give, to the bit.
    #[test]
    fn time_steps_are_the_steps_in_order_with_the_same_gradient() {
        let device = Device::flex().autodiff();
        for time in [0_usize, 1, 2, 7, 64] {
            let values: Vec<f32> = (0..2 * time * 3).map(|i| (i as f32 * 0.37).sin()).collect();
            let seq = || {
                Tensor::<3>::from_data(TensorData::new(values.clone(), [2, time, 3]), &device)
                    .require_grad()
            };
            let weight = |t: usize| t as f32 * 0.25 - 1.0;
            let loss = |steps: Vec<Tensor<3>>| {
                let terms = steps.into_iter().enumerate();
                terms.map(|(t, step)| (step * weight(t)).tanh().sum()).reduce(|a, b| a + b)
            };
            let (halved, one_by_one) = (seq(), seq());
            let steps = time_steps(halved.clone());
            assert_eq!(steps.len(), time);
            for (t, step) in steps.iter().enumerate() {
                let expected = one_by_one.clone().narrow(1, t, 1);
                assert_eq!(to_vec(step.clone()), to_vec(expected), "step {t} of {time}");
            }
            let Some(loss_halved) = loss(steps) else { continue };
            let cuts = (0..time).map(|t| one_by_one.clone().narrow(1, t, 1)).collect();
            let loss_one = loss(cuts).expect("as many steps");
            let grad = |loss: Tensor<1>, of: &Tensor<3>| {
                to_vec(of.grad(&loss.backward()).expect("tracked"))
            };
            assert_eq!(grad(loss_halved, &halved), grad(loss_one, &one_by_one), "time {time}");
        }
    }
}
