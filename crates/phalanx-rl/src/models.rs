//! Finding and loading trained policies: an explicit file or directory, or the shipped
//! `models/<policy>/`, and the hierarchy of a meta policy over the low-level policies it was
//! trained over. Inference only; every command, the benchmark and the Python package load
//! their policies here.
//!
//! A weights directory holds `policy.bin` (a policy file, what `models/` ships) or
//! `checkpoint` (a training run's directory, as `phalanx train --out` writes it).
//! Without a directory, the first of these that holds either file is used:
//! `$PHALANX_MODELS/<policy>`, `./models/<policy>`, `models/<policy>` beside an ancestor of the
//! executable (a build inside the repository), and the repository this crate was built from.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use thiserror::Error;

use crate::hierarchy::{HierarchyError, LowLevelError};
use crate::policy_file::{Header, load_policy_any};
use crate::{CheckpointError, Hierarchy, LowLevel, MetaInfo, Policy, PolicyRef};

/// File names a weights directory may hold, in order of preference.
const WEIGHT_FILES: [&str; 2] = ["policy.bin", "checkpoint"];

/// Why a policy cannot be found or put together.
#[derive(Debug, Error)]
pub enum ModelError {
    /// No weights file in any directory searched.
    #[error("no weights (policy.bin or checkpoint) for the {name} policy in {searched}")]
    NoWeights {
        /// The policy looked for.
        name: String,
        /// The directories searched, comma-separated.
        searched: String,
    },
    /// The file is there but cannot be read.
    #[error("loading the {name} policy")]
    Load {
        /// The policy.
        name: String,
        /// What the reader said (names the file).
        source: CheckpointError,
    },
    /// A meta policy was expected.
    #[error("{} is not a meta policy (its header has no hierarchy)", file.display())]
    NotMeta {
        /// The file read.
        file: PathBuf,
    },
    /// The low-level policies are not those the meta policy was trained over.
    #[error(
        "{owner} was trained over the {what} policy {} (crc32 {}), not {} (crc32 {})",
        saved.file, saved.crc32, now.file, now.crc32
    )]
    OtherLowLevel {
        /// The meta policy (its file, or "the checkpoint's meta policy").
        owner: String,
        /// "path-finding" or "formation".
        what: &'static str,
        /// The policy the meta policy records.
        saved: Box<PolicyRef>,
        /// The policy found now.
        now: Box<PolicyRef>,
    },
    /// The two low-level policies do not fit together.
    #[error("the low-level policies")]
    LowLevel(#[source] LowLevelError),
    /// The meta policy does not fit its low level.
    #[error("the meta policy {}", file.display())]
    Hierarchy {
        /// The meta policy's file.
        file: PathBuf,
        /// Why.
        source: HierarchyError,
    },
}

/// The weights file of `dir`, or of the shipped model `name` when `dir` is `None`.
///
/// # Errors
/// [`ModelError::NoWeights`] when no directory searched holds one.
pub fn weights_file(dir: Option<&Path>, name: &str) -> Result<PathBuf, ModelError> {
    let candidates: Vec<PathBuf> = match dir {
        Some(dir) => vec![dir.to_path_buf()],
        None => default_dirs(name),
    };
    for dir in &candidates {
        if let Some(file) = WEIGHT_FILES.iter().map(|f| dir.join(f)).find(|f| f.is_file()) {
            return Ok(file);
        }
    }
    let searched: Vec<String> = candidates.iter().map(|it| it.display().to_string()).collect();
    Err(ModelError::NoWeights { name: name.to_owned(), searched: searched.join(", ") })
}

fn default_dirs(name: &str) -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    if let Some(root) = std::env::var_os("PHALANX_MODELS") {
        dirs.push(PathBuf::from(root).join(name));
    }
    dirs.push(Path::new("models").join(name));
    if let Ok(exe) = std::env::current_exe() {
        dirs.extend(exe.ancestors().skip(1).map(|dir| dir.join("models").join(name)));
    }
    dirs.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models").join(name));
    dirs
}

/// Loads the policy `name` from `path` (a file or a weights directory) or the shipped model,
/// on the CPU, with its header and file.
///
/// # Errors
/// If no file is found or it cannot be read.
pub fn load_with_header(
    path: Option<&Path>,
    name: &str,
) -> Result<(Policy, Header, PathBuf), ModelError> {
    let file = match path {
        Some(path) if path.is_file() => path.to_path_buf(),
        other => weights_file(other, name)?,
    };
    let (policy, header) = load_policy_any(&file, &Device::flex())
        .map_err(|source| ModelError::Load { name: name.to_owned(), source })?;
    Ok((policy, header, file))
}

/// Loads the policy `name` from `path` or the shipped model, with its reference.
///
/// # Errors
/// As [`load_with_header`].
pub fn load(path: Option<&Path>, name: &str) -> Result<(Policy, PolicyRef), ModelError> {
    let (policy, _, file) = load_with_header(path, name)?;
    let reference = PolicyRef::of(&file)
        .map_err(|source| ModelError::Load { name: name.to_owned(), source })?;
    Ok((policy, reference))
}

/// Refuses low-level policies other than those `saved` records (`owner` names the meta
/// policy in the message).
///
/// # Errors
/// [`ModelError::OtherLowLevel`] for the first that differs.
pub fn check_low_level(
    saved: &MetaInfo,
    pathfinding: &PolicyRef,
    formation: &PolicyRef,
    owner: &str,
) -> Result<(), ModelError> {
    for (what, saved, now) in [
        ("path-finding", &saved.pathfinding, pathfinding),
        ("formation", &saved.formation, formation),
    ] {
        if saved.crc32 != now.crc32 {
            return Err(ModelError::OtherLowLevel {
                owner: owner.to_owned(),
                what,
                saved: Box::new(saved.clone()),
                now: Box::new(now.clone()),
            });
        }
    }
    Ok(())
}

/// The low level of the loaded path-finding policy and the formation policy of `formation`
/// (the shipped one by default).
///
/// # Errors
/// If the formation policy cannot be loaded or does not fit the path-finding one.
pub fn low_level_of(pathfinding: Policy, formation: Option<&Path>) -> Result<LowLevel, ModelError> {
    let (formation, _) = load(formation, "formation")?;
    LowLevel::new(pathfinding, formation).map_err(ModelError::LowLevel)
}

/// The hierarchy of the meta policy `meta` (read from `file` with `header`) over the
/// low-level policies it was trained over, or those given; run at `multiple` × `w_f`.
///
/// # Errors
/// If the file is no meta policy, or a low-level policy cannot be read or is not the one
/// the meta policy was trained over.
pub fn hierarchy(
    meta: Policy,
    header: &Header,
    file: &Path,
    pathfinding: Option<&Path>,
    formation: Option<&Path>,
    multiple: f64,
) -> Result<Hierarchy, ModelError> {
    let info = header.meta.as_ref().ok_or_else(|| ModelError::NotMeta { file: file.into() })?;
    let (pf, pf_ref) = load(pathfinding, "pathfinding")?;
    let (fm, fm_ref) = load(formation, "formation")?;
    check_low_level(info, &pf_ref, &fm_ref, &file.display().to_string())?;
    let low = LowLevel::new(pf, fm).map_err(ModelError::LowLevel)?;
    Hierarchy::new(meta, low, info.weight.clone(), multiple)
        .map_err(|source| ModelError::Hierarchy { file: file.into(), source })
}

/// The hierarchy of the meta policy in `path` (a file or weights directory; the shipped
/// `models/meta` when `None`) over its shipped low level, at `multiple` × `w_f`.
///
/// # Errors
/// As [`load_with_header`] and [`hierarchy`].
pub fn load_hierarchy(path: Option<&Path>, multiple: f64) -> Result<Hierarchy, ModelError> {
    let (meta, header, file) = load_with_header(path, "meta")?;
    hierarchy(meta, &header, &file, None, None, multiple)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_model_names_the_directories_searched() {
        let dir = tempfile::tempdir().unwrap();
        let err = weights_file(Some(dir.path()), "pathfinding").unwrap_err().to_string();
        assert!(err.contains("for the pathfinding policy in"), "{err}");
        assert!(err.contains(&dir.path().display().to_string()), "{err}");
    }

    #[test]
    fn the_shipped_models_load_and_fit_together() {
        let hierarchy = load_hierarchy(None, 1.0).unwrap();
        assert!(hierarchy.n_agents_max() >= 5);
        let (pathfinding, _) = load(None, "pathfinding").unwrap();
        assert!(low_level_of(pathfinding, None).is_ok());
    }
}
