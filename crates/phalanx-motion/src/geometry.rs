//! Plane geometry in metres: vectors, angles, the car's rectangle and cells as convex
//! quadrilaterals, and the distance between two of them (0 when they touch or overlap).

use std::f64::consts::{PI, TAU};
use std::ops::{Add, Mul, Sub};

/// A point or a vector of the plane, in metres.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Vec2 {
    pub(crate) x: f64,
    pub(crate) y: f64,
}

impl Vec2 {
    pub(crate) const fn new(x: f64, y: f64) -> Vec2 {
        Vec2 { x, y }
    }

    /// The unit vector at angle `angle` (radians, counter-clockwise from `+x`).
    pub(crate) fn from_angle(angle: f64) -> Vec2 {
        Vec2::new(angle.cos(), angle.sin())
    }

    pub(crate) fn dot(self, other: Vec2) -> f64 {
        self.x * other.x + self.y * other.y
    }

    /// The z component of the cross product: positive when `other` is to the left.
    pub(crate) fn cross(self, other: Vec2) -> f64 {
        self.x * other.y - self.y * other.x
    }

    pub(crate) fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }

    /// The angle of the vector (radians, `atan2`).
    pub(crate) fn angle(self) -> f64 {
        self.y.atan2(self.x)
    }

    /// The vector turned a quarter turn counter-clockwise.
    pub(crate) fn left(self) -> Vec2 {
        Vec2::new(-self.y, self.x)
    }
}

impl Add for Vec2 {
    type Output = Vec2;
    fn add(self, other: Vec2) -> Vec2 {
        Vec2::new(self.x + other.x, self.y + other.y)
    }
}

impl Sub for Vec2 {
    type Output = Vec2;
    fn sub(self, other: Vec2) -> Vec2 {
        Vec2::new(self.x - other.x, self.y - other.y)
    }
}

impl Mul<f64> for Vec2 {
    type Output = Vec2;
    fn mul(self, k: f64) -> Vec2 {
        Vec2::new(self.x * k, self.y * k)
    }
}

/// `angle` brought into `(-π, π]`.
pub(crate) fn wrap_angle(angle: f64) -> f64 {
    let res = angle.rem_euclid(TAU);
    if res > PI { res - TAU } else { res }
}

/// A convex quadrilateral, corners in order round it (a car body or a cell).
pub(crate) type Quad = [Vec2; 4];

/// The rectangle centred on `centre`, its length along `heading` (radians).
pub(crate) fn rectangle(centre: Vec2, heading: f64, half_length: f64, half_width: f64) -> Quad {
    let along = Vec2::from_angle(heading);
    let across = along.left();
    let (a, b) = (along * half_length, across * half_width);
    [centre + a + b, centre - a + b, centre - a - b, centre + a - b]
}

/// The axis-aligned square with lower corner `min` and side `side`.
pub(crate) fn square(min: Vec2, side: f64) -> Quad {
    [
        min,
        Vec2::new(min.x + side, min.y),
        Vec2::new(min.x + side, min.y + side),
        Vec2::new(min.x, min.y + side),
    ]
}

/// The distance between two convex quadrilaterals; 0 when they touch or overlap.
pub(crate) fn distance(a: &Quad, b: &Quad) -> f64 {
    if !separated(a, b) {
        return 0.0;
    }
    let mut res = f64::INFINITY;
    for (p, q) in [(a, b), (b, a)] {
        for &corner in p {
            for i in 0..4 {
                res = res.min(point_segment(corner, q[i], q[(i + 1) % 4]));
            }
        }
    }
    res
}

/// Whether an edge normal of `a` or `b` separates them (separating axis theorem).
fn separated(a: &Quad, b: &Quad) -> bool {
    [a, b].into_iter().any(|quad| {
        (0..4).any(|i| {
            let axis = (quad[(i + 1) % 4] - quad[i]).left();
            let (a_min, a_max) = extent(a, axis);
            let (b_min, b_max) = extent(b, axis);
            a_max < b_min || b_max < a_min
        })
    })
}

/// The smallest and largest projection of `quad`'s corners on `axis`.
fn extent(quad: &Quad, axis: Vec2) -> (f64, f64) {
    quad.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let v = p.dot(axis);
        (lo.min(v), hi.max(v))
    })
}

/// The distance from `p` to the segment `a`–`b`.
pub(crate) fn point_segment(p: Vec2, a: Vec2, b: Vec2) -> f64 {
    let ab = b - a;
    let len2 = ab.dot(ab);
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangles_side_by_side_are_their_gap_apart() {
        let a = rectangle(Vec2::new(0.0, 0.0), 0.0, 0.5, 0.1);
        let b = rectangle(Vec2::new(0.3, 1.0), 0.0, 0.5, 0.1);
        assert!((distance(&a, &b) - 0.8).abs() < 1e-12);
        let c = rectangle(Vec2::new(2.0, 0.0), PI / 2.0, 0.5, 0.1);
        assert!((distance(&a, &c) - 1.4).abs() < 1e-12);
        let d = rectangle(Vec2::new(0.4, 0.1), 0.3, 0.5, 0.1);
        assert_eq!(distance(&a, &d), 0.0);
        // A corner nearest an edge.
        let e = rectangle(Vec2::new(0.0, 1.0), PI / 4.0, 0.5, 0.5);
        let expected = 1.0 - 0.5 * 2f64.sqrt() - 0.1;
        assert!((distance(&a, &e) - expected).abs() < 1e-12);
        let cell = square(Vec2::new(1.0, -0.5), 1.0);
        assert!((distance(&a, &cell) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn angles_wrap_into_a_half_open_turn() {
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert_eq!(wrap_angle(PI), PI);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert_eq!(wrap_angle(0.25), 0.25);
    }
}
