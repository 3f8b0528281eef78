//! `cargo xtask`: the project's automation in Rust (no shell scripts).
//!
//! - `cargo xtask tidy`: every `.rs` file starts with a `//!` paragraph, no trailing
//!   whitespace, no `#[should_panic]`, no `#[ignore]`.
//! - `cargo xtask deps`: the dependency invariants of ARCHITECTURE.md (no burn below the
//!   learning crates; the benchmark uses them without naming burn).
//! - `cargo xtask demo`: the README's main job, end to end on generated data.

#![allow(clippy::print_stdout, clippy::print_stderr, reason = "a command-line tool")]

use std::path::Path;
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
    &["phalanx-core", "phalanx-io", "phalanx-gen", "phalanx-env", "phalanx-plan"];

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

/// Generates an instance, inspects it, solves it with CBS and SWARM-MAPF, validates the
/// plans and runs the simulator, all under `out/demo/`, then evaluates the shipped policies
/// on fresh maps.
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
    let out = root.join("out/demo");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let instance = out.join("instance.yaml");
    let steps: Vec<Vec<String>> = demo_steps(&instance, &out);
    for args in steps {
        println!("$ phalanx {}", args.join(" "));
        let status = Command::new(&bin).args(&args).current_dir(&root).status()?;
        if !status.success() {
            bail!("phalanx {} failed with {status}", args.join(" "));
        }
        println!();
    }
    Ok(())
}

fn demo_steps(instance: &Path, out: &Path) -> Vec<Vec<String>> {
    let inst = instance.display().to_string();
    let plan = |planner: &str| out.join(format!("plan-{planner}.yaml")).display().to_string();
    let (cbs, swarm) = (plan("cbs"), plan("swarm"));
    let steps: [&[&str]; 10] = [
        &["gen", "--size", "32", "--density", "0.15", "--agents", "3", "--seed", "1", "-o", &inst],
        &["info", &inst],
        &["solve", &inst, "--planner", "cbs", "-o", &cbs],
        &["validate", &inst, &cbs],
        &["solve", &inst, "--planner", "swarm", "-o", &swarm],
        &["validate", &inst, &swarm],
        &["sim", &inst, "--policy", "greedy"],
        &["sim", &inst, "--policy", &format!("plan:{swarm}")],
        &["eval", "--policy", "pathfinding", "--maps", "20", "--size", "32"],
        &["eval", "--policy", "formation", "--maps", "20", "--agents", "3"],
    ];
    steps.iter().map(|args| args.iter().map(|&a| a.to_string()).collect()).collect()
}
