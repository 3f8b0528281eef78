//! The five actions of the specification (docs/spec.md §1): `Up` is `y + 1`.

use std::fmt;

use crate::Cell;

/// One agent's move in one step. The discriminant is the action's index in Q-value vectors
/// and one-hot encodings (the order of the authors' environment).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Action {
    /// `y + 1`.
    Up = 0,
    /// `y - 1`.
    Down = 1,
    /// `x - 1`.
    Left = 2,
    /// `x + 1`.
    Right = 3,
    /// Stay in place.
    Wait = 4,
}

impl Action {
    /// Number of actions.
    pub const COUNT: usize = 5;

    /// All actions in index order.
    pub const ALL: [Action; 5] =
        [Action::Up, Action::Down, Action::Left, Action::Right, Action::Wait];

    /// The four moves (every action but `Wait`), in index order.
    pub const MOVES: [Action; 4] = [Action::Up, Action::Down, Action::Left, Action::Right];

    /// The action with index `idx`, if `idx < 5`.
    #[inline]
    pub const fn from_index(idx: usize) -> Option<Action> {
        match idx {
            0 => Some(Action::Up),
            1 => Some(Action::Down),
            2 => Some(Action::Left),
            3 => Some(Action::Right),
            4 => Some(Action::Wait),
            _ => None,
        }
    }

    /// The action's index, `0..5`.
    #[inline]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The displacement `(dx, dy)`.
    #[inline]
    pub const fn delta(self) -> (i32, i32) {
        match self {
            Action::Up => (0, 1),
            Action::Down => (0, -1),
            Action::Left => (-1, 0),
            Action::Right => (1, 0),
            Action::Wait => (0, 0),
        }
    }

    /// The cell reached from `from` (it may be outside the grid or blocked).
    #[inline]
    pub const fn apply(self, from: Cell) -> Cell {
        let (dx, dy) = self.delta();
        from.offset(dx, dy)
    }

    /// The action that moves `from` to `to`, if they are equal or adjacent.
    #[inline]
    pub const fn between(from: Cell, to: Cell) -> Option<Action> {
        match (to.x - from.x, to.y - from.y) {
            (0, 1) => Some(Action::Up),
            (0, -1) => Some(Action::Down),
            (-1, 0) => Some(Action::Left),
            (1, 0) => Some(Action::Right),
            (0, 0) => Some(Action::Wait),
            _ => None,
        }
    }

    /// The opposite move (`Wait` for `Wait`).
    #[inline]
    pub const fn reverse(self) -> Action {
        match self {
            Action::Up => Action::Down,
            Action::Down => Action::Up,
            Action::Left => Action::Right,
            Action::Right => Action::Left,
            Action::Wait => Action::Wait,
        }
    }

    /// Lower-case name, as used on the command line and in files.
    pub const fn name(self) -> &'static str {
        match self {
            Action::Up => "up",
            Action::Down => "down",
            Action::Left => "left",
            Action::Right => "right",
            Action::Wait => "wait",
        }
    }
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_round_trip_and_between() {
        for a in Action::ALL {
            assert_eq!(Action::from_index(a.index()), Some(a));
            let c = Cell::new(3, 3);
            assert_eq!(Action::between(c, a.apply(c)), Some(a));
            assert_eq!(a.reverse().apply(a.apply(c)), c);
        }
        assert_eq!(Action::from_index(5), None);
        assert_eq!(Action::Up.apply(Cell::new(0, 0)), Cell::new(0, 1));
    }
}
