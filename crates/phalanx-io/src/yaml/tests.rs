//! The obstacle list read line by line gives what serde_yaml gives, or is left to it.

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
