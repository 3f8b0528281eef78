//! `phalanx train imitation`: cloning then DAgger rounds, stopped anywhere with `--steps`
//! and resumed, ends with exactly the data, metrics and policy of a run never stopped; its
//! policy runs as the `imitation` method.

use std::path::Path;
use std::process::Output;

use super::{check, learning, phalanx};

/// A tiny run: a few 16² pool maps, teams of 3, the fast expert, two episodes on 16² mazes
/// labelled by CBS beside them, two DAgger rounds, no fine-tuning, validation on the 20²
/// rows only.
pub(crate) const CONFIG: &str = r#"{
    "data": {"pool": {"n_maps": 3, "size": 16}, "agents": [3], "episodes": 4, "seed": 2,
             "expert": "swarm"},
    "more_data": [{"pool": {"n_maps": 2, "size": 16, "kind": "maze"}, "expert": "cbs",
                   "episodes": 2}],
    "batch_size": 2, "updates": 5, "rounds": 2, "round_episodes": 2, "round_updates": 4,
    "checkpoint_every": 3, "validation_maps": 1, "validation_max_side": 20, "finetune": null
}"#;

/// `phalanx train imitation --config cfg.json --out OUT EXTRA…` in `dir`.
fn train(dir: &Path, out: &str, extra: &[&str]) -> Output {
    let args = [&["train", "imitation", "--config", "cfg.json", "--out", out][..], extra];
    phalanx(dir, &args.concat())
}

#[test]
fn an_imitation_run_stopped_anywhere_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cfg.json"), CONFIG).unwrap();
    let (stdout, _) = check(&train(d, "whole", &[]), 0);
    assert!(stdout.contains("13 of 13"), "{stdout}");
    // Stopped inside cloning, at a round's end, and inside the last round.
    check(&train(d, "parts", &["--steps", "4"]), 0);
    for steps in ["9", "11", "13"] {
        check(&train(d, "parts", &["--resume", "--steps", steps]), 0);
    }
    let run = |name: &str| d.join(name);
    assert_eq!(learning(&run("parts")), learning(&run("whole")), "the metrics differ");
    let files = ["data-0.bin", "data-0-1.bin", "data-1.bin", "data-2.bin", "policy.bin"];
    for file in files.into_iter().chain(["round-2.bin"]) {
        let read = |name: &str| std::fs::read(run(name).join(file)).unwrap();
        assert!(read("parts") == read("whole"), "{file} differs");
    }
    let validation = std::fs::read_to_string(run("parts").join("validation.jsonl")).unwrap();
    assert_eq!(validation.lines().count(), 3, "{validation}");
    // DAgger rounds on a warm-started student without cloning updates: round 0's student is
    // the one it starts from, validated and kept, which round 1 rolls out; a fine-tuning
    // after the round clones round 0's more_data set beside its policy gradient.
    let dagger = CONFIG.replace(
        r#""updates": 5, "rounds": 2"#,
        r#""updates": 0, "rounds": 1, "init_from": "whole/round-2.bin""#,
    );
    let finetune = r#""finetune": {"pools": [{"n_maps": 3, "size": 16}], "agents": [3],
        "iterations": 2, "instances": 1, "rollouts": 2, "cloning": 0.5}"#;
    let dagger = dagger.replace(r#""finetune": null"#, finetune);
    std::fs::write(d.join("dagger.json"), dagger).unwrap();
    let args = ["train", "imitation", "--config", "dagger.json", "--out", "dagger"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    assert!(stdout.contains("6 of 6"), "{stdout}");
    let metrics = std::fs::read_to_string(run("dagger").join("metrics.jsonl")).unwrap();
    let cloned = metrics.lines().filter(|l| l.contains("losses/imitation_loss")).count();
    assert_eq!(cloned, 4 + 2, "one cloning loss per update, the round's and fine-tuning's");
    assert!(
        ["round-0.bin", "data-1.bin", "round-1.bin"].iter().all(|f| run("dagger").join(f).exists())
    );
    let validation = std::fs::read_to_string(run("dagger").join("validation.jsonl")).unwrap();
    assert_eq!(validation.lines().count(), 3, "rounds 0 and 1, the fine-tuned: {validation}");
    // A folder without a checkpoint cannot be resumed: the message says what to do.
    let (_, stderr) = check(&train(d, "never", &["--resume"]), 2);
    assert!(
        stderr.contains("never/checkpoint does not exist") && stderr.contains("without --resume")
    );

    // The student is a method of its own.
    let inst = ["gen", "--size", "20", "--agents", "3", "--seed", "4", "-o", "inst.yaml"];
    check(&phalanx(d, &inst), 0);
    let solve = ["solve", "inst.yaml", "--planner", "imitation", "--weights", "whole", "--json"];
    let out = phalanx(d, &solve);
    assert!(matches!(out.status.code(), Some(0 | 1)), "{out:?}");
    let eval = ["eval", "--policy", "imitation", "--weights", "whole", "--maps", "2"];
    check(&phalanx(d, &eval), 0);
    // Settings a run cannot follow are refused with the field.
    std::fs::write(d.join("bad.json"), r#"{"round_epsilon": 3}"#).unwrap();
    let bad = ["train", "imitation", "--config", "bad.json", "--out", "bad"];
    let (_, stderr) = check(&phalanx(d, &bad), 2);
    assert!(stderr.contains("round_epsilon"), "{stderr}");
    let flag = ["train", "imitation", "--idle-cost", "1", "--out", "bad"];
    let (_, stderr) = check(&phalanx(d, &flag), 2);
    assert!(stderr.contains("--idle-cost"), "{stderr}");
}

#[test]
fn the_shipped_students_dead_band_is_a_test_time_flag() {
    // A generated 20² instance on which the band changes the shipped student's play: it
    // acts at its test-time band, 0.3 cells (docs/imitation.md), not the 0.6 of the
    // fine-tunings before its last; at 0.6 or a wider band a follower's lag stands, at 0.3
    // the agent in front waits for it and the team is tighter.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let inst = ["gen", "--size", "20", "--density", "0.05", "--agents", "3", "--seed", "105"];
    check(&phalanx(d, &[&inst[..], &["-o", "inst.yaml"]].concat()), 0);
    let solve = |band: &[&str]| {
        let args = ["solve", "inst.yaml", "--planner", "imitation", "--rollouts", "1", "--json"];
        let (stdout, _) = check(&phalanx(d, &[&args[..], band].concat()), 0);
        let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let metrics = &summary["metrics"];
        (metrics["makespan"].as_u64().unwrap(), metrics["formation_loss"].as_f64().unwrap())
    };
    let default = solve(&[]);
    assert_eq!(solve(&["--team-deadband", "0.3"]), default);
    let wider = solve(&["--team-deadband", "0.6"]);
    assert!(default.1 < wider.1, "at 0.3 {default:?}, at 0.6 {wider:?}");
    assert_ne!(solve(&["--team-deadband", "1.5"]), wider, "the band has no effect here");
    for bad in ["--team-deadband=-1", "--team-deadband=nan"] {
        let args = ["solve", "inst.yaml", "--planner", "imitation", bad];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains("--team-deadband"), "{stderr}");
    }
}

#[test]
fn validating_within_a_round_keeps_the_best_snapshot_and_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let config = CONFIG.replace(r#""rounds": 2"#, r#""rounds": 0, "validate_every": 2"#);
    std::fs::write(d.join("cfg.json"), config).unwrap();
    check(&train(d, "whole", &[]), 0);
    // Stopped at a checkpoint (3), and where a validation and a checkpoint fall together.
    let config = CONFIG.replace(r#""rounds": 2"#, r#""rounds": 0, "validate_every": 3"#);
    std::fs::write(d.join("cfg3.json"), config).unwrap();
    for (out, steps) in [("parts", "3"), ("at3", "3")] {
        let cfg = if out == "parts" { "cfg.json" } else { "cfg3.json" };
        let args = ["train", "imitation", "--config", cfg, "--out", out, "--steps", steps];
        check(&phalanx(d, &args), 0);
        check(&phalanx(d, &["train", "imitation", "--resume", "--out", out]), 0);
    }
    let read = |run: &str, file: &str| std::fs::read(d.join(run).join(file)).unwrap();
    assert_eq!(learning(&d.join("parts")), learning(&d.join("whole")), "the metrics differ");
    let at3 = String::from_utf8(read("at3", "validation.jsonl")).unwrap();
    assert_eq!(at3.lines().count(), 2, "{at3}");
    for file in ["validation.jsonl", "policy.bin", "update-2.bin", "update-4.bin", "round-0.bin"] {
        assert!(read("parts", file) == read("whole", file), "{file} differs");
    }
    // Updates 2 and 4 within cloning, 5 at its end; policy.bin is the best of them (success,
    // then loss; the first of equals).
    let lines: Vec<serde_json::Value> = String::from_utf8(read("whole", "validation.jsonl"))
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    let updates: Vec<u64> = lines.iter().map(|it| it["updates"].as_u64().unwrap()).collect();
    assert_eq!(updates, [2, 4, 5]);
    let key = |it: &serde_json::Value| {
        (it["success"].as_f64().unwrap(), -it["formation_loss"].as_f64().unwrap())
    };
    let mut best = &lines[0];
    for it in &lines[1..] {
        if key(it) > key(best) {
            best = it;
        }
    }
    let file = match best["updates"].as_u64().unwrap() {
        5 => "round-0.bin".to_owned(),
        n => format!("update-{n}.bin"),
    };
    assert!(read("whole", "policy.bin") == read("whole", &file), "policy.bin is not {file}");
    // A fresh run in the folder forgets the snapshots.
    let fresh = CONFIG.replace(r#""rounds": 2"#, r#""rounds": 0"#);
    std::fs::write(d.join("cfg.json"), fresh).unwrap();
    check(&train(d, "whole", &[]), 0);
    assert!(!d.join("whole").join("update-2.bin").exists());
}

#[test]
fn a_fine_tuning_stopped_anywhere_resumes_exactly_and_is_the_policy() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // With a cloning term on the more_data set beside the policy gradient.
    let finetune = r#""rounds": 0, "finetune": {"pools": [{"n_maps": 3, "size": 16}],
        "agents": [3], "iterations": 5, "instances": 1, "rollouts": 3, "cloning": 0.5}"#;
    let config = CONFIG.replace(r#""rounds": 2"#, finetune).replace(r#", "finetune": null"#, "");
    std::fs::write(d.join("cfg.json"), config).unwrap();
    let (stdout, _) = check(&train(d, "whole", &[]), 0);
    assert!(stdout.contains("10 of 10") && stdout.contains("fine-tuned"), "{stdout}");
    // Stopped at the cloning's end, at a checkpoint inside the fine-tuning, and after it.
    check(&train(d, "parts", &["--steps", "5"]), 0);
    for steps in ["6", "9"] {
        check(&train(d, "parts", &["--resume", "--steps", steps]), 0);
    }
    check(&train(d, "parts", &["--resume"]), 0);
    let read = |run: &str, file: &str| std::fs::read(d.join(run).join(file)).unwrap();
    assert_eq!(learning(&d.join("parts")), learning(&d.join("whole")), "the metrics differ");
    for file in ["finetune.bin", "policy.bin", "round-0.bin", "validation.jsonl"] {
        assert!(read("parts", file) == read("whole", file), "{file} differs");
    }
    assert!(read("whole", "policy.bin") == read("whole", "finetune.bin"));
    assert!(read("whole", "policy.bin") != read("whole", "round-0.bin"));
    let metrics = String::from_utf8(read("whole", "metrics.jsonl")).unwrap();
    let returns = metrics.lines().filter(|l| l.contains("charts/finetune_return")).count();
    assert_eq!(returns, 5, "one return per iteration");
    let cloned = metrics.lines().filter(|l| l.contains("losses/imitation_loss")).count();
    assert_eq!(cloned, 5 + 5, "one cloning loss per update, cloning's and fine-tuning's");

    // A run stopped inside the fine-tuning and resumed with its iterations lowered to the
    // checkpoint's ends there, as a run of that length does; lowered below it, it is refused.
    check(&train(d, "cut", &["--steps", "8"]), 0);
    let iterations = |from: &Path, to: &Path, n: u32| {
        let text = std::fs::read_to_string(from).unwrap();
        let mut settings: serde_json::Value = serde_json::from_str(&text).unwrap();
        settings["finetune"]["iterations"] = n.into();
        std::fs::write(to, serde_json::to_string_pretty(&settings).unwrap()).unwrap();
    };
    let settings = d.join("cut/config.json");
    iterations(&settings, &settings, 3);
    let (stdout, _) = check(&phalanx(d, &["train", "imitation", "--resume", "--out", "cut"]), 0);
    assert!(stdout.contains("8 of 8") && stdout.contains("fine-tuned"), "{stdout}");
    iterations(&d.join("cfg.json"), &d.join("cfg3.json"), 3);
    let args = ["train", "imitation", "--config", "cfg3.json", "--out", "three"];
    check(&phalanx(d, &args), 0);
    for file in ["finetune.bin", "policy.bin"] {
        assert!(read("cut", file) == read("three", file), "{file} differs");
    }
    iterations(&settings, &settings, 2);
    let (_, stderr) = check(&phalanx(d, &["train", "imitation", "--resume", "--out", "cut"]), 2);
    assert!(stderr.contains("at 8 updates, past the 7"), "{stderr}");

    // A student fine-tuned alone (no cloning, no expert data), from a policy file, at
    // another dead band of the team vector, which its policy file records.
    let alone = r#"{"more_data": [], "init_from": "whole/round-0.bin", "updates": 0, "rounds": 0,
        "validation_maps": 1, "validation_max_side": 20,
        "finetune": {"pools": [{"n_maps": 3, "size": 16}], "agents": [3], "iterations": 2,
        "instances": 1, "rollouts": 2, "team_deadband": 0.5}}"#;
    std::fs::write(d.join("alone.json"), alone).unwrap();
    let args = ["train", "imitation", "--config", "alone.json", "--out", "alone"];
    let (stdout, _) = check(&phalanx(d, &args), 0);
    assert!(stdout.contains("2 of 2"), "{stdout}");
    assert!(!d.join("alone/data-0.bin").exists(), "no expert data for a fine-tuning alone");
    // With a cloning term, the fine-tuning alone makes and clones the more_data set too.
    let sets = &CONFIG[CONFIG.find(r#""data""#).unwrap()..CONFIG.find(r#""batch_size""#).unwrap()];
    let cloning = alone.replace(r#""team_deadband": 0.5"#, r#""cloning": 0.5"#);
    let cloning = cloning.replacen(r#""more_data": [], "#, sets, 1);
    std::fs::write(d.join("cloning.json"), cloning).unwrap();
    let args = ["train", "imitation", "--config", "cloning.json", "--out", "cloning"];
    check(&phalanx(d, &args), 0);
    let set = "data-0-1.bin";
    assert!(read("cloning", set) == read("whole", set), "not the expert data");
    // Its cloning term draws on the more_data set only: the data of the paper's maps is not
    // made.
    assert!(!d.join("cloning/data-0.bin").exists());
    let metrics = String::from_utf8(read("cloning", "metrics.jsonl")).unwrap();
    let cloned = metrics.lines().filter(|l| l.contains("losses/imitation_loss")).count();
    assert_eq!(cloned, 2, "one cloning loss per iteration");
    let header = String::from_utf8_lossy(&read("alone", "policy.bin")).into_owned();
    assert!(header.contains(r#""team_deadband": 0.5"#), "the band is not in the policy file");
    // The cloning at the data's (default) band, the fine-tuning at its own (0.6 by default).
    let band = |file: &str| {
        let text = String::from_utf8_lossy(&read("whole", file)).into_owned();
        let field = |at: usize| text[at..].split([',', '\n', '}']).next().unwrap().to_owned();
        text.find("team_deadband").map(field)
    };
    assert_eq!(band("round-0.bin"), None);
    assert_eq!(band("policy.bin").as_deref(), Some(r#"team_deadband": 0.6"#));
    // Settings a fine-tuning cannot follow are refused with the field.
    std::fs::write(d.join("bad.json"), r#"{"finetune": {"temperature": 0}}"#).unwrap();
    let bad = ["train", "imitation", "--config", "bad.json", "--out", "bad"];
    let (_, stderr) = check(&phalanx(d, &bad), 2);
    assert!(stderr.contains("finetune.temperature"), "{stderr}");
    std::fs::write(d.join("bad.json"), r#"{"finetune": {"cloning": -1}}"#).unwrap();
    let (_, stderr) = check(&phalanx(d, &bad), 2);
    assert!(stderr.contains("cloning must be 0 or more"), "{stderr}");
}

#[test]
fn a_recipe_is_its_stages_run_by_hand_and_resumes_with_stages_added() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = CONFIG.replace(r#""rounds": 2"#, r#""rounds": 0"#);
    let second = |from: &str| {
        CONFIG.replace(
            r#""updates": 5, "rounds": 2"#,
            &format!(r#""updates": 0, "rounds": 1, "init_from": "{from}""#),
        )
    };
    let stage_a = format!(r#"{{"name": "a", "config": {first}}}"#);
    let stage_b = format!(r#"{{"name": "b", "seed": 3, "config": {}}}"#, second("a/round-0.bin"));
    let recipe = |stages: &[&str]| format!(r#"{{"stages": [{}]}}"#, stages.join(", "));
    std::fs::write(d.join("ab.json"), recipe(&[&stage_a, &stage_b])).unwrap();
    std::fs::write(d.join("a.json"), recipe(&[&stage_a])).unwrap();
    let cook = |file: &str, out: &str, extra: &[&str]| {
        let args = [&["train", "imitation", "--recipe", file, "--out", out][..], extra].concat();
        phalanx(d, &args)
    };
    let (stdout, _) = check(&cook("ab.json", "whole", &[]), 0);
    assert!(stdout.contains("all stages"), "{stdout}");
    // The same two runs by hand.
    std::fs::write(d.join("a-cfg.json"), &first).unwrap();
    std::fs::write(d.join("b-cfg.json"), second("hand/a/round-0.bin")).unwrap();
    let by_hand = |cfg: &str, out: &str, seed: &str| {
        let args = ["train", "imitation", "--config", cfg, "--out", out, "--seed", seed];
        check(&phalanx(d, &args), 0);
    };
    by_hand("a-cfg.json", "hand/a", "0");
    by_hand("b-cfg.json", "hand/b", "3");
    let read = |path: &str| std::fs::read(d.join(path)).unwrap();
    for file in ["a/policy.bin", "b/round-1.bin", "b/data-1.bin", "b/policy.bin"] {
        assert!(read(&format!("whole/{file}")) == read(&format!("hand/{file}")), "{file} differs");
    }
    assert!(read("whole/policy.bin") == read("hand/b/policy.bin"));
    // Stage b read stage a's expert data rather than making its own.
    assert!(read("whole/b/data-0.bin") == read("whole/a/data-0.bin"));
    let finished = std::fs::read_to_string(d.join("whole/stages.jsonl")).unwrap();
    assert_eq!(finished.lines().count(), 2, "{finished}");
    // A recipe of the first stage, resumed with the second added, is the whole recipe.
    check(&cook("a.json", "parts", &[]), 0);
    assert!(!d.join("parts/b").exists());
    check(&cook("ab.json", "parts", &["--resume"]), 0);
    assert!(read("parts/policy.bin") == read("whole/policy.bin"));
    // Resumed without the recipe: its own, every stage finished.
    check(&phalanx(d, &["train", "imitation", "--resume", "--out", "parts"]), 0);
    // A recipe whose finished stages are not its first is refused.
    std::fs::write(d.join("b.json"), recipe(&[&stage_b.replace("a/round-0.bin", "/x")])).unwrap();
    let (_, stderr) = check(&cook("b.json", "parts", &["--resume"]), 2);
    assert!(stderr.contains("stages.jsonl: the finished stages (a, b)"), "{stderr}");
    let seed_9 = stage_a.replace(r#""name": "a""#, r#""name": "a", "seed": 9"#);
    std::fs::write(d.join("a9.json"), recipe(&[&seed_9, &stage_b])).unwrap();
    let (_, stderr) = check(&cook("a9.json", "whole", &["--resume"]), 2);
    assert!(stderr.contains("first 2 stages are not those"), "{stderr}");
    let (_, stderr) = check(&cook("a9.json", "parts2", &["--seed", "4"]), 2);
    assert!(stderr.contains("--seed is a stage's setting"), "{stderr}");
}
