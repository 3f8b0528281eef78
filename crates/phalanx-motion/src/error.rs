//! Why a plan cannot be driven, or why the settings are refused: [`MotionError`].

use phalanx_core::{Cell, Violation};

/// A refused setting, an invalid plan, or a plan the car cannot drive.
///
/// [`MotionError::is_undrivable`] tells the plan's faults (the car cannot follow it: a U-turn,
/// a turn too tight, a step too fast) from bad input (settings out of range, a car too large
/// for a cell, a plan that breaks the grid's rules). Plan faults name the agent (its index in
/// the instance) and the plan step (0 is the start): U-turns and tight corners first, the
/// earliest step of any agent (then the lowest agent), then the speed of every step.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// A setting outside its range.
    #[error("{name} = {value} is out of range: expected {expected}")]
    Parameter {
        /// The setting, as [`crate::MotionConfig`] and [`crate::Car`] name it.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The range it must be in.
        expected: &'static str,
    },
    /// The run would take too many integration sub-steps or samples.
    #[error(
        "the run would take {sub_steps:.3e} integration sub-steps and {samples:.3e} samples (all cars together), more than {limit}: make the step duration or the sample rate smaller, or the sub-step longer"
    )]
    TooLong {
        /// Sub-steps: (plan steps + 1) × ⌈step duration / sub-step⌉ × cars.
        sub_steps: f64,
        /// Samples: (plan steps + 1) × step duration × sample rate × cars.
        samples: f64,
        /// The most of either.
        limit: u64,
    },
    /// The car's body does not stay in its cell whatever its heading when its rear axle is on
    /// the cell's centre, so the plan's separation of agents does not carry over.
    #[error(
        "the car ({length} m × {width} m, wheelbase {wheelbase} m) does not fit a {cell} m cell: its body reaches {reach:.3} m from the rear axle, more than half a cell"
    )]
    CarTooLarge {
        /// Body length.
        length: f64,
        /// Body width.
        width: f64,
        /// Wheelbase.
        wheelbase: f64,
        /// Cell side.
        cell: f64,
        /// The farthest point of the body from the rear axle.
        reach: f64,
    },
    /// The plan breaks a rule of the grid (`phalanx_core::validate`).
    #[error("invalid plan: {0}")]
    InvalidPlan(Violation),
    /// The agent goes back to the cell it came from: a reversal in place, which a car
    /// driving forwards cannot do.
    #[error(
        "agent {agent}, step {step}: the agent turns back to {cell}, the cell it came from (a U-turn in place, which a car cannot drive)"
    )]
    UTurn {
        /// The agent.
        agent: usize,
        /// The step at which it is back in `cell`.
        step: usize,
        /// The cell it returns to.
        cell: Cell,
    },
    /// A 90° turn whose fillet, to stay in the corner cell, needs a smaller radius than the
    /// car's minimum turning radius.
    #[error(
        "agent {agent}, step {step}: the turn at {cell} fits an arc of radius at most {radius:.3} m (half a cell), below the car's minimum turning radius {min_radius:.3} m"
    )]
    TooTight {
        /// The agent.
        agent: usize,
        /// The step at which it reaches the corner cell.
        step: usize,
        /// The corner cell.
        cell: Cell,
        /// The largest fillet radius that fits (half a cell).
        radius: f64,
        /// The car's minimum turning radius, `wheelbase / tan(max_steer)`.
        min_radius: f64,
    },
    /// With a given step duration, a step needs more than the car's maximum speed.
    #[error(
        "agent {agent}, step {step}: the step needs {speed:.3} m/s, above the maximum speed {max_speed} m/s (give a longer step duration, or none to derive it)"
    )]
    TooFast {
        /// The agent.
        agent: usize,
        /// The step at whose end it must be in its next cell.
        step: usize,
        /// The speed the step needs.
        speed: f64,
        /// The car's maximum speed.
        max_speed: f64,
    },
}

impl MotionError {
    /// Whether the plan is valid on the grid but a car cannot follow it (`UTurn`,
    /// `TooTight`, `TooFast`), as opposed to bad input.
    pub fn is_undrivable(&self) -> bool {
        matches!(
            self,
            MotionError::UTurn { .. } | MotionError::TooTight { .. } | MotionError::TooFast { .. }
        )
    }

    /// The agent and the plan step a plan fault names.
    pub fn agent_step(&self) -> Option<(usize, usize)> {
        match *self {
            MotionError::UTurn { agent, step, .. }
            | MotionError::TooTight { agent, step, .. }
            | MotionError::TooFast { agent, step, .. } => Some((agent, step)),
            MotionError::InvalidPlan(ref violation) => violation.agent.map(|a| (a, violation.step)),
            MotionError::Parameter { .. }
            | MotionError::CarTooLarge { .. }
            | MotionError::TooLong { .. } => None,
        }
    }
}
