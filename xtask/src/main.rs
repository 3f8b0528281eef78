//! `cargo xtask`: the project's automation in Rust (no shell scripts).
//!
//! - `cargo xtask tidy`: every `.rs` file starts with a `//!` paragraph, no trailing
//!   whitespace, no `#[should_panic]`, no `#[ignore]`.
//! - `cargo xtask deps`: the dependency invariants of ARCHITECTURE.md (no burn below the
//!   learning crates; the benchmark uses them without naming burn).
//! - `cargo xtask demo`: the README's main job, end to end on generated data.
//! - `cargo xtask test [CARGO TEST FLAGS]`: the README's test command: every Rust test
//!   (`cargo test --workspace --all-targets`), then the Python package's tests (a virtualenv
//!   in `target/py-venv` with the pinned test requirements, `maturin develop`, pytest).

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
        Some("test") => test(&args[1..]),
        _ => {
            eprintln!("usage: cargo xtask tidy|deps|demo|test");
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
const BURN_INDIRECT: &[&str] = &["phalanx-eval", "phalanx-py"];

/// Every crate but the Python package: none may depend on pyo3.
const PYO3_FREE: &[&str] = &[
    "phalanx-core",
    "phalanx-io",
    "phalanx-gen",
    "phalanx-env",
    "phalanx-plan",
    "phalanx-render",
    "phalanx-rl",
    "phalanx-eval",
    "phalanx-cli",
    "phalanx-fuzz",
];

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
    for krate in PYO3_FREE {
        if let Some(line) = tree(krate, &[])?.lines().find(|l| l.starts_with("pyo3")) {
            bail!("{krate} depends on pyo3 ({line}); only phalanx-py may");
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

/// Runs `program` with `args` in the workspace root (with `envs`), failing on a non-zero exit.
fn run(
    program: &std::path::Path,
    args: &[&str],
    envs: &[(&str, &std::ffi::OsStr)],
) -> anyhow::Result<()> {
    let root = xtask::workspace_root();
    println!("$ {} {}", program.display(), args.join(" "));
    let status = Command::new(program)
        .args(args)
        .envs(envs.iter().copied())
        .current_dir(&root)
        .status()
        .with_context(|| format!("running {}", program.display()))?;
    if !status.success() {
        bail!("{} {} failed with {status}", program.display(), args.join(" "));
    }
    Ok(())
}

/// Every Rust test, then the Python package's tests (see the module docs).
fn test(cargo_flags: &[String]) -> anyhow::Result<bool> {
    let root = xtask::workspace_root();
    let cargo = std::path::PathBuf::from(env!("CARGO"));
    let mut args = vec!["test", "--workspace", "--all-targets"];
    args.extend(cargo_flags.iter().map(String::as_str));
    run(&cargo, &args, &[])?;
    let venv = root.join("target/py-venv");
    let bin = venv.join("bin");
    if !bin.join("python").is_file() {
        run("python3".as_ref(), &["-m", "venv", &venv.to_string_lossy()], &[])?;
    }
    let requirements = root.join("crates/phalanx-py/requirements-test.txt");
    let pip = ["-m", "pip", "install", "--quiet", "--disable-pip-version-check", "-r"];
    let mut pip: Vec<&str> = pip.to_vec();
    let requirements = requirements.to_string_lossy();
    pip.push(&requirements);
    run(&bin.join("python"), &pip, &[])?;
    let path = std::env::join_paths(
        std::iter::once(bin.clone())
            .chain(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())),
    )?;
    let venv_env = [("VIRTUAL_ENV", venv.as_os_str()), ("PATH", path.as_os_str())];
    let mut develop = vec!["develop", "--quiet", "-m", "crates/phalanx-py/Cargo.toml"];
    develop.extend(cargo_flags.iter().map(String::as_str).filter(|f| *f == "--locked"));
    run(&bin.join("maturin"), &develop, &venv_env)?;
    let phalanx = root.join("target/debug/phalanx");
    let pytest_env = [("PHALANX_BIN", phalanx.as_os_str()), venv_env[0], venv_env[1]];
    run(&bin.join("python"), &["-m", "pytest", "-q", "crates/phalanx-py/tests"], &pytest_env)?;
    Ok(true)
}
