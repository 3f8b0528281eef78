//! One agent's reference path: the polyline through the centres of the cells it visits,
//! its 90° corners filleted with quarter circles that stay inside the corner cell, and the
//! arc length of each visited cell's reference point (its *anchor*), which the timing rule
//! reaches at the plan's step instants.
//!
//! Geometry (docs/motion.md): a fillet of radius `r` at a corner is tangent to both
//! segments at distance `d = r · tan(45°) = r` from the corner cell's centre, so it lies in the
//! corner cell when `d <= cell / 2`. The fillet radius is `cell / 2`, the largest that fits
//! (the tangent points are the mid-points of the cell's edges); it must be at least the
//! car's minimum turning radius. A straight cell's anchor is its centre, a corner cell's the
//! middle of its arc (`(√2 − 1) · r` from the centre).

use std::f64::consts::FRAC_PI_2;

use phalanx_core::Cell;

use crate::MotionError;
use crate::geometry::{Vec2, wrap_angle};

/// A piece of the path.
#[derive(Clone, Copy, Debug)]
enum Segment {
    /// A straight piece from `start` along the unit vector `dir`.
    Line { start: Vec2, dir: Vec2, len: f64 },
    /// A quarter circle round `centre` from angle `start_angle`, turning left (`turn = 1`)
    /// or right (`turn = -1`).
    Arc { centre: Vec2, radius: f64, start_angle: f64, turn: f64 },
}

impl Segment {
    fn len(&self) -> f64 {
        match *self {
            Segment::Line { len, .. } => len,
            Segment::Arc { radius, .. } => radius * FRAC_PI_2,
        }
    }

    /// The point at arc length `s` from the segment's start.
    fn point(&self, s: f64) -> Vec2 {
        match *self {
            Segment::Line { start, dir, .. } => start + dir * s,
            Segment::Arc { centre, radius, start_angle, turn } => {
                centre + Vec2::from_angle(start_angle + turn * s / radius) * radius
            }
        }
    }

    /// The heading (radians) at arc length `s`.
    fn heading(&self, s: f64) -> f64 {
        match *self {
            Segment::Line { dir, .. } => dir.angle(),
            Segment::Arc { radius, start_angle, turn, .. } => {
                wrap_angle(start_angle + turn * (s / radius + FRAC_PI_2))
            }
        }
    }

    /// The arc length in `[lo, hi]` (within the segment) of the point closest to `p`.
    fn closest(&self, p: Vec2, lo: f64, hi: f64) -> f64 {
        match *self {
            Segment::Line { start, dir, .. } => (p - start).dot(dir).clamp(lo, hi),
            Segment::Arc { centre, radius, start_angle, turn } => {
                // Unimodal in the angle except for a point on the far side of the centre:
                // compare the clamped angle with both ends.
                let offset = wrap_angle((p - centre).angle() - start_angle) * turn * radius;
                let candidates = [offset.clamp(lo, hi), lo, hi];
                let dist = |s: f64| (self.point(s) - p).norm();
                candidates
                    .into_iter()
                    .fold(candidates[0], |best, s| if dist(s) < dist(best) { s } else { best })
            }
        }
    }
}

/// One agent's reference path and timing.
#[derive(Clone, Debug)]
pub(crate) struct Path {
    /// The start cell's centre.
    start: Vec2,
    /// The unit direction before the first segment (the first move, else `+x`).
    start_dir: Vec2,
    /// The last cell's centre.
    end: Vec2,
    /// The unit direction after the last segment (the last move, else `+x`).
    end_dir: Vec2,
    segments: Vec<Segment>,
    /// Arc length at the start of each segment.
    offsets: Vec<f64>,
    length: f64,
    /// The arc length of the anchor of the agent's cell at each plan step.
    anchor_at_step: Vec<f64>,
    /// The number of 90° turns.
    n_corners: usize,
}

/// The centre of `cell` in metres.
pub(crate) fn centre(cell: Cell, side: f64) -> Vec2 {
    Vec2::new((f64::from(cell.x) + 0.5) * side, (f64::from(cell.y) + 0.5) * side)
}

fn unit(from: Cell, to: Cell) -> Vec2 {
    Vec2::new(f64::from(to.x - from.x), f64::from(to.y - from.y))
}

impl Path {
    /// The path of `agent` whose cell at each step is `steps` (a valid plan's path: every
    /// move to a neighbour), on cells of side `side`, its corners filleted with radius
    /// `side / 2`, which must be at least `min_radius`.
    ///
    /// # Errors
    /// The first [`MotionError::UTurn`] or [`MotionError::TooTight`] in step order.
    pub(crate) fn new(
        agent: usize,
        steps: &[Cell],
        side: f64,
        min_radius: f64,
    ) -> Result<Path, MotionError> {
        assert!(!steps.is_empty(), "a path has at least its start");
        let radius = side / 2.0;
        // The distinct cells visited, each with the step it is reached, and the node of
        // every step.
        let mut nodes: Vec<(Cell, usize)> = vec![(steps[0], 0)];
        let mut node_at_step = Vec::with_capacity(steps.len());
        node_at_step.push(0);
        for (step, &cell) in steps.iter().enumerate().skip(1) {
            let (here, _) = *nodes.last().expect("the start");
            if cell != here {
                debug_assert!(cell.is_adjacent(here), "a valid plan moves to neighbours");
                if let [.., (before, _), (turn, turn_step)] = nodes[..] {
                    if cell == before {
                        return Err(MotionError::UTurn { agent, step, cell });
                    }
                    let is_corner = unit(before, turn).dot(unit(turn, cell)) < 0.5;
                    if is_corner && radius < min_radius {
                        return Err(MotionError::TooTight {
                            agent,
                            step: turn_step,
                            cell: turn,
                            radius,
                            min_radius,
                        });
                    }
                }
                nodes.push((cell, step));
            }
            node_at_step.push(nodes.len() - 1);
        }

        let n_nodes = nodes.len();
        let dir = |k: usize| unit(nodes[k].0, nodes[k + 1].0);
        let is_corner = |k: usize| k > 0 && k + 1 < n_nodes && dir(k - 1).dot(dir(k)) < 0.5;
        // The fillet's tangent points are `d = r` from the corner for a 90° turn.
        let trim = |k: usize| if is_corner(k) { radius } else { 0.0 };
        let mut segments = Vec::new();
        let mut offsets = Vec::new();
        let mut anchors = Vec::with_capacity(n_nodes);
        let mut s = 0.0;
        let mut n_corners = 0;
        for (k, &(cell, _)) in nodes.iter().enumerate() {
            let here = centre(cell, side);
            if is_corner(k) {
                n_corners += 1;
                let (dir_in, dir_out) = (dir(k - 1), dir(k));
                let turn = dir_in.cross(dir_out).signum();
                let entry = here - dir_in * radius;
                let arc_centre = entry + dir_in.left() * (turn * radius);
                let arc = Segment::Arc {
                    centre: arc_centre,
                    radius,
                    start_angle: (entry - arc_centre).angle(),
                    turn,
                };
                anchors.push(s + arc.len() / 2.0);
                offsets.push(s);
                s += arc.len();
                segments.push(arc);
            } else {
                anchors.push(s);
            }
            if k + 1 < n_nodes {
                let len = side - trim(k) - trim(k + 1);
                if len > 1e-12 * side {
                    let line = Segment::Line { start: here + dir(k) * trim(k), dir: dir(k), len };
                    offsets.push(s);
                    s += len;
                    segments.push(line);
                }
            }
        }
        let plus_x = Vec2::new(1.0, 0.0);
        Ok(Path {
            start: centre(nodes[0].0, side),
            start_dir: if n_nodes > 1 { dir(0) } else { plus_x },
            end: centre(nodes[n_nodes - 1].0, side),
            end_dir: if n_nodes > 1 { dir(n_nodes - 2) } else { plus_x },
            segments,
            offsets,
            length: s,
            anchor_at_step: node_at_step.into_iter().map(|k| anchors[k]).collect(),
            n_corners,
        })
    }

    /// The number of 90° turns.
    pub(crate) fn n_corners(&self) -> usize {
        self.n_corners
    }

    /// The heading (radians) the car starts with: along its first move, else `+x`.
    pub(crate) fn start_heading(&self) -> f64 {
        self.start_dir.angle()
    }

    /// The start cell's centre.
    pub(crate) fn start(&self) -> Vec2 {
        self.start
    }

    /// The anchor's arc length at plan step `step` (the last step's past the plan's end).
    pub(crate) fn anchor(&self, step: usize) -> f64 {
        self.anchor_at_step[step.min(self.anchor_at_step.len() - 1)]
    }

    /// The index of the segment holding arc length `s` (the last one past the end).
    fn segment_at(&self, s: f64) -> usize {
        self.offsets.partition_point(|&off| off <= s).saturating_sub(1)
    }

    /// The point at arc length `s`; before the start and past the end, on the straight
    /// extensions along the first and last moves.
    pub(crate) fn point(&self, s: f64) -> Vec2 {
        if s <= 0.0 {
            return self.start + self.start_dir * s;
        }
        if s >= self.length {
            return self.end + self.end_dir * (s - self.length);
        }
        let i = self.segment_at(s);
        self.segments[i].point(s - self.offsets[i])
    }

    /// The path's heading (radians) at arc length `s`, extensions included.
    pub(crate) fn heading(&self, s: f64) -> f64 {
        if s <= 0.0 {
            return self.start_dir.angle();
        }
        if s >= self.length {
            return self.end_dir.angle();
        }
        let i = self.segment_at(s);
        self.segments[i].heading(s - self.offsets[i])
    }

    /// The arc length in `[lo, hi]` of the point of the (extended) path closest to `p`;
    /// ties go to the smaller arc length.
    pub(crate) fn project(&self, p: Vec2, lo: f64, hi: f64) -> f64 {
        let mut best = (f64::INFINITY, lo);
        let mut consider = |s: f64| {
            let dist = (self.point(s) - p).norm();
            if dist < best.0 {
                best = (dist, s);
            }
        };
        if lo < 0.0 {
            consider((p - self.start).dot(self.start_dir).clamp(lo, hi.min(0.0)));
        }
        for (segment, &offset) in self.segments.iter().zip(&self.offsets) {
            let (a, b) = (lo.max(offset), hi.min(offset + segment.len()));
            if a <= b {
                consider(offset + segment.closest(p, a - offset, b - offset));
            }
        }
        if hi > self.length {
            let beyond = (p - self.end).dot(self.end_dir);
            consider(
                self.length + beyond.clamp(lo.max(self.length) - self.length, hi - self.length),
            );
        }
        best.1
    }
}
