//! The same seed gives the same results on any thread count: `solve`, `eval`, `sim` and a
//! short `train` run on one and on two threads, compared with their timings left out; the
//! imitation data file and an imitation run's files, compared byte for byte.

use std::path::Path;
use std::process::Output;

use super::check;

/// `phalanx` in `dir` with `RAYON_NUM_THREADS=threads`.
fn on_threads(dir: &Path, threads: &str, args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_phalanx"))
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .current_dir(dir)
        .output()
        .expect("running phalanx")
}

/// A JSON report without its timings (wall seconds and rates) and its memory figures (the
/// thread pool's own allocations depend on the thread count).
pub(super) fn untimed(mut value: serde_json::Value) -> serde_json::Value {
    const TIMINGS: [&str; 5] =
        ["seconds", "runtime_s", "decisions_per_s", "agent_steps_per_s", "memory"];
    match &mut value {
        serde_json::Value::Object(map) => {
            for key in TIMINGS {
                map.remove(key);
            }
            for v in map.values_mut() {
                *v = untimed(v.take());
            }
        }
        serde_json::Value::Array(items) => {
            for v in items.iter_mut() {
                *v = untimed(v.take());
            }
        }
        _ => {}
    }
    value
}

/// The JSON that `args` prints on `threads` threads, without timings.
fn report(dir: &Path, threads: &str, args: &[&str]) -> serde_json::Value {
    let (stdout, _) = check(&on_threads(dir, threads, args), 0);
    untimed(serde_json::from_str(&stdout).unwrap_or_else(|err| panic!("{err}: {stdout}")))
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let generate = ["gen", "--size", "20", "--density", "0.15", "--agents", "3", "--seed", "4"];
    check(&on_threads(d, "1", &[&generate[..], &["-o", "inst.yaml"]].concat()), 0);
    let runs: [&[&str]; 4] = [
        &["solve", "inst.yaml", "--planner", "cbs", "--json"],
        &["solve", "inst.yaml", "--planner", "pathfinding", "--rollouts", "4", "--json"],
        &["eval", "--policy", "leader", "--maps", "4", "--size", "16", "--rollouts", "2", "--json"],
        &["sim", "--size", "16", "--episodes", "4", "--policy", "random", "--json"],
    ];
    for args in runs {
        assert_eq!(report(d, "1", args), report(d, "2", args), "{}", args.join(" "));
    }
    // The plans themselves (their statistics carry the runtime).
    for (threads, out) in [("1", "p1.yaml"), ("2", "p2.yaml")] {
        let args = ["solve", "inst.yaml", "--planner", "swarm", "-o", out];
        check(&on_threads(d, threads, &args), 0);
    }
    let names = phalanx_io::read_instance(&d.join("inst.yaml"), None).unwrap().names;
    let plan = |file: &str| phalanx_io::read_plan_for(&d.join(file), &names).unwrap();
    assert_eq!(plan("p1.yaml"), plan("p2.yaml"));

    // Training: the same metrics (timings aside) and a policy that plays the same.
    let config = r#"{"agent_counts": [2], "n_envs": 2, "pool": {"n_maps": 4},
        "env": {"step_limit": 20}, "learner": {"batch_size": 4, "learning_starts": 2}}"#;
    std::fs::write(d.join("cfg.json"), config).unwrap();
    let metrics = |run: &str| -> Vec<String> {
        let text = std::fs::read_to_string(d.join(run).join("metrics.jsonl")).unwrap();
        text.lines().filter(|l| !l.contains("\"perf/")).map(str::to_owned).collect()
    };
    for (threads, run) in [("1", "t1"), ("2", "t2")] {
        let args = ["train", "pathfinding", "--config", "cfg.json", "--steps", "120"];
        check(&on_threads(d, threads, &[&args[..], &["--out", run]].concat()), 0);
    }
    assert_eq!(metrics("t1"), metrics("t2"));
    // Parameter ids are sequential, not random: the policy files are byte-identical.
    let policy = |run: &str| std::fs::read(d.join(run).join("policy.bin")).unwrap();
    assert!(policy("t1") == policy("t2"), "the same run writes the same policy file");
    assert!(metrics("t1").iter().any(|l| l.contains("losses/td_loss")), "updates ran");
    let play = |run: &str| {
        let args =
            ["eval", "--policy", "pathfinding", "--weights", run, "--maps", "3", "--size", "16"];
        report(d, "1", &[&args[..], &["--json"]].concat())
    };
    let mut a = play("t1");
    let mut b = play("t2");
    for v in [&mut a, &mut b] {
        v.as_object_mut().unwrap().remove("weights");
    }
    assert_eq!(a, b);
}

#[test]
fn an_imitation_run_with_rounds_and_fine_tuning_writes_the_same_files_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let finetune = r#""finetune": {"pools": [{"n_maps": 3, "size": 16}], "agents": [3],
        "iterations": 2, "instances": 2, "rollouts": 3, "cloning": 0.5}"#;
    let config = super::imitation::CONFIG.replace(r#""finetune": null"#, finetune);
    std::fs::write(d.join("cfg.json"), config).unwrap();
    for (threads, out) in [("1", "t1"), ("2", "t2")] {
        let args = ["train", "imitation", "--config", "cfg.json", "--out", out];
        check(&on_threads(d, threads, &args), 0);
    }
    let files = ["data-0.bin", "data-0-1.bin", "data-1.bin", "round-2.bin", "policy.bin"];
    for file in files {
        let read = |run: &str| std::fs::read(d.join(run).join(file)).unwrap();
        assert!(read("t1") == read("t2"), "{file} differs between one and two threads");
    }
}

#[test]
fn imitation_data_is_the_same_file_on_one_and_two_threads_and_damage_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let args = |out: &'static str| {
        let mut a = vec!["imitate", "data", "--out", out, "--episodes", "6", "--seed", "2"];
        a.extend(["--pool-maps", "2", "--expert", "swarm", "--noise", "0.1"]);
        a
    };
    let (one, _) = check(&on_threads(dir.path(), "1", &args("one.bin")), 0);
    check(&on_threads(dir.path(), "2", &args("two.bin")), 0);
    assert!(one.contains("samples / s"), "{one}");
    let bytes = std::fs::read(dir.path().join("one.bin")).unwrap();
    assert_eq!(bytes, std::fs::read(dir.path().join("two.bin")).unwrap());

    let (summary, _) = check(&on_threads(dir.path(), "1", &["imitate", "check", "one.bin"]), 0);
    assert!(summary.contains("followers copying the leader"), "{summary}");
    let mut damaged = bytes.clone();
    let last = damaged.len() - 10;
    damaged[last] ^= 0x40;
    std::fs::write(dir.path().join("bad.bin"), &damaged).unwrap();
    let (_, err) = check(&on_threads(dir.path(), "1", &["imitate", "check", "bad.bin"]), 2);
    assert!(err.contains("bad.bin") && err.contains("CRC-32"), "{err}");
    let (_, err) = check(
        &on_threads(dir.path(), "1", &["imitate", "data", "--out", "x.bin", "--agents", "0"]),
        2,
    );
    assert!(err.contains("agents"), "{err}");
}
