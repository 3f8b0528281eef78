//! The vocabulary of phalanx: cells, actions, the grid, instances, joint plans, the formation
//! loss, BFS distance maps, the one plan validator and the metrics of a plan.
//!
//! Coordinates follow the specification: cell `(x, y)` with `0 <= x < width`,
//! `0 <= y < height`; `Up` is `y + 1`. In MovingAI files `x` is the column and `y` the row.
//! This crate does no IO and draws no random numbers.
//!
//! ```
//! use phalanx_core::{Cell, Grid, Instance, Plan, validate, PlanMetrics};
//!
//! let grid = Grid::new(4, 1);
//! let inst = Instance::new(grid, vec![Cell::new(0, 0)], vec![Cell::new(2, 0)]).unwrap();
//! let plan = Plan::from_paths(&[vec![Cell::new(0, 0), Cell::new(1, 0), Cell::new(2, 0)]]);
//! validate(&inst, &plan).unwrap();
//! let metrics = PlanMetrics::of(&inst, &plan);
//! assert_eq!(metrics.makespan, 2);
//! assert_eq!(metrics.sum_of_costs, 2);
//! ```

mod action;
mod cell;
mod distance;
mod formation;
mod grid;
mod instance;
mod metrics;
mod plan;
mod validate;

pub use action::Action;
pub use cell::{AgentId, Cell, CellId};
pub use distance::{DistanceMap, octile_distance};
pub use formation::{formation_fit, formation_loss, formation_loss_squared};
pub use grid::Grid;
pub use instance::{Instance, InstanceError, step_limit};
pub use metrics::{PlanMetrics, STALL_WINDOW, Stall};
pub use plan::Plan;
pub use validate::{Violation, ViolationKind, validate};
