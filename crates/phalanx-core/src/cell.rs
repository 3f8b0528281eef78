//! Cell coordinates, dense cell ids and agent ids.

use std::fmt;

/// A grid coordinate. `x` is the column, `y` the row; `Up` moves to `y + 1`.
///
/// Signed, so that a neighbour of a border cell can be formed and then found to be outside.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Cell {
    /// Column, `0 <= x < width` inside the grid.
    pub x: i32,
    /// Row, `0 <= y < height` inside the grid.
    pub y: i32,
}

impl Cell {
    /// The cell at column `x`, row `y`.
    #[inline]
    pub const fn new(x: i32, y: i32) -> Cell {
        Cell { x, y }
    }

    /// The cell shifted by `(dx, dy)`.
    #[inline]
    pub const fn offset(self, dx: i32, dy: i32) -> Cell {
        Cell { x: self.x + dx, y: self.y + dy }
    }

    /// Manhattan distance between two cells.
    #[inline]
    pub const fn manhattan(self, other: Cell) -> u32 {
        self.x.abs_diff(other.x) + self.y.abs_diff(other.y)
    }

    /// Whether the two cells share a side.
    #[inline]
    pub const fn is_adjacent(self, other: Cell) -> bool {
        self.manhattan(other) == 1
    }
}

impl fmt::Display for Cell {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {})", self.x, self.y)
    }
}

/// A dense cell index, `y * width + x`. Only meaningful together with its grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CellId(pub u32);

impl CellId {
    /// The index as `usize`, for slices indexed by cell.
    #[inline]
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

/// An agent's index in its instance: agent `i` starts at `starts[i]` and is tied to `goals[i]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct AgentId(pub u16);

impl AgentId {
    /// The index as `usize`.
    #[inline]
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for AgentId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "agent {}", self.0)
    }
}
