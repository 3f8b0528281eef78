//! The obstacle list and the plan schedule read line by line give what serde_yaml gives, or
//! are left to it.

use super::*;

/// The document as serde_yaml alone reads it.
fn full(text: &str) -> Option<(Vec<[i64; 2]>, usize)> {
    from_yaml::<InstanceDto>(text)
        .ok()
        .map(|d| (d.map.obstacles.unwrap_or_default(), d.agents.len()))
}

/// The document as [`instance_dto`] reads it.
fn fast(text: &str) -> Option<(Vec<[i64; 2]>, usize)> {
    instance_dto(text).ok().map(|d| (d.map.obstacles.unwrap_or_default(), d.agents.len()))
}

const AGENTS: &str = "agents:\n- name: a\n  start: [0, 0]\n  goal: [3, 3]\n";

#[test]
fn the_written_layout_is_read_line_by_line() {
    let text =
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - [1, 2]\n  - [2, 1]\n{AGENTS}");
    let (pairs, rest) = split_obstacles(&text).expect("the written layout");
    assert_eq!(pairs, vec![[1, 2], [2, 1]]);
    assert_eq!(rest.lines().count(), text.lines().count(), "line numbers hold");
    assert_eq!(fast(&text), full(&text));
    assert_eq!(fast(&text).unwrap().0.len(), 2);
}

#[test]
fn other_layouts_read_the_same() {
    let texts = [
        // CRLF line ends.
        "map:\r\n  dimensions: [4, 4]\r\n  obstacles:\r\n  - [1, 2]\r\n  - [2, 1]\r\nagents:\r\n- name: a\r\n  start: [0, 0]\r\n  goal: [3, 3]\r\n".to_owned(),
        // A blank line inside the list, then more pairs.
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - [1, 2]\n\n  - [2, 1]\n{AGENTS}"),
        // A comment after a pair, and a comment line.
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - [1, 2] # wall\n  # more\n  - [2, 1]\n{AGENTS}"),
        // A pair over two lines, and block pairs.
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - [1,\n     2]\n  - - 2\n    - 1\n{AGENTS}"),
        // Deeper indentation, and the map after the agents.
        format!("{AGENTS}map:\n    dimensions: [4, 4]\n    obstacles:\n      - [1, 2]\n      - [2, 1]\n"),
        // Tags and anchors.
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - &a [1, 2]\n  - *a\n{AGENTS}"),
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - !!python/tuple [1, 2]\n{AGENTS}"),
        // `obstacles:` twice, and as an agent's key.
        format!("map:\n  dimensions: [4, 4]\n  obstacles:\n  - [1, 2]\n  obstacles:\n  - [2, 1]\n{AGENTS}"),
        format!("map:\n  dimensions: [4, 4]\n{AGENTS}  obstacles:\n  - [1, 2]\n"),
        // No obstacles, and an empty list.
        format!("map:\n  dimensions: [4, 4]\n{AGENTS}"),
        format!("map:\n  dimensions: [4, 4]\n  obstacles: []\n{AGENTS}"),
    ];
    for text in &texts {
        assert_eq!(fast(text), full(text), "{text}");
    }
}

/// The plan as serde_yaml alone reads it (the schedule's layout made unusual by a comment
/// line at its end, which only the fallback accepts).
fn plan_full(text: &str) -> Result<YamlPlan, ParseError> {
    assert!(split_schedule(&format!("{text}# end\n")).is_none());
    YamlPlan::parse(&format!("{text}# end\n"))
}

#[test]
fn a_written_plan_is_read_line_by_line_as_serde_yaml_reads_it() {
    let plan = Plan::from_paths(&[
        vec![Cell::new(0, 0), Cell::new(1, 0), Cell::new(1, 1)],
        vec![Cell::new(3, 3), Cell::new(-2, 3)],
    ]);
    let names = vec!["agent0".to_owned(), "b_1".to_owned()];
    let text = YamlPlan::from_plan(&plan, &names, PlanStats::of(&plan, 0.5)).to_string();
    let (schedule, _) = split_schedule(&text).expect("the written layout");
    assert_eq!(schedule.len(), 2);
    let fast = YamlPlan::parse(&text).unwrap();
    assert_eq!(fast, plan_full(&text).unwrap());
    assert_eq!(fast.to_plan(&names).unwrap(), plan);
    assert_eq!(fast.schedule[1].line, text.lines().position(|l| l == "  b_1:").unwrap() + 1);
    // CRLF line ends, and no statistics.
    let crlf = text.replace('\n', "\r\n");
    assert_eq!(YamlPlan::parse(&crlf).unwrap(), fast);
    let bare = &text[text.find("schedule:").unwrap()..];
    let paths = |plan: &YamlPlan| plan.to_plan(&names).unwrap();
    assert_eq!(paths(&YamlPlan::parse(bare).unwrap()), plan);
    assert_eq!(paths(&fast), plan);
}

#[test]
fn other_plan_layouts_and_broken_plans_go_to_serde_yaml() {
    let texts = [
        // Flow steps, a quoted name, a numeric name, a key after the schedule.
        "schedule:\n  a:\n    - {x: 0, y: 0, t: 0}\n".to_owned(),
        "schedule:\n  \"a b\":\n    - x: 0\n      y: 0\n      t: 0\n".to_owned(),
        "schedule:\n  7:\n    - x: 0\n      y: 0\n      t: 0\n".to_owned(),
        "schedule:\n  a:\n    - x: 0\n      y: 0\n      t: 0\nstatistics:\n  cost: 0\n".to_owned(),
        // Times out of order, a name twice, an empty path, a step cut short.
        "schedule:\n  a:\n    - x: 0\n      y: 0\n      t: 1\n".to_owned(),
        "schedule:\n  a:\n    - x: 0\n      y: 0\n      t: 0\n  a:\n    - x: 1\n      y: 0\n      t: 0\n".to_owned(),
        "schedule:\n  a:\n".to_owned(),
        "schedule:\n  a:\n    - x: 0\n      y: 0\n".to_owned(),
    ];
    for text in &texts {
        assert!(split_schedule(text).is_none(), "{text}");
        // Whatever serde_yaml says (a plan or an error) is the answer.
        let _ = YamlPlan::parse(text);
    }
    let err = YamlPlan::parse(&texts[4]).unwrap_err();
    assert!(err.to_string().contains("t"), "{err}");
}
