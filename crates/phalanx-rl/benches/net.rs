//! Network cost: one learner update (batch 32 × 16 steps × 3 agents), one agent's decision
//! (one recurrent step plus the head, batch 1) for the default and the paper network, and one
//! agent's decision in the shipped hierarchy (meta network plus the low level).
//!
//! Run on one core: `RAYON_NUM_THREADS=1 cargo bench -p phalanx-rl --bench net`.

use std::hint::black_box;

use burn::tensor::Device;
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use phalanx_env::{EnvConfig, ObsBuffers};
use phalanx_gen::GenConfig;
use phalanx_rl::learner::obs_shape;
use phalanx_rl::models::load_hierarchy;
use phalanx_rl::policy_file::load_policy_any;
use phalanx_rl::{
    Episode, Episodes, Learner, LearnerConfig, Policy, QNetConfig, Replay, SequenceMode,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const BATCH: usize = 32;
const STEPS: usize = 16;
const AGENTS: usize = 3;

fn random_obs(obs: &mut ObsBuffers, rng: &mut ChaCha8Rng) {
    obs.grid.iter_mut().for_each(|it| *it = f32::from(u8::from(rng.random_bool(0.2))));
    obs.vec.iter_mut().for_each(|it| *it = rng.random_range(-1.0..1.0));
}

fn random_episode(config: &QNetConfig, rng: &mut ChaCha8Rng) -> Episode {
    let mut obs = ObsBuffers::new(AGENTS, obs_shape(config));
    random_obs(&mut obs, rng);
    let mut episode = Episode::start(&obs);
    for _ in 0..STEPS {
        random_obs(&mut obs, rng);
        let actions: Vec<u8> = (0..AGENTS).map(|_| rng.random_range(0..5)).collect();
        episode.push_step(&actions, rng.random_range(-1.0..1.0), &obs);
    }
    episode
}

fn presets() -> [(&'static str, QNetConfig); 2] {
    [("default", QNetConfig::default()), ("paper", QNetConfig::paper())]
}

fn update(c: &mut Criterion) {
    let device = Device::flex().autodiff();
    let mut group = c.benchmark_group("update");
    group.sample_size(10);
    for (name, config) in presets() {
        let learner_config = LearnerConfig {
            batch_size: BATCH,
            sequence: SequenceMode::Episodes,
            ..LearnerConfig::default()
        };
        let mut learner = Learner::new(config.clone(), learner_config, &[AGENTS], 1, &device);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut replay = Replay::new(64, AGENTS, obs_shape(&config));
        for _ in 0..64 {
            replay.push(random_episode(&config, &mut rng));
        }
        let batch = replay.sample(BATCH, SequenceMode::Episodes, &mut rng);
        assert_eq!((batch.batch, batch.len, batch.n_agents), (BATCH, STEPS, AGENTS));
        let id = BenchmarkId::new(name, format!("b{BATCH}xt{STEPS}xn{AGENTS}"));
        group.bench_function(id, |b| {
            b.iter(|| {
                let stats = learner.update_on(&batch);
                assert!(stats.td_loss.is_finite());
                black_box(stats)
            })
        });
    }
    group.finish();
}

fn decision(c: &mut Criterion) {
    let device = Device::flex();
    let mut group = c.benchmark_group("decision");
    for (name, config) in presets() {
        let net = config.init(&mut ChaCha8Rng::seed_from_u64(3), &device);
        let mut policy = Policy::new(&net, config.clone());
        let mut obs = ObsBuffers::new(1, obs_shape(&config));
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        random_obs(&mut obs, &mut rng);
        let mut actions = [0_u8];
        group.bench_function(BenchmarkId::new(name, "1"), |b| {
            b.iter(|| {
                policy.act(&obs, 0.0, &mut rng, &mut actions);
                assert!(actions[0] < 5);
                black_box(actions[0])
            })
        });
    }
    // Each shipped policy, one agent per call; then 16 teams of 3 per call for path finding
    // (batched inference as in training and evaluation; the time is per call of 48 decisions).
    for shipped in ["pathfinding", "formation"] {
        let path = format!("{}/../../models/{shipped}/policy.bin", env!("CARGO_MANIFEST_DIR"));
        let (mut policy, header) = load_policy_any(path.as_ref(), &device).expect(&path);
        let config = header.net_config;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut obs = ObsBuffers::new(1, obs_shape(&config));
        random_obs(&mut obs, &mut rng);
        let mut actions = [0_u8];
        group.bench_function(BenchmarkId::new(format!("shipped-{shipped}"), "1"), |b| {
            b.iter(|| {
                policy.act(&obs, 0.0, &mut rng, &mut actions);
                black_box(actions[0])
            })
        });
        if shipped != "pathfinding" {
            continue;
        }
        let teams: Vec<ObsBuffers> = (0..16)
            .map(|_| {
                let mut obs = ObsBuffers::new(3, obs_shape(&config));
                random_obs(&mut obs, &mut rng);
                obs
            })
            .collect();
        let mut actions = vec![0_u8; 48];
        policy.reset();
        group.bench_function(BenchmarkId::new("shipped-pathfinding", "16x3"), |b| {
            b.iter(|| {
                policy.act_batch(&teams, 0.0, &mut rng, &mut actions, None);
                black_box(actions[0])
            })
        });
    }
    group.finish();
}

/// One agent's decision in the hierarchy: the shipped meta policy (`models/meta`), then the
/// low level (both shipped recurrent passes, the formation frame, the chosen head), state
/// carried; per agent of a team of one, and per call for a team of 3.
fn hierarchy_decision(c: &mut Criterion) {
    let shipped = format!("{}/../../models/meta", env!("CARGO_MANIFEST_DIR"));
    let mut hierarchy = load_hierarchy(Some(shipped.as_ref())).expect(&shipped);
    let mut group = c.benchmark_group("hierarchy_decision");
    for agents in [1, 3] {
        let config = GenConfig { size: 32, density: 0.15, n_agents: agents, seed: 3, fov: 9 };
        let instance = phalanx_gen::generate(&config).unwrap();
        let mut episodes = Episodes::new();
        let instances = std::slice::from_ref(&instance);
        hierarchy.start(&mut episodes, instances, &EnvConfig::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let mut outs = Vec::with_capacity(1);
        // The episode is not stepped (`running` false): the decisions of its first state,
        // every recurrent state carried from call to call.
        group.bench_function(BenchmarkId::new("meta+low", agents), |b| {
            b.iter(|| {
                hierarchy.step(&mut episodes, &[false], 0.0, &mut rng, &mut outs);
                black_box(episodes.actions(0)[0])
            })
        });
    }
    group.finish();
}

criterion_group!(benches, update, decision, hierarchy_decision);
criterion_main!(benches);
