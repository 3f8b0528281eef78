//! `cargo xtask`: the project's automation in Rust (no shell scripts).
//!
//! - `cargo xtask tidy`: every `.rs` file starts with a `//!` paragraph, no trailing
//!   whitespace, no `#[should_panic]`, no `#[ignore]`.
//! - `cargo xtask deps`: the dependency invariants of ARCHITECTURE.md (no burn below the
//!   learning crates; the benchmark uses them without naming burn).
//! - `cargo xtask demo`: the README's main job, end to end on generated data.

#![allow(clippy::print_stdout, clippy::print_stderr, reason = "a command-line tool")]

use std::process::{Command, ExitCode};

use anyhow::{Context, bail};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let res = match args.first().map(String::as_str) {
        Some("tidy") => xtask::tidy(&xtask::workspace_root())
            .map(|problems| {
                for p in &problems {
                    eprintln!("{p}");
                }
                problems.is_empty()
            })
            .map_err(anyhow::Error::from),
        Some("deps") => deps().map(|()| true),
        Some("demo") => demo().map(|()| true),
        _ => {
            eprintln!("usage: cargo xtask tidy|deps|demo");
            return ExitCode::from(2);
        }
    };
    match res {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Crates that must never depend on burn (ARCHITECTURE.md, invariant 1).
const BURN_FREE: &[&str] =
    &["phalanx-core", "phalanx-io", "phalanx-gen", "phalanx-env", "phalanx-plan", "phalanx-render"];

/// Crates that use the learned policies through phalanx-rl but never name burn themselves.
const BURN_INDIRECT: &[&str] = &["phalanx-eval"];

fn deps() -> anyhow::Result<()> {
    for krate in BURN_FREE {
        if let Some(line) = tree(krate, &[])?.lines().find(|l| l.starts_with("burn")) {
            bail!("{krate} depends on burn ({line}); only the learning crates may");
        }
    }
    for krate in BURN_INDIRECT {
        let direct = tree(krate, &["--depth", "1"])?;
        if let Some(line) = direct.lines().find(|l| l.starts_with("burn")) {
            bail!("{krate} depends on burn directly ({line}); it must go through phalanx-rl");
        }
    }
    println!("dependency invariants hold");
    Ok(())
}

/// `cargo tree` of `krate`'s normal dependencies, one crate per line, with `extra` flags.
fn tree(krate: &str, extra: &[&str]) -> anyhow::Result<String> {
    let out = Command::new(env!("CARGO"))
        .args(["tree", "--quiet", "--edges", "normal", "-p", krate, "--prefix", "none"])
        .args(extra)
        .current_dir(xtask::workspace_root())
        .output()
        .with_context(|| format!("running cargo tree for {krate}"))?;
    if !out.status.success() {
        bail!("cargo tree -p {krate} failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Builds the `phalanx` binary and runs `phalanx demo` (the learned hierarchy, path finding,
/// CBS and SWARM-MAPF on a generated and a MovingAI instance; `out/demo/index.html`).
fn demo() -> anyhow::Result<()> {
    let root = xtask::workspace_root();
    let status = Command::new(env!("CARGO"))
        .args(["build", "--release", "--quiet", "-p", "phalanx-cli"])
        .current_dir(&root)
        .status()
        .context("building phalanx")?;
    if !status.success() {
        bail!("building phalanx failed");
    }
    let bin = root.join("target/release/phalanx");
    println!("$ phalanx demo");
    let status = Command::new(&bin).arg("demo").current_dir(&root).status()?;
    if !status.success() {
        bail!("phalanx demo failed with {status}");
    }
    Ok(())
}
