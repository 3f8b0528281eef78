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
use crate::{
    CheckpointError, Escape, Hierarchy, Keep, LowLevel, MetaInfo, Policy, PolicyRef,
    STUDENT_ROLLOUT_TEMPERATURE, STUDENT_TEAM_DEADBAND,
};

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
    /// A Pareto set's directory cannot be listed, holds no meta policy, or holds two at one
    /// multiple.
    #[error("the meta policies of the front in {}: {why}", dir.display())]
    Front {
        /// The directory.
        dir: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// The file holds another kind of policy than the one asked for.
    #[error("{} holds {found}, not the {expected} policy asked for", file.display())]
    WrongKind {
        /// The file read.
        file: PathBuf,
        /// What the file holds, and how that is known.
        found: String,
        /// The policy asked for.
        expected: String,
    },
    /// The meta policy does not fit its low level.
    #[error("the meta policy {}", file.display())]
    Hierarchy {
        /// The meta policy's file.
        file: PathBuf,
        /// Why.
        source: HierarchyError,
    },
}

/// The weights file `dir` itself when it is a file, else the one in the directory `dir`, or
/// that of the shipped model `name` when `dir` is `None`.
///
/// # Errors
/// [`ModelError::NoWeights`] when no directory searched holds one.
pub fn weights_file(dir: Option<&Path>, name: &str) -> Result<PathBuf, ModelError> {
    let candidates: Vec<PathBuf> = match dir {
        Some(file) if file.is_file() => return Ok(file.to_path_buf()),
        Some(dir) => vec![dir.to_path_buf()],
        None => default_dirs(name),
    };
    for dir in &candidates {
        if let Some(file) = WEIGHT_FILES.iter().map(|f| dir.join(f)).find(|f| f.is_file()) {
            return Ok(file);
        }
    }
    Err(no_weights(name, &candidates))
}

/// [`ModelError::NoWeights`] for `name`, naming the directories searched.
fn no_weights(name: &str, searched: &[PathBuf]) -> ModelError {
    let searched: Vec<String> = searched.iter().map(|it| it.display().to_string()).collect();
    ModelError::NoWeights { name: name.to_owned(), searched: searched.join(", ") }
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
/// on the CPU, with its header and file. The `imitation` student acts at the dead band
/// [`STUDENT_TEAM_DEADBAND`] (not the one its file records) with its stall escape
/// ([`Escape::STUDENT`]) and plays its test-time rollouts as [`Keep::STUDENT`] and
/// [`STUDENT_ROLLOUT_TEMPERATURE`] say, wherever it is loaded;
/// the other policies greedily as trained, the fastest rollout kept.
///
/// # Errors
/// If no file is found or it cannot be read.
pub fn load_with_header(
    path: Option<&Path>,
    name: &str,
) -> Result<(Policy, Header, PathBuf), ModelError> {
    let file = weights_file(path, name)?;
    let (mut policy, header) = load_policy_any(&file, &Device::flex())
        .map_err(|source| ModelError::Load { name: name.to_owned(), source })?;
    check_kind(&file, &header, name)?;
    if name == "imitation" {
        policy.set_team_deadband(STUDENT_TEAM_DEADBAND).expect("a valid band");
        policy.set_escape(Some(Escape::STUDENT));
        policy.set_keep(Keep::STUDENT);
        policy.set_rollout_temperature(Some(STUDENT_ROLLOUT_TEMPERATURE));
    }
    Ok((policy, header, file))
}

/// The shipped policies by name, and what each is: the per-agent low-level networks (five
/// actions) share one shape, the meta policy (two actions) records its low level, the
/// centralised baseline reads the whole team.
const KINDS: [(&str, &str); 6] = [
    ("pathfinding", "low-level"),
    ("formation", "low-level"),
    ("e2e", "low-level"),
    ("imitation", "low-level"),
    ("meta", "meta"),
    ("ctce", "centralised"),
];

/// What the network of `header` is, as its header tells: `meta`, `centralised` or
/// `low-level`.
fn kind_of(header: &Header) -> &'static str {
    if header.meta.is_some() || header.net_config.n_actions == 2 {
        "meta"
    } else if header.net_config.centralised {
        "centralised"
    } else {
        "low-level"
    }
}

/// Refuses the policy file `file` (its header `header`) for the policy `name` when it holds
/// another kind: a network of another kind than `name`'s (a meta policy given as the
/// path-finding policy), or, beside a `model.json` (as `models/` ships them), one whose
/// `model.json` names another of the shipped policies. Names not in the list (a low level
/// named by its directory) are not checked.
///
/// # Errors
/// [`ModelError::WrongKind`], naming the file, what it holds and what was asked for.
pub fn check_kind(file: &Path, header: &Header, name: &str) -> Result<(), ModelError> {
    let Some(&(_, expected)) = KINDS.iter().find(|(it, _)| *it == name) else {
        return Ok(());
    };
    let wrong = |found: String| ModelError::WrongKind {
        file: file.to_path_buf(),
        found,
        expected: name.to_owned(),
    };
    let found = kind_of(header);
    if expected == "meta" && header.meta.is_none() {
        return Err(ModelError::NotMeta { file: file.to_path_buf() });
    }
    if found != expected {
        let net = &header.net_config;
        return Err(wrong(format!(
            "a {found} policy ({} actions, a vector of {} values)",
            net.n_actions, net.env_vec
        )));
    }
    let card = file.with_file_name("model.json");
    let recorded = std::fs::read_to_string(&card)
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok())
        .and_then(|json| json["policy"].as_str().map(str::to_owned));
    match recorded {
        Some(other) if other != name && KINDS.iter().any(|(it, _)| *it == other) => {
            Err(wrong(format!("the {other} policy (as {} says)", card.display())))
        }
        _ => Ok(()),
    }
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

/// The shipped model a meta policy's low-level policy defaults to: the one whose directory
/// under `models/` names the file it was trained over (`models/formation/policy.bin`: `formation`),
/// else `fallback`.
fn shipped_name<'a>(policy: &'a PolicyRef, fallback: &'a str) -> &'a str {
    let path = Path::new(&policy.file);
    let models = path.parent().and_then(Path::parent).and_then(Path::file_name);
    match (models, path.parent().and_then(Path::file_name).and_then(|d| d.to_str())) {
        (Some(models), Some(dir)) if models == "models" => dir,
        _ => fallback,
    }
}

/// The hierarchy of the meta policy `meta` (read from `file` with `header`) over the
/// low-level policies it was trained over (by default the shipped models its files name),
/// or those given.
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
) -> Result<Hierarchy, ModelError> {
    let info = header.meta.as_ref().ok_or_else(|| ModelError::NotMeta { file: file.into() })?;
    let (pf, pf_ref) = load(pathfinding, "pathfinding")?;
    let (fm, fm_ref) = load(formation, shipped_name(&info.formation, "formation"))?;
    check_low_level(info, &pf_ref, &fm_ref, &file.display().to_string())?;
    let low = LowLevel::new(pf, fm).map_err(ModelError::LowLevel)?;
    Hierarchy::new(meta, low, info.weight.clone(), info.place_input)
        .map_err(|source| ModelError::Hierarchy { file: file.into(), source })
}

/// The hierarchy of the meta policy in `path` (a file or weights directory; the shipped
/// `models/meta` when `None`) over its shipped low level.
///
/// # Errors
/// As [`load_with_header`] and [`hierarchy`].
pub fn load_hierarchy(path: Option<&Path>) -> Result<Hierarchy, ModelError> {
    let (meta, header, file) = load_with_header(path, "meta")?;
    hierarchy(meta, &header, &file, None, None)
}

/// A Pareto set: meta policies each trained at one fixed multiple of `w_f`.
#[derive(Debug, Clone, PartialEq)]
pub struct MetaFront {
    /// `(multiple, policy file)`, ascending by multiple.
    pub points: Vec<(f64, PathBuf)>,
}

impl MetaFront {
    /// The meta policies in the subdirectories of `dir` (each a weights directory, as
    /// `phalanx train meta --weight-multiple M --out DIR/M` leaves it, or a `models/`-style
    /// one); the shipped `models/meta-front` when `None`. Each point is named by the multiple
    /// its header records, not by its directory's name.
    ///
    /// # Errors
    /// [`ModelError::NoWeights`] without a directory, and [`ModelError::Front`] if one cannot
    /// be listed, holds no meta policy, or two at one multiple.
    pub fn load(dir: Option<&Path>) -> Result<MetaFront, ModelError> {
        let dir = match dir {
            Some(dir) => dir.to_path_buf(),
            None => {
                let candidates = default_dirs("meta-front");
                let found = candidates.iter().find(|d| d.is_dir()).cloned();
                found.ok_or_else(|| no_weights("meta-front", &candidates))?
            }
        };
        let front = |why: String| ModelError::Front { dir: dir.clone(), why };
        let listing = std::fs::read_dir(&dir).map_err(|err| front(err.to_string()))?;
        let mut subdirs: Vec<PathBuf> =
            listing.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_dir()).collect();
        subdirs.sort();
        let mut points: Vec<(f64, PathBuf)> = Vec::new();
        for sub in subdirs {
            let Ok(file) = weights_file(Some(&sub), "meta") else { continue };
            let header = crate::policy_file::read_header(&file)
                .map_err(|source| ModelError::Load { name: "meta".into(), source })?;
            let info = header.meta.ok_or_else(|| ModelError::NotMeta { file: file.clone() })?;
            let multiple = info.weight.multiple();
            if let Some((_, other)) = points.iter().find(|(m, _)| *m == multiple) {
                return Err(front(format!(
                    "{} and {} were both trained at the multiple {multiple}",
                    other.display(),
                    file.display()
                )));
            }
            points.push((multiple, file));
        }
        if points.is_empty() {
            return Err(front("no subdirectory holds a meta policy".into()));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(MetaFront { points })
    }

    /// The policy file trained at `multiple`, if the front has one.
    pub fn at(&self, multiple: f64) -> Option<&Path> {
        self.points.iter().find(|(m, _)| *m == multiple).map(|(_, file)| file.as_path())
    }

    /// The multiples, ascending.
    pub fn multiples(&self) -> Vec<f64> {
        self.points.iter().map(|(m, _)| *m).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_meta_policy_defaults_to_the_shipped_low_level_its_file_names() {
        let named = |file: &str| PolicyRef { file: file.into(), crc32: "0".into() };
        assert_eq!(shipped_name(&named("models/tuned/policy.bin"), "formation"), "tuned");
        assert_eq!(shipped_name(&named("/x/models/formation/policy.bin"), "f"), "formation");
        assert_eq!(shipped_name(&named("/work/runs/f/policy.bin"), "formation"), "formation");
        assert_eq!(shipped_name(&named("policy.bin"), "formation"), "formation");
    }

    #[test]
    fn a_missing_model_names_the_directories_searched() {
        let dir = tempfile::tempdir().unwrap();
        let err = weights_file(Some(dir.path()), "pathfinding").unwrap_err().to_string();
        assert!(err.contains("for the pathfinding policy in"), "{err}");
        assert!(err.contains(&dir.path().display().to_string()), "{err}");
    }

    #[test]
    fn a_front_names_its_points_by_their_multiples_and_refuses_two_at_one() {
        let dir = tempfile::tempdir().unwrap();
        let shipped = weights_file(None, "meta").unwrap();
        let place = |sub: &str| {
            std::fs::create_dir_all(dir.path().join(sub)).unwrap();
            std::fs::copy(&shipped, dir.path().join(sub).join("policy.bin")).unwrap();
        };
        let err = MetaFront::load(Some(dir.path())).unwrap_err().to_string();
        assert!(err.contains("no subdirectory holds a meta policy"), "{err}");
        place("any-name");
        std::fs::create_dir_all(dir.path().join("empty")).unwrap();
        let front = MetaFront::load(Some(dir.path())).unwrap();
        let multiple = front.multiples()[0];
        assert_eq!(front.multiples(), [multiple]);
        assert!(front.at(multiple).unwrap().ends_with("any-name/policy.bin"));
        assert_eq!(front.at(multiple + 1.0), None);
        place("other");
        let err = MetaFront::load(Some(dir.path())).unwrap_err().to_string();
        assert!(err.contains(&format!("both trained at the multiple {multiple}")), "{err}");
        // A policy that is not a meta policy is refused by its file.
        std::fs::remove_dir_all(dir.path().join("other")).unwrap();
        std::fs::create_dir_all(dir.path().join("pf")).unwrap();
        let pathfinding = weights_file(None, "pathfinding").unwrap();
        std::fs::copy(pathfinding, dir.path().join("pf/policy.bin")).unwrap();
        let err = MetaFront::load(Some(dir.path())).unwrap_err().to_string();
        assert!(err.contains("pf/policy.bin is not a meta policy"), "{err}");
    }

    #[test]
    fn the_shipped_models_load_and_fit_together() {
        let hierarchy = load_hierarchy(None).unwrap();
        assert!(hierarchy.n_agents_max() >= 5);
        let (pathfinding, _) = load(None, "pathfinding").unwrap();
        assert!(low_level_of(pathfinding, None).is_ok());
    }
}
