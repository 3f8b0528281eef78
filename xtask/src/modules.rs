//! The module graph of each crate: which top-level modules a module names through `crate::`,
//! so that `tidy` can hold ARCHITECTURE.md's module invariants (no module cycle in any
//! crate; phalanx-rl's inference modules import no training module).
//!
//! A top-level module is `src/m.rs` with the files under `src/m/`, or `src/m/mod.rs` with
//! its folder. Its imports are the paths `crate::x` and `crate::{x, y::z}` outside comments,
//! outside a `#[cfg(test)] mod` block at the end of a file and outside `tests.rs` files; a
//! name the crate root re-exports (`pub use m::{A, B}`) counts as its module. Names written
//! with `super::` stay inside a module and are not edges.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Module name → the other top-level modules it imports.
pub type Graph = BTreeMap<String, BTreeSet<String>>;

/// phalanx-rl's modules that acting and deployment link: none imports a training module.
pub const RL_INFERENCE: &[&str] = &[
    "agent",
    "escape",
    "eval",
    "frozen",
    "hierarchy",
    "hyper",
    "keep",
    "models",
    "net",
    "policy",
    "policy_file",
    "weight",
];
/// phalanx-rl's training modules.
pub const RL_TRAINING: &[&str] =
    &["checkpoint", "imitation", "learner", "meta_env", "replay", "resume", "settings", "train"];

/// The module graph of the crate whose sources are in `src`.
pub fn graph(src: &Path) -> std::io::Result<Graph> {
    let mut texts: BTreeMap<String, String> = BTreeMap::new();
    for entry in std::fs::read_dir(src)? {
        let path = entry?.path();
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()).map(str::to_owned) else {
            continue;
        };
        if path.is_dir() {
            if !path.join("mod.rs").exists() && !src.join(format!("{stem}.rs")).exists() {
                continue;
            }
        } else if path.extension().is_none_or(|e| e != "rs") || stem == "lib" || stem == "main" {
            continue;
        }
        let text = texts.entry(stem).or_default();
        for file in files_of(&path)? {
            text.push_str(&code_of(&std::fs::read_to_string(file)?));
            text.push('\n');
        }
    }
    let mut root = String::new();
    for name in ["lib.rs", "main.rs"] {
        if let Ok(text) = std::fs::read_to_string(src.join(name)) {
            root.push_str(&code_of(&text));
        }
    }
    let reexported = reexports(&root);
    let modules: BTreeSet<String> = texts.keys().cloned().collect();
    Ok(texts
        .iter()
        .map(|(module, text)| {
            let imports = crate_names(text)
                .into_iter()
                .filter_map(|name| {
                    if modules.contains(&name) {
                        Some(name)
                    } else {
                        reexported.get(&name).cloned()
                    }
                })
                .filter(|target| target != module)
                .collect();
            (module.clone(), imports)
        })
        .collect())
}

/// Every cycle of `graph` as its modules, one line per strongly connected set of two or more.
pub fn cycles(graph: &Graph) -> Vec<Vec<String>> {
    let reach = |from: &str| -> BTreeSet<String> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.to_owned()];
        while let Some(node) = stack.pop() {
            for next in graph.get(&node).into_iter().flatten() {
                if seen.insert(next.clone()) {
                    stack.push(next.clone());
                }
            }
        }
        seen
    };
    let reachable: BTreeMap<&String, BTreeSet<String>> =
        graph.keys().map(|m| (m, reach(m))).collect();
    let mut found: Vec<Vec<String>> = Vec::new();
    for (module, from) in &reachable {
        if !from.contains(*module) || found.iter().any(|set| set.contains(*module)) {
            continue;
        }
        let set: Vec<String> =
            from.iter().filter(|other| reachable[other].contains(*module)).cloned().collect();
        if set.len() > 1 {
            found.push(set);
        }
    }
    found
}

/// The files behind one entry of `src`: the file itself, or every `.rs` file under the folder
/// (a module's submodules), `tests.rs` files left out.
fn files_of(path: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    if path.is_dir() {
        crate::collect_rs(path, &mut files)?;
    } else {
        files.push(path.to_path_buf());
    }
    files.retain(|f| f.file_name().is_none_or(|n| n != "tests.rs"));
    files.sort();
    Ok(files)
}

/// A file's code: comment lines and `#[cfg(test)] mod m;` declarations dropped, and
/// everything from a `#[cfg(test)]` followed by an inline `mod` on (test modules close the
/// file).
fn code_of(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let code = line.trim_start();
        if code == "#[cfg(test)]" {
            match lines.peek().map(|next| next.trim()) {
                Some(next) if next.starts_with("mod ") && next.ends_with(';') => {
                    lines.next();
                    continue;
                }
                Some(next) if next.starts_with("mod ") => break,
                _ => {}
            }
        }
        if code.starts_with("//") {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// The first segment of each path after `crate::` (`crate::a::B` → `a`, `crate::{a, b::C}` →
/// `a`, `b`).
fn crate_names(code: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        rest = &rest[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0usize;
            let mut item = String::new();
            let mut head = true;
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        head = true;
                        if !item.is_empty() {
                            names.insert(std::mem::take(&mut item));
                        }
                    }
                    c if head && (c.is_alphanumeric() || c == '_') => item.push(c),
                    c if head && !c.is_whitespace() => head = item.is_empty(),
                    _ => {}
                }
            }
            if !item.is_empty() {
                names.insert(item);
            }
        } else {
            let name: String =
                rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if !name.is_empty() {
                names.insert(name);
            }
        }
    }
    names
}

/// Names the crate root re-exports, each with its module (`pub use m::{A, b::C};` → `A`,
/// `b`, `C` to `m`).
fn reexports(root: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for statement in root.split(';') {
        let statement = statement.trim();
        let Some(path) = ["pub use ", "pub(crate) use "]
            .iter()
            .find_map(|prefix| statement.strip_prefix(prefix))
        else {
            continue;
        };
        let Some((module, items)) = path.split_once("::") else { continue };
        for name in items.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
            if !name.is_empty() && name != "self" {
                out.entry(name.to_owned()).or_insert_with(|| module.trim().to_owned());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_after_crate_are_read_in_groups_and_paths() {
        let code =
            "use crate::a::B;\nuse crate::{c, d::{E, F}, g::H as I};\nfn f(x: crate::j::K) {}";
        let names: Vec<String> = crate_names(code).into_iter().collect();
        assert_eq!(names, ["a", "c", "d", "g", "j"]);
    }

    #[test]
    fn comments_and_trailing_test_modules_are_not_code() {
        let text = "//! uses crate::a\nuse crate::b;\n/// [`crate::c`]\n#[cfg(test)]\nmod tests {\n    use crate::d;\n}\n";
        assert_eq!(crate_names(&code_of(text)).into_iter().collect::<Vec<_>>(), ["b"]);
    }

    #[test]
    fn reexports_map_names_to_their_module() {
        let root = "pub use a::{B, c::D};\npub(crate) use e::F;\nuse g::H;";
        let map = reexports(root);
        assert_eq!(map["B"], "a");
        assert_eq!(map["D"], "a");
        assert_eq!(map["F"], "e");
        assert!(!map.contains_key("H"));
    }

    #[test]
    fn cycles_are_found_once_each() {
        let edge = |pairs: &[(&str, &[&str])]| -> Graph {
            pairs
                .iter()
                .map(|(m, to)| ((*m).to_owned(), to.iter().map(|t| (*t).to_owned()).collect()))
                .collect()
        };
        let acyclic = edge(&[("a", &["b"]), ("b", &["c"]), ("c", &[])]);
        assert!(cycles(&acyclic).is_empty());
        let cyclic = edge(&[
            ("a", &["b"]),
            ("b", &["c"]),
            ("c", &["a"]),
            ("d", &["a"]),
            ("e", &["f"]),
            ("f", &["e"]),
        ]);
        assert_eq!(cycles(&cyclic), [vec!["a", "b", "c"], vec!["e", "f"]]);
    }
}
