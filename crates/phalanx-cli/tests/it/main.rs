//! Integration tests of the `phalanx` binary: it runs in a temporary directory and is
//! checked by exit code, stdout and stderr.

use std::path::Path;
use std::process::Output;

use phalanx_core::{DistanceMap, Instance, Plan};
use phalanx_io::PlanStats;

mod hostile;
mod imitation;
mod kill;
mod models;
mod motion;
mod numeric_flags;
mod processes;
mod render;
mod threads;

fn phalanx(dir: &Path, args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_phalanx"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("running phalanx")
}

#[track_caller]
fn check(out: &Output, code: i32) -> (String, String) {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "stdout:\n{stdout}\nstderr:\n{stderr}");
    (stdout, stderr)
}

/// The metrics of the run in `dir` but the timings: what an exact resume reproduces.
fn learning(dir: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    text.lines().filter(|line| !line.contains("\"perf/")).map(str::to_owned).collect()
}

/// A single agent walking down its BFS gradient to its goal.
fn walk(inst: &Instance) -> Plan {
    assert_eq!(inst.n_agents(), 1);
    let dist = DistanceMap::bfs(inst.grid(), inst.goals()[0]);
    let mut path = vec![inst.starts()[0]];
    while *path.last().unwrap() != inst.goals()[0] {
        let here = *path.last().unwrap();
        path.push(inst.grid().free_neighbours(here).min_by_key(|&n| dist.raw(n)).unwrap());
    }
    Plan::from_paths(&[path])
}

#[test]
fn gen_info_validate_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for file in ["inst.yaml", "inst.scen"] {
        let args = ["gen", "--size", "20", "--density", "0.15", "--agents", "1", "--seed", "7"];
        let (stdout, _) = check(&phalanx(d, &[&args[..], &["-o", file]].concat()), 0);
        assert!(stdout.contains("20x20"), "{stdout}");
        let (info, _) = check(&phalanx(d, &["info", file]), 0);
        assert!(info.contains("size       20x20") && info.contains("agents     1"), "{info}");
        assert!(info.contains("formation") && info.contains("agent0"), "{info}");

        let named = phalanx_io::read_instance(&d.join(file), None).unwrap();
        let plan = walk(&named.instance);
        phalanx_io::write_plan(&d.join("plan.yaml"), &plan, &PlanStats::of(&plan, 0.0)).unwrap();
        let (table, _) = check(&phalanx(d, &["validate", file, "plan.yaml"]), 0);
        assert!(table.starts_with("valid plan\nsuccess"), "{table}");
        let (json, _) = check(&phalanx(d, &["validate", file, "plan.yaml", "--json"]), 0);
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["success"], true);
        assert_eq!(v["n_agents"], 1);
        assert_eq!(v["makespan"], plan.horizon());
        assert_eq!(v["sum_of_costs"], plan.horizon());
        assert_eq!(v["formation_loss"], 0.0);
        for key in ["formation_loss_mean", "formation_loss_max"] {
            assert!(v[key].is_f64(), "{key} in {json}");
        }
    }
    assert!(d.join("inst.map").is_file());
}

#[test]
fn gen_draws_mazes_and_rooms_and_places_the_formation_on_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (kind, size, file) in [("maze", "32", "maze.scen"), ("rooms", "64", "rooms.yaml")] {
        let args =
            ["gen", "--kind", kind, "--size", size, "--agents", "4", "--seed", "5", "-o", file];
        check(&phalanx(d, &args), 0);
        let named = phalanx_io::read_instance(&d.join(file), None).unwrap();
        let inst = &named.instance;
        let side: u32 = size.parse().unwrap();
        let grid = match kind {
            "maze" => phalanx_gen::maze(side, phalanx_gen::MAZE_CORRIDOR, 5),
            _ => phalanx_gen::rooms(side, phalanx_gen::ROOM_SIDE, 5),
        };
        assert_eq!(inst.grid(), &grid.unwrap());
        assert_eq!(inst.n_agents(), 4);
        // The goals are the formation translated.
        assert_eq!(phalanx_core::formation_loss(inst.starts(), inst.goals()), 0.0);
        // The same seed, the same file.
        let again = format!("again-{file}");
        check(&phalanx(d, &[&args[..10], &[again.as_str()]].concat()), 0);
        assert_eq!(phalanx_io::read_instance(&d.join(&again), None).unwrap().instance, *inst);
    }
    let (_, err) =
        check(&phalanx(d, &["gen", "--kind", "rooms", "--size", "9", "-o", "x.yaml"]), 2);
    assert!(err.contains("9x9 map holds no two rooms"), "{err}");
    assert!(!d.join("x.yaml").exists());
}

const INSTANCE: &str = "\
map:
  dimensions: [4, 3]
  obstacles:
  - [1, 1]
agents:
- name: left
  start: [0, 0]
  goal: [0, 2]
- name: right
  start: [2, 0]
  goal: [2, 2]
";

/// Both agents walk up their columns side by side: a valid, formation-keeping plan.
const PLAN: &str = "\
schedule:
  right:
    - {x: 2, y: 0, t: 0}
    - {x: 2, y: 1, t: 1}
    - {x: 2, y: 2, t: 2}
  left:
    - {x: 0, y: 0, t: 0}
    - {x: 0, y: 1, t: 1}
    - {x: 0, y: 2, t: 2}
";

#[test]
fn hand_made_plan_and_its_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("i.yaml"), INSTANCE).unwrap();
    std::fs::write(d.join("p.yaml"), PLAN).unwrap();
    let (json, _) = check(&phalanx(d, &["validate", "i.yaml", "p.yaml", "--json"]), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!((v["makespan"].as_u64(), v["sum_of_costs"].as_u64()), (Some(2), Some(4)));
    assert_eq!(v["formation_loss"], 0.0);
    let (info, _) = check(&phalanx(d, &["info", "i.yaml"]), 0);
    assert!(info.contains("  0.1\n"), "{info}");
    assert!(info.contains("right  (2, 0)  (2, 2)  2"), "{info}");
}

#[test]
fn invalid_plans_exit_1_naming_the_violation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("i.yaml"), INSTANCE).unwrap();
    let through_wall = PLAN.replace("{x: 0, y: 1, t: 1}", "{x: 1, y: 1, t: 1}");
    std::fs::write(d.join("p.yaml"), through_wall).unwrap();
    let (_, stderr) = check(&phalanx(d, &["validate", "i.yaml", "p.yaml"]), 1);
    assert_eq!(stderr, "invalid plan: step 1, agent 0: (1, 1) is an obstacle\n");
    let (json, _) = check(&phalanx(d, &["validate", "i.yaml", "p.yaml", "--json"]), 1);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["valid"], false);
    let collide = PLAN.replace("{x: 0, y: 2, t: 2}", "{x: 0, y: 1, t: 2}");
    std::fs::write(d.join("p.yaml"), collide).unwrap();
    let (_, stderr) = check(&phalanx(d, &["validate", "i.yaml", "p.yaml"]), 1);
    assert!(stderr.contains("step 2, agent 0: ends at (0, 1), not on its goal (0, 2)"), "{stderr}");
}

#[test]
fn bad_input_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("i.yaml"), INSTANCE).unwrap();
    std::fs::write(d.join("p.yaml"), PLAN).unwrap();
    let (_, stderr) = check(&phalanx(d, &["validate", "none.yaml", "p.yaml"]), 2);
    assert!(stderr.starts_with("error: reading the instance: none.yaml: "), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["validate", "i.yaml", "p.yaml", "--bogus"]), 2);
    assert!(stderr.contains("--bogus"), "{stderr}");
    check(&phalanx(d, &["frobnicate"]), 2);
    check(&phalanx(d, &["--help"]), 0);
    std::fs::write(d.join("bad.yaml"), "map:\n  dimensions: [4, 3]\n").unwrap();
    let (_, stderr) = check(&phalanx(d, &["info", "bad.yaml"]), 2);
    assert_eq!(stderr, "error: reading the instance: bad.yaml:1: missing field `agents`\n");
    let one = PLAN.split("  left:").next().unwrap();
    std::fs::write(d.join("one.yaml"), one).unwrap();
    let (_, stderr) = check(&phalanx(d, &["validate", "i.yaml", "one.yaml"]), 2);
    assert_eq!(
        stderr,
        "error: reading the plan: one.yaml:1: the plan has 1 agents, the instance has 2\n"
    );
    let (_, stderr) = check(&phalanx(d, &["gen", "--size", "3", "-o", "x.yaml"]), 2);
    assert!(stderr.contains("map size 3 is out of range"), "{stderr}");
    check(&phalanx(d, &["gen", "-o", "x.txt"]), 2);
    assert!(!d.join("x.yaml").exists());
    // An output that cannot be written is a failure while working, not bad input.
    let (_, stderr) = check(&phalanx(d, &["gen", "-o", "no/such/dir/x.yaml"]), 3);
    assert!(stderr.contains("writing no/such/dir/x.yaml"), "{stderr}");
    // Non-finite and out-of-range numbers are refused, naming the flag.
    for (flag, value) in [("--density", "NaN"), ("--density", "0.5e1"), ("--fov", "x")] {
        let (_, stderr) = check(&phalanx(d, &["gen", flag, value, "-o", "y.yaml"]), 2);
        assert!(stderr.contains(flag) && stderr.contains(value), "{stderr}");
    }
    let (_, stderr) = check(&phalanx(d, &["eval", "--policy", "pathfinding", "--maps", "0"]), 2);
    assert!(stderr.contains("--maps 0"), "{stderr}");
    for bad in ["--rollouts=0", "--random-prob=inf"] {
        let (_, stderr) = check(&phalanx(d, &["eval", "--policy", "hrl", bad]), 2);
        assert!(stderr.contains(bad.split('=').next().unwrap()), "{stderr}");
    }
}

/// The metrics of a run: `(name, step)` of every line of `metrics.jsonl`.
fn read_metrics(path: &Path) -> Vec<(String, u64)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .map(|line| {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            assert!(v["value"].is_number(), "{line}");
            (v["name"].as_str().unwrap().to_owned(), v["step"].as_u64().unwrap())
        })
        .collect()
}

#[test]
fn train_writes_metrics_and_checkpoint_then_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let config =
        r#"{"agent_counts": [2], "n_envs": 1, "pool": {"n_maps": 4}, "env": {"step_limit": 20}}"#;
    std::fs::write(d.join("cfg.json"), config).unwrap();
    let args = ["train", "pathfinding", "--config", "cfg.json", "--steps", "200", "--out", "run"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    assert!(stdout.contains("env steps"), "{stdout}");
    assert!(d.join("run/checkpoint").is_file());
    assert!(d.join("run/policy.bin").is_file());
    let curves = std::fs::read_to_string(d.join("run/curves.svg")).unwrap();
    assert!(curves.starts_with("<svg") && curves.contains("success rate"), "{curves:.200}");
    let first = read_metrics(&d.join("run/metrics.jsonl"));
    let n_episodes = first.iter().filter(|(name, _)| name == "charts/episodic_return").count();
    assert_eq!(n_episodes, 10, "200 steps of 20-step episodes");
    assert!(first.iter().any(|(name, _)| name == "charts/success_rate"));
    assert!(first.iter().any(|(name, _)| name == "perf/sps"));
    assert_eq!(first.last().unwrap().1, 200);

    // Resumed: the saved config is read back, the counters continue, metrics are appended.
    let args = ["train", "pathfinding", "--resume", "--steps", "300", "--out", "run"];
    check(&phalanx(d, &args), 0);
    let both = read_metrics(&d.join("run/metrics.jsonl"));
    assert_eq!(both[..first.len()], first[..]);
    assert_eq!(both.last().unwrap().1, 300);
    assert!(both[first.len()..].iter().all(|(_, step)| *step > 200));
}

#[test]
fn train_with_updates_then_resume_continues() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let config = r#"{
        "agent_counts": [2, 3], "n_envs": 4, "checkpoint_every": 5, "pool": {"n_maps": 2}, "env": {"step_limit": 10},
        "learner": {"gamma": 0.95, "lr": 0.0005, "batch_size": 4, "replay_capacity": 100,
            "sequence": {"kind": "windows", "len": 4, "burn_in": 2},
            "target_update_interval": 10,
            "epsilon": {"start": 1.0, "end": 0.05, "decay_steps": 1000},
            "grad_clip_norm": 10.0, "learning_starts": 2, "train_every": 4}
    }"#;
    std::fs::write(d.join("cfg.json"), config).unwrap();
    let args = ["train", "formation", "--config", "cfg.json", "--steps", "100", "--out", "run"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    let first = summary_value(&stdout, "updates");
    assert!(first >= 10, "{stdout}");
    let metrics = read_metrics(&d.join("run/metrics.jsonl"));
    let n_losses = metrics.iter().filter(|(name, _)| name == "losses/td_loss").count();
    assert_eq!(n_losses as u64, first);
    let args = ["train", "formation", "--resume", "--steps", "140", "--out", "run"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    assert!(summary_value(&stdout, "updates") > first, "{stdout}");
    assert!(summary_value(&stdout, "env steps") >= 140, "{stdout}");
    // Exactly where it left off: the same metrics as a run that never stopped (timings aside).
    let args = ["train", "formation", "--config", "cfg.json", "--steps", "140", "--out", "whole"];
    check(&phalanx(d, &args), 0);
    assert_eq!(learning(&d.join("run")), learning(&d.join("whole")));

    // The run directory evaluates on fresh maps, for either team size.
    for agents in ["2", "3"] {
        let args = ["eval", "--policy", "formation", "--weights", "run", "--maps", "3"];
        let args = [&args[..], &["--size", "16", "--agents", agents, "--json"]].concat();
        let (stdout, _) = check(&phalanx(d, &args), 0);
        let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        for key in ["success_rate", "makespan", "collisions", "formation_loss"] {
            assert!(report.get(key).is_some(), "{key} missing: {stdout}");
        }
        assert_eq!(report["episodes"], 3, "{stdout}");
        assert_eq!(report["max_steps"], 50, "{stdout}");
    }
}

#[test]
fn eval_bad_input_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["eval", "--policy", "pathfinding", "--weights", "nowhere"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("nowhere"), "{stderr}");
    std::fs::create_dir(d.join("bad")).unwrap();
    std::fs::write(d.join("bad/policy.bin"), "not a policy").unwrap();
    let args = ["eval", "--policy", "pathfinding", "--weights", "bad"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("policy.bin") && stderr.contains("magic"), "{stderr}");
}

/// The integer after `key` in `phalanx train`'s summary table.
#[track_caller]
fn summary_value(stdout: &str, key: &str) -> u64 {
    let line = stdout.lines().find(|it| it.starts_with(key)).expect("a summary row");
    line[key.len()..].trim().parse().unwrap()
}

#[test]
fn train_bad_config_exits_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, stderr) = check(&phalanx(d, &["train", "formation", "--config", "nope.json"]), 2);
    assert!(stderr.contains("nope.json"), "{stderr}");
    std::fs::write(d.join("bad.json"), "{ n_agents: 2").unwrap();
    let (_, stderr) = check(&phalanx(d, &["train", "formation", "--config", "bad.json"]), 2);
    assert!(stderr.contains("bad.json"), "{stderr}");
    std::fs::write(d.join("typo.json"), r#"{"n_agnets": 2}"#).unwrap();
    let (_, stderr) = check(&phalanx(d, &["train", "formation", "--config", "typo.json"]), 2);
    assert!(stderr.contains("typo.json") && stderr.contains("n_agnets"), "{stderr}");
    std::fs::write(d.join("many.json"), r#"{"agent_counts": [3, 9]}"#).unwrap();
    let (_, stderr) = check(&phalanx(d, &["train", "formation", "--config", "many.json"]), 2);
    assert!(stderr.contains("agent count 9"), "{stderr}");
    std::fs::write(d.join("share.json"), r#"{"meta": {"wide_share": 1.5}}"#).unwrap();
    let (_, stderr) = check(&phalanx(d, &["train", "meta", "--config", "share.json"]), 2);
    assert!(stderr.contains("share.json") && stderr.contains("wide_share 1.5"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["train", "formation", "--wide-share", "0.5"]), 2);
    assert!(stderr.contains("--wide-share"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["train", "meta", "--wide-share", "NaN"]), 2);
    assert!(stderr.contains("NaN"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["train", "pathfinding", "--resume"]), 2);
    assert!(stderr.contains("checkpoint"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["train", "pathfinding", "--maps", "none.map"]), 2);
    assert!(stderr.contains("training map") && stderr.contains("none.map"), "{stderr}");
    assert!(!d.join("run").exists(), "nothing written on bad input");
}

#[test]
fn train_on_ones_own_maps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../test-data/movingai/warehouse-10-20-10-2-1.map")
        .canonicalize()
        .unwrap();
    std::fs::write(d.join("small.json"), r#"{"n_envs": 2, "env": {"step_limit": 20}}"#).unwrap();
    let args = ["train", "pathfinding", "--config", "small.json", "--steps", "40", "--out", "run"];
    check(&phalanx(d, &[&args[..], &["--maps", map.to_str().unwrap()]].concat()), 0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("run/config.json")).unwrap()).unwrap();
    assert_eq!(saved["pool"]["maps"][0], map.to_str().unwrap(), "{saved}");
    // The run resumes on the same maps (its saved config).
    let args = ["train", "pathfinding", "--resume", "--steps", "60", "--out", "run"];
    check(&phalanx(d, &args), 0);
}

#[test]
fn eval_finds_the_shipped_models() {
    let dir = tempfile::tempdir().unwrap();
    for policy in ["pathfinding", "formation"] {
        let args = ["eval", "--policy", policy, "--maps", "10", "--size", "20", "--json"];
        let (stdout, _) = check(&phalanx(dir.path(), &args), 0);
        let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let weights = report["weights"].as_str().unwrap();
        let expected = Path::new("models").join(policy).join("policy.bin");
        assert!(weights.ends_with(expected.to_str().unwrap()), "{weights}");
        if policy == "pathfinding" {
            // A guard against shipping a broken model: the shipped one solves about 0.9.
            let success = report["success_rate"].as_f64().unwrap();
            assert!(success >= 0.7, "shipped path-finding policy: success {success}");
        }
    }
}

#[test]
fn learned_policies_solve_instance_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "16", "--density", "0.1", "--agents", "3", "--seed", "4"];
    check(&phalanx(d, &[&args[..], &["-o", "inst.yaml"]].concat()), 0);
    let args = ["solve", "inst.yaml", "--planner", "pathfinding", "--rollouts", "2"];
    let (stdout, _) = check(&phalanx(d, &[&args[..], &["-o", "plan.yaml", "--json"]].concat()), 0);
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(summary["outcome"], "solved", "{stdout}");
    assert!(summary["decisions"].as_u64().unwrap() > 0, "{stdout}");
    check(&phalanx(d, &["validate", "inst.yaml", "plan.yaml"]), 0);

    // Two agents that must swap in a corridor: no rollout gets there.
    let swap = "map:\n  dimensions: [5, 1]\n  obstacles: []\nagents:\n- name: a\n  start: [0, 0]\n  goal: [4, 0]\n- name: b\n  start: [4, 0]\n  goal: [0, 0]\n";
    std::fs::write(d.join("swap.yaml"), swap).unwrap();
    let args =
        ["solve", "swap.yaml", "--planner", "pathfinding", "--rollouts", "2", "-o", "none.yaml"];
    let (stdout, _) = check(&phalanx(d, &args), 1);
    assert!(stdout.contains("outcome: step_limit"), "{stdout}");
    assert!(!d.join("none.yaml").exists(), "no plan is written");
    // With --partial the best rollout is written: a plan that stops short of the goals.
    check(&phalanx(d, &[&args[..], &["--partial"]].concat()), 1);
    let (_, stderr) = check(&phalanx(d, &["validate", "swap.yaml", "none.yaml"]), 1);
    assert!(stderr.contains("not on its goal"), "{stderr}");

    // The scripted leader rule over the shipped low level, with and without closing up.
    for extra in [&[][..], &["--wait-above", "0.5"]] {
        let args = [&["solve", "inst.yaml", "--planner", "leader", "-o", "lead.yaml"][..], extra];
        check(&phalanx(d, &args.concat()), 0);
        check(&phalanx(d, &["validate", "inst.yaml", "lead.yaml"]), 0);
    }
    let args = ["eval", "--policy", "leader", "--maps", "2", "--size", "16", "--wait-above", "1"];
    let (stdout, _) = check(&phalanx(d, &[&args[..], &["--json"]].concat()), 0);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["episodes"], 2, "{stdout}");
    let args = ["solve", "inst.yaml", "--planner", "pathfinding", "--wait-above", "1"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--wait-above"), "{stderr}");

    for bad in [
        &["--rollouts", "0"][..],
        &["--random-prob", "2"],
        &["--weight", "NaN"],
        &["--wait-above", "NaN"],
    ] {
        let planner = if bad[0] == "--wait-above" { "leader" } else { "pathfinding" };
        let args = [&["solve", "inst.yaml", "--planner", planner][..], bad].concat();
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains(bad[0]), "{bad:?}: {stderr}");
    }
    // A policy file with a flipped byte is refused, naming it.
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pathfinding/policy.bin");
    let mut bytes = std::fs::read(shipped).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 1;
    std::fs::create_dir(d.join("flipped")).unwrap();
    std::fs::write(d.join("flipped/policy.bin"), bytes).unwrap();
    let args = ["solve", "inst.yaml", "--planner", "pathfinding", "--weights", "flipped"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("flipped/policy.bin") && stderr.contains("damaged"), "{stderr}");
}

#[test]
fn meta_training_weight_and_hierarchy_run_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (stdout, _) =
        check(&phalanx(d, &["weight", "--agents", "3", "--episodes", "4", "--json"]), 0);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(report["estimates"][0]["weight"].as_f64().unwrap() > 0.0, "{stdout}");
    let config = r#"{
        "agent_counts": [3], "n_envs": 2, "checkpoint_every": 5, "pool": {"n_maps": 2},
        "env": {"step_limit": 12},
        "learner": {"batch_size": 4, "learning_starts": 2, "train_every": 4},
        "meta": {"base_weight": [[3, 4.5]], "place_input": false}
    }"#;
    std::fs::write(d.join("meta.json"), config).unwrap();
    let args = ["train", "meta", "--config", "meta.json", "--steps", "60", "--out", "run"];
    check(&phalanx(d, &args), 0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("run/config.json")).unwrap()).unwrap();
    assert_eq!(saved["net"]["n_actions"], 2);
    let args = ["eval", "--policy", "hrl", "--weights", "run", "--maps", "2", "--size", "16"];
    let (stdout, _) = check(&phalanx(d, &[&args[..], &["--json"]].concat()), 0);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["episodes"], 2, "{stdout}");
    // A meta policy that reads the place vector (the task's default), warm-started from the
    // one above (its three new inputs weighted zero); solved alone and run decentralised,
    // the same plan.
    let place = config
        .replacen('{', r#"{"init_from": "run/policy.bin", "#, 1)
        .replace(r#""place_input": false"#, r#""place_input": true"#);
    std::fs::write(d.join("place.json"), place).unwrap();
    let args = ["train", "meta", "--config", "place.json", "--steps", "60", "--out", "place"];
    check(&phalanx(d, &args), 0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("place/config.json")).unwrap())
            .unwrap();
    // The goal vector, then the place vector.
    let inputs = (&saved["net"]["env_vec"], &saved["meta"]["place_input"]);
    assert_eq!(inputs, (&6.into(), &true.into()));
    check(&phalanx(d, &["gen", "--size", "16", "--seed", "3", "-o", "inst.yaml"]), 0);
    let solve = ["solve", "inst.yaml", "--planner", "hrl", "--weights", "place", "--rollouts"];
    check(&phalanx(d, &[&solve[..], &["1", "--partial", "-o", "solved.yaml"]].concat()), 0);
    let run = ["run", "inst.yaml", "--policy", "hrl", "--weights", "place", "-o", "run.yaml"];
    check(&phalanx(d, &run), 0);
    let schedule = |file: &str| {
        let text = std::fs::read_to_string(d.join(file)).unwrap();
        text[text.find("schedule:").unwrap()..].to_string()
    };
    assert_eq!(schedule("solved.yaml"), schedule("run.yaml"));
    // A resumed run refuses other inputs than its checkpoint's.
    let args = ["train", "meta", "--config", "meta.json", "--resume", "--out", "place"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("place_input") || stderr.contains("env_vec"), "{stderr}");
    // The end-to-end baseline: the same settings with the five moves; evaluated, drawn and
    // benchmarked as a method.
    let args = ["train", "e2e", "--config", "meta.json", "--steps", "60", "--out", "e2e"];
    check(&phalanx(d, &args), 0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("e2e/config.json")).unwrap()).unwrap();
    assert_eq!(saved["net"]["n_actions"], 5);
    let args = ["eval", "--policy", "e2e", "--weights", "e2e", "--maps", "2", "--size", "16"];
    let (stdout, _) = check(&phalanx(d, &[&args[..], &["--render", "pics", "--json"]].concat()), 0);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["episodes"], 2, "{stdout}");
    for k in 0..2 {
        let svg = std::fs::read_to_string(d.join(format!("pics/episode-{k}.svg"))).unwrap();
        assert!(svg.contains("animateTransform") || svg.contains("<svg"), "episode {k}");
    }
    assert!(!d.join("pics/episode-2.svg").exists(), "only the episodes run are drawn");
    // The centralised baseline: the e2e settings with a centralised network.
    let args = ["train", "ctce", "--config", "meta.json", "--steps", "60", "--out", "ctce"];
    check(&phalanx(d, &args), 0);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("ctce/config.json")).unwrap())
            .unwrap();
    assert_eq!(
        (&saved["net"]["n_actions"], &saved["net"]["centralised"]),
        (&5.into(), &true.into())
    );
    let args = ["eval", "--policy", "ctce", "--weights", "ctce", "--maps", "2", "--size", "16"];
    let (stdout, _) = check(&phalanx(d, &[&args[..], &["--json"]].concat()), 0);
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["episodes"], 2, "{stdout}");
    let bench = ["bench", "table2", "--quick", "--methods", "e2e,ctce", "--out", "b"];
    check(&phalanx(d, &[&bench[..], &["--e2e", "e2e", "--ctce", "ctce"]].concat()), 0);
    let runs = std::fs::read_to_string(d.join("b/runs.jsonl")).unwrap();
    assert_eq!(runs.lines().count(), 7 * 2 * 2);
    assert!(runs.lines().all(|l| !l.contains("\"outcome\":\"invalid\"")), "{runs}");
    // The three runs' curves on one figure (the paper's Fig. 4).
    check(&phalanx(d, &["curves", "hrl=run", "e2e", "ctce/metrics.jsonl", "-o", "fig4.svg"]), 0);
    let svg = std::fs::read_to_string(d.join("fig4.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.len() > 1000);
    let (_, stderr) = check(&phalanx(d, &["curves", "nowhere", "-o", "x.svg"]), 2);
    assert!(stderr.contains("nowhere"), "{stderr}");
    assert!(!d.join("x.svg").exists());
    // A low-level policy file is no meta policy.
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pathfinding");
    let args = ["eval", "--policy", "hrl", "--weights", shipped.to_str().unwrap(), "--maps", "1"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("not a meta policy"), "{stderr}");
}

#[test]
fn bench_pareto_runs_the_shipped_front_and_refuses_points_it_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // models/meta-front: one meta policy per multiple, each named by the multiple it records.
    let args = ["bench", "pareto", "--quick", "--methods", "hrl:0.3,hrl:3", "--out", "p"];
    check(&phalanx(d, &args), 0);
    let text = std::fs::read_to_string(d.join("p/runs.jsonl")).unwrap();
    for method in ["hrl:0.3", "hrl:3"] {
        assert_eq!(text.matches(&format!("\"method\":\"{method}\"")).count(), 3 * 2, "{text}");
    }
    let settings = std::fs::read_to_string(d.join("p/bench.json")).unwrap();
    assert!(settings.contains("\"meta_front\""), "{settings}");
    assert!(d.join("p/pareto.svg").is_file());
    // The front as a table: one line per (row, point), the success rate and the means.
    let cells = std::fs::read_to_string(d.join("p/cells.csv")).unwrap();
    assert!(cells.starts_with("case,method,runs,solved,success_rate,makespan,formation_loss,"));
    assert_eq!(cells.lines().count(), 1 + 3 * 2, "{cells}");
    assert!(cells.lines().any(|l| l.starts_with("20x3@0.15,hrl:0.3,2,")), "{cells}");
    let args = ["bench", "pareto", "--quick", "--methods", "hrl:0.5", "--out", "q"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("none at 0.5 (it has 0, 0.1, 0.3, 1, 2, 3)"), "{stderr}");
    let args = ["bench", "pareto", "--quick", "--meta-front", "nowhere", "--out", "r"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("nowhere"), "{stderr}");
    assert!(!d.join("r").exists());
}

#[test]
fn bench_quick_runs_every_row_and_method_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["bench", "table2", "--quick", "--out", "b"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    let text = std::fs::read_to_string(d.join("b/runs.jsonl")).unwrap();
    let records: Vec<serde_json::Value> =
        text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    // The shipped meta policy (models/meta), end-to-end baselines (models/e2e, models/ctce)
    // and the planners' student (models/imitation) join the planners and the low level.
    let methods =
        ["cbs", "ecbs", "swarm", "jsa", "pathfinding", "leader", "hrl", "e2e", "ctce", "imitation"];
    // 7 rows × 2 instances × 10 methods, every plan valid.
    assert_eq!(records.len(), 7 * 2 * methods.len());
    for r in &records {
        assert_ne!(r["run"]["outcome"], "invalid", "{r}");
        assert!(r["run"]["violation"].is_null(), "{r}");
    }
    for row in ["20x3@0.15", "20x3@0.05", "20x5@0.05", "512x3@0.15 (20²)", "1024x3@0.15 (20²)"] {
        for m in methods {
            assert!(records.iter().any(|r| r["case"] == row && r["method"] == m), "{row} {m}");
        }
    }
    for file in ["runs.csv", "cells.json", "cells.csv", "table2.md", "table2.svg", "bench.json"] {
        assert!(d.join("b").join(file).is_file(), "{file}");
    }
    assert!(stdout.contains("| 20² | 3 | 0.15 | cbs |"), "{stdout}");
    // Not overwritten without --resume.
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--resume"), "{stderr}");
    // Killed after some runs: --resume makes only the missing ones.
    let kept: Vec<&str> = text.lines().take(10).collect();
    std::fs::write(d.join("b/runs.jsonl"), format!("{}\n", kept.join("\n"))).unwrap();
    check(&phalanx(d, &[&args[..], &["--resume"]].concat()), 0);
    let again = std::fs::read_to_string(d.join("b/runs.jsonl")).unwrap();
    assert_eq!(again.lines().count(), records.len());
    assert_eq!(again.lines().take(10).collect::<Vec<_>>(), kept);
    // The scaling benchmark: quick, on sides up to 64 with the first team size.
    let scaling = ["bench", "scaling", "--quick", "--out", "s", "--methods", "cbs,pathfinding"];
    let (stdout, _) = check(&phalanx(d, &scaling), 0);
    assert!(stdout.contains("| 64² | 3 | 0.15 | pathfinding |"), "{stdout}");
    assert!(d.join("s/scaling.svg").is_file());
    let cells: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("s/cells.json")).unwrap()).unwrap();
    assert_eq!(cells.as_array().unwrap().len(), 3 * 2, "sides 20, 32, 64 × two methods");
    // Real maps: a formation placed on each shipped MovingAI map.
    let maps = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../test-data/movingai/den312d.map");
    let real = ["bench", "movingai", "--quick", "--out", "m", "--methods", "cbs,swarm"];
    let maps_from = maps.display().to_string();
    let (stdout, _) = check(&phalanx(d, &[&real[..], &["--maps-from", &maps_from]].concat()), 0);
    assert!(stdout.contains("| den312d x3 (81²) | 3 |"), "{stdout}");
    let runs = std::fs::read_to_string(d.join("m/runs.jsonl")).unwrap();
    assert_eq!(runs.lines().count(), 2 * 2);
    assert!(runs.lines().all(|l| l.contains("\"outcome\":\"solved\"")), "{runs}");
    // Other settings are refused on resume.
    let (_, stderr) = check(&phalanx(d, &[&args[..], &["--resume", "--seed", "5"]].concat()), 2);
    assert!(stderr.contains("other settings"), "{stderr}");
    // Nothing to resume: said so, nothing made.
    let nothing = ["bench", "table2", "--quick", "--out", "none", "--resume"];
    let (_, stderr) = check(&phalanx(d, &nothing), 2);
    assert!(stderr.contains("holds no benchmark to continue"), "{stderr}");
    assert!(!d.join("none").exists());
    // Given instance files, with CBS ablations: the crossing case solved at its optimum
    // with and without the improvements, one run each whatever --maps says.
    let case = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../phalanx-plan/tests/data/cbs-timeout-64x64-4agents.yaml");
    let files =
        ["bench", "files", "--out", "f", "--time-limit", "10", "--methods", "cbs,cbs:plain"];
    let (stdout, _) = check(&phalanx(d, &[&files[..], &[case.to_str().unwrap()]].concat()), 0);
    assert!(stdout.contains("| cbs-timeout-64x64-4agents.yaml (64²) | 4 |"), "{stdout}");
    let runs = std::fs::read_to_string(d.join("f/runs.jsonl")).unwrap();
    assert_eq!(runs.lines().count(), 2);
    assert!(runs.lines().all(|l| l.contains("\"sum_of_costs\":480")), "{runs}");
    let (_, stderr) = check(&phalanx(d, &["bench", "files", "--methods", "cbs:fast", "x.yaml"]), 2);
    assert!(stderr.contains("x.yaml") || stderr.contains("fast"), "{stderr}");
}

#[test]
fn prioritised_a_star_failing_its_order_is_incomplete_not_unsolvable() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A corridor with a pocket: agent 0 parks on its goal before agent 1 can pass.
    let grid = phalanx_core::Grid::from_fn(5, 2, |c| c.y == 1 && c.x != 2);
    let cell = phalanx_core::Cell::new;
    let inst = Instance::new(grid, vec![cell(1, 0), cell(4, 0)], vec![cell(3, 0), cell(0, 0)]);
    phalanx_io::write_instance(&d.join("pocket.yaml"), &inst.unwrap()).unwrap();
    let (stdout, _) = check(&phalanx(d, &["solve", "pocket.yaml", "--planner", "astar"]), 4);
    assert!(stdout.contains("outcome: incomplete"), "{stdout}");
    check(&phalanx(d, &["solve", "pocket.yaml", "--planner", "cbs"]), 0);
}

#[test]
fn a_run_past_its_memory_bound_ends_with_a_message_and_keeps_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("big.yaml"), "kept\n").unwrap();
    let args = ["--memory-limit", "16M", "gen", "--size", "4096", "-o", "big.yaml"];
    let (_, stderr) = check(&phalanx(d, &args), 5);
    assert!(stderr.contains("bound of 16 MiB") && stderr.contains("--memory-limit"), "{stderr}");
    assert_eq!(std::fs::read_to_string(d.join("big.yaml")).unwrap(), "kept\n");
    let leftovers: Vec<_> = std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers, ["big.yaml"], "no temporary file is left");
    // A bound it fits in, given after the subcommand or in the environment.
    check(&phalanx(d, &["gen", "--size", "64", "-o", "small.yaml", "--memory-limit", "1G"]), 0);
    let env_bound = std::process::Command::new(env!("CARGO_BIN_EXE_phalanx"))
        .args(["gen", "--size", "4096", "-o", "big.yaml"])
        .env("PHALANX_MEMORY_LIMIT", "16M")
        .current_dir(d)
        .output()
        .unwrap();
    check(&env_bound, 5);
    // Sizes that are not sizes.
    let (_, stderr) =
        check(&phalanx(d, &["--memory-limit", "12 parsecs", "info", "small.yaml"]), 2);
    assert!(stderr.contains("--memory-limit \"12 parsecs\""), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["--memory-limit=0", "info", "small.yaml"]), 2);
    assert!(stderr.contains("must be positive"), "{stderr}");
}

#[test]
fn a_decentralised_run_plans_what_the_batched_policy_plans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "20", "--agents", "4", "--seed", "5", "-o", "inst.yaml"];
    check(&phalanx(d, &args), 0);
    let (table, _) = check(&phalanx(d, &["run", "inst.yaml", "-o", "run.yaml"]), 0);
    assert!(table.contains("outcome: solved") && table.contains("missed_actions: 0"), "{table}");
    let solve = ["solve", "inst.yaml", "--planner", "pathfinding", "--rollouts", "1"];
    check(&phalanx(d, &[&solve[..], &["-o", "solve.yaml"]].concat()), 0);
    let names = phalanx_io::read_instance(&d.join("inst.yaml"), None).unwrap().names;
    let plan = |file: &str| phalanx_io::read_plan_for(&d.join(file), &names).unwrap();
    assert_eq!(plan("run.yaml"), plan("solve.yaml"));
    let (json, _) = check(&phalanx(d, &["run", "inst.yaml", "--json"]), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!((v["outcome"].as_str(), v["stale_actions"].as_u64()), (Some("solved"), Some(0)));
    let (_, stderr) = check(&phalanx(d, &["run", "inst.yaml", "--step-timeout", "0"]), 2);
    assert!(stderr.contains("--step-timeout"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["run", "missing.yaml"]), 2);
    assert!(stderr.contains("missing.yaml"), "{stderr}");

    // The hierarchy as threads plans what `solve --planner hrl --rollouts 1` plans.
    let hrl = ["run", "inst.yaml", "--policy", "hrl", "-o", "hrl.yaml"];
    let (table, _) = check(&phalanx(d, &hrl), 0);
    assert!(
        table.contains("hrl (decentralised)") && table.contains("missed_choices: 0"),
        "{table}"
    );
    let solve =
        ["solve", "inst.yaml", "--planner", "hrl", "--rollouts", "1", "-o", "solve-hrl.yaml"];
    check(&phalanx(d, &solve), 0);
    assert_eq!(plan("hrl.yaml"), plan("solve-hrl.yaml"));
    let (_, stderr) = check(&phalanx(d, &["run", "inst.yaml", "--policy", "meta"]), 2);
    assert!(stderr.contains("meta"), "{stderr}");
}
