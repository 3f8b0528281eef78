//! Continuous car-like motion from discrete grid plans: each agent of a
//! [`phalanx_core::Plan`] becomes a car with Ackermann steering (a kinematic bicycle) that
//! drives a smooth version of its grid path on the plan's clock, and the run is measured:
//! tracking errors, the closest two cars' bodies came, their clearance to obstacles.
//!
//! [`drive`] builds each agent's reference path (cell centres joined by straight pieces,
//! 90° corners filleted with quarter circles of radius `cell / 2` that stay in the corner
//! cell), times it so that the reference is on the plan's cell at every step instant
//! `t = step × dt` (all agents share one clock, so the plan's ordering carries over), and
//! tracks it with pure pursuit and a proportional speed controller, integrating the bicycle
//! model exactly over fixed sub-steps. A U-turn in place, a corner tighter than the car can
//! turn, or (with a given step duration) a step faster than its top speed is a
//! [`MotionError`] naming the agent and the step. Settings, geometry, gains and the measured
//! figures: docs/motion.md. No IO, and the same input gives the same output, bit for bit.
//!
//! ```
//! use phalanx_core::{Cell, Grid, Instance, Plan};
//! use phalanx_motion::{Car, MotionConfig, drive};
//!
//! // One agent turning left round a corner on 1 m cells.
//! let path = vec![Cell::new(0, 0), Cell::new(1, 0), Cell::new(2, 0), Cell::new(2, 1), Cell::new(2, 2)];
//! let inst = Instance::new(Grid::new(3, 3), vec![path[0]], vec![path[4]]).unwrap();
//! let plan = Plan::from_paths(&[path]);
//! let config = MotionConfig::new(Car::new(0.25, 30.0), 1.0);
//! let motion = drive(&inst, &plan, &config).unwrap();
//! assert!(motion.report.fillet_radius >= motion.report.min_turning_radius);
//! assert!(motion.report.cars[0].cross_track_max < 0.05);
//! ```

mod drive;
mod error;
mod geometry;
mod path;

pub use drive::{LENGTH_RANGE, MAX_SUB_STEPS, drive};
pub use error::MotionError;

use serde::Serialize;

/// The car: a kinematic bicycle model (Ackermann steering) referenced at the rear axle, with
/// a rectangular body centred on the middle of the wheelbase.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Car {
    /// Distance between the axles, in metres (above 0).
    pub wheelbase: f64,
    /// The largest steering angle either way, in degrees, in `(0, 90)`.
    pub max_steer_deg: f64,
    /// Body length in metres, at least the wheelbase ([`Car::new`]: `1.4 × wheelbase`, an
    /// overhang of `0.2 × wheelbase` at either end).
    pub length: f64,
    /// Body width in metres ([`Car::new`]: `0.8 × wheelbase`).
    pub width: f64,
    /// The highest speed in m/s; `None`: unbounded.
    pub max_speed: Option<f64>,
}

impl Car {
    /// A car with the default body (`1.4 × wheelbase` by `0.8 × wheelbase`) and no top speed.
    pub fn new(wheelbase: f64, max_steer_deg: f64) -> Car {
        Car {
            wheelbase,
            max_steer_deg,
            length: 1.4 * wheelbase,
            width: 0.8 * wheelbase,
            max_speed: None,
        }
    }

    /// The largest steering angle in radians.
    pub fn max_steer(&self) -> f64 {
        self.max_steer_deg.to_radians()
    }

    /// The minimum turning radius of the rear axle, `wheelbase / tan(max_steer)`.
    pub fn min_turning_radius(&self) -> f64 {
        self.wheelbase / self.max_steer().tan()
    }

    /// The farthest point of the body from the rear axle (a front corner).
    pub fn reach(&self) -> f64 {
        f64::hypot((self.length + self.wheelbase) / 2.0, self.width / 2.0)
    }
}

/// The tracking controller's gains: pure pursuit for the steering, a proportional
/// controller on the along-path error for the speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tracker {
    /// The smallest look-ahead distance, in cells (default 0.25).
    pub lookahead_min: f64,
    /// The look-ahead time in seconds: the look-ahead distance is
    /// `max(lookahead_min × cell, lookahead_time × speed)` (default 0.1 s).
    pub lookahead_time: f64,
    /// The speed controller's gain in 1/s: `speed = v_ref + speed_gain × (s_ref − s)`
    /// (default 4).
    pub speed_gain: f64,
}

impl Default for Tracker {
    fn default() -> Tracker {
        Tracker { lookahead_min: 0.25, lookahead_time: 0.1, speed_gain: 4.0 }
    }
}

/// The settings of a run: the car, the grid's scale, the clock, the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionConfig {
    /// The car (every agent drives the same).
    pub car: Car,
    /// The side of a grid cell in metres.
    pub cell: f64,
    /// The duration of one plan step `dt` in seconds; `None`: the shortest at which no step
    /// needs more than the car's top speed, or 1 s when it has none.
    pub step_duration: Option<f64>,
    /// The longest integration sub-step in seconds (default 0.01); the sub-step used divides
    /// `dt` evenly.
    pub sub_step: f64,
    /// Trajectory samples per second (default 10), rounded to a whole number of sub-steps.
    pub sample_rate: f64,
    /// The controller's gains.
    pub tracker: Tracker,
}

impl MotionConfig {
    /// The default settings for `car` on cells of side `cell` metres.
    pub fn new(car: Car, cell: f64) -> MotionConfig {
        MotionConfig {
            car,
            cell,
            step_duration: None,
            sub_step: 0.01,
            sample_rate: 10.0,
            tracker: Tracker::default(),
        }
    }
}

/// The outcome of [`drive`]: the report and the trajectory samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Motion {
    /// What was measured.
    pub report: Report,
    /// Every car's state at each sample instant, time-major (all cars at one instant, in
    /// agent order, then the next instant).
    pub samples: Vec<Sample>,
}

/// The run's settings as used and its measured figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The car.
    pub car: Car,
    /// The cell side in metres.
    pub cell: f64,
    /// The duration of one plan step in seconds (given or derived).
    pub step_duration: f64,
    /// The integration sub-step in seconds.
    pub sub_step: f64,
    /// The time between two samples in seconds.
    pub sample_period: f64,
    /// The run's length in seconds: the plan's horizon times `dt`, plus one `dt` to settle.
    pub duration: f64,
    /// The car's minimum turning radius in metres.
    pub min_turning_radius: f64,
    /// The corners' fillet radius in metres (`cell / 2`).
    pub fillet_radius: f64,
    /// The highest reference speed any car needs, in m/s.
    pub required_speed: f64,
    /// Per car, in agent order.
    pub cars: Vec<CarReport>,
    /// The closest two cars' bodies came; `None` with one agent.
    pub closest: Option<Closest>,
}

impl Report {
    /// Whether two bodies touched, or a body touched a blocked cell or the map's border.
    pub fn has_contact(&self) -> bool {
        self.closest.is_some_and(|c| c.distance <= 0.0)
            || self.cars.iter().any(|c| c.obstacle_clearance.is_some_and(|d| d <= 0.0))
    }
}

/// One car's figures over the whole run (every sub-step counts).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CarReport {
    /// The agent.
    pub agent: usize,
    /// Its 90° turns.
    pub corners: usize,
    /// The largest distance of the rear axle from the reference path, in metres.
    pub cross_track_max: f64,
    /// The root mean square of that distance.
    pub cross_track_rms: f64,
    /// The largest difference between the car's heading and the path's at the closest
    /// point, in degrees.
    pub heading_error_max_deg: f64,
    /// The largest distance of the rear axle from the reference point of the plan's cell at
    /// the step instants, in metres.
    pub step_error_max: f64,
    /// The highest reference speed it needs, in m/s.
    pub required_speed: f64,
    /// The highest speed it drove.
    pub speed_max: f64,
    /// The largest steering angle it used, in degrees.
    pub steer_max_deg: f64,
    /// The closest its body came to a blocked cell or the map's border, in metres; `None`
    /// when it never came within a cell of one.
    pub obstacle_clearance: Option<f64>,
}

/// Where two cars' bodies came closest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Closest {
    /// The distance between the bodies in metres (0: they touch or overlap).
    pub distance: f64,
    /// When, in seconds (the first such instant).
    pub time: f64,
    /// The two agents, the lower first.
    pub agents: [usize; 2],
}

/// One car's state at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Time in seconds.
    pub t: f64,
    /// The agent.
    pub agent: usize,
    /// The rear axle's position in metres (`x` along the grid's columns, `y` its rows; cell
    /// `(i, j)` has its centre at `((i + 0.5) × cell, (j + 0.5) × cell)`).
    pub x: f64,
    /// See `x`.
    pub y: f64,
    /// Heading in radians, counter-clockwise from `+x`, in `(-π, π]`.
    pub heading: f64,
    /// Speed in m/s over the next sub-step.
    pub speed: f64,
    /// Steering angle in radians over the next sub-step (positive: left).
    pub steer: f64,
}
