//! The formation loss `L_f` (docs/spec.md §3): the distance between a joint position and the desired
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
    let Some(fit) = Fit::of(positions, goals) else {
        return 0.0;
    };
    let mut d2 = 0.0;
    for (p, g) in positions.iter().zip(goals) {
        let (x, y) = (f64::from(p.x) - fit.cp.0, f64::from(p.y) - fit.cp.1);
        let (rx, ry) = fit.rotate(g);
        d2 += (x - rx) * (x - rx) + (y - ry) * (y - ry);
    }
    if d2 < 1e-9 { 0.0 } else { d2 }
}

/// The target formation aligned to the team: where [`formation_loss`]'s best rotation and
/// translation put each goal, `R(θ)·g̃ᵢ + x̄` (the positions' centroid `x̄`), in the grid's
/// coordinates; [`formation_loss`] is the root of the summed squared distances from the
/// positions to these points. Fewer than two agents stand on their own fit.
///
/// # Panics
/// If the slices differ in length.
///
/// ```
/// use phalanx_core::{Cell, formation_fit};
/// // Two agents side by side fit a vertical pair of goals exactly.
/// let fit = formation_fit(&[Cell::new(0, 0), Cell::new(1, 0)], &[Cell::new(5, 5), Cell::new(5, 6)]);
/// assert!((fit[0].0 - 0.0).abs() < 1e-12 && (fit[1].0 - 1.0).abs() < 1e-12);
/// ```
pub fn formation_fit(positions: &[Cell], goals: &[Cell]) -> Vec<(f64, f64)> {
    let Some(fit) = Fit::of(positions, goals) else {
        return positions.iter().map(|p| (f64::from(p.x), f64::from(p.y))).collect();
    };
    goals
        .iter()
        .map(|g| {
            let (rx, ry) = fit.rotate(g);
            (rx + fit.cp.0, ry + fit.cp.1)
        })
        .collect()
}

/// The best rotation of the centred goals onto the centred positions.
struct Fit {
    /// Centroid of the positions.
    cp: (f64, f64),
    /// Centroid of the goals.
    cg: (f64, f64),
    sin: f64,
    cos: f64,
}

impl Fit {
    /// `None` for fewer than two agents.
    fn of(positions: &[Cell], goals: &[Cell]) -> Option<Fit> {
        assert_eq!(positions.len(), goals.len(), "formation loss of sets of different sizes");
        let n = positions.len();
        if n < 2 {
            return None;
        }
        let inv_n = 1.0 / n as f64;
        let (mut px, mut py, mut gx, mut gy) = (0i64, 0i64, 0i64, 0i64);
        for (p, g) in positions.iter().zip(goals) {
            px += i64::from(p.x);
            py += i64::from(p.y);
            gx += i64::from(g.x);
            gy += i64::from(g.y);
        }
        let cp = (px as f64 * inv_n, py as f64 * inv_n);
        let cg = (gx as f64 * inv_n, gy as f64 * inv_n);
        let (mut num, mut den) = (0.0, 0.0);
        for (p, g) in positions.iter().zip(goals) {
            let (x, y) = (f64::from(p.x) - cp.0, f64::from(p.y) - cp.1);
            let (u, v) = (f64::from(g.x) - cg.0, f64::from(g.y) - cg.1);
            num += u * y - v * x;
            den += u * x + v * y;
        }
        // `(sin θ, cos θ)` of `θ = atan2(num, den)` without the trigonometry: the unit vector
        // along `(den, num)`. With both sums 0 every angle fits equally; `θ = 0` is taken.
        let r = num.hypot(den);
        let (sin, cos) = if r > 0.0 { (num / r, den / r) } else { (0.0, 1.0) };
        Some(Fit { cp, cg, sin, cos })
    }

    /// The centred goal `g` rotated by `θ`.
    fn rotate(&self, g: &Cell) -> (f64, f64) {
        let (u, v) = (f64::from(g.x) - self.cg.0, f64::from(g.y) - self.cg.1);
        (self.cos * u - self.sin * v, self.sin * u + self.cos * v)
    }
}

#[cfg(test)]
mod tests;
