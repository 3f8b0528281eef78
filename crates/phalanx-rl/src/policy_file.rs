//! Policy files and checkpoints on disk: one format of sections, written atomically, each
//! section checked by CRC-32 on reading; and loading a policy for acting (what `models/` ships
//! and what deployment links), apart from the learner.
//!
//! Layout: an 8-byte magic, then sections, each a little-endian `u64` length, its bytes and
//! the little-endian CRC-32 of those bytes. A *checkpoint* (`PHXRLCK3`) has the JSON header
//! ([`Header`]), the online network, the target network (burnpack records of burn's
//! `ModuleRecord`), the optimiser record and, when written with the collection state
//! (`Learner::save_with_collection`), a fifth section with it. A *policy file* (`PHXRLPL3`)
//! has the header and the online network. Files of the first layout (`PHXRLCK1`,
//! `PHXRLPL1`: the same sections without CRCs, written before checksums existed) are still
//! read, unchecked. A loaded network whose weights are not all finite is refused.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use burn::module::{Module, ModuleVisitor, Param};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, DType, Device, Tensor};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::hierarchy::{MetaInfo, PolicyRef};
use crate::hyper::{Counters, LearnerConfig};
use crate::net::{QNet, QNetConfig, to_vec};
use crate::policy::Policy;

/// Magic of a checkpoint with checksummed sections.
pub(crate) const MAGIC: &[u8; 8] = b"PHXRLCK3";
/// Magic of a policy file with checksummed sections.
pub(crate) const POLICY_MAGIC: &[u8; 8] = b"PHXRLPL3";
/// Magics of the first layout, without checksums (read only).
const LEGACY_MAGIC: &[u8; 8] = b"PHXRLCK1";
const LEGACY_POLICY_MAGIC: &[u8; 8] = b"PHXRLPL1";
/// Header format version.
pub(crate) const VERSION: u32 = 2;

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
    /// A section's bytes do not match its checksum (the file was damaged).
    #[error(
        "checkpoint {path}: section {section} is damaged (CRC-32 {found:08x}, expected {expected:08x})"
    )]
    Checksum {
        /// The file.
        path: PathBuf,
        /// Which section (0: the header).
        section: usize,
        /// The CRC-32 of the bytes read.
        found: u32,
        /// The CRC-32 the file records.
        expected: u32,
    },
    /// The network's weights include NaN or infinite values.
    #[error("checkpoint {path}, section {section}: the weights include non-finite values")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// `online` or `target`.
        section: &'static str,
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
    /// The team vector's dead band the network was trained with, where it is not the
    /// default ([`phalanx_env::obs::TEAM_DEADBAND`]): a policy loaded from the file acts with
    /// it ([`Policy::team_deadband`]). Not written when the default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub team_deadband: Option<f64>,
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
    let mut policy = Policy::new(&net, expected.clone());
    if let Some(cells) = file.header.team_deadband {
        policy.set_team_deadband(cells).expect("checked when read");
    }
    Ok(policy)
}

/// Load the acting policy of a checkpoint or policy file with the network its header names,
/// and the header; `device` should be a plain (non-autodiff) device.
pub fn load_policy_any(path: &Path, device: &Device) -> Result<(Policy, Header), CheckpointError> {
    let header = read_header(path)?;
    Ok((load_policy(path, &header.net_config, device)?, header))
}

/// The CRC-32 of a checkpoint's or policy file's online network (its weights as stored,
/// the same whichever layout holds them): what a meta policy records of its low level.
pub fn network_checksum(path: &Path) -> Result<u32, CheckpointError> {
    Ok(crc32fast::hash(&read_file(path)?.online))
}

impl PolicyRef {
    /// The reference of the policy in the file at `path`.
    ///
    /// # Errors
    /// If the file cannot be read.
    pub fn of(path: &Path) -> Result<PolicyRef, CheckpointError> {
        let crc = network_checksum(path)?;
        Ok(PolicyRef { file: path.display().to_string(), crc32: format!("{crc:08x}") })
    }
}

/// Read a checkpoint's header only.
pub fn read_header(path: &Path) -> Result<Header, CheckpointError> {
    Ok(read_file(path)?.header)
}

/// The sections of a file.
pub(crate) struct File {
    pub(crate) header: Header,
    pub(crate) online: Vec<u8>,
    /// `None` in a policy file.
    pub(crate) target: Option<Vec<u8>>,
    /// `None` in a policy file.
    pub(crate) optim: Option<Vec<u8>>,
    /// The collection state, when saved.
    pub(crate) collection: Option<Vec<u8>>,
}

/// `magic`, then each section as a little-endian `u64` length, its bytes and their CRC-32.
pub(crate) fn sections(magic: &[u8; 8], parts: &[&[u8]]) -> Vec<u8> {
    let mut buf = Vec::with_capacity(parts.iter().map(|it| it.len() + 12).sum::<usize>() + 8);
    buf.extend_from_slice(magic);
    for part in parts {
        buf.extend_from_slice(&(part.len() as u64).to_le_bytes());
        buf.extend_from_slice(part);
        buf.extend_from_slice(&crc32fast::hash(part).to_le_bytes());
    }
    buf
}

/// Reads and checks a checkpoint or policy file.
pub(crate) fn read_file(path: &Path) -> Result<File, CheckpointError> {
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
    let (magic, rest) = bytes.split_at(bytes.len().min(8));
    let (n_sections, optional, checked) = match magic {
        m if m == MAGIC => (4, 1, true),
        m if m == POLICY_MAGIC => (2, 0, true),
        m if m == LEGACY_MAGIC => (4, 1, false),
        m if m == LEGACY_POLICY_MAGIC => (2, 0, false),
        _ => return Err(malformed("bad magic (neither a checkpoint nor a policy file)")),
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
        let (section, mut tail) = tail.split_at(len);
        if checked {
            let (crc, after) =
                tail.split_first_chunk::<4>().ok_or_else(|| malformed("truncated"))?;
            let (expected, found) = (u32::from_le_bytes(*crc), crc32fast::hash(section));
            if expected != found {
                return Err(CheckpointError::Checksum {
                    path: path.to_path_buf(),
                    section: i,
                    found,
                    expected,
                });
            }
            tail = after;
        }
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
    header.net_config.check().map_err(|err| malformed(&format!("header: {err}")))?;
    if let Some(cells) = header.team_deadband {
        phalanx_env::check_team_deadband(cells)
            .map_err(|err| malformed(&format!("header: team_deadband: {err}")))?;
    }
    // Every weight takes 4 bytes of a record: a smaller one cannot hold the network, whose
    // allocation is then never tried (a damaged header cannot ask for more than the file).
    let weights = header.net_config.n_params().unwrap_or(usize::MAX);
    if sections.iter().skip(1).take(2).any(|record| record.len() / 4 < weights) {
        return Err(malformed(&format!(
            "header: a network of {weights} weights does not fit its records"
        )));
    }
    let mut sections = sections.into_iter().skip(1);
    let online = sections.next().expect("at least two sections");
    let target = sections.next();
    let optim = sections.next();
    let collection = sections.next();
    Ok(File { header, online, target, optim, collection })
}

/// `net` with the weights of the record `bytes` (section `section` of `path`), refused when
/// a weight is not finite.
pub(crate) fn apply(
    net: QNet,
    bytes: &[u8],
    path: &Path,
    section: &'static str,
) -> Result<QNet, CheckpointError> {
    check_record(bytes, path, section, None)?;
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
        .map_err(|err| record_error(path, section, err))?;
    let net = net.try_load_record(record).map_err(|err| record_error(path, section, err))?;
    if !all_finite(&net) {
        return Err(CheckpointError::NonFinite { path: path.to_path_buf(), section });
    }
    Ok(net)
}

/// The shape of every parameter of `net`, by parameter id: what an optimiser record's
/// tensors must match.
pub(crate) fn param_shapes(net: &QNet) -> BTreeMap<u64, Vec<usize>> {
    struct Shapes(BTreeMap<u64, Vec<usize>>);
    impl ModuleVisitor for Shapes {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            self.0.insert(param.id.val(), param.lazy_shape().as_slice().to_vec());
        }
    }
    let mut shapes = Shapes(BTreeMap::new());
    net.visit(&mut shapes);
    shapes.0
}

/// Refuses a record (section `section` of `path`) that burn would read but that would make it
/// panic later: a tensor that is not `f32` (the network has float weights only) or whose
/// bytes do not fill its shape; for an optimiser record (`params`: the network's parameter
/// shapes by id), a tensor without a parameter id, or whose parameter is not the network's or
/// has another shape, and a parameter's rank recorded other than its own.
pub(crate) fn check_record(
    bytes: &[u8],
    path: &Path,
    section: &'static str,
    params: Option<&BTreeMap<u64, Vec<usize>>>,
) -> Result<(), CheckpointError> {
    let refuse = |message: String| record_error(path, section, message);
    let reader = burn_pack::Reader::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
        .map_err(|err| refuse(err.to_string()))?;
    if let Some(params) = params {
        for (key, value) in reader.scalars() {
            let Some((id, field)) = key.split_once('.') else { continue };
            let param = id.parse::<u64>().ok().and_then(|id| params.get(&id));
            let Some(shape) = param else {
                return Err(refuse(format!("state {key} of a parameter the network has not")));
            };
            if field == "__rank" && usize::try_from(*value).ok() != Some(shape.len()) {
                return Err(refuse(format!("state {key}: rank {value:?}, not {}", shape.len())));
            }
        }
    }
    for tensor in reader.into_tensors().map_err(|err| refuse(err.to_string()))? {
        let name = &tensor.name;
        if tensor.dtype != DType::F32 {
            return Err(refuse(format!("tensor {name} is {:?}, not F32", tensor.dtype)));
        }
        let dims = tensor.shape.as_slice();
        let numel = dims.iter().try_fold(4usize, |n, &d| n.checked_mul(d));
        if numel != Some(tensor.byte_len()) {
            return Err(refuse(format!("tensor {name}: its bytes do not fill shape {dims:?}")));
        }
        if let Some(params) = params {
            let shape = tensor.param_id.and_then(|id| params.get(&id));
            if shape != Some(&dims.to_vec()) {
                return Err(refuse(format!(
                    "state {name} (shape {dims:?}) fits no parameter of the network"
                )));
            }
        }
    }
    Ok(())
}

/// Whether every weight of `net` is finite.
fn all_finite(net: &QNet) -> bool {
    struct Finite(bool);
    impl ModuleVisitor for Finite {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            if self.0 {
                self.0 = to_vec(param.val()).iter().all(|v| v.is_finite());
            }
        }
    }
    let mut finite = Finite(true);
    net.visit(&mut finite);
    finite.0
}

/// A record error of section `section` of `path`.
pub(crate) fn record_error(
    path: &Path,
    section: &'static str,
    err: impl std::fmt::Display,
) -> CheckpointError {
    CheckpointError::Record { path: path.to_path_buf(), section, message: err.to_string() }
}

/// Writes `bytes` to `path` with the project's one atomic write ([`phalanx_io::write_atomic`]).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    phalanx_io::write_atomic(path, bytes)
        .map_err(|source| CheckpointError::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests;
