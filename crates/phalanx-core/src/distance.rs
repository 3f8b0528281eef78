//! Shortest-path distances on the static grid: BFS distance maps (4-connected, unit cost) and
//! the octile distance that MovingAI scenario files record.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::{Cell, CellId, Grid};

/// BFS distances from one source cell over the 4-connected grid, one `u32` per cell.
///
/// **Invariant:** blocked cells and free cells that cannot reach the source hold
/// [`DistanceMap::UNREACHABLE`], which differs from every distance (the authors' environment
/// gave such cells 0, the goal's own value; this one does not).
#[derive(Clone, PartialEq, Eq)]
pub struct DistanceMap {
    width: u32,
    height: u32,
    source: Cell,
    dist: Vec<u32>,
}

impl DistanceMap {
    /// The value of a cell that cannot reach the source (blocked, cut off or outside).
    pub const UNREACHABLE: u32 = u32::MAX;

    /// BFS from `source` over the free cells of `grid`. A blocked or outside source gives a
    /// map in which every cell is unreachable.
    pub fn bfs(grid: &Grid, source: Cell) -> DistanceMap {
        let mut res = DistanceMap {
            width: grid.width(),
            height: grid.height(),
            source,
            dist: vec![Self::UNREACHABLE; grid.n_cells()],
        };
        let mut queue = Vec::with_capacity(grid.n_cells() - grid.n_blocked());
        res.fill(grid, &mut queue);
        res
    }

    /// Recomputes the map in place for a new source on a grid of the same size, reusing the
    /// allocation and the caller's queue (the environment calls this on every reset).
    ///
    /// # Panics
    /// If `grid` has another size than the map.
    pub fn recompute(&mut self, grid: &Grid, source: Cell, queue: &mut Vec<u32>) {
        assert_eq!((grid.width(), grid.height()), (self.width, self.height), "grid size changed");
        self.source = source;
        self.dist.fill(Self::UNREACHABLE);
        self.fill(grid, queue);
    }

    /// BFS over `self.dist`, which holds `UNREACHABLE` everywhere on entry. Blocked cells
    /// are first marked `BLOCKED` so that the inner loop tests one value per neighbour, then
    /// set back to `UNREACHABLE`. The queue holds packed coordinates `(y << 16) | x`, which
    /// spares a division per cell.
    fn fill(&mut self, grid: &Grid, queue: &mut Vec<u32>) {
        const BLOCKED: u32 = DistanceMap::UNREACHABLE - 1;
        queue.clear();
        if grid.is_blocked(self.source) {
            return;
        }
        for_each_blocked(grid, |id| self.dist[id] = BLOCKED);
        let (width, height) = (self.width as usize, self.height as usize);
        let dist = &mut self.dist[..width * height];
        let src = self.source;
        dist[src.y as usize * width + src.x as usize] = 0;
        queue.push((src.y as u32) << 16 | src.x as u32);
        let mut head = 0;
        while head < queue.len() {
            let packed = queue[head];
            head += 1;
            let (x, y) = ((packed & 0xffff) as usize, (packed >> 16) as usize);
            let id = y * width + x;
            let next = dist[id] + 1;
            let mut visit = |n: usize, packed: u32| {
                if dist[n] == DistanceMap::UNREACHABLE {
                    dist[n] = next;
                    queue.push(packed);
                }
            };
            if y + 1 < height {
                visit(id + width, packed + (1 << 16));
            }
            if y > 0 {
                visit(id - width, packed - (1 << 16));
            }
            if x > 0 {
                visit(id - 1, packed - 1);
            }
            if x + 1 < width {
                visit(id + 1, packed + 1);
            }
        }
        for_each_blocked(grid, |id| self.dist[id] = DistanceMap::UNREACHABLE);
    }

    /// The source cell (for a goal's map, the goal).
    #[inline]
    pub fn source(&self) -> Cell {
        self.source
    }

    /// Distance from `cell` to the source, `None` when unreachable, blocked or outside.
    #[inline]
    pub fn get(&self, cell: Cell) -> Option<u32> {
        let d = self.raw(cell);
        (d != Self::UNREACHABLE).then_some(d)
    }

    /// Distance from `cell` to the source, [`DistanceMap::UNREACHABLE`] when there is none.
    #[inline]
    pub fn raw(&self, cell: Cell) -> u32 {
        if (cell.x as u32) < self.width && (cell.y as u32) < self.height {
            self.dist[(cell.y as u32 * self.width + cell.x as u32) as usize]
        } else {
            Self::UNREACHABLE
        }
    }

    /// All distances indexed by `CellId`.
    #[inline]
    pub fn as_slice(&self) -> &[u32] {
        &self.dist
    }
}

impl std::fmt::Debug for DistanceMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DistanceMap {}x{} from {}", self.width, self.height, self.source)
    }
}

/// Calls `f` with the id of every blocked cell, skipping free 64-cell words at once.
fn for_each_blocked(grid: &Grid, mut f: impl FnMut(usize)) {
    let n_cells = grid.n_cells();
    let mut base = 0;
    while base < n_cells {
        let mut word = grid.blocked_word(base / 64);
        while word != 0 {
            let id = base + word.trailing_zeros() as usize;
            if id < n_cells {
                f(id);
            }
            word &= word - 1;
        }
        base += 64;
    }
}

/// Octile shortest-path length from `from` to `to`: 8-connected, straight steps cost 1,
/// diagonal steps √2, and a diagonal step may not cut a blocked corner (both cells beside it
/// must be free). This is the `optimal_length` column of MovingAI `.scen` files.
///
/// Returns `None` when `to` cannot be reached. The length is summed as
/// `straight + diagonal · √2` from integer counts (no accumulated rounding); it agrees with
/// the benchmark files to 1e-6, while their eighth decimal is sometimes off by one.
pub fn octile_distance(grid: &Grid, from: Cell, to: Cell) -> Option<f64> {
    if grid.is_blocked(from) || grid.is_blocked(to) {
        return None;
    }
    let cost =
        |straight: u32, diag: u32| f64::from(straight) + f64::from(diag) * std::f64::consts::SQRT_2;
    let heuristic = |c: Cell| {
        let (dx, dy) = (c.x.abs_diff(to.x), c.y.abs_diff(to.y));
        cost(dx.max(dy) - dx.min(dy), dx.min(dy))
    };
    // best[id] = (straight, diagonal) counts of the best known path.
    let mut best = vec![(u32::MAX, u32::MAX); grid.n_cells()];
    let mut open = BinaryHeap::new();
    best[grid.id(from).index()] = (0, 0);
    open.push(Reverse((OrdF64(heuristic(from)), 0u32, 0u32, grid.id(from).0)));
    while let Some(Reverse((_, straight, diag, id))) = open.pop() {
        let cell = grid.cell(CellId(id));
        if best[id as usize] != (straight, diag) {
            continue;
        }
        if cell == to {
            return Some(cost(straight, diag));
        }
        let g = cost(straight, diag);
        for dy in -1..=1 {
            for dx in -1..=1 {
                if dx == 0 && dy == 0 {
                    continue;
                }
                let n = cell.offset(dx, dy);
                if grid.is_blocked(n) {
                    continue;
                }
                let is_diag = dx != 0 && dy != 0;
                if is_diag
                    && (grid.is_blocked(cell.offset(dx, 0)) || grid.is_blocked(cell.offset(0, dy)))
                {
                    continue;
                }
                let next = if is_diag { (straight, diag + 1) } else { (straight + 1, diag) };
                let nid = grid.id(n);
                let old = best[nid.index()];
                if old.0 == u32::MAX || cost(next.0, next.1) < cost(old.0, old.1) {
                    best[nid.index()] = next;
                    let f = cost(next.0, next.1) + heuristic(n);
                    debug_assert!(f + 1e-9 >= g);
                    open.push(Reverse((OrdF64(f), next.0, next.1, nid.0)));
                }
            }
        }
    }
    None
}

/// A total order on finite `f64` for the priority queue.
#[derive(Clone, Copy, PartialEq)]
struct OrdF64(f64);

impl Eq for OrdF64 {}

impl PartialOrd for OrdF64 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrdF64 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bfs_distances_and_unreachable() {
        // . . # .
        // . # # .
        // . . . .   (y = 0 at the bottom)
        let grid = Grid::from_fn(4, 3, |c| matches!((c.x, c.y), (2, 2) | (1, 1) | (2, 1)));
        let dm = DistanceMap::bfs(&grid, Cell::new(0, 2));
        assert_eq!(dm.get(Cell::new(0, 2)), Some(0));
        assert_eq!(dm.get(Cell::new(1, 2)), Some(1));
        assert_eq!(dm.get(Cell::new(3, 2)), Some(7));
        assert_eq!(dm.get(Cell::new(2, 2)), None);
        assert_eq!(dm.get(Cell::new(9, 9)), None);
        let walled = Grid::from_fn(3, 1, |c| c.x == 1);
        let dm = DistanceMap::bfs(&walled, Cell::new(0, 0));
        assert_eq!(dm.raw(Cell::new(2, 0)), DistanceMap::UNREACHABLE);
        assert_ne!(dm.raw(Cell::new(2, 0)), dm.raw(Cell::new(0, 0)));
    }

    #[test]
    fn recompute_matches_fresh_bfs() {
        let grid = Grid::from_fn(9, 7, |c| (c.x * 7 + c.y * 3) % 5 == 0 && c.x != 4);
        let mut dm = DistanceMap::bfs(&grid, Cell::new(4, 0));
        let mut queue = Vec::new();
        for src in [Cell::new(4, 6), Cell::new(1, 1), Cell::new(0, 0)] {
            dm.recompute(&grid, src, &mut queue);
            assert_eq!(dm, DistanceMap::bfs(&grid, src));
        }
    }

    #[test]
    fn octile_no_corner_cutting() {
        let open = Grid::new(5, 5);
        let d = octile_distance(&open, Cell::new(0, 0), Cell::new(4, 2)).unwrap();
        assert!((d - (2.0 + 2.0 * std::f64::consts::SQRT_2)).abs() < 1e-12);
        // A blocked corner forbids the diagonal: (0,0) -> (1,1) with (1,0) blocked costs 2.
        let corner = Grid::from_fn(2, 2, |c| c == Cell::new(1, 0));
        assert_eq!(octile_distance(&corner, Cell::new(0, 0), Cell::new(1, 1)), Some(2.0));
        let walled = Grid::from_fn(3, 3, |c| c.x == 1);
        assert_eq!(octile_distance(&walled, Cell::new(0, 0), Cell::new(2, 2)), None);
    }
}
