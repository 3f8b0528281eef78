//! Network shapes and recurrence.

use burn::tensor::{Distribution, Tensor, Tolerance};
use phalanx_rl::{QNetConfig, RecurrentState};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[track_caller]
fn check_shapes(config: &QNetConfig, batch: usize, time: usize) {
    let device = crate::plain_device();
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(1), &device);
    let (c, f) = (config.channels, config.fov);
    let obs = Tensor::<5>::random([batch, time, c, f, f], Distribution::Default, &device);
    let vec = Tensor::<3>::zeros([batch, time, config.vec_dim()], &device);
    let (features, state) = net.forward_recurrent(obs, vec, None);
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
fn meta_network_has_two_actions() {
    check_shapes(&QNetConfig { n_actions: 2, ..QNetConfig::default() }, 2, 2);
}

#[test]
fn stepwise_recurrence_equals_sequence() {
    let device = crate::plain_device();
    let config = QNetConfig { lstm_layers: 2, ..QNetConfig::default() };
    let net = config.init(&mut ChaCha8Rng::seed_from_u64(2), &device);
    let (batch, time, c, f) = (2, 5, config.channels, config.fov);
    let obs = Tensor::<5>::random([batch, time, c, f, f], Distribution::Default, &device);
    let vec = Tensor::<3>::random([batch, time, config.vec_dim()], Distribution::Default, &device);
    let (whole, _) = net.forward_recurrent(obs.clone(), vec.clone(), None);
    let mut state = Some(RecurrentState::zeros(&config, batch, &device));
    let mut steps = Vec::new();
    for t in 0..time {
        let (out, next) =
            net.forward_recurrent(obs.clone().narrow(1, t, 1), vec.clone().narrow(1, t, 1), state);
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
        let (features, _) = net.forward_recurrent(obs.clone(), vec.clone(), None);
        let msg = Tensor::<3>::zeros([1, 1, config.message_dim()], &device);
        net.head(features, msg).into_data().try_to_vec::<f32>().unwrap()
    };
    assert_eq!(q(3), q(3));
    assert_ne!(q(3), q(4));
}
