//! libMultiRobotPlanning YAML instances and plans.

use phalanx_core::{Cell, Grid, Instance, Plan};
use phalanx_io::{PlanStats, YamlInstance, YamlPlan};

fn c(x: i32, y: i32) -> Cell {
    Cell::new(x, y)
}

/// libMRP's own example layout: agents first, block style, a tuple tag on obstacles.
const LIBMRP: &str = "\
agents:
-   goal: [2, 0]
    name: agent0
    start: [0, 0]
-   goal: [0, 0]
    name: agent1
    start: [2, 0]
map:
    dimensions: [3, 3]
    obstacles:
    - !!python/tuple [0, 1]
    - !!python/tuple [2, 1]
";

#[test]
fn libmrp_instance_with_python_tuples() {
    let yaml = YamlInstance::parse(LIBMRP).unwrap();
    assert_eq!((yaml.width, yaml.height), (3, 3));
    assert_eq!(yaml.obstacles, vec![c(0, 1), c(2, 1)]);
    assert_eq!(yaml.names(), vec!["agent0", "agent1"]);
    assert_eq!(yaml.agents[1].line, 6);
    let inst = yaml.to_instance().unwrap();
    assert_eq!(inst.starts(), &[c(0, 0), c(2, 0)]);
    assert_eq!(inst.grid().n_blocked(), 2);
}

#[test]
fn our_instance_output_round_trips() {
    let grid = Grid::from_fn(5, 4, |p| p.x == 2 && p.y < 3);
    let inst = Instance::new(grid, vec![c(0, 0), c(1, 0)], vec![c(4, 0), c(3, 0)]).unwrap();
    let yaml = YamlInstance::from_instance(&inst);
    let text = yaml.to_string();
    assert_eq!(
        text,
        "map:\n  dimensions: [5, 4]\n  obstacles:\n  - [2, 0]\n  - [2, 1]\n  - [2, 2]\nagents:\n\
         - name: agent0\n  start: [0, 0]\n  goal: [4, 0]\n\
         - name: agent1\n  start: [1, 0]\n  goal: [3, 0]\n"
    );
    let back = YamlInstance::parse(&text).unwrap();
    assert_eq!(back.to_string(), text);
    assert_eq!(back.to_instance().unwrap(), inst);
    // Odd names are quoted and survive.
    let mut odd = yaml.clone();
    odd.agents[0].name = "true".into();
    odd.agents[1].name = "a: b".into();
    let back = YamlInstance::parse(&odd.to_string()).unwrap();
    assert_eq!(back.names(), vec!["true", "a: b"]);
}

#[test]
fn plan_round_trip_trims_and_pads() {
    let plan =
        Plan::from_paths(&[vec![c(0, 0), c(1, 0), c(1, 0)], vec![c(5, 5), c(5, 4), c(5, 3)]]);
    let names = vec!["a".to_owned(), "b".to_owned()];
    let stats = PlanStats::of(&plan, 0.25);
    assert_eq!((stats.cost, stats.makespan), (3, 2));
    let text = YamlPlan::from_plan(&plan, &names, stats.clone()).to_string();
    assert!(text.starts_with(
        "statistics:\n  cost: 3\n  makespan: 2\n  runtime: 0.25\n  highLevelExpanded: 0\n  \
         lowLevelExpanded: 0\nschedule:\n  a:\n    - x: 0\n      y: 0\n      t: 0\n    - x: 1\n"
    ));
    let back = YamlPlan::parse(&text).unwrap();
    assert_eq!(back.statistics, Some(stats));
    assert_eq!(back.schedule[0].path, vec![c(0, 0), c(1, 0)]);
    assert_eq!(back.to_string(), text);
    assert_eq!(back.to_plan(&names).unwrap(), plan);
    // Keys map by name, not by order.
    let swapped = back.to_plan(&["b".to_owned(), "a".to_owned()]).unwrap();
    assert_eq!(swapped.at(2), &[c(5, 3), c(1, 0)]);
}

#[test]
fn plan_without_statistics() {
    let text = "schedule:\n  agent0:\n    - {x: 1, y: 2, t: 0}\n";
    let plan = YamlPlan::parse(text).unwrap();
    assert_eq!(plan.statistics, None);
    assert_eq!(plan.to_plan(&["agent0".to_owned()]).unwrap().at(0), &[c(1, 2)]);
}

#[test]
fn schedule_keys_that_look_like_statistics() {
    let text = "statistics:\n  cost: 1\nschedule:\n  cost:\n    - {x: 0, y: 0, t: 0}\n  bad: []\n";
    let err = YamlPlan::parse(text).unwrap_err();
    assert_eq!(err.to_string(), "line 6: agent 'bad' has an empty path");
    let ok = "statistics:\n  cost: 1\nschedule:\n  cost:\n    - {x: 0, y: 0, t: 0}\n";
    assert_eq!(YamlPlan::parse(ok).unwrap().schedule[0].line, 4);
}
