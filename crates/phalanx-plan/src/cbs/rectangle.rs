//! Start-based rectangle reasoning (Li, Harabor, Stuckey, Ma, Koenig, "Symmetry-breaking
//! constraints for grid-based multi-agent path finding", AAAI 2019): barrier constraints
//! that resolve a whole rectangle of symmetric vertex conflicts in one split.
//!
//! Coordinates are normalised so that both agents move in `+X` and `+Y`. Agent `L` enters
//! the rectangle `[Rs, Rg]` through its left side, agent `B` through its bottom. An agent at a
//! cell at exactly its Manhattan distance from its start got there monotonically; so if `L` is
//! on column `Rg.X` (rows `Rs.Y..=Rg.Y`) and `B` on row `Rg.Y` (columns `Rs.X..=Rg.X`), each
//! at its Manhattan time, their paths cross the rectangle orthogonally, share a cell, and,
//! since both start at the same Manhattan "phase", are there at the same time: a conflict.
//! So every conflict-free solution avoids one of the two barriers, which makes the split
//! sound and keeps CBS optimal.

use phalanx_core::{CellId, Grid};

use crate::search::at;

/// The barriers `[of agent 0, of agent 1]` as `(cell, t)` vertex constraints, or `None` when
/// the conflict at `(v, t)` is not a start-based rectangle conflict.
pub(super) fn barriers(
    grid: &Grid,
    paths: [&[CellId]; 2],
    v: CellId,
    t: u32,
) -> Option<[Vec<(CellId, u32)>; 2]> {
    let width = grid.width() as i32;
    let xy = |id: CellId| ((id.0 as i32) % width, (id.0 as i32) / width);
    let (vx, vy) = xy(v);
    let starts = [xy(paths[0][0]), xy(paths[1][0])];
    // Both must reach v at t along Manhattan-monotone paths from their starts.
    for (i, path) in paths.iter().enumerate() {
        let (sx, sy) = starts[i];
        if (vx - sx).abs() + (vy - sy).abs() != t as i32 {
            return None;
        }
        for tau in 1..=t {
            let (x, y) = xy(at(path, tau));
            if (x - sx).abs() + (y - sy).abs() != tau as i32 {
                return None;
            }
        }
    }
    let direction = |a: i32, b: i32| -> Option<i32> {
        match (a.signum(), b.signum()) {
            (p, q) if p * q < 0 => None,
            (0, 0) => Some(1),
            (0, q) => Some(q),
            (p, _) => Some(p),
        }
    };
    let dx = direction(vx - starts[0].0, vx - starts[1].0)?;
    let dy = direction(vy - starts[0].1, vy - starts[1].1)?;
    let norm = |(x, y): (i32, i32)| (x * dx, y * dy);
    let s = [norm(starts[0]), norm(starts[1])];
    let (l, b) = match s[0].1.cmp(&s[1].1) {
        std::cmp::Ordering::Greater => (0, 1),
        std::cmp::Ordering::Less => (1, 0),
        std::cmp::Ordering::Equal => return None,
    };
    if s[l].0 >= s[b].0 {
        return None;
    }
    let rs = (s[b].0, s[l].1);
    let v_n = norm((vx, vy));
    // Monotone prefixes (each step +X or +Y) and their ends.
    let prefix = |path: &[CellId]| -> Vec<(i32, i32)> {
        let mut res = vec![norm(xy(path[0]))];
        for &cell in &path[1..] {
            let p = norm(xy(cell));
            let q = *res.last().expect("non-empty");
            if (p.0 - q.0, p.1 - q.1) == (1, 0) || (p.0 - q.0, p.1 - q.1) == (0, 1) {
                res.push(p);
            } else {
                break;
            }
        }
        res
    };
    let (pl, pb) = (prefix(paths[l]), prefix(paths[b]));
    let (el, eb) = (*pl.last().expect("non-empty"), *pb.last().expect("non-empty"));
    let candidate = (el.0.min(eb.0), el.1.min(eb.1));
    let crosses = |rg: (i32, i32)| {
        let l_ok = pl.iter().find(|p| p.0 == rg.0).is_some_and(|p| p.1 <= rg.1 && p.1 >= rs.1);
        let b_ok = pb.iter().find(|p| p.1 == rg.1).is_some_and(|p| p.0 <= rg.0 && p.0 >= rs.0);
        l_ok && b_ok
    };
    let rg = if candidate.0 >= v_n.0 && candidate.1 >= v_n.1 && crosses(candidate) {
        candidate
    } else {
        v_n
    };
    debug_assert!(crosses(v_n), "the conflict cell is on both barriers");
    let cell_of = |(x, y): (i32, i32)| -> Option<CellId> {
        let (x, y) = (x * dx, y * dy);
        (x >= 0 && y >= 0 && x < width && y < grid.height() as i32)
            .then(|| CellId((y * width + x) as u32))
            .filter(|&id| !grid.is_blocked_id(id))
    };
    let mut res = [Vec::new(), Vec::new()];
    for y in rs.1..=rg.1 {
        let time = (rg.0 - s[l].0) + (y - s[l].1);
        if let Some(cell) = cell_of((rg.0, y)) {
            res[l].push((cell, time as u32));
        }
    }
    for x in rs.0..=rg.0 {
        let time = (x - s[b].0) + (rg.1 - s[b].1);
        if let Some(cell) = cell_of((x, rg.1)) {
            res[b].push((cell, time as u32));
        }
    }
    Some(res)
}
