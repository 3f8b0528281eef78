//! The forward pass of a frozen [`crate::QNet`] for acting, written for its fixed sizes.
//!
//! Acting runs one time step for a handful of rows (the agents of a team, of a few episodes in
//! lockstep) through three small networks per agent in the hierarchy. Through burn's general
//! tensor operations most of that time went to dispatch, allocation and a matrix kernel made
//! for large products (docs/hierarchy.md, *Speed*). [`FrozenNet`] holds the weights as plain
//! arrays and runs the same layers with loops the compiler vectorises:
//!
//! - **one summation order**: every output is its bias plus the products of its inputs in
//!   ascending input order, each added with one fused multiply-add. A row's result therefore
//!   does not depend on the other rows of the batch, on the thread count or on the vector width
//!   (the AVX-512, AVX2 and portable paths give the same bits: a fused multiply-add is exactly
//!   rounded however it is computed);
//! - **zero inputs are skipped**: the observation channels, the agent-slot one-hot, the
//!   message and the ReLU outputs are mostly zeros. Adding a zero product leaves a sum as it
//!   is (up to the sign of a zero), so skipping it changes no result;
//! - **its own `exp`**: the LSTM's sigmoids and tanhs use a polynomial exponential (relative
//!   error about 2 × 10⁻⁷) instead of the C library's, so that they vectorise and give the same
//!   bits on every platform.
//!
//! It agrees with [`crate::QNet::forward_recurrent`] and [`crate::QNet::head`] to rounding
//! (tested to 10⁻⁴ on every kind of network); training keeps burn's network, whose gradients
//! it needs.

/// A dense layer: `out = bias + x · weight`, `weight` `[d_in, d_out]` row-major.
#[derive(Clone, Debug)]
pub(crate) struct Dense {
    pub(crate) d_in: usize,
    pub(crate) d_out: usize,
    pub(crate) weight: Vec<f32>,
    pub(crate) bias: Vec<f32>,
}

impl Dense {
    /// `out[r] = bias + x[r] · weight` for every row of `x` (`[rows, d_in]`; `out` `[rows,
    /// d_out]`).
    fn forward(&self, x: &[f32], out: &mut [f32]) {
        for row in out.chunks_exact_mut(self.d_out) {
            row.copy_from_slice(&self.bias);
        }
        matmul_acc(x, self.d_in, &self.weight, self.d_out, out);
    }
}

/// A 3 × 3 convolution, stride 1, "same" padding, run as a product of each cell's 3 × 3
/// patch (zeros beyond the edge) with the kernels: `weight` `[c_in × 9, c_out]` (the input
/// channel, then the kernel row and column).
#[derive(Clone, Debug)]
pub(crate) struct Conv {
    pub(crate) c_in: usize,
    pub(crate) c_out: usize,
    pub(crate) weight: Vec<f32>,
    pub(crate) bias: Vec<f32>,
}

impl Conv {
    /// The layer of burn's kernels `[c_out, c_in, 3, 3]`.
    pub(crate) fn of_kernels(c_in: usize, c_out: usize, kernels: &[f32], bias: Vec<f32>) -> Conv {
        let patch = c_in * 9;
        let mut weight = vec![0.0; patch * c_out];
        for co in 0..c_out {
            for p in 0..patch {
                weight[p * c_out + co] = kernels[co * patch + p];
            }
        }
        Conv { c_in, c_out, weight, bias }
    }

    /// One row's maps `x` `[c_in, fov, fov]` to `out` `[c_out, fov, fov]`, with ReLU.
    fn forward_relu(&self, fov: usize, x: &[f32], out: &mut [f32]) {
        let (area, patch) = (fov * fov, self.c_in * 9);
        let mut patches = vec![0.0; area * patch];
        for (cell, row) in patches.chunks_exact_mut(patch).enumerate() {
            let (y, x_at) = (cell / fov, cell % fov);
            for ci in 0..self.c_in {
                for dy in 0..3 {
                    for dx in 0..3 {
                        let (sy, sx) = ((y + dy).wrapping_sub(1), (x_at + dx).wrapping_sub(1));
                        if sy < fov && sx < fov {
                            row[ci * 9 + dy * 3 + dx] = x[ci * area + sy * fov + sx];
                        }
                    }
                }
            }
        }
        let mut maps = vec![0.0; area * self.c_out];
        for cell in maps.chunks_exact_mut(self.c_out) {
            cell.copy_from_slice(&self.bias);
        }
        matmul_acc(&patches, patch, &self.weight, self.c_out, &mut maps); // [area, c_out]
        for (cell, values) in maps.chunks_exact(self.c_out).enumerate() {
            for (co, &v) in values.iter().enumerate() {
                out[co * area + cell] = v.max(0.0);
            }
        }
    }
}

/// One LSTM layer: `gates = x · input + bias + hidden · recurrent`, gate order input,
/// forget, cell, output (as [`crate::net::LstmLayer`]).
#[derive(Clone, Debug)]
pub(crate) struct Lstm {
    pub(crate) input: Dense,
    /// `[H, 4H]`.
    pub(crate) recurrent: Vec<f32>,
    pub(crate) hidden: usize,
}

/// The weights of a [`crate::QNet`] (`QNet::frozen`) as plain arrays, for acting
/// ([`FrozenNet::recurrent`], [`FrozenNet::head`]).
#[derive(Clone, Debug)]
pub(crate) struct FrozenNet {
    pub(crate) channels: usize,
    pub(crate) fov: usize,
    pub(crate) vec_dim: usize,
    pub(crate) convs: Vec<Conv>,
    pub(crate) dense: Vec<Dense>,
    /// A centralised network's team layer: own encoding and one block per agent slot.
    pub(crate) team: Option<(Dense, usize)>,
    pub(crate) lstm: Vec<Lstm>,
    pub(crate) head_hidden: Dense,
    pub(crate) head_out: Dense,
}

/// The recurrent state of a batch of rows: `(cell, hidden)` per LSTM layer, each `[rows, H]`.
pub(crate) type State = Vec<(Vec<f32>, Vec<f32>)>;

impl FrozenNet {
    /// The LSTM width.
    pub(crate) fn hidden(&self) -> usize {
        self.lstm.last().map_or(0, |layer| layer.hidden)
    }

    /// One time step of every row: `grid` `[rows, C, F, F]`, `vec` `[rows, V]` (environment
    /// vector, then the agent-slot one-hot), `teams` the agent counts of consecutive blocks
    /// of rows (read by a centralised network only), `state` carried (zeros when `None`).
    /// Returns the features `[rows, H]` the head reads.
    pub(crate) fn recurrent(
        &self,
        grid: &[f32],
        vec: &[f32],
        teams: &[usize],
        state: &mut Option<State>,
    ) -> Vec<f32> {
        let grid_len = self.channels * self.fov * self.fov;
        let rows = vec.len() / self.vec_dim;
        assert_eq!(grid.len(), rows * grid_len, "one grid per row");
        let mut x = self.encoder_input(grid, vec, rows);
        for layer in &self.dense {
            x = relu_dense(layer, &x, rows);
        }
        if let Some((team, slots)) = &self.team {
            x = relu_dense(team, &team_input(&x, teams, *slots, rows), rows);
        }
        let state = state.get_or_insert_with(|| {
            self.lstm
                .iter()
                .map(|layer| (vec![0.0; rows * layer.hidden], vec![0.0; rows * layer.hidden]))
                .collect()
        });
        assert_eq!(state[0].0.len(), rows * self.hidden(), "agent counts changed without a reset");
        for (layer, (cell, hidden)) in self.lstm.iter().zip(state.iter_mut()) {
            lstm_step(layer, &x, rows, cell, hidden);
            x.clone_from(hidden);
        }
        x
    }

    /// The encoder's input rows: the grid (or the convolutions' maps) and the vector.
    fn encoder_input(&self, grid: &[f32], vec: &[f32], rows: usize) -> Vec<f32> {
        let area = self.fov * self.fov;
        let grid_len = self.channels * area;
        let maps = self.convs.last().map_or(self.channels, |conv| conv.c_out) * area;
        let width = maps + self.vec_dim;
        let mut x = vec![0.0; rows * width];
        for (r, out) in x.chunks_exact_mut(width).enumerate() {
            let own = &grid[r * grid_len..(r + 1) * grid_len];
            if self.convs.is_empty() {
                out[..maps].copy_from_slice(own);
            } else {
                let mut input = own.to_vec();
                for conv in &self.convs {
                    let mut next = vec![0.0; conv.c_out * area];
                    conv.forward_relu(self.fov, &input, &mut next);
                    input = next;
                }
                out[..maps].copy_from_slice(&input);
            }
            out[maps..].copy_from_slice(&vec[r * self.vec_dim..(r + 1) * self.vec_dim]);
        }
        x
    }

    /// The Q-values `[rows, A]` of `features` `[rows, H]` with `message` `[rows, M]`.
    pub(crate) fn head(&self, features: &[f32], message: &[f32]) -> Vec<f32> {
        let h = self.hidden();
        let rows = features.len() / h;
        let m = self.head_hidden.d_in - h;
        assert_eq!(message.len(), rows * m, "one message per row");
        let mut x = vec![0.0; rows * (h + m)];
        for (r, out) in x.chunks_exact_mut(h + m).enumerate() {
            out[..h].copy_from_slice(&features[r * h..(r + 1) * h]);
            out[h..].copy_from_slice(&message[r * m..(r + 1) * m]);
        }
        let hidden = relu_dense(&self.head_hidden, &x, rows);
        let mut q = vec![0.0; rows * self.head_out.d_out];
        self.head_out.forward(&hidden, &mut q);
        q
    }
}

/// `relu(layer(x))` for `rows` rows.
fn relu_dense(layer: &Dense, x: &[f32], rows: usize) -> Vec<f32> {
    let mut out = vec![0.0; rows * layer.d_out];
    layer.forward(x, &mut out);
    for value in &mut out {
        *value = value.max(0.0);
    }
    out
}

/// A centralised network's team-layer input: each row's own encoding, then the encodings of
/// every agent of its team, one block per agent slot, zeros in the slots the team leaves.
fn team_input(x: &[f32], teams: &[usize], slots: usize, rows: usize) -> Vec<f32> {
    assert_eq!(teams.iter().sum::<usize>(), rows, "the teams must cover the batch's rows");
    let e = x.len() / rows;
    let width = (slots + 1) * e;
    let mut out = vec![0.0; rows * width];
    let mut first = 0;
    for &n in teams {
        assert!(n <= slots, "a team of {n} agents does not fit {slots} agent slots");
        for row in first..first + n {
            let dst = &mut out[row * width..(row + 1) * width];
            dst[..e].copy_from_slice(&x[row * e..(row + 1) * e]);
            dst[e..(n + 1) * e].copy_from_slice(&x[first * e..(first + n) * e]);
        }
        first += n;
    }
    out
}

/// One LSTM step of `rows` rows with input `x` `[rows, D]`, updating `cell` and `hidden`.
fn lstm_step(layer: &Lstm, x: &[f32], rows: usize, cell: &mut [f32], hidden: &mut [f32]) {
    let h = layer.hidden;
    let mut gates = vec![0.0; rows * 4 * h];
    layer.input.forward(x, &mut gates);
    matmul_acc(hidden, h, &layer.recurrent, 4 * h, &mut gates);
    lstm_update(&gates, h, cell, hidden);
}

/// Defines a function whose body is compiled three times: for AVX-512, for AVX2 with FMA and
/// as portable code; each call runs the widest the processor has (detected once). The bits
/// of the result are the same on each: the bodies use fused multiply-adds and no
/// reassociation. `$at` is the same function run at a given level (for the tests).
macro_rules! vectorised {
    ($(#[$meta:meta])* $vis:vis fn $name:ident / $at:ident ($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            $at(simd::detected(), $($arg),*)
        }

        #[doc = concat!(
            "[`", stringify!($name), "`] with the vector instructions of `level` (which the ",
            "processor must have)."
        )]
        fn $at(level: simd::Level, $($arg: $ty),*) {
            #[inline(always)]
            fn portable($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx2,fma")]
                fn avx512($($arg: $ty),*) {
                    portable($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($arg: $ty),*) {
                    portable($($arg),*)
                }
                assert!(level <= simd::detected(), "the processor lacks {level:?}");
                match level {
                    // SAFETY: the processor has these features (checked above).
                    simd::Level::Avx512 => return unsafe { avx512($($arg),*) },
                    // SAFETY: as above.
                    simd::Level::Avx2 => return unsafe { avx2($($arg),*) },
                    simd::Level::Portable => {}
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = level;
            portable($($arg),*)
        }
    };
}

mod simd {
    /// Vector instruction sets, narrowest first.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
    pub(super) enum Level {
        Portable,
        #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
        Avx2,
        #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
        Avx512,
    }

    /// The widest the processor has (detected on first use).
    #[cfg(target_arch = "x86_64")]
    pub(super) fn detected() -> Level {
        static LEVEL: std::sync::LazyLock<Level> = std::sync::LazyLock::new(|| {
            let fma = std::arch::is_x86_feature_detected!("fma");
            if fma && std::arch::is_x86_feature_detected!("avx512f") {
                Level::Avx512
            } else if fma && std::arch::is_x86_feature_detected!("avx2") {
                Level::Avx2
            } else {
                Level::Portable
            }
        });
        *LEVEL
    }

    /// Portable code only.
    #[cfg(not(target_arch = "x86_64"))]
    pub(super) fn detected() -> Level {
        Level::Portable
    }
}

vectorised! {
    /// The LSTM cell update of every row from its gates (`[rows, 4H]`, order input, forget,
    /// cell, output): `c = σ(f) c + σ(i) tanh(g)`, `h = σ(o) tanh(c)`.
    fn lstm_update / lstm_update_at(gates: &[f32], h: usize, cell: &mut [f32], hidden: &mut [f32]) {
        let rows = gates.chunks_exact(4 * h).zip(cell.chunks_exact_mut(h));
        for ((g, c), hid) in rows.zip(hidden.chunks_exact_mut(h)) {
            let (i, f, cand, o) = (&g[..h], &g[h..2 * h], &g[2 * h..3 * h], &g[3 * h..]);
            for j in 0..h {
                c[j] = sigmoid(f[j]).mul_add(c[j], sigmoid(i[j]) * tanh(cand[j]));
                hid[j] = sigmoid(o[j]) * tanh(c[j]);
            }
        }
    }
}

/// Outputs per tile: four AVX-512 registers (a tile of up to four rows keeps its sixteen
/// accumulators in registers while the weights' rows stream through).
const TILE: usize = 64;

vectorised! {
    /// `out[r] += x[r] · w` for every row: `x` `[rows, d_in]`, `w` `[d_in, d_out]`, `out`
    /// `[rows, d_out]`. Each output adds its products in ascending input order, one fused
    /// multiply-add each; an input that is zero in every row of a tile is skipped (adding
    /// `0 · w` leaves a sum as it is, up to the sign of a zero, as the weights are finite).
    fn matmul_acc / matmul_acc_at(
        x: &[f32],
        d_in: usize,
        w: &[f32],
        d_out: usize,
        out: &mut [f32],
    ) {
        assert_eq!(w.len(), d_in * d_out, "weights of another shape");
        assert_eq!(x.len() / d_in, out.len() / d_out, "one output row per input row");
        let rows = out.len() / d_out;
        let mut r0 = 0;
        while r0 < rows {
            let tile_rows = (rows - r0).min(4);
            let x = &x[r0 * d_in..(r0 + tile_rows) * d_in];
            let out = &mut out[r0 * d_out..(r0 + tile_rows) * d_out];
            match tile_rows {
                4 => tile::<4>(x, d_in, w, d_out, out),
                3 => tile::<3>(x, d_in, w, d_out, out),
                2 => tile::<2>(x, d_in, w, d_out, out),
                _ => tile::<1>(x, d_in, w, d_out, out),
            }
            r0 += tile_rows;
        }
    }
}

/// [`matmul_acc`] of `R` rows: whole tiles of [`TILE`] outputs, then of 16 (one AVX-512
/// register), with the accumulators in registers; then the outputs left over.
#[inline(always)]
fn tile<const R: usize>(x: &[f32], d_in: usize, w: &[f32], d_out: usize, out: &mut [f32]) {
    let mut j0 = 0;
    while j0 + TILE <= d_out {
        block::<R, TILE>(x, d_in, w, d_out, out, j0);
        j0 += TILE;
    }
    while j0 + 16 <= d_out {
        block::<R, 16>(x, d_in, w, d_out, out, j0);
        j0 += 16;
    }
    if j0 < d_out {
        for i in 0..R {
            let acc = &mut out[i * d_out + j0..(i + 1) * d_out];
            for (k, &v) in x[i * d_in..(i + 1) * d_in].iter().enumerate() {
                if v != 0.0 {
                    for (a, &wv) in acc.iter_mut().zip(&w[k * d_out + j0..(k + 1) * d_out]) {
                        *a = v.mul_add(wv, *a);
                    }
                }
            }
        }
    }
}

/// The outputs `j0..j0 + W` of `R` rows, accumulated in registers over every input.
#[inline(always)]
fn block<const R: usize, const W: usize>(
    x: &[f32],
    d_in: usize,
    w: &[f32],
    d_out: usize,
    out: &mut [f32],
    j0: usize,
) {
    let mut acc = [[0.0_f32; W]; R];
    for (i, acc) in acc.iter_mut().enumerate() {
        acc.copy_from_slice(&out[i * d_out + j0..i * d_out + j0 + W]);
    }
    for k in 0..d_in {
        let v: [f32; R] = std::array::from_fn(|i| x[i * d_in + k]);
        if v.iter().all(|&v| v == 0.0) {
            continue;
        }
        let wk: &[f32; W] = w[k * d_out + j0..][..W].try_into().expect("a tile");
        for (acc, &v) in acc.iter_mut().zip(&v) {
            for (a, &wv) in acc.iter_mut().zip(wk) {
                *a = v.mul_add(wv, *a);
            }
        }
    }
    for (i, acc) in acc.iter().enumerate() {
        out[i * d_out + j0..i * d_out + j0 + W].copy_from_slice(acc);
    }
}

/// `1 / (1 + e^-x)`.
#[inline(always)]
fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp(-x))
}

/// `tanh x = 2 sigmoid(2x) − 1`.
#[inline(always)]
fn tanh(x: f32) -> f32 {
    2.0 / (1.0 + exp(-2.0 * x)) - 1.0
}

/// `e^x` to about 2 × 10⁻⁷ relative, in arithmetic only: `x = n ln 2 + r` with `|r| ≤ ln 2 /
/// 2`, `e^r` by its Taylor polynomial of degree 7, times `2^n` built in the exponent bits.
/// Inputs are clamped to `[−87, 88]` (the result stays a normal `f32`).
#[inline(always)]
fn exp(x: f32) -> f32 {
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let x = x.clamp(-87.0, 88.0);
    let n = (x * std::f32::consts::LOG2_E + 0.5).floor();
    let r = n.mul_add(-LN2_LO, n.mul_add(-LN2_HI, x));
    let mut p: f32 = 1.0 / 5040.0;
    for c in [1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0] {
        p = p.mul_add(r, c);
    }
    p * f32::from_bits(((n as i32 + 127) << 23) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Burn's forward pass and the frozen one on the same rows, two steps with the state
    /// carried, for every kind of network: features and Q-values agree to 10⁻⁴.
    #[test]
    fn agrees_with_burns_forward_pass() {
        use crate::net::{QNetConfig, tensor3, to_vec};
        use burn::tensor::{Device, Tensor, TensorData};
        use rand::{Rng, SeedableRng};
        use rand_chacha::ChaCha8Rng;

        let small_conv = QNetConfig {
            encoder: crate::net::EncoderConfig::Conv { channels: vec![6, 5], hidden: 40 },
            lstm_hidden: 24,
            lstm_layers: 2,
            head_hidden: 16,
            ..QNetConfig::default()
        };
        let configs = [
            QNetConfig::default(),
            QNetConfig { n_actions: 2, env_vec: 4, ..QNetConfig::default() },
            QNetConfig { centralised: true, ..QNetConfig::default() },
            small_conv,
        ];
        let device = Device::flex();
        for (seed, config) in configs.into_iter().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(seed as u64);
            let net = config.init(&mut rng, &device);
            let frozen = net.frozen(&config);
            let teams = [3, 2];
            let rows = 5;
            let (grid_len, vec_dim) = (config.channels * config.fov * config.fov, config.vec_dim());
            let mut burn_state = None;
            let mut state = None;
            for _step in 0..2 {
                // Sparse like an observation: three values in four are zero.
                let mut draw = |n: usize| -> Vec<f32> {
                    (0..n)
                        .map(|_| if rng.random::<f32>() < 0.75 { 0.0 } else { rng.random() })
                        .collect()
                };
                let (grid, vec, msg) = (
                    draw(rows * grid_len),
                    draw(rows * vec_dim),
                    draw(rows * config.message_dim()),
                );
                let (c, f) = (config.channels, config.fov);
                let obs = Tensor::<5>::from_data(
                    TensorData::new(grid.clone(), [rows, 1, c, f, f]),
                    &device,
                );
                let v = tensor3(vec.clone(), [rows, 1, vec_dim], &device);
                let (burn_features, next) = net.forward_recurrent(obs, v, burn_state, &teams);
                burn_state = Some(next);
                let m = tensor3(msg.clone(), [rows, 1, config.message_dim()], &device);
                let burn_q = to_vec(net.head(burn_features.clone(), m));
                let features = frozen.recurrent(&grid, &vec, &teams, &mut state);
                let q = frozen.head(&features, &msg);
                for (what, ours, theirs) in
                    [("features", features, to_vec(burn_features)), ("q", q, burn_q)]
                {
                    assert_eq!(ours.len(), theirs.len());
                    for (a, b) in ours.iter().zip(&theirs) {
                        assert!((a - b).abs() < 1e-4, "network {seed}: {what} {a} against {b}");
                    }
                }
            }
        }
    }

    /// Every vector width the processor has gives the portable code's bits.
    #[test]
    fn every_vector_width_gives_the_same_bits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let (rows, d_in, h) = (5, 70, 48);
        let mut draw = |n: usize| -> Vec<f32> {
            (0..n).map(|_| if rng.random::<f32>() < 0.5 { 0.0 } else { rng.random() }).collect()
        };
        let (x, w, gates) = (draw(rows * d_in), draw(d_in * 4 * h), draw(rows * 4 * h));
        let (cell, hidden) = (draw(rows * h), draw(rows * h));
        let levels = [simd::Level::Portable, simd::Level::Avx2, simd::Level::Avx512];
        let run = |level| {
            let mut out = gates.clone();
            matmul_acc_at(level, &x, d_in, &w, 4 * h, &mut out);
            let (mut c, mut hid) = (cell.clone(), hidden.clone());
            lstm_update_at(level, &out, h, &mut c, &mut hid);
            [out, c, hid].map(|v| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>())
        };
        let portable = run(simd::Level::Portable);
        for level in levels.into_iter().filter(|&l| l <= simd::detected()) {
            assert!(run(level) == portable, "{level:?} differs from the portable code");
        }
    }

    #[test]
    fn exp_is_close_to_the_library_one() {
        for i in -8700..=8800 {
            let x = i as f32 / 100.0;
            let (ours, libm) = (exp(x), x.exp());
            assert!(((ours - libm) / libm).abs() < 4e-7, "exp({x}) = {ours}, not {libm}");
        }
    }

    #[test]
    fn matmul_skips_nothing_it_needs() {
        let (d_in, d_out) = (3, 130);
        let w: Vec<f32> = (0..d_in * d_out).map(|i| (i % 7) as f32 - 3.0).collect();
        let x = [1.0, 0.0, -2.0, 0.5, 0.25, 0.0];
        let mut out = vec![1.0; 2 * d_out];
        matmul_acc(&x, d_in, &w, d_out, &mut out);
        for r in 0..2 {
            for j in 0..d_out {
                let want: f32 =
                    1.0 + (0..d_in).map(|k| x[r * d_in + k] * w[k * d_out + j]).sum::<f32>();
                assert_eq!(out[r * d_out + j], want, "row {r}, output {j}");
            }
        }
    }
}
