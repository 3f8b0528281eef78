//! `cargo xtask`: the project's automation in Rust (no shell scripts).
//!
//! - `cargo xtask tidy`: every `.rs` file starts with a `//!` paragraph, no trailing
//!   whitespace, no `#[should_panic]`, no `#[ignore]`; no crate's modules import each other
//!   in a cycle, and phalanx-rl's inference modules import no training module.
//! - `cargo xtask deps`: the dependency invariants of ARCHITECTURE.md (no burn below the
//!   learning crates; the benchmark uses them without naming burn; pyo3 in the Python
//!   package only, zenoh in the transport crate only).
//! - `cargo xtask demo`: the README's main job, end to end on generated data: builds the
//!   release binary (cargo's progress shown; without the `processes` feature, which the demo
//!   does not use), then runs `phalanx demo`.
//! - `cargo xtask test [CARGO TEST FLAGS]`: the README's test command: every Rust test
//!   (`cargo test --workspace --all-targets`), then the Python package's tests (a virtualenv
//!   in `target/py-venv` with the pinned test requirements, `maturin develop`, pytest).
//! - `cargo xtask fuzz [--seconds N] [TARGET...]`: each fuzz target of `fuzz/` under
//!   libFuzzer for `N` seconds (default 600), one after the other; `cargo xtask fuzz
//!   --replay`: build the targets and run each over its corpus and crash inputs once (CI).
//!   Both need cargo-fuzz (`cargo install cargo-fuzz --locked`); no nightly toolchain.

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
        Some("fuzz") => fuzz(&args[1..]).map(|()| true),
        _ => {
            eprintln!("usage: cargo xtask tidy|deps|demo|test|fuzz");
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
const BURN_FREE: &[&str] = &[
    "phalanx-core",
    "phalanx-io",
    "phalanx-msg",
    "phalanx-motion",
    "phalanx-gen",
    "phalanx-env",
    "phalanx-plan",
    "phalanx-render",
    // the transport between processes: its trait lives in phalanx-msg, so the crate builds
    // without the learned policies
    "phalanx-zenoh",
];

/// Crates that use the learned policies through phalanx-rl but never name burn themselves.
const BURN_INDIRECT: &[&str] = &["phalanx-eval", "phalanx-runtime", "phalanx-py"];

/// The crates that may have `zenoh` among their dependencies: the transport crate, and the
/// binary through it.
const ZENOH_USERS: &[&str] = &["phalanx-zenoh", "phalanx-cli"];

/// The workspace's crates: the folders of `crates/`, each named as its package.
fn crates() -> anyhow::Result<Vec<String>> {
    let dir = xtask::workspace_root().join("crates");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        if path.join("Cargo.toml").is_file() {
            names.extend(path.file_name().and_then(|n| n.to_str()).map(str::to_owned));
        }
    }
    names.sort();
    Ok(names)
}

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
    for krate in crates()? {
        let all = tree(&krate, &[])?;
        if krate != "phalanx-py"
            && let Some(line) = all.lines().find(|l| l.starts_with("pyo3"))
        {
            bail!("{krate} depends on pyo3 ({line}); only phalanx-py may");
        }
        let zenoh = |l: &&str| l.starts_with("zenoh ");
        if !ZENOH_USERS.contains(&krate.as_str())
            && let Some(line) = all.lines().find(zenoh)
        {
            bail!("{krate} depends on zenoh ({line}); only phalanx-zenoh may");
        }
        if krate == "phalanx-cli"
            && let Some(line) = tree(&krate, &["--depth", "1"])?.lines().find(zenoh)
        {
            bail!("{krate} depends on zenoh directly ({line}); it must go through phalanx-zenoh");
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
    // Cargo's progress shows (a first build takes minutes); only the binary, without the
    // decentralised processes' Zenoh transport, which the demo does not use.
    println!("$ cargo build --release -p phalanx-cli --bin phalanx --no-default-features");
    let status = Command::new(env!("CARGO"))
        .args(["build", "--release", "-p", "phalanx-cli", "--bin", "phalanx"])
        .arg("--no-default-features")
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
    println!(
        "(this target/release/phalanx leaves out the processes of a decentralised run, \
         `world` and `agent`: `cargo build --release -p phalanx-cli` adds them)"
    );
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

/// The fuzz targets: the files of `fuzz/fuzz_targets`, by name.
fn fuzz_targets(fuzz_dir: &std::path::Path) -> anyhow::Result<Vec<String>> {
    let dir = fuzz_dir.join("fuzz_targets");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        if path.extension().is_some_and(|ext| ext == "rs") {
            names.extend(path.file_stem().map(|stem| stem.to_string_lossy().into_owned()));
        }
    }
    names.sort();
    Ok(names)
}

/// `cargo xtask fuzz` (see the module docs). The targets are built optimised, without a
/// sanitizer (safe Rust: a panic is the failure), on the stable toolchain.
fn fuzz(args: &[String]) -> anyhow::Result<()> {
    let root = xtask::workspace_root();
    let cargo = std::path::PathBuf::from(env!("CARGO"));
    let fuzz_dir = root.join("fuzz");
    let installed = Command::new(&cargo).args(["fuzz", "--version"]).output();
    if !installed.is_ok_and(|out| out.status.success()) {
        bail!("cargo-fuzz is missing: cargo install cargo-fuzz --locked");
    }
    let all = fuzz_targets(&fuzz_dir)?;
    let (mut seconds, mut replay, mut targets) = (600u64, false, Vec::new());
    let mut rest = args.iter();
    while let Some(arg) = rest.next() {
        match arg.as_str() {
            "--replay" => replay = true,
            "--seconds" => {
                let value = rest.next().context("--seconds needs a value")?;
                seconds = value.parse().with_context(|| format!("--seconds {value}"))?;
            }
            name if all.iter().any(|it| it == name) => targets.push(name.to_owned()),
            other => bail!("unknown fuzz target or flag {other:?} (targets: {all:?})"),
        }
    }
    if targets.is_empty() {
        targets = all;
    }
    let build = ["fuzz", "build", "-O", "-s", "none", "--fuzz-dir"];
    let fuzz_path = fuzz_dir.to_string_lossy();
    run(&cargo, &[&build[..], &[&fuzz_path]].concat(), &[])?;
    for target in &targets {
        let corpus = fuzz_dir.join("corpus").join(target);
        let regressions = fuzz_dir.join("regressions").join(target);
        let mut dirs = vec![corpus.to_string_lossy().into_owned()];
        if replay && regressions.is_dir() {
            dirs.push(regressions.to_string_lossy().into_owned());
        }
        let time = format!("-max_total_time={seconds}");
        let libfuzzer: Vec<&str> = if replay {
            vec!["-runs=0"]
        } else {
            vec![&time, "-rss_limit_mb=4096", "-timeout=10", "-print_final_stats=1"]
        };
        let mut args = vec!["fuzz", "run", "-O", "-s", "none", "--fuzz-dir", &fuzz_path, target];
        args.extend(dirs.iter().map(String::as_str));
        args.push("--");
        args.extend(libfuzzer);
        run(&cargo, &args, &[])?;
    }
    Ok(())
}
