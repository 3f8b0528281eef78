//! Checkpoints of the whole learner: online and target networks, Adam state, counters, configs
//! and the RNG state in one file of the format of [`crate::policy_file`], written atomically;
//! and warm starts from a checkpoint or policy file.

use std::path::Path;

use burn::module::Module;
use burn::tensor::{Bytes, Device};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::learner::Learner;
use crate::net::QNetConfig;
use crate::policy_file::{
    CheckpointError, Header, MAGIC, POLICY_MAGIC, VERSION, apply, check_record, param_shapes,
    read_file, record_error, sections, write_atomic,
};

impl Learner {
    pub(crate) fn header(&self) -> Header {
        let word_pos = self.rng.get_word_pos();
        Header {
            version: VERSION,
            net_config: self.net_config.clone(),
            learner_config: self.config.clone(),
            agent_counts: self.agent_counts.clone(),
            counters: self.counters,
            rng_seed: self.rng.get_seed(),
            rng_stream: self.rng.get_stream(),
            rng_word_pos: [(word_pos >> 64) as u64, word_pos as u64],
            meta: self.meta.clone(),
            team_deadband: (self.team_deadband != phalanx_env::obs::TEAM_DEADBAND)
                .then_some(self.team_deadband),
        }
    }

    /// Write the learner's state to `path` atomically (without the collection state: a run
    /// resumed from it refills its replay buffers; see [`Learner::save_with_collection`]).
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        self.write_checkpoint(path, None)
    }

    /// The checkpoint's four sections, then `collection` as the fifth when given.
    pub(crate) fn write_checkpoint(
        &self,
        path: &Path,
        collection: Option<&[u8]>,
    ) -> Result<(), CheckpointError> {
        let header = serde_json::to_vec_pretty(&self.header()).expect("header serialises");
        let record_err = |section| {
            move |err: burn::store::RecordError| CheckpointError::Record {
                path: path.to_path_buf(),
                section,
                message: err.to_string(),
            }
        };
        let online =
            self.online.clone().into_record().into_bytes().map_err(record_err("online"))?;
        let target =
            self.target.clone().into_record().into_bytes().map_err(record_err("target"))?;
        let optim = self.optim.into_bytes().map_err(record_err("optimizer"))?;

        let mut parts: Vec<&[u8]> = vec![&header, &online, &target, &optim];
        parts.extend(collection);
        write_atomic(path, &sections(MAGIC, &parts))
    }

    /// Write only what acting needs (the header and the online network) to `path`
    /// atomically: a policy file for [`crate::policy_file::load_policy`], a quarter of a checkpoint's size.
    pub fn save_policy(&self, path: &Path) -> Result<(), CheckpointError> {
        let header = serde_json::to_vec_pretty(&self.header()).expect("header serialises");
        let online = self
            .online
            .clone()
            .into_record()
            .into_bytes()
            .map_err(|err| record_error(path, "online", err))?;
        write_atomic(path, &sections(POLICY_MAGIC, &[&header, &online]))
    }

    /// Restore a learner saved by [`Learner::save`] onto `device` (with autodiff).
    pub fn load(path: &Path, device: &Device) -> Result<Self, CheckpointError> {
        let file = read_file(path)?;
        let (Some(target), Some(optim)) = (file.target, file.optim) else {
            return Err(CheckpointError::Malformed {
                path: path.to_path_buf(),
                reason: "a policy file cannot resume training (no target network or optimizer)"
                    .into(),
            });
        };
        let slots = file.header.net_config.n_agents_max;
        let counts = &file.header.agent_counts;
        if counts.is_empty() || counts.iter().any(|n| !(1..=slots).contains(n)) {
            return Err(CheckpointError::Malformed {
                path: path.to_path_buf(),
                reason: format!("header: agent counts {counts:?} do not fit {slots} agent slots"),
            });
        }
        let mut learner = Learner::new(
            file.header.net_config.clone(),
            file.header.learner_config.clone(),
            &file.header.agent_counts,
            0,
            device,
        );
        learner.online = apply(learner.online, &file.online, path, "online")?;
        learner.target = apply(learner.target, &target, path, "target")?;
        check_record(&optim, path, "optimizer", Some(&param_shapes(&learner.online)))?;
        learner.optim = learner
            .optim
            .from_bytes(Bytes::from_bytes_vec(optim))
            .map_err(|err| record_error(path, "optimizer", err))?;
        learner.counters = file.header.counters;
        learner.meta = file.header.meta.clone();
        learner.team_deadband =
            file.header.team_deadband.unwrap_or(phalanx_env::obs::TEAM_DEADBAND);
        let mut rng = ChaCha8Rng::from_seed(file.header.rng_seed);
        rng.set_stream(file.header.rng_stream);
        let [high, low] = file.header.rng_word_pos;
        rng.set_word_pos((u128::from(high) << 64) | u128::from(low));
        learner.rng = rng;
        Ok(learner)
    }
}

impl Learner {
    /// Start from the online network of a checkpoint or policy file (a warm start: both
    /// networks take its weights), keeping this learner's optimiser, counters and RNG. A
    /// network whose environment vector is shorter and is otherwise this one's also serves:
    /// the inputs it lacks start with zero weights ([`crate::QNet::widen_env_vec`]).
    ///
    /// # Errors
    /// If the file cannot be read or holds another network.
    pub fn init_from(&mut self, path: &Path) -> Result<(), CheckpointError> {
        let file = read_file(path)?;
        let found = &file.header.net_config;
        let widened = QNetConfig { env_vec: self.net_config.env_vec, ..found.clone() };
        if found.env_vec > self.net_config.env_vec || widened != self.net_config {
            return Err(CheckpointError::ConfigMismatch {
                path: path.to_path_buf(),
                expected: Box::new(self.net_config.clone()),
                found: Box::new(file.header.net_config),
            });
        }
        let extra = self.net_config.env_vec - found.env_vec;
        if extra == 0 {
            self.online = apply(self.online.clone(), &file.online, path, "online")?;
        } else {
            let device = self.online.devices().into_iter().next().unwrap_or_default();
            let net = found.init(&mut ChaCha8Rng::seed_from_u64(0), &device);
            let net = apply(net, &file.online, path, "online")?.widen_env_vec(found, extra);
            self.online = self.online.clone().load_record(net.into_record());
        }
        self.target = self.online.valid();
        Ok(())
    }
}

/// A checkpoint's header and collection state (`None` when it has none).
pub(crate) fn read_collection(path: &Path) -> Result<(Header, Option<Vec<u8>>), CheckpointError> {
    let file = read_file(path)?;
    Ok((file.header, file.collection))
}
