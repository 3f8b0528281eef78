//! Finding trained weights: an explicit directory, or the shipped `models/<policy>/`.
//!
//! A weights directory holds `policy.bin` (a policy file, what `models/` ships) or
//! `checkpoint` (a training run's directory, as `phalanx train --out` writes it).
//! Without `--weights`, the first of these directories that holds either file is used:
//! `$PHALANX_MODELS/<policy>`, `./models/<policy>`, `models/<policy>` beside an ancestor of the
//! executable (a build inside the repository), and the repository the binary was built from.

use std::path::{Path, PathBuf};

use anyhow::bail;

/// File names a weights directory may hold, in order of preference.
const WEIGHT_FILES: [&str; 2] = ["policy.bin", "checkpoint"];

/// The weights file of `dir`, or of the shipped model `name` when `dir` is `None`.
pub(crate) fn weights_file(dir: Option<&Path>, name: &str) -> anyhow::Result<PathBuf> {
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
    bail!("no weights (policy.bin or checkpoint) for the {name} policy in {}", searched.join(", "))
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
