//! Kill anywhere: a short `phalanx train` run killed with SIGKILL at random moments (seeded
//! delays; some fall inside checkpoint writes, which are atomic) and resumed each time ends
//! with exactly the metrics and the policy file of a run never stopped. After every kill the
//! checkpoint, when there is one, reads back, and it is at most one checkpoint interval
//! behind the progress the metrics show; metrics written past it, and a line torn by the
//! kill, are cut by the resume.

use std::path::Path;
use std::time::Duration;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::check;

/// Checkpoints far enough apart that more metrics than the writer's buffer holds come
/// between two: a killed run has flushed lines past its checkpoint, which a resume must cut.
const CONFIG: &str = r#"{"agent_counts": [2], "n_envs": 2, "pool": {"n_maps": 4},
    "checkpoint_every": 32, "env": {"step_limit": 20},
    "learner": {"batch_size": 4, "learning_starts": 2}}"#;
const STEPS: &str = "1500";
/// Environment steps between two checkpoints: `checkpoint_every × train_every` (8).
const INTERVAL: u64 = 32 * 8;

/// `phalanx ARGS` in `dir`, quiet, with `--resume` when `resume`.
fn phalanx(dir: &Path, args: &[&str], resume: bool) -> std::process::Command {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_phalanx"));
    cmd.args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
    if resume {
        cmd.arg("--resume");
    }
    cmd
}

fn train(dir: &Path, run: &str, resume: bool) -> std::process::Command {
    let args = ["train", "pathfinding", "--config", "cfg.json", "--steps", STEPS, "--out", run];
    phalanx(dir, &args, resume)
}

/// The metric lines of `run`, without the timings (`perf/`).
fn metrics(dir: &Path, run: &str) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join(run).join("metrics.jsonl")).unwrap_or_default();
    text.lines().filter(|l| !l.contains("\"perf/")).map(str::to_owned).collect()
}

/// The last step the complete metric lines of `run` reach.
fn progress(dir: &Path, run: &str) -> u64 {
    let text = std::fs::read_to_string(dir.join(run).join("metrics.jsonl")).unwrap_or_default();
    text.split_inclusive('\n')
        .filter(|l| l.ends_with('\n'))
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok()?["step"].as_u64())
        .max()
        .unwrap_or(0)
}

#[test]
fn training_killed_anywhere_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cfg.json"), CONFIG).unwrap();
    let started = std::time::Instant::now();
    let whole = train(d, "whole", false).output().unwrap();
    assert!(whole.status.success(), "the uninterrupted run failed");
    // Kills land between a twentieth and a quarter of a whole run's time after each start.
    let span = started.elapsed().as_millis() as u64;

    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let checkpoint = d.join("parts").join("checkpoint");
    let mut kills = 0;
    for _ in 0..5 {
        let resume = checkpoint.exists();
        let mut child = train(d, "parts", resume).spawn().unwrap();
        std::thread::sleep(Duration::from_millis(rng.random_range(span / 20..span / 4)));
        if child.try_wait().unwrap().is_some() {
            break; // finished before the kill
        }
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        kills += 1;
        if checkpoint.exists() {
            let header = phalanx_rl::policy_file::read_header(&checkpoint)
                .unwrap_or_else(|err| panic!("after kill {kills}: {err}"));
            let (saved, shown) = (header.counters.env_steps, progress(d, "parts"));
            assert!(
                shown <= saved + INTERVAL,
                "kill {kills}: the checkpoint at {saved} steps is more than one interval behind {shown}"
            );
            // A resume needs what the checkpoint holds: the learner loads.
            let device = burn::tensor::Device::flex().autodiff();
            phalanx_rl::Learner::load(&checkpoint, &device).unwrap();
        }
    }
    assert!(kills >= 3, "only {kills} kills landed before the run ended");
    // Whether or not a kill left lines past the checkpoint (flushed when the writer's buffer
    // filled) depends on timing; make sure of one, and of a line torn by the kill.
    if checkpoint.exists() {
        let saved = phalanx_rl::policy_file::read_header(&checkpoint).unwrap().counters.env_steps;
        let extra = format!(
            "{{\"name\":\"charts/episodic_return\",\"step\":{},\"value\":1.0}}\n{{\"name\":\"cha",
            saved + 1
        );
        let path = d.join("parts").join("metrics.jsonl");
        let mut file = std::fs::OpenOptions::new().append(true).open(path).unwrap();
        std::io::Write::write_all(&mut file, extra.as_bytes()).unwrap();
    }
    let last = train(d, "parts", checkpoint.exists()).output().unwrap();
    assert!(last.status.success(), "the last resume failed");

    assert_eq!(metrics(d, "parts"), metrics(d, "whole"), "the metrics differ");
    let policy = |run: &str| std::fs::read(d.join(run).join("policy.bin")).unwrap();
    assert!(policy("parts") == policy("whole"), "the policy files differ");
    check(&last, 0);
}

fn bench(dir: &Path, out: &str, resume: bool) -> std::process::Command {
    let scaling = ["bench", "scaling", "--sides", "128,256", "--agents", "3", "--maps", "8"];
    let methods = ["--methods", "pathfinding,ecbs", "--rollouts", "2", "--out", out];
    phalanx(dir, &[&scaling[..], &methods[..]].concat(), resume)
}

/// The run records of `out` without their timings, sorted.
fn records(dir: &Path, out: &str) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join(out).join("runs.jsonl")).unwrap();
    let mut res: Vec<serde_json::Value> =
        text.lines().map(|l| super::threads::untimed(serde_json::from_str(l).unwrap())).collect();
    res.sort_by_key(|r| r.to_string());
    res
}

#[test]
fn a_benchmark_killed_anywhere_resumes_to_the_same_records() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let started = std::time::Instant::now();
    assert!(bench(d, "whole", false).status().unwrap().success());
    let span = started.elapsed().as_millis() as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut kills = 0;
    for _ in 0..4 {
        let resume = d.join("parts").join("bench.json").exists();
        let mut child = bench(d, "parts", resume).spawn().unwrap();
        std::thread::sleep(Duration::from_millis(rng.random_range(span / 10..span / 3)));
        if child.try_wait().unwrap().is_some() {
            break;
        }
        child.kill().unwrap();
        child.wait().unwrap();
        kills += 1;
    }
    assert!(kills >= 2, "only {kills} kills landed before the benchmark ended");
    assert!(bench(d, "parts", true).status().unwrap().success(), "the last resume failed");
    let (parts, whole) = (records(d, "parts"), records(d, "whole"));
    assert_eq!(parts.len(), whole.len(), "a run is missing or made twice");
    assert_eq!(parts, whole);
}
