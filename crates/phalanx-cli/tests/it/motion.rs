//! `phalanx motion`: a generated instance solved by CBS and driven by car-like robots, its
//! table, JSON, CSV and JSON trajectories; bad settings exit 2, a plan a car cannot drive
//! exits 1 naming the agent and the step; `--render` draws the cars.

use super::{check, phalanx};

#[test]
fn motion_drives_a_solved_plan_and_writes_the_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "20", "--density", "0.15", "--agents", "3", "--seed", "2"];
    check(&phalanx(d, &[&args[..], &["-o", "inst.yaml"]].concat()), 0);
    check(&phalanx(d, &["solve", "inst.yaml", "--planner", "cbs", "-o", "plan.yaml"]), 0);
    let car = ["--wheelbase", "0.25", "--max-steer", "30", "--cell", "1"];
    let motion = |extra: &[&str]| {
        phalanx(d, &[&["motion", "inst.yaml", "plan.yaml"], &car[..], extra].concat())
    };

    let (table, _) = check(&motion(&["-o", "traj.csv"]), 0);
    assert!(table.contains("turning_radius  0.4330 m (fillets 0.5000 m)"), "{table}");
    assert!(table.contains("step_duration   1 s"), "{table}");
    assert!(table.contains("closest_bodies") && table.contains("wrote traj.csv"), "{table}");
    assert!(table.lines().any(|l| l.starts_with("agent2 ")), "{table}");
    let text = std::fs::read_to_string(d.join("traj.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,agent,name,x,y,heading,speed,steer"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r.len() == 8), "{text:.300}");
    assert_eq!(rows.len() % 3, 0);
    assert_eq!(
        &rows[..3].iter().map(|r| r[2]).collect::<Vec<_>>(),
        &["agent0", "agent1", "agent2"]
    );
    assert_eq!(rows[3][0], "0.100", "10 samples a second");
    // The same input gives the same bytes.
    check(&motion(&["-o", "again.csv"]), 0);
    assert_eq!(std::fs::read(d.join("again.csv")).unwrap(), text.as_bytes());

    let (json, _) = check(&motion(&["-o", "traj.json", "--json", "--max-speed", "2"]), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!((v["drivable"].as_bool(), v["contact"].as_bool()), (Some(true), Some(false)));
    assert_eq!(v["step_duration"], 0.5, "a straight cell at 2 m/s");
    let cars = v["cars"].as_array().unwrap();
    assert_eq!(cars.len(), 3);
    for car in cars {
        assert!(car["cross_track_max"].as_f64().unwrap() < 0.05, "{car}");
        assert!(car["speed_max"].as_f64().unwrap() <= 2.0, "{car}");
        assert!(car["name"].as_str().unwrap().starts_with("agent"), "{car}");
    }
    assert!(v["closest"]["distance"].as_f64().unwrap() > 0.0, "{json}");
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("traj.json")).unwrap()).unwrap();
    assert_eq!(file["report"]["cars"], v["cars"]);
    let samples = file["samples"].as_array().unwrap();
    assert_eq!(samples.len() % 3, 0);
    for key in ["t", "agent", "x", "y", "heading", "speed", "steer"] {
        assert!(samples[0].get(key).is_some(), "{key} in {}", samples[0]);
    }
}

#[test]
fn motion_renders_the_cars_driving() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "12", "--density", "0.1", "--agents", "2", "--seed", "3"];
    check(&phalanx(d, &[&args[..], &["-o", "inst.yaml"]].concat()), 0);
    check(&phalanx(d, &["solve", "inst.yaml", "--planner", "cbs", "-o", "plan.yaml"]), 0);
    let car = ["--wheelbase", "0.25", "--max-steer", "30", "--cell", "1", "--rate", "4"];
    let motion = |extra: &[&str]| {
        phalanx(d, &[&["motion", "inst.yaml", "plan.yaml"], &car[..], extra].concat())
    };
    for name in ["cars.svg", "cars.gif"] {
        let (out, _) = check(&motion(&["--render", name]), 0);
        assert!(out.contains(&format!("wrote {name}")), "{out}");
        let bytes = std::fs::read(d.join(name)).unwrap();
        assert!(!bytes.is_empty(), "{name} is empty");
    }
    let svg = std::fs::read_to_string(d.join("cars.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("type=\"translate\""), "{svg:.300}");
    assert_eq!(svg.matches("<g transform=\"scale(0.01)\"><rect").count(), 2, "a body per car");
    assert_eq!(&std::fs::read(d.join("cars.gif")).unwrap()[..6], b"GIF89a");
    let (_, err) = check(&motion(&["--render", "cars.txt"]), 2);
    assert!(err.contains("cars.txt"), "{err}");
    assert!(!d.join("cars.txt").exists(), "nothing written");
}

const INSTANCE: &str = "\
map:
  dimensions: [4, 3]
  obstacles: []
agents:
- name: a
  start: [0, 0]
  goal: [1, 0]
- name: b
  start: [0, 2]
  goal: [2, 1]
";

/// `a` goes two cells right and comes back one (a U-turn at step 3); `b` turns right at
/// (2, 2) at step 2.
const PLAN: &str = "\
schedule:
  a:
    - {x: 0, y: 0, t: 0}
    - {x: 1, y: 0, t: 1}
    - {x: 2, y: 0, t: 2}
    - {x: 1, y: 0, t: 3}
  b:
    - {x: 0, y: 2, t: 0}
    - {x: 1, y: 2, t: 1}
    - {x: 2, y: 2, t: 2}
    - {x: 2, y: 1, t: 3}
";

#[test]
fn motion_refuses_bad_settings_and_undrivable_plans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("i.yaml"), INSTANCE).unwrap();
    std::fs::write(d.join("p.yaml"), PLAN).unwrap();
    let motion = |extra: &[&str]| phalanx(d, &[&["motion", "i.yaml", "p.yaml"], extra].concat());

    let (_, err) = check(&motion(&["--wheelbase", "0.25", "--max-steer", "30", "--cell", "1"]), 1);
    assert_eq!(
        err,
        "p.yaml cannot be driven: agent 0 (a), step 3: the agent turns back to (1, 0), the cell it came from (a U-turn in place, which a car cannot drive)\n"
    );
    let (json, _) =
        check(&motion(&["--wheelbase", "0.25", "--max-steer", "20", "--cell", "1", "--json"]), 1);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        (v["drivable"].as_bool(), v["name"].as_str(), v["step"].as_u64()),
        (Some(false), Some("b"), Some(2))
    );
    assert!(v["error"].as_str().unwrap().contains("minimum turning radius 0.687 m"), "{json}");

    for (flags, needle) in [
        (&["--wheelbase", "0.25", "--max-steer", "95", "--cell", "1"][..], "--max-steer"),
        (&["--wheelbase", "0", "--max-steer", "30", "--cell", "1"], "--wheelbase"),
        (&["--wheelbase", "0.25", "--max-steer", "30", "--cell", "1", "--dt=-1"], "--dt"),
        (&["--wheelbase", "0.25", "--max-steer", "30"], "--cell"),
        (&["--wheelbase", "0.25", "--max-steer", "30", "--cell", "1", "-o", "t.txt"], "t.txt"),
        (
            &["--wheelbase", "0.25", "--max-steer", "45", "--cell", "0.5"],
            "does not fit a 0.5 m cell",
        ),
    ] {
        let (_, err) = check(&motion(flags), 2);
        assert!(err.contains(needle), "{needle}: {err}");
    }
    let (_, err) = check(
        &phalanx(
            d,
            &[
                "motion",
                "i.yaml",
                "none.yaml",
                "--wheelbase",
                "0.25",
                "--max-steer",
                "30",
                "--cell",
                "1",
            ],
        ),
        2,
    );
    assert!(err.contains("none.yaml"), "{err}");
    assert!(!d.join("t.txt").exists(), "nothing written");
}
