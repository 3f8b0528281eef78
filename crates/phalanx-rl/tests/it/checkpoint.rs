//! Checkpoints: bit-identical round trip, typed errors.

use std::path::Path;

use burn::tensor::Device;
use phalanx_env::ObsBuffers;
use phalanx_rl::policy_file::{load_policy, load_policy_any, read_header};
use phalanx_rl::{CheckpointError, Collector, Learner, Policy, QNetConfig, ResumeError};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::corridor::{Corridor, corridor_learner, corridor_net};

/// Greedy actions of a policy on a fixed observation sequence.
fn greedy_actions(policy: &mut Policy) -> Vec<u8> {
    let mut obs = ObsBuffers::new(2, phalanx_rl::learner::obs_shape(&corridor_net()));
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut actions = vec![0; 2];
    let mut res = Vec::new();
    for t in 0..6 {
        obs.grid.iter_mut().enumerate().for_each(|(idx, it)| *it = ((idx + t) % 3) as f32);
        obs.vec.iter_mut().enumerate().for_each(|(idx, it)| *it = (idx * t) as f32 * 0.1);
        policy.act(&obs, 0.0, &mut rng, &mut actions);
        res.extend_from_slice(&actions);
    }
    res
}

fn trained_learner(device: &Device) -> Learner {
    let mut config = corridor_learner();
    config.learning_starts = 2;
    let mut learner = Learner::new(corridor_net(), config, &[2], 9, device);
    learner.train(
        &mut Collector::new(vec![Corridor::new()], 10),
        60,
        &mut |_: &'static str, _, _| {},
    );
    assert!(learner.counters().updates > 0);
    learner
}

#[test]
fn checkpoint_round_trip_is_bit_identical() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("learner.ckpt");
    let mut learner = trained_learner(&device);
    learner.save(&path).unwrap();
    let files: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|it| it.unwrap().file_name()).collect();
    assert_eq!(files, ["learner.ckpt"], "no temporary file is left");
    let mut loaded = Learner::load(&path, &device).unwrap();
    assert_eq!(loaded.counters(), learner.counters());
    assert_eq!(loaded.config(), learner.config());

    // Same Q-values, bit for bit, through the acting path.
    let q_before = q_values(&learner);
    let q_after = q_values(&loaded);
    assert_eq!(q_before, q_after);
    assert_eq!(greedy_actions(&mut learner.policy()), greedy_actions(&mut loaded.policy()));

    // Same optimiser and RNG state: the next updates (on the same replay) agree.
    for episode in learner.replays()[0].episodes() {
        loaded.store(episode.clone());
    }
    let a = learner.update().unwrap();
    let b = loaded.update().unwrap();
    assert_eq!(a, b);
    assert_eq!(q_values(&learner), q_values(&loaded));

    // The policy alone loads too.
    let mut policy = load_policy(&path, &corridor_net(), &crate::plain_device()).unwrap();
    let _ = greedy_actions(&mut policy);
}

#[test]
fn policy_file_acts_like_the_learner_and_cannot_resume() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let (full, slim) = (dir.path().join("checkpoint"), dir.path().join("policy.bin"));
    let learner = trained_learner(&device);
    learner.save(&full).unwrap();
    learner.save_policy(&slim).unwrap();
    let (full_len, slim_len) = (file_len(&full), file_len(&slim));
    assert!(slim_len * 3 < full_len, "policy file {slim_len} B, checkpoint {full_len} B");
    let (mut policy, header) = load_policy_any(&slim, &crate::plain_device()).unwrap();
    assert_eq!(header.agent_counts, [2]);
    assert_eq!(header.counters, learner.counters());
    assert_eq!(greedy_actions(&mut policy), greedy_actions(&mut learner.policy()));
    match Learner::load(&slim, &device) {
        Err(CheckpointError::Malformed { reason, .. }) => {
            assert!(reason.contains("policy file"), "{reason}");
        }
        other => panic!("expected Malformed, got {:?}", other.map(|_| ())),
    }
}

#[test]
fn warm_start_takes_the_weights_only() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("policy.bin");
    let trained = trained_learner(&device);
    trained.save_policy(&path).unwrap();
    let mut fresh = Learner::new(corridor_net(), corridor_learner(), &[2], 1, &device);
    assert_ne!(q_values(&fresh), q_values(&trained));
    fresh.init_from(&path).unwrap();
    assert_eq!(q_values(&fresh), q_values(&trained));
    assert_eq!(fresh.counters(), phalanx_rl::Counters::default());
    let other = QNetConfig { lstm_hidden: 8, ..corridor_net() };
    let mut mismatched = Learner::new(other, corridor_learner(), &[2], 1, &device);
    let err = mismatched.init_from(&path).unwrap_err();
    assert!(matches!(err, CheckpointError::ConfigMismatch { .. }), "{err}");
    // A network with a longer vector starts from it, the new inputs weighted zero; one with
    // a shorter vector is refused.
    let wider = QNetConfig { env_vec: corridor_net().env_vec + 2, ..corridor_net() };
    let mut widened = Learner::new(wider, corridor_learner(), &[2], 1, &device);
    widened.init_from(&path).unwrap();
    let narrower = QNetConfig { env_vec: corridor_net().env_vec - 1, ..corridor_net() };
    let mut narrow = Learner::new(narrower, corridor_learner(), &[2], 1, &device);
    let err = narrow.init_from(&path).unwrap_err();
    assert!(matches!(err, CheckpointError::ConfigMismatch { .. }), "{err}");
}

fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).unwrap().len()
}

/// Q-values of the online network on a fixed observation, as raw bits.
fn q_values(learner: &Learner) -> Vec<u32> {
    let mut obs = ObsBuffers::new(2, phalanx_rl::learner::obs_shape(&corridor_net()));
    obs.grid.iter_mut().enumerate().for_each(|(idx, it)| *it = (idx % 2) as f32);
    obs.vec.fill(0.3);
    let mut q = vec![0.0; 10];
    let mut actions = vec![0; 2];
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    learner.policy().act_with_q(&obs, 0.0, &mut rng, &mut actions, &mut q);
    q.into_iter().map(f32::to_bits).collect()
}

#[test]
fn missing_checkpoint_is_a_typed_error() {
    let err = Learner::load(Path::new("/nonexistent/learner.ckpt"), &crate::train_device())
        .err()
        .unwrap();
    assert!(matches!(err, CheckpointError::Missing { .. }), "{err}");
}

#[test]
fn wrong_network_is_a_config_mismatch() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("learner.ckpt");
    Learner::new(corridor_net(), corridor_learner(), &[2], 1, &device).save(&path).unwrap();
    let wrong = QNetConfig { lstm_hidden: 16, ..corridor_net() };
    let err = load_policy(&path, &wrong, &crate::plain_device()).err().unwrap();
    assert!(matches!(err, CheckpointError::ConfigMismatch { .. }), "{err}");
    assert_eq!(read_header(&path).unwrap().net_config, corridor_net());
}

#[test]
fn garbage_is_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("garbage.ckpt");
    std::fs::write(&path, b"not a checkpoint").unwrap();
    let err = Learner::load(&path, &crate::train_device()).err().unwrap();
    assert!(matches!(err, CheckpointError::Malformed { .. }), "{err}");
}

#[test]
fn tensors_of_another_network_are_a_record_error() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.ckpt"), dir.path().join("b.ckpt"));
    Learner::new(corridor_net(), corridor_learner(), &[2], 1, &device).save(&a).unwrap();
    let small = QNetConfig { lstm_hidden: 16, ..corridor_net() };
    Learner::new(small, corridor_learner(), &[2], 1, &device).save(&b).unwrap();
    // Header of `b`, tensors of `a` (tensors too small for a header are refused earlier,
    // before any network is allocated).
    let sections = |path: &Path| {
        let bytes = std::fs::read(path).unwrap();
        let mut rest = &bytes[8..];
        let mut res = Vec::new();
        while !rest.is_empty() {
            let len = u64::from_le_bytes(rest[..8].try_into().unwrap()) as usize;
            res.push(rest[..8 + len + 4].to_vec());
            rest = &rest[8 + len + 4..];
        }
        res
    };
    let (sa, sb) = (sections(&a), sections(&b));
    let mut spliced = b"PHXRLCK3".to_vec();
    spliced.extend_from_slice(&sb[0]);
    for section in &sa[1..] {
        spliced.extend_from_slice(section);
    }
    let path = dir.path().join("spliced.ckpt");
    std::fs::write(&path, spliced).unwrap();
    let err = Learner::load(&path, &device).err().unwrap();
    assert!(matches!(err, CheckpointError::Record { section: "online", .. }), "{err}");
    assert!(err.to_string().contains("shape"), "{err}");
    // Header of `a`, tensors of `b`: too few bytes for `a`'s weights.
    let mut spliced = b"PHXRLCK3".to_vec();
    spliced.extend_from_slice(&sa[0]);
    for section in &sb[1..] {
        spliced.extend_from_slice(section);
    }
    std::fs::write(&path, spliced).unwrap();
    let err = Learner::load(&path, &device).err().unwrap();
    assert!(matches!(err, CheckpointError::Malformed { .. }), "{err}");
    assert!(err.to_string().contains("does not fit its records"), "{err}");
}

/// Non-timing metrics as `(name, step, value bits)`.
type Log = Vec<(&'static str, u64, u64)>;

fn logger(log: &mut Log) -> impl FnMut(&'static str, u64, f64) + '_ {
    |name, step, value| {
        if !name.starts_with("perf/") {
            log.push((name, step, value.to_bits()));
        }
    }
}

#[test]
fn a_resumed_run_continues_exactly() {
    let device = crate::train_device();
    let config = phalanx_rl::LearnerConfig { learning_starts: 2, ..corridor_learner() };
    let fresh = || Learner::new(corridor_net(), config.clone(), &[2], 4, &device);
    let envs = || Collector::new((0..3).map(|_| Corridor::new()).collect(), 10);

    let (mut whole, mut parts) = (Log::new(), Log::new());
    let (mut learner, mut collector) = (fresh(), envs());
    learner.train(&mut collector, 90, &mut logger(&mut whole));
    learner.train(&mut collector, 90, &mut logger(&mut whole));

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ckpt");
    let (mut first, mut collector) = (fresh(), envs());
    first.train(&mut collector, 90, &mut logger(&mut parts));
    assert!(first.replays()[0].len() > 2, "the replay must hold episodes to restore");
    first.save_with_collection(&path, &collector).unwrap();
    drop(collector);
    let mut second = Learner::load(&path, &device).unwrap();
    let mut collector = envs();
    assert!(second.restore_collection(&path, &mut collector).unwrap());
    assert_eq!(second.replays()[0].len(), first.replays()[0].len());
    second.train(&mut collector, 90, &mut logger(&mut parts));
    assert!(whole.iter().any(|it| it.0 == phalanx_rl::metrics::TD_LOSS));
    assert_eq!(whole, parts);

    // A collector of other team sizes is refused, naming the file.
    let mut learner = Learner::load(&path, &device).unwrap();
    let mut other = Collector::new(vec![Corridor::new()], 10);
    let err = learner.restore_collection(&path, &mut other).unwrap_err();
    assert!(
        matches!(
            err,
            ResumeError::Collection { source: phalanx_rl::CollectionError::Teams { .. }, .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("ckpt"), "{err}");
    // A checkpoint without collection state restores nothing.
    first.save(&path).unwrap();
    let mut learner = Learner::load(&path, &device).unwrap();
    assert!(!learner.restore_collection(&path, &mut envs()).unwrap());
    assert!(learner.replays()[0].is_empty());
}

/// The checkpoint at `path` with section `index` (1 online, 3 optimiser) rewritten by `edit`
/// tensor by tensor, keeping the burnpack scalars, and every section's CRC-32 recomputed.
fn rewrite_section(path: &Path, index: usize, edit: &dyn Fn(&mut burn_pack::Tensor)) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap();
    let mut parts: Vec<Vec<u8>> = Vec::new();
    let mut rest = &bytes[8..];
    while !rest.is_empty() {
        let len = u64::from_le_bytes(rest[..8].try_into().unwrap()) as usize;
        parts.push(rest[8..8 + len].to_vec());
        rest = &rest[8 + len + 4..];
    }
    let section = burn::tensor::Bytes::from_bytes_vec(parts[index].clone());
    let reader = burn_pack::Reader::from_bytes(section).unwrap();
    let scalars = reader.scalars().clone();
    let mut tensors = reader.into_tensors().unwrap();
    assert!(!tensors.is_empty(), "section {index} holds tensors");
    tensors.iter_mut().for_each(edit);
    let mut writer = burn_pack::Writer::new(tensors);
    for (key, value) in &scalars {
        writer = writer.with_scalar(key, *value);
    }
    parts[index] = writer.into_bytes().unwrap().to_vec();
    let mut out = bytes[..8].to_vec();
    for part in &parts {
        out.extend_from_slice(&(part.len() as u64).to_le_bytes());
        out.extend_from_slice(part);
        out.extend_from_slice(&crc32fast::hash(part).to_le_bytes());
    }
    out
}

#[test]
fn records_burn_would_panic_on_are_refused() {
    let device = crate::train_device();
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.ckpt");
    trained_learner(&device).save(&good).unwrap();
    let bad = dir.path().join("bad.ckpt");
    type Edit = Box<dyn Fn(&mut burn_pack::Tensor)>;
    let cases: [(usize, &str, Edit); 4] = [
        // Found by the `checkpoint` fuzz target: a weight stored as I32 panicked inside burn.
        (1, "not F32", Box::new(|t| t.dtype = burn_pack::DType::I32)),
        (3, "not F32", Box::new(|t| t.dtype = burn_pack::DType::I32)),
        // An Adam moment of another shape than its parameter, or of no parameter.
        (3, "fits no parameter", Box::new(|t| t.shape = [t.byte_len() / 4].into())),
        (3, "fits no parameter", Box::new(|t| t.param_id = None)),
    ];
    for (section, expected, edit) in cases {
        std::fs::write(&bad, rewrite_section(&good, section, &*edit)).unwrap();
        let err = Learner::load(&bad, &device).err().expect("refused");
        let text = err.to_string();
        assert!(matches!(err, CheckpointError::Record { .. }), "{text}");
        assert!(text.contains(expected) && text.contains("bad.ckpt"), "{text}");
    }
    assert!(Learner::load(&good, &device).is_ok());
}
