//! Unit tests of CBS internals.

use super::*;

#[test]
fn vertex_cover_sizes() {
    let edges = |pairs: &[(u16, u16)]| -> Vec<(AgentId, AgentId)> {
        pairs.iter().map(|&(a, b)| (AgentId(a), AgentId(b))).collect()
    };
    assert_eq!(min_vertex_cover(&[]), 0);
    assert_eq!(min_vertex_cover(&edges(&[(0, 1)])), 1);
    assert_eq!(min_vertex_cover(&edges(&[(0, 1), (1, 2), (0, 2)])), 2);
    assert_eq!(min_vertex_cover(&edges(&[(0, 1), (0, 2), (0, 3)])), 1);
}

#[test]
fn rectangle_barriers_cover_the_conflict() {
    // 6x6 open grid; ids are y * 6 + x.
    let grid = phalanx_core::Grid::new(6, 6);
    let id = |x: u32, y: u32| phalanx_core::CellId(y * 6 + x);
    // Agent 0 enters from the left along y = 2, agent 1 from the bottom along x = 2; both
    // reach (2, 2) at t = 2, then continue monotonically up and right.
    let p0 = vec![id(0, 2), id(1, 2), id(2, 2), id(3, 2), id(3, 3), id(4, 3), id(4, 4)];
    let p1 = vec![id(2, 0), id(2, 1), id(2, 2), id(2, 3), id(3, 3), id(3, 4)];
    let [b0, b1] = rectangle::barriers(&grid, [&p0, &p1], id(2, 2), 2).expect("a rectangle");
    // The far corner is pushed to (3, 4): agent 0's barrier is column 3, rows 2..=4, at its
    // Manhattan times; agent 1's is row 4, columns 2..=3.
    assert_eq!(b0, vec![(id(3, 2), 3), (id(3, 3), 4), (id(3, 4), 5)]);
    assert_eq!(b1, vec![(id(2, 4), 4), (id(3, 4), 5)]);
    // Each barrier excludes the agent's current path.
    assert!(b0.iter().any(|&(c, t)| search::at(&p0, t) == c));
    assert!(b1.iter().any(|&(c, t)| search::at(&p1, t) == c));
    // A wait before the conflict breaks the Manhattan condition.
    let waiting = vec![id(0, 2), id(0, 2), id(1, 2), id(2, 2)];
    assert!(rectangle::barriers(&grid, [&waiting, &p1], id(2, 2), 3).is_none());
}
