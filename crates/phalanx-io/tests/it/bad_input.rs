//! Every kind of bad input gives a typed error with file, line and value (docs/errors.md
//! lists the same cases with the CLI's exit code).

use std::path::Path;

use phalanx_core::{Cell, Grid, Plan};
use phalanx_io::{
    Error, MovingAiMap, ParseError, Scenario, YamlInstance, YamlPlan, instance_from_scen,
    read_instance, read_plan_for, write_text,
};

/// The message of a parse error as the file helpers print it for `name`.
fn shown(name: &str, res: Result<impl std::fmt::Debug, ParseError>) -> String {
    Error::parse(name, res.expect_err("input should be rejected")).to_string()
}

#[track_caller]
fn check_map(text: &str, expected: &str) {
    assert_eq!(shown("x.map", MovingAiMap::parse(text)), expected);
}

#[track_caller]
fn check_scen(text: &str, grid: Grid, expected: &str) {
    let res = Scenario::parse(text).and_then(|scen| instance_from_scen(grid, &scen, 2));
    assert_eq!(shown("x.scen", res), expected);
}

#[track_caller]
fn check_yaml(text: &str, expected: &str) {
    let res = YamlInstance::parse(text).and_then(|y| y.to_instance());
    assert_eq!(shown("x.yaml", res), expected);
}

const HEAD: &str = "type octile\nheight 2\nwidth 3\nmap\n";

#[test]
fn bad_maps() {
    check_map("", "x.map:1: empty file");
    check_map(" \n\r\n", "x.map:1: empty file");
    check_map(&format!("{HEAD}...\n"), "x.map:6: map has 1 rows, expected 2");
    check_map(&format!("{HEAD}...\n..\n"), "x.map:6: row has 2 characters, expected 3");
    check_map(&format!("{HEAD}...\n.é.\n"), "x.map:6: unknown terrain character 'é' at column 1");
    check_map(&format!("{HEAD}...\n..#\n"), "x.map:6: unknown terrain character '#' at column 2");
    check_map(
        &format!("{HEAD}...\n...\n...\n"),
        "x.map:7: unexpected text after the last map row: \"...\"",
    );
    check_map(
        "type octile\nheight two\nwidth 3\nmap\n",
        "x.map:2: field 'height' is not a number: \"two\"",
    );
    check_map("type octile\nwidth 3\nmap\n...\n", "x.map:3: missing 'height' line in the header");
    check_map("type octile\nheight 1\nwidth 3\n", "x.map:3: missing 'map' line in the header");
    check_map(
        "height 0\nwidth 3\nmap\n",
        "x.map:3: map size 3x0 is out of range (1 to 65536 per side, fewer than 2^32 cells)",
    );
    check_map("hight 1\nwidth 3\nmap\n", "x.map:1: unknown header line \"hight 1\"");
}

#[test]
fn bad_scenarios() {
    let grid = || Grid::from_fn(4, 2, |c| c.x == 3 && c.y == 1);
    let line = |fields: &str| fields.replace(' ', "\t");
    let ok = line("0 m.map 4 2 0 0 1 0 1.00000000");
    check_scen("", grid(), "x.scen:1: empty file");
    check_scen("0\tm.map\n", grid(), "x.scen:1: expected 'version 1', found \"0\\tm.map\"");
    check_scen("version 2\n", grid(), "x.scen:1: expected 'version 1', found \"version 2\"");
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 abc 0 1 0 1.0")),
        grid(),
        "x.scen:3: field 'start_x' is not a number: \"abc\"",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 0 0 1 0 nan")),
        grid(),
        "x.scen:3: field 'optimal_length' is not a number: \"nan\"",
    );
    check_scen(
        &format!("version 1\n{ok}\n0 m.map 4 2\n"),
        grid(),
        "x.scen:3: expected 9 fields, found 4",
    );
    check_scen(
        &format!("version 1\n{ok}\n\n{ok}\n"),
        grid(),
        "x.scen:3: blank line between scenario entries",
    );
    check_scen(
        &format!("version 1\n{ok}\n"),
        grid(),
        "x.scen:1: 2 agents requested but the file has 1",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 32 32 1 1 2 1 1.0")),
        grid(),
        "x.scen:3: scenario entry is for a 32x32 map, the map is 4x2",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 n.map 4 2 1 1 2 1 1.0")),
        grid(),
        "x.scen:3: scenario entry names map \"n.map\", the first entry names \"m.map\"",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 4 1 2 1 1.0")),
        grid(),
        "x.scen:3: agent 1's start (4, 1) is outside the 4x2 map",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 1 1 3 1 1.0")),
        grid(),
        "x.scen:3: agent 1's goal (3, 1) is on an obstacle",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 0 0 2 0 2.0")),
        grid(),
        "x.scen:3: agents 0 and 1 have the same start (0, 0)",
    );
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 1 1 1 0 1.0")),
        grid(),
        "x.scen:3: agents 0 and 1 have the same goal (1, 0)",
    );
    let walled = || Grid::from_fn(4, 2, |c| c.x == 2);
    check_scen(
        &format!("version 1\n{ok}\n{}\n", line("0 m.map 4 2 1 1 3 1 2.0")),
        walled(),
        "x.scen:3: agent 1's goal (3, 1) cannot be reached from its start (1, 1)",
    );
}

const AGENTS: &str =
    "agents:\n- name: a\n  start: [0, 0]\n  goal: [1, 0]\n- name: b\n  start: [0, 1]\n";

#[test]
fn bad_yaml_instances() {
    check_yaml("", "x.yaml:1: empty file");
    check_yaml("map: [\n", "x.yaml:2: did not find expected node content");
    check_yaml("agents: []\n", "x.yaml:1: missing field `map`");
    check_yaml("map:\n  obstacles: []\nagents: []\n", "x.yaml:2: map: missing field `dimensions`");
    check_yaml(
        &format!("map:\n  dimensions: [3, 3]\n{AGENTS}"),
        "x.yaml:7: agents[1]: missing field `goal`",
    );
    check_yaml(
        &format!("map:\n  dimensions: [3, 3]\n{AGENTS}  goal: [9, 9]\n"),
        "x.yaml:7: agent 1's goal (9, 9) is outside the 3x3 map",
    );
    check_yaml(
        &format!("map:\n  dimensions: [3, 3]\n  obstacles: [[1, 0]]\n{AGENTS}  goal: [2, 2]\n"),
        "x.yaml:5: agent 0's goal (1, 0) is on an obstacle",
    );
    check_yaml(
        &format!("map:\n  dimensions: [3, 3]\n{AGENTS}  goal: [1, 0]\n"),
        "x.yaml:7: agents 0 and 1 have the same goal (1, 0)",
    );
    check_yaml(
        &format!(
            "map:\n  dimensions: [3, 3]\n{}",
            AGENTS.replace("name: b", "name: a") + "  goal: [2, 2]\n"
        ),
        "x.yaml:7: two agents are named \"a\"",
    );
    check_yaml(
        "map:\n  dimensions: [3, 3]\n  obstacles:\n  - [3, 0]\nagents: []\n",
        "x.yaml:3: obstacle (3, 0) is outside the 3x3 map",
    );
    check_yaml(
        "map:\n  dimensions: [0, 3]\nagents: []\n",
        "x.yaml:2: map size 0x3 is out of range (1 to 65536 per side, fewer than 2^32 cells)",
    );
    check_yaml(
        "map:\n  dimensions: [-4, 5]\nagents: []\n",
        "x.yaml:2: map size -4x5 is out of range (1 to 65536 per side, fewer than 2^32 cells)",
    );
    check_yaml(
        "map:\n  dimensions: [x, 3]\nagents: []\n",
        "x.yaml:2: map.dimensions[0]: invalid type: string \"x\", expected i64",
    );
    check_yaml("map:\n  dimensions: [3, 3]\nagents: []\n", "x.yaml:1: the instance has no agents");
}

#[test]
fn bad_plans() {
    let names = |n: usize| (0..n).map(phalanx_io::agent_name).collect::<Vec<_>>();
    let two =
        "schedule:\n  agent0:\n    - {x: 0, y: 0, t: 0}\n  agent1:\n    - {x: 1, y: 0, t: 0}\n";
    let plan = |text: &str, n| YamlPlan::parse(text).and_then(|p| p.to_plan(&names(n)));
    assert_eq!(
        shown("p.yaml", plan(two, 1)),
        "p.yaml:4: the plan has 2 agents, the instance has 1"
    );
    assert_eq!(
        shown("p.yaml", plan(two, 3)),
        "p.yaml:1: the plan has 2 agents, the instance has 3"
    );
    let other = two.replace("agent1", "bob");
    assert_eq!(
        shown("p.yaml", plan(&other, 2)),
        "p.yaml:4: the schedule has a path for 'bob', which is no agent of the instance"
    );
    assert_eq!(shown("p.yaml", plan("statistics: {}\n", 1)), "p.yaml:1: missing field `schedule`");
    assert_eq!(
        shown("p.yaml", plan("schedule:\n  agent0: []\n", 1)),
        "p.yaml:2: agent 'agent0' has an empty path"
    );
    assert_eq!(
        shown("p.yaml", plan("schedule:\n  agent0:\n    - {x: 0, y: 0, t: 1}\n", 1)),
        "p.yaml:2: agent 'agent0' has t = 1 at position 0 of its path, expected 0"
    );
    assert_eq!(
        shown("p.yaml", plan("schedule:\n  agent0:\n    - {x: 0, t: 0}\n", 1)),
        "p.yaml:2: path of agent 'agent0': missing field `y`"
    );
}

#[test]
fn file_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("none.yaml");
    let err = read_instance(&missing, None).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err}");
    assert!(err.to_string().starts_with(&format!("{}: ", missing.display())), "{err}");
    let txt = dir.path().join("x.txt");
    write_text(&txt, "").unwrap();
    assert_eq!(
        read_instance(&txt, None).unwrap_err().to_string(),
        format!("{}: unsupported file extension, expected .yaml, .yml or .scen", txt.display())
    );
    // A scen whose map is missing, then a map with a bad row: the error names the map file.
    let scen = dir.path().join("s.scen");
    write_text(&scen, "version 1\n0\tsub/m.map\t3\t1\t0\t0\t2\t0\t2.0\n").unwrap();
    let err = read_instance(&scen, None).unwrap_err().to_string();
    assert!(err.contains(":2: map file \"sub/m.map\" not found (tried "), "{err}");
    let map = dir.path().join("m.map");
    write_text(&map, "type octile\nheight 1\nwidth 3\nmap\n..\n").unwrap();
    assert_eq!(
        read_instance(&scen, None).unwrap_err().to_string(),
        format!("{}:5: row has 2 characters, expected 3", map.display())
    );
    write_text(&map, "type octile\nheight 1\nwidth 3\nmap\n...\n").unwrap();
    assert_eq!(read_instance(&scen, None).unwrap().instance.n_agents(), 1);
    // A plan for another number of agents.
    let plan_path = dir.path().join("p.yaml");
    let two = Plan::from_paths(&[vec![Cell::new(0, 0)], vec![Cell::new(1, 0)]]);
    phalanx_io::write_plan(&plan_path, &two, &Default::default()).unwrap();
    let err = read_plan_for(&plan_path, &["agent0".to_owned()]).unwrap_err().to_string();
    assert!(err.ends_with("the plan has 2 agents, the instance has 1"), "{err}");
    assert!(Path::new(&plan_path).is_file());
}
