//! Network shapes and recurrence.

use burn::module::Module;
use burn::tensor::{Distribution, Tensor, TensorData, Tolerance};
use phalanx_rl::{QNet, QNetConfig, RecurrentState};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[track_caller]
fn check_shapes(config: &QNetConfig, batch: usize, time: usize) {
    let device = crate::plain_device();
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(1), &device);
    let (c, f) = (config.channels, config.fov);
    let obs = Tensor::<5>::random([batch, time, c, f, f], Distribution::Default, &device);
    let vec = Tensor::<3>::zeros([batch, time, config.vec_dim()], &device);
    let (features, state) = net.forward_recurrent(obs, vec, None, &[batch]);
    assert_eq!(features.dims(), [batch, time, config.lstm_hidden]);
    assert_eq!(state.layers.len(), config.lstm_layers);
    for (cell, hidden) in &state.layers {
        assert_eq!(cell.dims(), [batch, config.lstm_hidden]);
        assert_eq!(hidden.dims(), [batch, config.lstm_hidden]);
    }
    let messages = Tensor::<3>::zeros([batch, time, config.message_dim()], &device);
    let q = net.head(features, messages);
    assert_eq!(q.dims(), [batch, time, config.n_actions]);
}

#[test]
fn default_network_shapes() {
    check_shapes(&QNetConfig::default(), 3, 4);
}

#[test]
fn paper_network_shapes() {
    check_shapes(&QNetConfig::paper(), 2, 3);
}

#[test]
fn centralised_network_shapes() {
    check_shapes(&QNetConfig { centralised: true, ..QNetConfig::default() }, 3, 4);
    check_shapes(&QNetConfig { centralised: true, ..QNetConfig::paper() }, 2, 3);
}

#[test]
fn meta_network_has_two_actions() {
    check_shapes(&QNetConfig { n_actions: 2, ..QNetConfig::default() }, 2, 2);
}

#[test]
fn stepwise_recurrence_equals_sequence() {
    check_stepwise(&QNetConfig { lstm_layers: 2, ..QNetConfig::default() }, &[2]);
}

#[test]
fn centralised_stepwise_recurrence_equals_sequence() {
    let config = QNetConfig { lstm_layers: 2, centralised: true, ..QNetConfig::default() };
    check_stepwise(&config, &[2, 3]);
}

#[track_caller]
fn check_stepwise(config: &QNetConfig, teams: &[usize]) {
    let device = crate::plain_device();
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(2), &device);
    let (batch, time, c, f) = (teams.iter().sum(), 5, config.channels, config.fov);
    let obs = Tensor::<5>::random([batch, time, c, f, f], Distribution::Default, &device);
    let vec = Tensor::<3>::random([batch, time, config.vec_dim()], Distribution::Default, &device);
    let (whole, _) = net.forward_recurrent(obs.clone(), vec.clone(), None, teams);
    let mut state = Some(RecurrentState::zeros(config, batch, &device));
    let mut steps = Vec::new();
    for t in 0..time {
        let (obs_t, vec_t) = (obs.clone().narrow(1, t, 1), vec.clone().narrow(1, t, 1));
        let (out, next) = net.forward_recurrent(obs_t, vec_t, state, teams);
        steps.push(out);
        state = Some(next);
    }
    let stepwise = Tensor::cat(steps, 1);
    whole.into_data().assert_approx_eq::<f32>(&stepwise.into_data(), Tolerance::absolute(1e-5));
}

#[test]
fn same_seed_same_weights() {
    let device = crate::plain_device();
    let config = QNetConfig::default();
    let obs = Tensor::<5>::ones([1, 1, config.channels, config.fov, config.fov], &device);
    let vec = Tensor::<3>::ones([1, 1, config.vec_dim()], &device);
    let q = |seed| {
        let net = config.init(&mut ChaCha8Rng::seed_from_u64(seed), &device);
        let (features, _) = net.forward_recurrent(obs.clone(), vec.clone(), None, &[1]);
        let msg = Tensor::<3>::zeros([1, 1, config.message_dim()], &device);
        net.head(features, msg).into_data().try_to_vec::<f32>().unwrap()
    };
    assert_eq!(q(3), q(3));
    assert_ne!(q(3), q(4));
}

/// The features of every row of `teams` (one step), with row `changed`'s observation
/// replaced by ones.
fn features_with(
    net: &QNet,
    config: &QNetConfig,
    teams: &[usize],
    changed: Option<usize>,
) -> Vec<f32> {
    let device = crate::plain_device();
    let rows: usize = teams.iter().sum();
    let (c, f) = (config.channels, config.fov);
    let grid_len = c * f * f;
    let mut grid: Vec<f32> = (0..rows * grid_len).map(|i| (i % 7) as f32 / 7.0).collect();
    if let Some(row) = changed {
        grid[row * grid_len..(row + 1) * grid_len].fill(1.0);
    }
    let obs = Tensor::<5>::from_data(TensorData::new(grid, [rows, 1, c, f, f]), &device);
    let vec = Tensor::<3>::zeros([rows, 1, config.vec_dim()], &device);
    let (features, _) = net.forward_recurrent(obs, vec, None, teams);
    features.into_data().try_to_vec::<f32>().unwrap()
}

#[test]
fn a_centralised_row_reads_its_team_and_no_other() {
    let teams = [2, 3];
    let width = QNetConfig::default().lstm_hidden;
    let row = |features: &[f32], r: usize| features[r * width..(r + 1) * width].to_vec();
    for centralised in [false, true] {
        let config = QNetConfig { centralised, ..QNetConfig::default() };
        let net = config.init(&mut ChaCha8Rng::seed_from_u64(9), &crate::plain_device());
        assert_eq!(net.is_centralised(), centralised);
        // Row 3 (the second agent of the second team) sees something else.
        let before = features_with(&net, &config, &teams, None);
        let after = features_with(&net, &config, &teams, Some(3));
        for r in 0..5 {
            let moved = row(&before, r) != row(&after, r);
            let expected = r == 3 || (centralised && r >= 2);
            assert_eq!(moved, expected, "row {r}, centralised {centralised}");
        }
    }
}

#[test]
fn the_weight_count_is_the_networks() {
    for config in [
        QNetConfig::default(),
        QNetConfig { centralised: true, ..QNetConfig::default() },
        QNetConfig { centralised: true, ..QNetConfig::paper() },
    ] {
        let net = config.init(&mut ChaCha8Rng::seed_from_u64(1), &crate::plain_device());
        assert_eq!(Some(net.num_params()), config.n_params(), "{config:?}");
    }
    // The figures docs/hierarchy.md gives for the default network and its centralised form.
    let centralised = QNetConfig { centralised: true, ..QNetConfig::default() };
    assert_eq!(
        (QNetConfig::default().n_params(), centralised.n_params()),
        (Some(185_733), Some(333_317))
    );
}

#[test]
fn a_widened_network_ignores_its_new_inputs() {
    let device = crate::plain_device();
    let config = QNetConfig::default();
    let wide = QNetConfig { env_vec: config.env_vec + 3, ..config.clone() };
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(5), &device);
    let (c, f) = (config.channels, config.fov);
    let obs = Tensor::<5>::random([2, 3, c, f, f], Distribution::Default, &device);
    let narrow_vec = Tensor::<3>::random([2, 3, config.vec_dim()], Distribution::Default, &device);
    let q = |net: &QNet, config: &QNetConfig, vec: Tensor<3>| {
        let (features, _) = net.forward_recurrent(obs.clone(), vec, None, &[2]);
        let msg = Tensor::<3>::zeros([2, 3, config.message_dim()], &device);
        net.head(features, msg).into_data().try_to_vec::<f32>().unwrap()
    };
    let before = q(&net, &config, narrow_vec.clone());
    let widened = net.widen_env_vec(&config, 3);
    // The new inputs sit between the environment vector and the agent-slot one-hot.
    let env = narrow_vec.clone().slice([0..2, 0..3, 0..config.env_vec]);
    let slot = narrow_vec.slice([0..2, 0..3, config.env_vec..config.vec_dim()]);
    for fill in [0.0, 1.0, -7.5] {
        let extra = Tensor::<3>::full([2, 3, 3], fill, &device);
        let vec = Tensor::cat(vec![env.clone(), extra, slot.clone()], 2);
        assert_eq!(q(&widened, &wide, vec), before, "new inputs at {fill}");
    }
    let mut moved = Tensor::<3>::zeros([2, 3, wide.vec_dim()], &device);
    moved = moved.slice_assign(
        [0..2, 0..3, wide.env_vec..wide.env_vec + 1],
        Tensor::ones([2, 3, 1], &device),
    );
    assert_ne!(q(&widened, &wide, moved), before, "the slot one-hot is still read");
}
