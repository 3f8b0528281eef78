//! Every numeric flag of every subcommand, fed hostile values: 0, −1, NaN, ±inf, 1e300 and
//! 1e-300. The flags are those the command definitions give (`numeric_flags.txt`, which a
//! unit test of the binary keeps equal to what `Cli::command()` defines); the other
//! arguments of each subcommand come from small fixtures, so that a value the parser takes
//! reaches the command. Each run must end within [`LIMIT`] with a documented exit code
//! (0 success, 1 no plan, 2 bad input, 4 incomplete planner, 6 no peer: never 101, a
//! panic, nor 3 or 5 for a flag's value), and a refused value must be named on stderr.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::{INSTANCE, PLAN};

/// The hostile values.
const VALUES: [&str; 7] = ["0", "-1", "NaN", "inf", "-inf", "1e300", "1e-300"];

/// The longest a run may take (a debug build, on a busy machine).
const LIMIT: Duration = Duration::from_secs(30);

/// The exit codes a run may end with (docs/errors.md).
const DOCUMENTED: [i32; 5] = [0, 1, 2, 4, 6];

/// The arguments that make `subcommand` (its words, e.g. `bench files`) run on the fixtures
/// in its directory; `None` for one without a fixture (the test then fails).
fn fixture(subcommand: &str) -> Option<Vec<String>> {
    let movingai = concat!(env!("CARGO_MANIFEST_DIR"), "/../../test-data/movingai/den312d.map");
    let bench = |rest: &[&'static str]| -> Vec<&'static str> {
        let common = ["--maps", "1", "--methods", "cbs", "--out", "b", "--time-limit", "5"];
        [&common[..], rest].concat()
    };
    let args: Vec<&str> = match subcommand {
        "gen" => vec!["--size", "8", "-o", "g.yaml"],
        "info" => vec!["i.yaml"],
        "validate" => vec!["i.yaml", "p.yaml"],
        "sim" => vec!["--size", "8", "--agents", "2"],
        "solve" => vec!["i.yaml", "--time-limit", "5"],
        "run" => vec!["i.yaml", "--step-timeout", "2000"],
        "world" => vec!["i.yaml", "--listen", "tcp/127.0.0.1:0", "--join-timeout", "0.3"],
        "agent" => vec![
            "--id",
            "0",
            "--connect",
            "tcp/127.0.0.1:9",
            "--listen",
            "tcp/127.0.0.1:0",
            "--join-timeout",
            "0.3",
        ],
        "train" => vec!["pathfinding", "--config", "cfg.json", "--steps", "20", "--out", "run"],
        "eval" => vec!["--policy", "pathfinding", "--maps", "1", "--size", "8", "--agents", "2"],
        "curves" => vec!["m.jsonl", "-o", "c.svg"],
        "weight" => vec!["--agents", "2", "--steps", "3", "--episodes", "1"],
        "demo" => vec!["--time-limit", "0.2", "--rollouts", "1", "--out", "d"],
        "render" => vec!["i.yaml", "p.yaml", "-o", "r.svg"],
        "motion" => {
            vec!["i.yaml", "p.yaml", "--wheelbase", "0.2", "--max-steer", "30", "--cell", "1"]
        }
        "bench table2" | "bench pareto" => bench(&["--quick"]),
        "bench scaling" => bench(&["--sides", "20", "--agents", "2"]),
        "bench movingai" => bench(&["--maps-from", movingai, "--agents", "2"]),
        "bench files" => bench(&["i.yaml"]),
        "imitate expert" => {
            vec!["--maps", "1", "--max-side", "20", "--node-limit", "2000", "--cbs-time-limit", "5"]
        }
        "imitate data" => {
            vec!["--out", "d.bin", "--episodes", "2", "--pool-maps", "2", "--node-limit", "2000"]
        }
        _ => return None,
    };
    Some(args.into_iter().map(str::to_owned).collect())
}

/// Flags that only count with another setting: the planner or policy that reads them.
fn enabling(subcommand: &str, flag: &str) -> &'static [&'static str] {
    match (subcommand, flag) {
        ("solve", "--weight") => &["--planner", "ecbs"],
        ("solve", "--rollouts" | "--random-prob") => &["--planner", "hrl"],
        ("solve", "--wait-above" | "--patience") => &["--planner", "leader"],
        ("eval", "--wait-above" | "--patience") => &["--policy", "leader"],
        _ => &[],
    }
}

/// The fixture's arguments without the flag under test (and its value), then the flag's
/// enabling setting, then the flag with `value`.
fn arguments(subcommand: &str, flag: &str, value: &str) -> Vec<String> {
    let base = fixture(subcommand).unwrap_or_default();
    let mut args: Vec<String> = subcommand.split(' ').map(str::to_owned).collect();
    let mut skip = false;
    for (i, arg) in base.iter().enumerate() {
        if skip {
            skip = false;
            continue;
        }
        let enabled = enabling(subcommand, flag);
        if arg == flag || enabled.first().is_some_and(|it| it == arg) {
            skip = base.get(i + 1).is_some_and(|next| !next.starts_with("--"));
            continue;
        }
        args.push(arg.clone());
    }
    args.extend(enabling(subcommand, flag).iter().map(|it| (*it).to_owned()));
    args.push(format!("{flag}={value}"));
    args
}

/// The small files every run finds in its directory.
fn fixtures(dir: &Path) {
    std::fs::write(dir.join("i.yaml"), INSTANCE).unwrap();
    std::fs::write(dir.join("p.yaml"), PLAN).unwrap();
    let config =
        r#"{"agent_counts": [2], "n_envs": 1, "pool": {"n_maps": 2}, "env": {"step_limit": 10}}"#;
    std::fs::write(dir.join("cfg.json"), config).unwrap();
    let metrics: String = (1..=3)
        .map(|step| {
            format!("{{\"name\": \"charts/episodic_return\", \"step\": {step}, \"value\": 1.5}}\n")
        })
        .collect();
    std::fs::write(dir.join("m.jsonl"), metrics).unwrap();
}

/// Runs `args` in `dir`, killed after [`LIMIT`]: the exit code (`None`: killed or a signal),
/// the time taken and stderr.
fn run_bounded(dir: &Path, args: &[String]) -> (Option<i32>, Duration, String) {
    let started = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_phalanx"))
        .args(args)
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("running phalanx");
    let mut stderr = child.stderr.take().expect("piped");
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut text);
        text
    });
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for phalanx") {
            break Some(status);
        }
        if started.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let text = reader.join().unwrap_or_default();
    (status.and_then(|s| s.code()), started.elapsed(), text)
}

#[test]
fn every_numeric_flag_takes_hostile_values_without_a_panic_or_a_hang() {
    let list = include_str!("numeric_flags.txt");
    let flags: Vec<(String, String)> = list
        .lines()
        .filter_map(|line| {
            let (path, rest) = line.split_once(" --")?;
            let flag = rest.split(' ').next()?;
            Some((path.to_owned(), format!("--{flag}")))
        })
        .collect();
    assert!(flags.len() > 50, "the list holds the flags of every subcommand: {list}");
    let missing: Vec<&String> =
        flags.iter().map(|(path, _)| path).filter(|p| fixture(p).is_none()).collect();
    assert!(missing.is_empty(), "no fixture for the subcommands {missing:?}");

    let jobs: Vec<(String, String, &str)> = flags
        .iter()
        .flat_map(|(path, flag)| VALUES.iter().map(move |v| (path.clone(), flag.clone(), *v)))
        .collect();
    let next = Mutex::new(jobs.into_iter());
    let failures = Mutex::new(Vec::new());
    let slowest = Mutex::new((Duration::ZERO, String::new()));
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(2, 8);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let Some((path, flag, value)) = next.lock().unwrap().next() else { break };
                    let dir = tempfile::tempdir().unwrap();
                    fixtures(dir.path());
                    let args = arguments(&path, &flag, value);
                    let (code, took, stderr) = run_bounded(dir.path(), &args);
                    let shown = args.join(" ");
                    {
                        let mut slowest = slowest.lock().unwrap();
                        if took > slowest.0 {
                            *slowest = (took, shown.clone());
                        }
                    }
                    let fault = match code {
                        None => Some(format!("no exit within {LIMIT:?}")),
                        Some(code) if !DOCUMENTED.contains(&code) => {
                            Some(format!("exit {code}: {stderr}"))
                        }
                        Some(2) if !stderr.contains(&flag) && !stderr.contains("error") => {
                            Some(format!("exit 2 without a message: {stderr}"))
                        }
                        _ => None,
                    };
                    if let Some(fault) = fault {
                        failures.lock().unwrap().push(format!("phalanx {shown}: {fault}"));
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    let (took, slowest) = slowest.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} runs failed (slowest {took:?}: {slowest}):\n{}",
        failures.len(),
        failures.join("\n")
    );
}
