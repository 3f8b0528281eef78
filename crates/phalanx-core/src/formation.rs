//! The formation loss `L_f` (SPEC §3): the distance between a joint position and the desired
//! formation (the goals' layout) after the best rotation and translation, without scaling
//! or reflection (2-D Procrustes, matched by agent index).

use crate::Cell;

/// Root formation loss: `sqrt(Σ‖x̃ᵢ − R(θ)·g̃ᵢ‖²)` over the centred positions `x̃` and goals
/// `g̃`, with the optimal angle `θ = atan2(Σ(g̃x·x̃y − g̃y·x̃x), Σ(g̃x·x̃x + g̃y·x̃y))`.
///
/// This is the value the authors' environment computes and the per-step loss of every
/// metric here. Sums below `1e-9` count as exactly 0. Invariant to translating or rotating
/// either set, symmetric, and 0 exactly for congruent layouts.
///
/// # Panics
/// If the slices differ in length.
///
/// ```
/// use phalanx_core::{Cell, formation_loss};
/// let goals = [Cell::new(2, 1), Cell::new(2, 0)];
/// let positions = [Cell::new(1, 2), Cell::new(0, 1)];
/// assert!((formation_loss(&positions, &goals) - 0.2928932188134525).abs() < 1e-12);
/// ```
#[inline]
pub fn formation_loss(positions: &[Cell], goals: &[Cell]) -> f64 {
    formation_loss_squared(positions, goals).sqrt()
}

/// Squared formation loss, the paper's Eq. 1 (`‖X₂ − X₁Γ − 1γᵀ‖²` with centred sets): the
/// square of [`formation_loss`].
///
/// # Panics
/// If the slices differ in length.
pub fn formation_loss_squared(positions: &[Cell], goals: &[Cell]) -> f64 {
    assert_eq!(positions.len(), goals.len(), "formation loss of sets of different sizes");
    let n = positions.len();
    if n < 2 {
        return 0.0;
    }
    let inv_n = 1.0 / n as f64;
    let (mut px, mut py, mut gx, mut gy) = (0i64, 0i64, 0i64, 0i64);
    for (p, g) in positions.iter().zip(goals) {
        px += i64::from(p.x);
        py += i64::from(p.y);
        gx += i64::from(g.x);
        gy += i64::from(g.y);
    }
    let (cpx, cpy) = (px as f64 * inv_n, py as f64 * inv_n);
    let (cgx, cgy) = (gx as f64 * inv_n, gy as f64 * inv_n);
    let (mut num, mut den) = (0.0, 0.0);
    for (p, g) in positions.iter().zip(goals) {
        let (x, y) = (f64::from(p.x) - cpx, f64::from(p.y) - cpy);
        let (u, v) = (f64::from(g.x) - cgx, f64::from(g.y) - cgy);
        num += u * y - v * x;
        den += u * x + v * y;
    }
    let theta = num.atan2(den);
    let (sin, cos) = theta.sin_cos();
    let mut d2 = 0.0;
    for (p, g) in positions.iter().zip(goals) {
        let (x, y) = (f64::from(p.x) - cpx, f64::from(p.y) - cpy);
        let (u, v) = (f64::from(g.x) - cgx, f64::from(g.y) - cgy);
        let (rx, ry) = (cos * u - sin * v, sin * u + cos * v);
        d2 += (x - rx) * (x - rx) + (y - ry) * (y - ry);
    }
    if d2 < 1e-9 { 0.0 } else { d2 }
}

#[cfg(test)]
mod tests;
