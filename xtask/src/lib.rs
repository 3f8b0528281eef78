//! Checks shared by `cargo xtask` and the test suite.

use std::path::{Path, PathBuf};

pub mod modules;

/// The workspace root (the parent of this crate's folder).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

/// Style problems in the workspace's Rust files, one line each (`path:line: problem`), and
/// breaches of the module invariants ([`module_problems`]).
pub fn tidy(root: &Path) -> std::io::Result<Vec<String>> {
    let mut problems = Vec::new();
    let mut files = Vec::new();
    for dir in ["crates", "xtask"] {
        collect_rs(&root.join(dir), &mut files)?;
    }
    files.sort();
    for path in files {
        let text = std::fs::read_to_string(&path)?;
        let shown = path.strip_prefix(root).unwrap_or(&path).display().to_string();
        if !text.trim_start().starts_with("//!") {
            problems.push(format!("{shown}:1: file does not start with a `//!` doc paragraph"));
        }
        for (idx, line) in text.lines().enumerate() {
            if line.ends_with(' ') || line.ends_with('\t') {
                problems.push(format!("{shown}:{}: trailing whitespace", idx + 1));
            }
            let code = line.trim_start();
            if code.starts_with("#[should_panic") || code.starts_with("#[ignore") {
                problems.push(format!("{shown}:{}: check outcomes instead of {code}", idx + 1));
            }
        }
    }
    problems.extend(module_problems(root)?);
    Ok(problems)
}

/// The module invariants of ARCHITECTURE.md: no crate's modules import each other in a
/// cycle, and phalanx-rl's inference modules import no training module (each of its modules
/// is one or the other).
pub fn module_problems(root: &Path) -> std::io::Result<Vec<String>> {
    let mut problems = Vec::new();
    let mut crates: Vec<PathBuf> = std::fs::read_dir(root.join("crates"))?
        .map(|entry| entry.map(|e| e.path().join("src")))
        .collect::<Result<_, _>>()?;
    crates.retain(|src| src.is_dir());
    crates.sort();
    for src in crates {
        let shown = src.strip_prefix(root).unwrap_or(&src).display().to_string();
        let graph = modules::graph(&src)?;
        for cycle in modules::cycles(&graph) {
            problems.push(format!("{shown}: modules import each other: {}", cycle.join(", ")));
        }
        if !shown.ends_with("phalanx-rl/src") {
            continue;
        }
        for (module, imports) in &graph {
            let inference = modules::RL_INFERENCE.contains(&module.as_str());
            if !inference && !modules::RL_TRAINING.contains(&module.as_str()) {
                problems.push(format!(
                    "{shown}/{module}: neither an inference nor a training module (xtask/src/modules.rs)"
                ));
            }
            if !inference {
                continue;
            }
            for import in imports.iter().filter(|i| modules::RL_TRAINING.contains(&i.as_str())) {
                problems.push(format!(
                    "{shown}/{module}: an inference module imports the training module {import}"
                ));
            }
        }
    }
    Ok(problems)
}

fn collect_rs(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    if !dir.exists() {
        return Ok(());
    }
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n == "target") {
                continue;
            }
            collect_rs(&path, out)?;
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn workspace_is_tidy() {
        let problems = super::tidy(&super::workspace_root()).unwrap();
        assert!(problems.is_empty(), "{}", problems.join("\n"));
    }
}
