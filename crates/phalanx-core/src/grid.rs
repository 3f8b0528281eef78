//! The static world: a `width × height` 4-connected grid with bit-packed obstacles.

use crate::{Cell, CellId};

/// A 4-connected grid of `width × height` cells; a cell is free or blocked, and every cell
/// outside the grid counts as blocked.
///
/// **Invariant:** `1 <= width, height <= 65_536` and `width * height < 2^32`, so a cell id
/// fits in `u32`. Obstacle look-up is one shift and one mask.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Grid {
    width: u32,
    height: u32,
    /// One bit per cell, set when the cell is blocked, indexed by `CellId`.
    blocked: Vec<u64>,
    n_blocked: u32,
}

impl Grid {
    /// Largest supported side.
    pub const MAX_SIDE: u32 = 65_536;

    /// An obstacle-free grid.
    ///
    /// # Panics
    /// If a side is 0 or larger than [`Grid::MAX_SIDE`], or the grid has `2^32` cells or more;
    /// readers check sizes before they build a grid.
    pub fn new(width: u32, height: u32) -> Grid {
        assert!(
            (1..=Grid::MAX_SIDE).contains(&width) && (1..=Grid::MAX_SIDE).contains(&height),
            "grid side out of range: {width}x{height}"
        );
        let n_cells = u64::from(width) * u64::from(height);
        assert!(n_cells < 1 << 32, "grid too large: {width}x{height}");
        Grid { width, height, blocked: vec![0; n_cells.div_ceil(64) as usize], n_blocked: 0 }
    }

    /// A grid whose blocked cells are those for which `is_blocked(cell)` holds.
    pub fn from_fn(width: u32, height: u32, mut is_blocked: impl FnMut(Cell) -> bool) -> Grid {
        let mut grid = Grid::new(width, height);
        for y in 0..height as i32 {
            for x in 0..width as i32 {
                let cell = Cell::new(x, y);
                if is_blocked(cell) {
                    grid.set_blocked(cell, true);
                }
            }
        }
        grid
    }

    /// Number of columns.
    #[inline]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Number of rows.
    #[inline]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The longer side, `max(width, height)`: the "map side" of the metrics (docs/spec.md §3).
    #[inline]
    pub fn side(&self) -> u32 {
        self.width.max(self.height)
    }

    /// Number of cells.
    #[inline]
    pub fn n_cells(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Number of blocked cells.
    #[inline]
    pub fn n_blocked(&self) -> usize {
        self.n_blocked as usize
    }

    /// Fraction of cells that are blocked.
    pub fn density(&self) -> f64 {
        self.n_blocked as f64 / self.n_cells() as f64
    }

    /// Whether `cell` lies inside the grid.
    #[inline]
    pub fn in_bounds(&self, cell: Cell) -> bool {
        (cell.x as u32) < self.width && (cell.y as u32) < self.height
    }

    /// The dense id of an in-bounds cell.
    #[inline]
    pub fn id(&self, cell: Cell) -> CellId {
        debug_assert!(self.in_bounds(cell), "{cell} outside {}x{}", self.width, self.height);
        CellId(cell.y as u32 * self.width + cell.x as u32)
    }

    /// The cell of a dense id.
    #[inline]
    pub fn cell(&self, id: CellId) -> Cell {
        Cell::new((id.0 % self.width) as i32, (id.0 / self.width) as i32)
    }

    /// Whether the cell with this id is blocked (the id must be in range).
    #[inline]
    pub fn is_blocked_id(&self, id: CellId) -> bool {
        let i = id.index();
        self.blocked[i >> 6] >> (i & 63) & 1 != 0
    }

    /// The 64 obstacle bits of cells `64 * word .. 64 * word + 64` (bit `i` is cell id
    /// `64 * word + i`; bits past the last cell are 0).
    #[inline]
    pub fn blocked_word(&self, word: usize) -> u64 {
        self.blocked[word]
    }

    /// Whether `cell` is blocked; every cell outside the grid is.
    #[inline]
    pub fn is_blocked(&self, cell: Cell) -> bool {
        !self.in_bounds(cell) || self.is_blocked_id(self.id(cell))
    }

    /// Whether `cell` is inside the grid and not blocked.
    #[inline]
    pub fn is_free(&self, cell: Cell) -> bool {
        !self.is_blocked(cell)
    }

    /// Blocks or frees an in-bounds cell.
    ///
    /// # Panics
    /// If `cell` is outside the grid.
    pub fn set_blocked(&mut self, cell: Cell, blocked: bool) {
        assert!(self.in_bounds(cell), "{cell} outside {}x{}", self.width, self.height);
        let i = self.id(cell).index();
        let (word, bit) = (i >> 6, 1u64 << (i & 63));
        let was = self.blocked[word] & bit != 0;
        if was != blocked {
            self.blocked[word] ^= bit;
            if blocked {
                self.n_blocked += 1;
            } else {
                self.n_blocked -= 1;
            }
        }
    }

    /// The free 4-neighbours of `cell`, in action order (up, down, left, right).
    #[inline]
    pub fn free_neighbours(&self, cell: Cell) -> impl Iterator<Item = Cell> + '_ {
        [(0, 1), (0, -1), (-1, 0), (1, 0)]
            .into_iter()
            .map(move |(dx, dy)| cell.offset(dx, dy))
            .filter(|&n| self.is_free(n))
    }

    /// Every free cell, in id order.
    pub fn free_cells(&self) -> impl Iterator<Item = Cell> + '_ {
        (0..self.n_cells() as u32)
            .map(CellId)
            .filter(|&id| !self.is_blocked_id(id))
            .map(|id| self.cell(id))
    }
}

impl std::fmt::Debug for Grid {
    /// Rows from `y = height - 1` down to `y = 0`, `#` blocked, `.` free (so `Up` points up).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "Grid {}x{}", self.width, self.height)?;
        for y in (0..self.height as i32).rev() {
            for x in 0..self.width as i32 {
                f.write_str(if self.is_blocked(Cell::new(x, y)) { "#" } else { "." })?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocked_bits_and_bounds() {
        let mut g = Grid::new(70, 3);
        assert_eq!(g.n_blocked(), 0);
        g.set_blocked(Cell::new(65, 2), true);
        g.set_blocked(Cell::new(65, 2), true);
        assert_eq!(g.n_blocked(), 1);
        assert!(g.is_blocked(Cell::new(65, 2)));
        assert!(!g.is_blocked(Cell::new(64, 2)));
        assert!(g.is_blocked(Cell::new(-1, 0)));
        assert!(g.is_blocked(Cell::new(0, 3)));
        assert!(g.is_blocked(Cell::new(70, 0)));
        assert_eq!(g.cell(g.id(Cell::new(65, 2))), Cell::new(65, 2));
        g.set_blocked(Cell::new(65, 2), false);
        assert_eq!(g.n_blocked(), 0);
        assert_eq!(g.free_cells().count(), 210);
    }
}
