//! Unit tests of CBS internals.

use super::*;

#[test]
fn vertex_cover_sizes() {
    assert_eq!(min_vertex_cover(&[]), 0);
    assert_eq!(min_vertex_cover(&[(0, 1)]), 1);
    assert_eq!(min_vertex_cover(&[(0, 1), (1, 2), (0, 2)]), 2);
    assert_eq!(min_vertex_cover(&[(0, 1), (0, 2), (0, 3)]), 1);
}
