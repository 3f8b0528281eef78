//! [`drive`]: the settings checked, the reference paths built and timed, then every car
//! tracked at once on one clock, sub-step by sub-step, with the measurements taken as it
//! goes.

use phalanx_core::{Cell, Instance, Plan, validate};

use crate::geometry::{Quad, Vec2, distance, rectangle, square, wrap_angle};
use crate::path::Path;
use crate::{CarReport, Closest, Motion, MotionConfig, MotionError, Report, Sample};

/// Drives `plan` on `instance` with the cars and settings of `config`.
///
/// The reference of each agent is on its cell's anchor at every step instant `k × dt` and
/// moves at a constant speed in between (waits hold it still); each car starts on its start
/// cell's centre heading along its first move (`+x` if it never moves) and is tracked for
/// the plan's horizon plus one step interval.
///
/// # Errors
/// [`MotionError::Parameter`] or [`MotionError::CarTooLarge`] for settings out of range,
/// [`MotionError::InvalidPlan`] for a plan that breaks the grid's rules, and
/// [`MotionError::UTurn`], [`MotionError::TooTight`] or [`MotionError::TooFast`] for the
/// first step (then agent) a car cannot drive.
pub fn drive(
    instance: &Instance,
    plan: &Plan,
    config: &MotionConfig,
) -> Result<Motion, MotionError> {
    check(config)?;
    validate(instance, plan).map_err(MotionError::InvalidPlan)?;
    let min_radius = config.car.min_turning_radius();
    let mut paths = Vec::with_capacity(plan.n_agents());
    let mut first: Option<MotionError> = None;
    for agent in 0..plan.n_agents() {
        let steps: Vec<Cell> = plan.path(agent).collect();
        match Path::new(agent, &steps, config.cell, min_radius) {
            Ok(path) => paths.push(path),
            Err(err) => first = Some(earlier(first, err)),
        }
    }
    if let Some(err) = first {
        return Err(err);
    }
    let horizon = plan.horizon();
    let step_len = |path: &Path, k: usize| path.anchor(k + 1) - path.anchor(k);
    let longest = paths
        .iter()
        .flat_map(|path| (0..horizon).map(move |k| step_len(path, k)))
        .fold(0.0, f64::max);
    let dt = match (config.step_duration, config.car.max_speed) {
        (Some(dt), Some(max_speed)) => {
            for k in 0..horizon {
                for (agent, path) in paths.iter().enumerate() {
                    let speed = step_len(path, k) / dt;
                    if speed > max_speed * (1.0 + 1e-9) {
                        return Err(MotionError::TooFast { agent, step: k + 1, speed, max_speed });
                    }
                }
            }
            dt
        }
        (Some(dt), None) => dt,
        (None, Some(max_speed)) if longest > 0.0 => longest / max_speed,
        (None, _) => 1.0,
    };
    let required = |path: &Path| (0..horizon).map(|k| step_len(path, k) / dt).fold(0.0, f64::max);
    let sub_steps = (horizon as f64 + 1.0) * (dt / config.sub_step).ceil() * paths.len() as f64;
    let samples = (horizon as f64 + 1.0) * dt * config.sample_rate * paths.len() as f64;
    if sub_steps > MAX_SUB_STEPS as f64 || samples > MAX_SUB_STEPS as f64 {
        return Err(MotionError::TooLong { sub_steps, samples, limit: MAX_SUB_STEPS });
    }
    Ok(Run::new(instance, config, &paths, dt).simulate(horizon, &required))
}

/// The most integration sub-steps, and the most trajectory samples, of one run (all cars
/// together): beyond, the run would take minutes and gigabytes.
pub const MAX_SUB_STEPS: u64 = 50_000_000;

/// The shortest and longest lengths in metres (wheelbase, body, cell): within them the
/// geometry's tolerances hold.
pub const LENGTH_RANGE: (f64, f64) = (1e-3, 1e4);

/// Of two errors, the one at the earlier step, then the lower agent.
fn earlier(kept: Option<MotionError>, new: MotionError) -> MotionError {
    match kept {
        Some(kept)
            if kept.agent_step().map(|(a, s)| (s, a)) <= new.agent_step().map(|(a, s)| (s, a)) =>
        {
            kept
        }
        _ => new,
    }
}

/// Refuses settings out of range.
fn check(config: &MotionConfig) -> Result<(), MotionError> {
    let car = &config.car;
    let above_zero = |name: &'static str, value: f64| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(MotionError::Parameter { name, value, expected: "a finite number above 0" })
        }
    };
    above_zero("wheelbase", car.wheelbase)?;
    if !(car.max_steer_deg > 0.0 && car.max_steer_deg < 90.0) {
        return Err(MotionError::Parameter {
            name: "max_steer",
            value: car.max_steer_deg,
            expected: "an angle in (0, 90) degrees",
        });
    }
    above_zero("width", car.width)?;
    if !(car.length.is_finite() && car.length >= car.wheelbase) {
        return Err(MotionError::Parameter {
            name: "length",
            value: car.length,
            expected: "a finite length of at least the wheelbase",
        });
    }
    if let Some(max_speed) = car.max_speed {
        above_zero("max_speed", max_speed)?;
    }
    above_zero("cell", config.cell)?;
    if let Some(dt) = config.step_duration {
        above_zero("step_duration", dt)?;
    }
    above_zero("sub_step", config.sub_step)?;
    above_zero("sample_rate", config.sample_rate)?;
    above_zero("lookahead_min", config.tracker.lookahead_min)?;
    if !(config.tracker.lookahead_time.is_finite() && config.tracker.lookahead_time >= 0.0) {
        return Err(MotionError::Parameter {
            name: "lookahead_time",
            value: config.tracker.lookahead_time,
            expected: "a finite number of at least 0",
        });
    }
    above_zero("speed_gain", config.tracker.speed_gain)?;
    for (name, value) in [
        ("wheelbase", car.wheelbase),
        ("length", car.length),
        ("width", car.width),
        ("cell", config.cell),
    ] {
        if !(LENGTH_RANGE.0..=LENGTH_RANGE.1).contains(&value) {
            let expected = "a length from 0.001 to 10000 m";
            return Err(MotionError::Parameter { name, value, expected });
        }
    }
    if car.reach() > config.cell / 2.0 {
        return Err(MotionError::CarTooLarge {
            length: car.length,
            width: car.width,
            wheelbase: car.wheelbase,
            cell: config.cell,
            reach: car.reach(),
        });
    }
    Ok(())
}

/// One car's state and running figures.
#[derive(Clone, Debug)]
struct CarState {
    /// The rear axle.
    pos: Vec2,
    heading: f64,
    /// The arc length of the closest point of the path.
    progress: f64,
    cross_max: f64,
    cross_sum_sq: f64,
    heading_max: f64,
    step_error_max: f64,
    speed_max: f64,
    steer_max: f64,
    clearance: Option<f64>,
}

/// A run in progress: the settings, the paths, the cars.
struct Run<'a> {
    instance: &'a Instance,
    config: &'a MotionConfig,
    paths: &'a [Path],
    dt: f64,
    /// Sub-steps per plan step.
    n_sub: usize,
    /// The sub-step, `dt / n_sub`.
    h: f64,
    cars: Vec<CarState>,
}

impl<'a> Run<'a> {
    fn new(
        instance: &'a Instance,
        config: &'a MotionConfig,
        paths: &'a [Path],
        dt: f64,
    ) -> Run<'a> {
        let n_sub = ((dt / config.sub_step).ceil() as usize).max(1);
        let cars = paths
            .iter()
            .map(|path| CarState {
                pos: path.start(),
                heading: path.start_heading(),
                progress: 0.0,
                cross_max: 0.0,
                cross_sum_sq: 0.0,
                heading_max: 0.0,
                step_error_max: 0.0,
                speed_max: 0.0,
                steer_max: 0.0,
                clearance: None,
            })
            .collect();
        Run { instance, config, paths, dt, n_sub, h: dt / n_sub as f64, cars }
    }

    /// Tracks every car for `horizon` plan steps plus one to settle.
    fn simulate(mut self, horizon: usize, required: &dyn Fn(&Path) -> f64) -> Motion {
        let n_total = (horizon + 1) * self.n_sub;
        let sample_every = ((1.0 / (self.config.sample_rate * self.h)).round() as usize).max(1);
        let mut samples = Vec::new();
        let mut closest: Option<Closest> = None;
        let mut controls = vec![(0.0, 0.0); self.cars.len()];
        for i in 0..=n_total {
            let t = i as f64 * self.h;
            let (step, frac) = (i / self.n_sub, (i % self.n_sub) as f64 / self.n_sub as f64);
            for (agent, control) in controls.iter_mut().enumerate() {
                self.measure(agent, (i % self.n_sub == 0).then_some(step));
                *control = self.control(agent, step, frac, horizon);
                if i % sample_every == 0 || i == n_total {
                    let car = &self.cars[agent];
                    let (speed, steer) = *control;
                    let (x, y) = (car.pos.x, car.pos.y);
                    samples.push(Sample { t, agent, x, y, heading: car.heading, speed, steer });
                }
            }
            self.measure_bodies(t, &mut closest);
            if i < n_total {
                for (car, &(speed, steer)) in self.cars.iter_mut().zip(&controls) {
                    advance(car, speed, steer, self.config.car.wheelbase, self.h);
                }
            }
        }
        let n_instants = (n_total + 1) as f64;
        let cars = self
            .cars
            .iter()
            .zip(self.paths)
            .enumerate()
            .map(|(agent, (car, path))| CarReport {
                agent,
                corners: path.n_corners(),
                cross_track_max: car.cross_max,
                cross_track_rms: (car.cross_sum_sq / n_instants).sqrt(),
                heading_error_max_deg: car.heading_max.to_degrees(),
                step_error_max: car.step_error_max,
                required_speed: required(path),
                speed_max: car.speed_max,
                steer_max_deg: car.steer_max.to_degrees(),
                obstacle_clearance: car.clearance,
            })
            .collect::<Vec<_>>();
        let report = Report {
            car: self.config.car,
            cell: self.config.cell,
            step_duration: self.dt,
            sub_step: self.h,
            sample_period: sample_every as f64 * self.h,
            duration: n_total as f64 * self.h,
            min_turning_radius: self.config.car.min_turning_radius(),
            fillet_radius: self.config.cell / 2.0,
            required_speed: cars.iter().map(|c| c.required_speed).fold(0.0, f64::max),
            cars,
            closest,
        };
        Motion { report, samples }
    }

    /// Projects the car on its path and records its errors; at a step instant, its distance
    /// from the step's anchor too.
    fn measure(&mut self, agent: usize, step: Option<usize>) {
        let path = &self.paths[agent];
        let cell = self.config.cell;
        let car = &mut self.cars[agent];
        // The car moves a few millimetres per sub-step: a window round the last projection
        // keeps it on its own stretch where the path passes a cell away from itself.
        car.progress = path.project(car.pos, car.progress - 0.25 * cell, car.progress + 0.5 * cell);
        let cross = (path.point(car.progress) - car.pos).norm();
        car.cross_max = car.cross_max.max(cross);
        car.cross_sum_sq += cross * cross;
        let heading_error = wrap_angle(car.heading - path.heading(car.progress)).abs();
        car.heading_max = car.heading_max.max(heading_error);
        if let Some(step) = step {
            let error = (path.point(path.anchor(step)) - car.pos).norm();
            car.step_error_max = car.step_error_max.max(error);
        }
    }

    /// The speed and steering angle for the next sub-step: the reference's speed plus a
    /// proportional correction of the along-path error, and pure pursuit of the point one
    /// look-ahead distance ahead of the car's projection.
    fn control(&mut self, agent: usize, step: usize, frac: f64, horizon: usize) -> (f64, f64) {
        let path = &self.paths[agent];
        let config = self.config;
        let car = &mut self.cars[agent];
        let (s_ref, v_ref) = if step < horizon {
            let (a, b) = (path.anchor(step), path.anchor(step + 1));
            (a + frac * (b - a), (b - a) / self.dt)
        } else {
            (path.anchor(horizon), 0.0)
        };
        let mut speed = (v_ref + config.tracker.speed_gain * (s_ref - car.progress)).max(0.0);
        if let Some(max_speed) = config.car.max_speed {
            speed = speed.min(max_speed);
        }
        let lookahead =
            (config.tracker.lookahead_min * config.cell).max(config.tracker.lookahead_time * speed);
        let to_target = path.point(car.progress + lookahead) - car.pos;
        let dist = to_target.norm();
        let max_steer = config.car.max_steer();
        let steer = if dist > 1e-9 {
            let alpha = wrap_angle(to_target.angle() - car.heading);
            (2.0 * config.car.wheelbase * alpha.sin() / dist).atan().clamp(-max_steer, max_steer)
        } else {
            0.0
        };
        car.speed_max = car.speed_max.max(speed);
        car.steer_max = car.steer_max.max(steer.abs());
        (speed, steer)
    }

    /// Every car's body at this instant: the closest pair so far, each car's clearance to
    /// blocked cells and the map's border.
    fn measure_bodies(&mut self, t: f64, closest: &mut Option<Closest>) {
        let car = &self.config.car;
        let (half_length, half_width) = (car.length / 2.0, car.width / 2.0);
        let bounding = half_length.hypot(half_width);
        let centres: Vec<Vec2> = self
            .cars
            .iter()
            .map(|c| c.pos + Vec2::from_angle(c.heading) * (car.wheelbase / 2.0))
            .collect();
        let bodies: Vec<Quad> = centres
            .iter()
            .zip(&self.cars)
            .map(|(&centre, c)| rectangle(centre, c.heading, half_length, half_width))
            .collect();
        for a in 0..bodies.len() {
            for b in a + 1..bodies.len() {
                let best = closest.map_or(f64::INFINITY, |c| c.distance);
                if (centres[a] - centres[b]).norm() - 2.0 * bounding >= best {
                    continue;
                }
                let dist = distance(&bodies[a], &bodies[b]);
                if dist < best {
                    *closest = Some(Closest { distance: dist, time: t, agents: [a, b] });
                }
            }
        }
        let (side, grid) = (self.config.cell, self.instance.grid());
        for (body, state) in bodies.iter().zip(&mut self.cars) {
            let (lo, hi) = body.iter().fold(
                (
                    Vec2::new(f64::INFINITY, f64::INFINITY),
                    Vec2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
                ),
                |(lo, hi), p| {
                    (
                        Vec2::new(lo.x.min(p.x), lo.y.min(p.y)),
                        Vec2::new(hi.x.max(p.x), hi.y.max(p.y)),
                    )
                },
            );
            let index = |v: f64| (v / side).floor() as i32;
            for y in index(lo.y) - 1..=index(hi.y) + 1 {
                for x in index(lo.x) - 1..=index(hi.x) + 1 {
                    let cell = Cell::new(x, y);
                    if grid.is_free(cell) {
                        continue;
                    }
                    let corner = Vec2::new(f64::from(x) * side, f64::from(y) * side);
                    let dist = distance(body, &square(corner, side));
                    state.clearance = Some(state.clearance.map_or(dist, |c| c.min(dist)));
                }
            }
        }
    }
}

/// Integrates the kinematic bicycle over `h` seconds at constant speed and steering: the
/// rear axle moves on an arc of curvature `tan(steer) / wheelbase` (exactly).
fn advance(car: &mut CarState, speed: f64, steer: f64, wheelbase: f64, h: f64) {
    let rate = speed * steer.tan() / wheelbase;
    let turn = rate * h;
    if turn.abs() < 1e-12 {
        car.pos = car.pos + Vec2::from_angle(car.heading) * (speed * h);
    } else {
        let radius = speed / rate;
        let after = car.heading + turn;
        car.pos = car.pos
            + Vec2::new(after.sin() - car.heading.sin(), car.heading.cos() - after.cos()) * radius;
        car.heading = wrap_angle(after);
    }
}
