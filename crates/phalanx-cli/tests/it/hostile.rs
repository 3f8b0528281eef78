//! Bad input found by attacking the binary as a careless or hostile user would: each case
//! gets a message naming the file, line or flag and value, its documented exit code, no
//! panic, no hang and no half-written output (docs/errors.md, "Hostile input").

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use crate::{INSTANCE, PLAN, check, phalanx};

/// The shipped model `name`'s directory.
fn model(name: &str) -> String {
    format!("{}/../../models/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// A directory holding the two-agent instance `i.yaml` and its plan `p.yaml`.
fn fixtures() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("i.yaml"), INSTANCE).unwrap();
    std::fs::write(dir.path().join("p.yaml"), PLAN).unwrap();
    dir
}

#[test]
fn durations_too_long_for_a_clock_are_refused_by_every_duration_flag() {
    let dir = fixtures();
    let d = dir.path();
    for planner in ["cbs", "swarm", "jsa", "astar"] {
        let args = ["solve", "i.yaml", "--planner", planner, "--time-limit", "1e20"];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains("--time-limit") && stderr.contains("longest"), "{stderr}");
    }
    let runs: [&[&str]; 4] = [
        &["bench", "files", "i.yaml", "--out", "b", "--time-limit", "1e300"],
        &["world", "i.yaml", "--join-timeout", "1e300"],
        &["agent", "--id", "0", "--join-timeout", "2e19"],
        &["agent", "--id", "0", "--silence", "1e10"],
    ];
    for args in runs {
        let (_, stderr) = check(&phalanx(d, args), 2);
        assert!(stderr.contains(args[args.len() - 2]), "{stderr}");
        assert!(stderr.len() < 300, "a value is shown short: {stderr}");
    }
    assert!(!d.join("b").exists(), "a refused benchmark leaves no folder");
}

#[test]
fn an_ecbs_bound_below_1_is_bad_input_and_leaves_no_benchmark_behind() {
    let dir = fixtures();
    let d = dir.path();
    for bound in ["0", "0.5", "0.999"] {
        let args = ["solve", "i.yaml", "--planner", "ecbs", "--weight", bound];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains("--weight") && stderr.contains("at least 1"), "{stderr}");
    }
    let args = ["bench", "files", "i.yaml", "--methods", "ecbs:0.5", "--out", "b"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("ecbs:0.5") && stderr.contains("at least 1"), "{stderr}");
    assert!(!d.join("b").exists(), "no bench.json, no runs.jsonl");
    check(&phalanx(d, &["bench", "files", "i.yaml", "--methods", "ecbs:1", "--out", "b"]), 0);
    // A weight the planner does not read is refused, not ignored.
    let args = ["solve", "i.yaml", "--planner", "cbs", "--weight", "0.5"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--weight is a flag of") && stderr.contains("cbs"), "{stderr}");
}

#[test]
fn a_benchmark_counts_each_run_once() {
    let dir = fixtures();
    let d = dir.path();
    let args = ["bench", "files", "i.yaml", "--methods", "cbs,cbs", "--out", "b"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--methods names cbs twice"), "{stderr}");
    assert!(!d.join("b").exists());
    let args = ["bench", "files", "i.yaml", "--methods", "cbs,ecbs", "--out", "b"];
    check(&phalanx(d, &args), 0);
    let runs = d.join("b/runs.jsonl");
    let text = std::fs::read_to_string(&runs).unwrap();
    let first = text.lines().next().unwrap().to_owned();
    let resume = [&args[..], &["--resume"]].concat();

    std::fs::write(&runs, format!("{text}{first}\n")).unwrap();
    let (_, stderr) = check(&phalanx(d, &resume), 2);
    assert!(stderr.contains("runs.jsonl:3: the run of case i.yaml, instance 0"), "{stderr}");

    let other = first.replace("\"case\":\"i.yaml\"", "\"case\":\"elsewhere\"");
    assert_ne!(other, first, "{first}");
    std::fs::write(&runs, format!("{other}\n")).unwrap();
    let (_, stderr) = check(&phalanx(d, &resume), 2);
    assert!(stderr.contains("runs.jsonl:1: a run of case elsewhere"), "{stderr}");

    std::fs::write(&runs, format!("{first}\n")).unwrap();
    let (table, _) = check(&phalanx(d, &resume), 0);
    assert!(table.contains("cbs") && table.contains("ecbs"), "{table}");
}

#[test]
fn a_policy_file_of_another_kind_is_refused_naming_file_and_kinds() {
    let dir = fixtures();
    let d = dir.path();
    let meta = model("meta");
    let args = ["solve", "i.yaml", "--planner", "pathfinding", "--weights", &meta];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(
        stderr.contains("meta/policy.bin holds a meta policy")
            && stderr.contains("not the pathfinding policy"),
        "{stderr}"
    );
    for policy in ["pathfinding", "formation"] {
        let args = ["eval", "--policy", policy, "--weights", &meta, "--maps", "1"];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains(&format!("not the {policy} policy")), "{stderr}");
    }
    let pathfinding = model("pathfinding");
    let args = ["eval", "--policy", "e2e", "--weights", &pathfinding, "--maps", "1"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(
        stderr.contains("holds the pathfinding policy") && stderr.contains("model.json"),
        "{stderr}"
    );
    let (_, stderr) = check(&phalanx(d, &["run", "i.yaml", "--weights", &meta]), 2);
    assert!(stderr.contains("meta/policy.bin holds a meta policy"), "{stderr}");
}

#[test]
fn pictures_refuse_runaway_frame_rates_and_plans_off_the_map() {
    let dir = fixtures();
    let d = dir.path();
    for fps in ["1e8", "1e7", "1e300", "0.01"] {
        let args = ["render", "i.yaml", "p.yaml", "-o", "r.svg", "--fps", fps];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains("--fps") && stderr.contains("[0.1, 100]"), "{stderr}");
    }
    assert!(!d.join("r.svg").exists());
    check(&phalanx(d, &["render", "i.yaml", "p.yaml", "-o", "r.svg", "--fps", "100"]), 0);

    std::fs::write(d.join("off.yaml"), PLAN.replace("{x: 0, y: 1, t: 1}", "{x: -5, y: 1, t: 1}"))
        .unwrap();
    let (_, stderr) = check(&phalanx(d, &["render", "i.yaml", "off.yaml", "-o", "off.svg"]), 2);
    assert!(stderr.contains("off.yaml") && stderr.contains("(-5, 1) is outside"), "{stderr}");
    assert!(!d.join("off.svg").exists());
    let teleport = PLAN.replace("{x: 2, y: 1, t: 1}", "{x: 2, y: 2, t: 1}");
    std::fs::write(d.join("jump.yaml"), teleport).unwrap();
    let (_, stderr) = check(&phalanx(d, &["render", "i.yaml", "jump.yaml", "-o", "j.svg"]), 0);
    assert!(stderr.contains("warning: jump.yaml is not a valid plan"), "{stderr}");

    // A whole large map in every frame: refused before minutes of drawing.
    let mut big = String::from("map:\n  dimensions: [2048, 2048]\n  obstacles: []\nagents:\n");
    big.push_str("- name: a\n  start: [0, 0]\n  goal: [40, 0]\n");
    std::fs::write(d.join("big.yaml"), big).unwrap();
    let mut plan = String::from("schedule:\n  a:\n");
    for t in 0..=40 {
        writeln!(plan, "    - {{x: {t}, y: 0, t: {t}}}").unwrap();
    }
    std::fs::write(d.join("long.yaml"), plan).unwrap();
    let started = Instant::now();
    let args = ["render", "big.yaml", "long.yaml", "-o", "big.svg", "--crop", "full"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--max-frames") && stderr.contains("41 frames"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(20));
}

#[test]
fn motion_settings_out_of_scale_are_refused() {
    let dir = fixtures();
    let d = dir.path();
    let car = ["motion", "i.yaml", "p.yaml", "--max-steer", "30"];
    let bad: [&[&str]; 6] = [
        &["--wheelbase", "0.2", "--cell", "1", "--sub-step", "1e-12"],
        &["--wheelbase", "0.2", "--cell", "1", "--dt", "1e9"],
        &["--wheelbase", "0.2", "--cell", "1", "--dt", "1e300"],
        &["--wheelbase", "1e-20", "--cell", "1"],
        &["--wheelbase", "0.2", "--cell", "1e50"],
        &["--wheelbase", "0.2", "--cell", "1", "--rate", "1e9"],
    ];
    for flags in bad {
        let (_, stderr) = check(&phalanx(d, &[&car[..], flags].concat()), 2);
        assert!(stderr.contains("invalid value"), "{flags:?}: {stderr}");
    }
    // Within every flag's range, but too much work together: refused at once.
    let slow = ["--wheelbase", "0.2", "--cell", "1", "--dt", "9000", "--sub-step", "1e-5"];
    let started = Instant::now();
    let (_, stderr) = check(&phalanx(d, &[&car[..], &slow[..]].concat()), 2);
    assert!(stderr.contains("integration sub-steps"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(20));
    // The smallest car in the largest cell: two cells apart, they do not touch.
    let tiny = ["--wheelbase", "0.002", "--cell", "10000", "--json"];
    let (json, _) = check(&phalanx(d, &[&car[..], &tiny[..]].concat()), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(v["closest"]["distance"].as_f64().unwrap() > 1000.0, "{json}");
}

#[test]
fn training_curves_refuse_values_beyond_an_axis_and_a_png_name() {
    let dir = fixtures();
    let d = dir.path();
    let line = |step: u32, value: &str| {
        format!("{{\"name\": \"charts/episodic_return\", \"step\": {step}, \"value\": {value}}}\n")
    };
    std::fs::write(d.join("m.jsonl"), line(1, "1e308") + &line(2, "1e308")).unwrap();
    let started = Instant::now();
    let (_, stderr) = check(&phalanx(d, &["curves", "m.jsonl", "-o", "c.svg"]), 2);
    assert!(stderr.contains("c.svg") && stderr.contains("beyond"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(20));
    std::fs::write(d.join("m.jsonl"), line(1, "1") + &line(2, "2")).unwrap();
    let (_, stderr) = check(&phalanx(d, &["curves", "m.jsonl", "-o", "c.png"]), 2);
    assert!(stderr.contains("c.png") && stderr.contains(".svg"), "{stderr}");
    assert!(!d.join("c.png").exists());
    check(&phalanx(d, &["curves", "m.jsonl", "-o", "c.svg"]), 0);
}

/// A YAML instance of `n` agents on an empty `side`² map, starts and goals in reading order
/// from opposite corners.
fn many_agents(side: u32, n: u32) -> String {
    let mut text = format!("map:\n  dimensions: [{side}, {side}]\n  obstacles: []\nagents:\n");
    for i in 0..n {
        let (x, y) = (i % side, i / side);
        let (gx, gy) = (side - 1 - x, side - 1 - y);
        writeln!(text, "- name: a{i}\n  start: [{x}, {y}]\n  goal: [{gx}, {gy}]").unwrap();
    }
    text
}

#[test]
fn large_instances_are_described_or_refused_at_once() {
    let dir = fixtures();
    let d = dir.path();
    std::fs::write(d.join("many.yaml"), many_agents(128, 10_000)).unwrap();
    let started = Instant::now();
    let (info, _) = check(&phalanx(d, &["info", "many.yaml"]), 0);
    assert!(info.contains("… and 9900 more agents"), "{}", &info[info.len() - 300..]);
    std::fs::write(d.join("over.yaml"), many_agents(300, 70_000)).unwrap();
    let (_, stderr) = check(&phalanx(d, &["info", "over.yaml"]), 2);
    assert!(stderr.contains("over.yaml:4: too many agents: 70000"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(30), "{:?}", started.elapsed());

    let huge = "map:\n  dimensions: [65536, 65535]\n  obstacles: []\nagents:\n- name: a\n  \
                start: [0, 0]\n  goal: [1, 1]\n";
    std::fs::write(d.join("huge.yaml"), huge).unwrap();
    let (_, stderr) = check(&phalanx(d, &["--memory-limit", "256M", "info", "huge.yaml"]), 2);
    assert!(stderr.contains("huge.yaml:2: map size 65536x65535 is larger"), "{stderr}");
}

#[test]
fn an_instance_may_begin_with_a_byte_order_mark() {
    let dir = fixtures();
    let d = dir.path();
    std::fs::write(d.join("bom.yaml"), format!("\u{feff}{INSTANCE}")).unwrap();
    let (info, _) = check(&phalanx(d, &["info", "bom.yaml"]), 0);
    assert!(info.contains("agents     2"), "{info}");
}

#[test]
fn flags_that_would_print_nonsense_are_refused() {
    let dir = fixtures();
    let d = dir.path();
    let (_, stderr) = check(&phalanx(d, &["sim", "--episodes", "0"]), 2);
    assert!(stderr.contains("--episodes 0"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["--memory-limit", "1K", "info", "i.yaml"]), 2);
    assert!(stderr.contains("--memory-limit \"1K\": below the least"), "{stderr}");
    let args = ["solve", "i.yaml", "--planner", "pathfinding", "--rollouts", "1000000000"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("--rollouts"), "{stderr}");
    // A rollout rule's budget below the lower bound would keep nothing; a band below 0 has
    // no meaning: both refused with the value, for every command that takes them.
    for (flag, value, why) in [
        ("--keep", "within:0.5", "at least 1"),
        ("--keep", "within:NaN", "at least 1"),
        ("--keep", "slowest", "one of fastest, tightest, within:BUDGET"),
        ("--second-band", "-1", "0 or more"),
        ("--second-band", "inf", "not a finite number"),
        ("--rollout-temperature", "0", "not a positive number"),
        ("--rollout-temperature", "-inf", "not a positive number"),
    ] {
        let flag_value = format!("{flag}={value}");
        let args = ["solve", "i.yaml", "--planner", "imitation", &flag_value];
        let (_, stderr) = check(&phalanx(d, &args), 2);
        assert!(stderr.contains(flag) && stderr.contains(value), "{stderr}");
        assert!(stderr.contains(why), "{stderr}");
    }
    let args = ["bench", "files", "i.yaml", "--methods", "imitation:second=-1", "--out", "b"];
    let (_, stderr) = check(&phalanx(d, &args), 2);
    assert!(stderr.contains("imitation:second=-1"), "{stderr}");
    assert!(!d.join("b").exists(), "no bench.json, no runs.jsonl");
}

#[test]
fn a_scenario_naming_a_file_that_is_no_map_is_refused_without_showing_it() {
    let dir = fixtures();
    let d = dir.path();
    std::fs::write(d.join("secret.map"), "root:x:0:0:root:/root:/bin/bash\n").unwrap();
    for (map, expected) in
        [("secret.map", "unknown header line (not shown"), ("/dev/zero", "not a regular file")]
    {
        let scen = format!("version 1\n0\t{map}\t4\t3\t0\t0\t0\t2\t2\n");
        std::fs::write(d.join("x.scen"), scen).unwrap();
        let (_, stderr) = check(&phalanx(d, &["info", "x.scen"]), 2);
        assert!(stderr.contains(expected) && !stderr.contains("root:"), "{stderr}");
    }
}

#[test]
fn outputs_are_not_written_among_devices() {
    let dir = fixtures();
    let d = dir.path();
    let (_, stderr) = check(&phalanx(d, &["render", "i.yaml", "p.yaml", "-o", "/dev/full.svg"]), 3);
    assert!(stderr.contains("devices or kernel files"), "{stderr}");
    assert!(!Path::new("/dev/full.svg").exists());
}
