//! Checkpoints: online and target networks, Adam state, counters, configs and the RNG state in
//! one file, written atomically (temporary file in the same directory, then rename).
//!
//! Layout: the magic `PHXRLCK1`, then four or five sections, each a little-endian `u64` length
//! and its bytes: the JSON header ([`Header`]), the online network, the target network (both
//! burnpack records from burn's `ModuleRecord`), the optimiser record and, when written by
//! [`Learner::save_with_collection`], the collection state (JSON: every replay buffer's and
//! running episode's reset seed and actions, see `resume.rs`), with which a resumed run
//! continues exactly.
//!
//! A *policy file* ([`Learner::save_policy`], what `models/` ships) has the magic `PHXRLPL1`
//! and two sections: the same JSON header and the online network. [`load_policy`] reads both
//! kinds.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::hierarchy::MetaInfo;
use crate::learner::{Counters, Learner, LearnerConfig};
use crate::net::{QNet, QNetConfig};
use crate::policy::Policy;

const MAGIC: &[u8; 8] = b"PHXRLCK1";
const POLICY_MAGIC: &[u8; 8] = b"PHXRLPL1";
const VERSION: u32 = 2;

/// Errors reading or writing a checkpoint.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// The file does not exist.
    #[error("checkpoint {path} does not exist")]
    Missing {
        /// The path asked for.
        path: PathBuf,
    },
    /// Reading, writing or renaming failed.
    #[error("checkpoint {path}: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is not a checkpoint of this format (bad magic, truncated section, bad header).
    #[error("checkpoint {path} is malformed: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The checkpoint's network does not match the one asked for.
    #[error("checkpoint {path} holds network {found:?}, expected {expected:?}")]
    ConfigMismatch {
        /// The file.
        path: PathBuf,
        /// The configuration the caller expected.
        expected: Box<QNetConfig>,
        /// The configuration in the file.
        found: Box<QNetConfig>,
    },
    /// A tensor record does not fit the network (wrong shapes or missing parameters).
    #[error("checkpoint {path}, section {section}: {message}")]
    Record {
        /// The file.
        path: PathBuf,
        /// `online`, `target` or `optimizer`.
        section: &'static str,
        /// burn's message (names the parameter and both shapes).
        message: String,
    },
}

/// The JSON header of a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Format version (1).
    pub version: u32,
    /// Network sizes.
    pub net_config: QNetConfig,
    /// Learner hyper-parameters.
    pub learner_config: LearnerConfig,
    /// Team sizes trained, ascending.
    pub agent_counts: Vec<usize>,
    /// Counters at save time.
    pub counters: Counters,
    /// The learner RNG: ChaCha8 seed, stream and word position (`[high, low]` 64-bit halves).
    pub rng_seed: [u8; 32],
    /// ChaCha8 stream.
    pub rng_stream: u64,
    /// ChaCha8 word position.
    pub rng_word_pos: [u64; 2],
    /// For a meta policy: its formation weights and the low-level policies it was trained
    /// over.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub meta: Option<MetaInfo>,
}

impl Learner {
    fn header(&self) -> Header {
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
    /// atomically: a policy file for [`load_policy`], a quarter of a checkpoint's size.
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
        let mut learner = Learner::new(
            file.header.net_config.clone(),
            file.header.learner_config.clone(),
            &file.header.agent_counts,
            0,
            device,
        );
        learner.online = apply(learner.online, &file.online, path, "online")?;
        learner.target = apply(learner.target, &target, path, "target")?;
        learner.optim = learner
            .optim
            .from_bytes(Bytes::from_bytes_vec(optim))
            .map_err(|err| record_error(path, "optimizer", err))?;
        learner.counters = file.header.counters;
        learner.meta = file.header.meta.clone();
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
    /// networks take its weights), keeping this learner's optimiser, counters and RNG.
    ///
    /// # Errors
    /// If the file cannot be read or holds another network.
    pub fn init_from(&mut self, path: &Path) -> Result<(), CheckpointError> {
        let file = read_file(path)?;
        if file.header.net_config != self.net_config {
            return Err(CheckpointError::ConfigMismatch {
                path: path.to_path_buf(),
                expected: Box::new(self.net_config.clone()),
                found: Box::new(file.header.net_config),
            });
        }
        self.online = apply(self.online.clone(), &file.online, path, "online")?;
        self.target = self.online.valid();
        Ok(())
    }
}

/// Load only the acting policy (online network) of a checkpoint or policy file, checking that
/// its network is `expected`; `device` should be a plain (non-autodiff) device.
pub fn load_policy(
    path: &Path,
    expected: &QNetConfig,
    device: &Device,
) -> Result<Policy, CheckpointError> {
    let file = read_file(path)?;
    if file.header.net_config != *expected {
        return Err(CheckpointError::ConfigMismatch {
            path: path.to_path_buf(),
            expected: Box::new(expected.clone()),
            found: Box::new(file.header.net_config),
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let net = apply(expected.init(&mut rng, device), &file.online, path, "online")?;
    Ok(Policy::new(net, expected.clone(), device))
}

/// Load the acting policy of a checkpoint or policy file with the network its header names,
/// and the header; `device` should be a plain (non-autodiff) device.
pub fn load_policy_any(path: &Path, device: &Device) -> Result<(Policy, Header), CheckpointError> {
    let header = read_header(path)?;
    Ok((load_policy(path, &header.net_config, device)?, header))
}

/// A checkpoint's header and collection state (`None` when it has none).
pub(crate) fn read_collection(path: &Path) -> Result<(Header, Option<Vec<u8>>), CheckpointError> {
    let file = read_file(path)?;
    Ok((file.header, file.collection))
}

/// Read a checkpoint's header only.
pub fn read_header(path: &Path) -> Result<Header, CheckpointError> {
    Ok(read_file(path)?.header)
}

struct File {
    header: Header,
    online: Vec<u8>,
    /// `None` in a policy file.
    target: Option<Vec<u8>>,
    /// `None` in a policy file.
    optim: Option<Vec<u8>>,
    /// The collection state, when saved.
    collection: Option<Vec<u8>>,
}

/// `magic`, then each section as a little-endian `u64` length and its bytes.
fn sections(magic: &[u8; 8], parts: &[&[u8]]) -> Vec<u8> {
    let mut buf = Vec::with_capacity(parts.iter().map(|it| it.len() + 8).sum::<usize>() + 8);
    buf.extend_from_slice(magic);
    for part in parts {
        buf.extend_from_slice(&(part.len() as u64).to_le_bytes());
        buf.extend_from_slice(part);
    }
    buf
}

fn read_file(path: &Path) -> Result<File, CheckpointError> {
    let bytes = fs::read(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::NotFound {
            CheckpointError::Missing { path: path.to_path_buf() }
        } else {
            CheckpointError::Io { path: path.to_path_buf(), source }
        }
    })?;
    let malformed = |reason: &str| CheckpointError::Malformed {
        path: path.to_path_buf(),
        reason: reason.into(),
    };
    // A checkpoint has four sections and an optional fifth; a policy file two.
    let (rest, n_sections, optional) = if let Some(rest) = bytes.strip_prefix(MAGIC) {
        (rest, 4, 1)
    } else if let Some(rest) = bytes.strip_prefix(POLICY_MAGIC) {
        (rest, 2, 0)
    } else {
        return Err(malformed("bad magic (neither a checkpoint nor a policy file)"));
    };
    let mut sections = Vec::with_capacity(n_sections + optional);
    let mut rest = rest;
    for i in 0..n_sections + optional {
        if i >= n_sections && rest.is_empty() {
            break;
        }
        let (len, tail) = rest.split_first_chunk::<8>().ok_or_else(|| malformed("truncated"))?;
        let len = usize::try_from(u64::from_le_bytes(*len)).map_err(|_| malformed("too large"))?;
        if tail.len() < len {
            return Err(malformed("truncated section"));
        }
        let (section, tail) = tail.split_at(len);
        sections.push(section.to_vec());
        rest = tail;
    }
    if !rest.is_empty() {
        return Err(malformed("trailing bytes"));
    }
    let header: Header =
        serde_json::from_slice(&sections[0]).map_err(|err| malformed(&format!("header: {err}")))?;
    if header.version != VERSION {
        return Err(malformed(&format!("version {} (expected {VERSION})", header.version)));
    }
    let mut sections = sections.into_iter().skip(1);
    let online = sections.next().expect("at least two sections");
    let target = sections.next();
    let optim = sections.next();
    let collection = sections.next();
    Ok(File { header, online, target, optim, collection })
}

fn apply(
    net: QNet,
    bytes: &[u8],
    path: &Path,
    section: &'static str,
) -> Result<QNet, CheckpointError> {
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
        .map_err(|err| record_error(path, section, err))?;
    net.try_load_record(record).map_err(|err| record_error(path, section, err))
}

fn record_error(
    path: &Path,
    section: &'static str,
    err: impl std::fmt::Display,
) -> CheckpointError {
    CheckpointError::Record { path: path.to_path_buf(), section, message: err.to_string() }
}

/// Write `bytes` to a temporary file next to `path`, sync it, then rename it over `path`.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    let io_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| CheckpointError::Io { path, source }
    };
    let mut tmp_name = path.file_name().map(|it| it.to_os_string()).unwrap_or_default();
    tmp_name.push(".tmp");
    let tmp = path.with_file_name(tmp_name);
    {
        let mut file = fs::File::create(&tmp).map_err(io_err(&tmp))?;
        file.write_all(bytes).map_err(io_err(&tmp))?;
        file.sync_all().map_err(io_err(&tmp))?;
    }
    fs::rename(&tmp, path).map_err(io_err(path))
}
