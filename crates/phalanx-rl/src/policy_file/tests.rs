//! Policy files that cannot be trusted are refused: flipped bytes (checksums), non-finite
//! weights; files of the first layout (no checksums) still load.

use burn::module::{Module, ModuleMapper, Param};
use burn::tensor::{Device, Tensor};

use super::*;
use crate::learner::Learner;

fn small() -> QNetConfig {
    QNetConfig { lstm_hidden: 8, head_hidden: 8, ..QNetConfig::default() }
}

fn learner() -> Learner {
    Learner::new(small(), LearnerConfig::default(), &[3], 1, &Device::flex().autodiff())
}

#[test]
fn a_flipped_byte_in_any_section_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (name, save) in [
        ("policy.bin", Learner::save_policy as fn(&Learner, &Path) -> Result<(), CheckpointError>),
        ("checkpoint", Learner::save),
    ] {
        let path = dir.path().join(name);
        save(&learner(), &path).unwrap();
        let good = fs::read(&path).unwrap();
        // A byte inside the header and one inside the network.
        for at in [20, good.len() / 2] {
            let mut bad = good.clone();
            bad[at] ^= 0x10;
            fs::write(&path, &bad).unwrap();
            let err = load_policy(&path, &small(), &Device::flex()).unwrap_err();
            assert!(matches!(err, CheckpointError::Checksum { .. }), "{name} byte {at}: {err}");
            assert!(err.to_string().contains(name), "{err}");
        }
    }
}

#[test]
fn non_finite_weights_are_refused() {
    struct Poison;
    impl ModuleMapper for Poison {
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            param.map(|t| t.mul_scalar(f32::NAN))
        }
    }
    let learner = learner();
    let header = serde_json::to_vec_pretty(&learner.header()).unwrap();
    let net = small().init(&mut ChaCha8Rng::seed_from_u64(0), &Device::flex()).map(&mut Poison);
    let online = net.into_record().into_bytes().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.bin");
    fs::write(&path, sections(POLICY_MAGIC, &[&header, &online])).unwrap();
    let err = load_policy(&path, &small(), &Device::flex()).unwrap_err();
    assert!(matches!(err, CheckpointError::NonFinite { section: "online", .. }), "{err}");
    assert!(err.to_string().contains("nan.bin"), "{err}");
}

#[test]
fn files_of_the_first_layout_still_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("policy.bin");
    learner().save_policy(&path).unwrap();
    let bytes = fs::read(&path).unwrap();
    // The same sections without their CRCs, behind the first layout's magic.
    let mut legacy = LEGACY_POLICY_MAGIC.to_vec();
    let mut rest = &bytes[8..];
    while !rest.is_empty() {
        let len = u64::from_le_bytes(rest[..8].try_into().unwrap()) as usize;
        legacy.extend_from_slice(&rest[..8 + len]);
        rest = &rest[8 + len + 4..];
    }
    let old = dir.path().join("old.bin");
    fs::write(&old, &legacy).unwrap();
    let (a, _) = load_policy_any(&path, &Device::flex()).unwrap();
    let (b, _) = load_policy_any(&old, &Device::flex()).unwrap();
    assert_eq!(a.config(), b.config());
}

#[test]
fn a_policy_acts_with_the_dead_band_it_was_trained_with() {
    let dir = tempfile::tempdir().unwrap();
    let (policy, checkpoint) = (dir.path().join("policy.bin"), dir.path().join("checkpoint"));
    // The default band is not written: files of the default learner keep their bytes.
    learner().save_policy(&policy).unwrap();
    assert!(!String::from_utf8_lossy(&fs::read(&policy).unwrap()).contains("team_deadband"));
    let loaded = load_policy(&policy, &small(), &Device::flex()).unwrap();
    assert_eq!(loaded.team_deadband(), phalanx_env::obs::TEAM_DEADBAND);

    let mut narrow = learner();
    assert!(narrow.set_team_deadband(-1.0).is_err());
    narrow.set_team_deadband(0.5).unwrap();
    assert_eq!(narrow.policy().team_deadband(), 0.5);
    narrow.save_policy(&policy).unwrap();
    narrow.save(&checkpoint).unwrap();
    assert_eq!(load_policy(&policy, &small(), &Device::flex()).unwrap().team_deadband(), 0.5);
    let resumed = Learner::load(&checkpoint, &Device::flex().autodiff()).unwrap();
    assert_eq!(resumed.policy().team_deadband(), 0.5);

    // A band a policy cannot act with is refused, naming the file and the field.
    let mut header = narrow.header();
    header.team_deadband = Some(-2.0);
    let header = serde_json::to_vec_pretty(&header).unwrap();
    let online = narrow.online.clone().into_record().into_bytes().unwrap();
    let bad = dir.path().join("band.bin");
    fs::write(&bad, sections(POLICY_MAGIC, &[&header, &online])).unwrap();
    let err = load_policy(&bad, &small(), &Device::flex()).unwrap_err().to_string();
    assert!(err.contains("band.bin") && err.contains("team_deadband"), "{err}");
}
